"""The report subcommands of the command line: `reproduce`, `report` and `compare`.

    wbcbench reproduce [--quick] [--jobs N] [--no-keyframes] [--video] [--robot NAME | --robots all|R1,R2] --out DIR
    wbcbench report RUN_DIR... --out DIR
    wbcbench compare RUN_A RUN_B
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

COMMANDS = ("reproduce", "report", "compare")


def add_subcommands(sub: argparse._SubParsersAction) -> None:
    """Register the report subcommands on the CLI's subparsers."""
    r = sub.add_parser("reproduce", help="run the paper's matrix in parallel and write report.md/html, "
                                         "results.json and figures")
    r.add_argument("--out", "-o", required=True, help="report directory (run directories go to DIR/runs)")
    r.add_argument("--quick", action="store_true", help="shortened walks and sanity runs (minutes, not an hour)")
    r.add_argument("--jobs", "-j", type=int, default=None, help="parallel processes (default: the cores available)")
    r.add_argument("--ray", default=None, metavar="ADDRESS|auto",
                   help="run the cells on Ray ('auto': a local instance, HOST:PORT: a cluster)")
    r.add_argument("--envelope", action="store_true",
                   help="also measure capability envelopes (a few axes, coarse resolution) into DIR/envelope and "
                        "add them to the report (wbcbench envelope)")
    r.add_argument("--no-sanity", action="store_true", help="skip the standing scenarios' sanity section")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    r.add_argument("--controllers", default=None,
                   help="comma-separated controllers (default: the paper's three, every one in the sanity section); "
                        "a controller of yours is run on the paper's scenarios and joins the tables")
    r.add_argument("--scenarios", default=None, help="comma-separated scenarios to keep (default: all)")
    r.add_argument("--no-keyframes", action="store_true",
                   help="no key-frame strip per table cell in the report (they are rendered where the cell ran)")
    r.add_argument("--video", action="store_true",
                   help="also render each table cell's video (RUN_DIR/video.mp4), linked from the report")
    r.add_argument("--robot", default="talos",
                   help="robot name or profile YAML (default talos); another robot's report has our numbers only, "
                        "at the scenario sizes of its profile")
    r.add_argument("--sensors", default=None,
                   help="also run the paper's walk, platforms and stairs under this sensor profile (e.g. talos-like)")
    r.add_argument("--engine", default="mujoco", help="physics engine of every run: mujoco (default), dart, a plugin's")
    r.add_argument("--realism", default=None, metavar="PRESET",
                   help="the matrix on the ideal robot (OUT/ideal/) and on this realistic one (OUT/<preset>/, e.g. "
                        "talos-real: actuator chains, hip flexibility, talos-like sensors) side by side "
                        "(OUT/real-robot.md, .html, .json), then paper 000's Tables 9-10 on the same preset "
                        "(OUT/posture-gains/, `wbcbench robustness posture-gains`)")
    r.add_argument("--no-posture-gains", action="store_true",
                   help="with --realism: skip the Tables 9-10 posture-gain study")
    r.add_argument("--engines", default=None, metavar="E1,E2",
                   help="the matrix on each engine (OUT/<engine>/) and an engine-sensitivity section beside them "
                        "(OUT/engine-sensitivity.md, .html, .json), the first engine the reference")
    r.add_argument("--robots", default=None, metavar="all|R1,R2",
                   help="the matrix on every robot ('all') or on these, on one process pool (OUT/<robot>/ each), "
                        "and a cross-robot section beside them (OUT/robots.md, .html, .json)")
    p = sub.add_parser("report", help="remake tables and figures from existing run directories (no simulation)")
    p.add_argument("run_dirs", nargs="+", metavar="RUN_DIR", help="run directories (from `wbcbench run`)")
    p.add_argument("--out", "-o", required=True, help="report directory")
    c = sub.add_parser("compare", help="two runs' summaries and metrics side by side")
    c.add_argument("run_a", metavar="A", help="run directory A")
    c.add_argument("run_b", metavar="B", help="run directory B")


def _print_side_by_side(console, reports, out: Path, what: str, stem: str) -> None:
    """Each variant's report (named by its folder: the engine, `ideal`, the preset) and the comparison's files."""
    for r in reports:
        n_ok = sum(o.status == "ok" for o in r.outcomes)
        console.print(f"{r.out_dir.name}: {len(r.outcomes)} cells, {n_ok} ok; report {r.out_dir / 'report.md'}")
    console.print(f"{what}: {out / (stem + '.md')}, {out / (stem + '.html')}")


def run_command(args: argparse.Namespace) -> int:
    """Execute a report subcommand. Domain errors propagate to the CLI (one line, exit 2)."""
    from rich.console import Console

    from ..errors import WbcError
    from .compare import compare
    from .reproduce import report, reproduce

    console = Console()
    if args.command == "reproduce":
        if args.jobs is not None and args.jobs < 1:
            raise WbcError(f"--jobs must be >= 1, got {args.jobs}")
        kwargs = dict(quick=args.quick, jobs=args.jobs, progress=not args.quiet,
                      sanity=not args.no_sanity, sensors=args.sensors,
                      controllers=args.controllers.split(",") if args.controllers else None,
                      scenarios=args.scenarios.split(",") if args.scenarios else None, ray=args.ray,
                      keyframes=not args.no_keyframes, video=args.video, robot=args.robot)
        if args.robots:
            if args.engines or args.realism or args.robot != "talos" or args.envelope:
                raise WbcError("--robots runs every robot on one engine, ideal: not with --robot, --engines, "
                               "--realism or --envelope")
            from .reproduce import reproduce_robots

            kwargs.pop("robot")
            reports, _ = reproduce_robots(args.out, args.robots, engine=args.engine, **kwargs)
            _print_side_by_side(console, reports, Path(args.out), "robots side by side", "robots")
            return 0
        if args.realism:
            if args.engines:
                raise WbcError("--realism and --engines: one comparison at a time")
            from .reproduce import reproduce_realism

            reports, _ = reproduce_realism(args.out, args.realism, engine=args.engine,
                                           posture_gains=not args.no_posture_gains, **kwargs)
            _print_side_by_side(console, reports, Path(args.out), "ideal vs realistic", "real-robot")
            if args.envelope:  # the envelopes of both robots, each in its own report
                from ..envelope.report import reproduce_section

                for r, preset in zip(reports, (None, args.realism)):
                    env = reproduce_section(r.out_dir, args.robot, args.controllers, args.jobs or 1, args.ray,
                                            args.engine, realism=preset)
                    console.print(f"envelope ({r.out_dir.name}): {env}")
            return 0
        if args.engines:
            from .reproduce import reproduce_engines

            reports, _ = reproduce_engines(args.out, args.engines.split(","), **kwargs)
            _print_side_by_side(console, reports, Path(args.out), "engine sensitivity", "engine-sensitivity")
            return 0
        res = reproduce(args.out, engine=args.engine, **kwargs)
        if args.envelope:
            from ..envelope.report import reproduce_section

            env = reproduce_section(res.out_dir, args.robot, args.controllers, args.jobs or 1, args.ray, args.engine)
            console.print(f"envelope: {env}")
        counts: dict[str, int] = {}
        for o in res.outcomes:
            counts[o.status] = counts.get(o.status, 0) + 1
        console.print(f"{len(res.outcomes)} cells: " + ", ".join(f"{n} {s}" for s, n in sorted(counts.items())))
        for o in res.outcomes:
            if o.media_error:
                console.print(f"  {o.section}-{o.scenario}-{o.controller}: {o.media_error}")
        console.print(f"wall time {res.wall_time_s:.1f} s; report: {res.out_dir / 'report.md'}, "
                      f"{res.out_dir / 'report.html'}, {res.out_dir / 'results.json'}")
        return 0
    if args.command == "report":
        res = report(args.run_dirs, args.out)
        for e in res.errors:
            print(f"wbcbench: error: {e}", file=sys.stderr)
        console.print(f"{len(res.outcomes)} run(s) reported in {res.out_dir / 'report.md'}")
        return 2 if res.errors else 0
    if args.command == "compare":
        compare(args.run_a, args.run_b, console)
        return 0
    raise ValueError(f"not a report command: {args.command}")
