"""`wbcbench envelope AXES... -c CONTROLLERS [--robot R] [--range AXIS=EASY:HARD] [--resolution R|AXIS=R]
[--jobs N | --ray ADDRESS] --out DIR`."""

from __future__ import annotations

import argparse

from ..errors import ConfigError

RESOLUTION_PRESETS = {"coarse": 4.0, "default": 1.0, "fine": 0.25}


def add_subcommand(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("envelope", help="capability envelopes: the hardest value of each axis a controller passes")
    from .axes import available_axes
    p.add_argument("axes", nargs="+", help=f"axes, or 'all': {', '.join(available_axes())}")
    p.add_argument("--controllers", "-c", required=True, help="comma-separated controller names")
    p.add_argument("--robot", "-r", default="talos")
    p.add_argument("--range", action="append", default=[], metavar="AXIS=EASY:HARD",
                   help="the search range of an axis (from a passing value to the hardest one tried)")
    p.add_argument("--resolution", action="append", default=[], metavar="coarse|default|fine|AXIS=WIDTH",
                   help="bracket width at which the bisection stops: a preset scaling every axis's default "
                        "(coarse x4, fine /4) or one axis's width (repeatable)")
    p.add_argument("--tolerance", type=float, default=0.10, help="final CoM error bound [m] (default 0.10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random axes (sensor noise)")
    p.add_argument("--engine", default="mujoco")
    p.add_argument("--realism", default=None, metavar="PRESET",
                   help="the simulated robot's hidden hardware in every trial: talos-real or a preset YAML "
                        "(wbcbench/sim/realism)")
    p.add_argument("--jobs", "-j", type=int, default=1, help="processes (default 1)")
    p.add_argument("--ray", default=None, metavar="ADDRESS|auto", help="run the searches on Ray")
    p.add_argument("--out", "-o", required=True, help="output directory (a finished trial there is not re-run)")
    p.add_argument("--no-keyframes", action="store_true",
                   help="do not render the key frames of each cell's last success and first failure")


def _parse(args):
    from .axes import AXES, get_axis
    from .search import EnvelopeStudy

    names = list(AXES) if args.axes == ["all"] else args.axes
    axes = [get_axis(a) for a in names]
    ranges, res = {}, {}
    scale = 1.0
    for item in args.range:
        name, _, rng = item.partition("=")
        get_axis(name)
        try:
            easy, hard = (float(x) for x in rng.split(":"))
        except ValueError:
            raise ConfigError(f"'{item}' is not AXIS=EASY:HARD", key="--range") from None
        ranges[name] = (easy, hard)
    for item in args.resolution:
        if item in RESOLUTION_PRESETS:
            scale = RESOLUTION_PRESETS[item]
            continue
        name, eq, width = item.partition("=")
        if not eq:
            raise ConfigError(f"'{item}' is not one of {', '.join(RESOLUTION_PRESETS)} nor AXIS=WIDTH",
                              key="--resolution")
        get_axis(name)
        try:
            res[name] = float(width)
        except ValueError:
            raise ConfigError(f"'{item}': width is not a number", key="--resolution") from None
    for a in axes:
        res.setdefault(a.name, a.resolution * scale)
    if args.tolerance <= 0:
        raise ConfigError(f"must be > 0, got {args.tolerance}", key="--tolerance")
    ctrls = tuple(c for c in args.controllers.split(",") if c)
    return EnvelopeStudy(axes=tuple(a.name for a in axes), controllers=ctrls, robot=args.robot, ranges=ranges,
                         resolutions=res, tolerance=args.tolerance, seed=args.seed, engine=args.engine,
                         realism=_preset(args.realism))


def _preset(realism: str | None) -> str | None:
    """A preset file as an absolute path (the trials may run in another working directory), a name as is."""
    if realism is not None and realism.endswith((".yaml", ".yml")):
        from pathlib import Path

        return str(Path(realism).resolve())
    return realism


def run_command(args) -> int:
    from rich.console import Console

    from ..study.execute import make_executor
    from .report import write_report
    from .search import run_envelope

    study = _parse(args)
    console = Console()

    def progress(k, n, r):
        lim = "-" if r["limit"] is None else f"{r['limit']:g}"
        console.print(f"[{k}/{n}] {r['controller']} {r['axis']}: {lim} {r['unit']} ({r['mode']}; "
                      f"{len(r['trials'])} trials, {r['wall_s']:.0f} s)")

    with make_executor(args.jobs, args.ray) as ex:
        results = run_envelope(study, args.out, executor=ex, progress=progress)
    md = write_report(study, results, args.out, keyframes=not args.no_keyframes)
    console.print(md.read_text(), markup=False)
    crashed = [r for r in results if r["limit"] is None and r["mode"] == "error"]
    if crashed:  # a crash (not a fall) at the easy value: the controller cannot run the axis's scenario
        r = crashed[0]
        raise ConfigError(f"controller '{r['controller']}' cannot run axis '{r['axis']}': its run at the easy value "
                          f"{r['easy']:g} crashed ({r['reason']}); report of the others in {md}", key="--controllers")
    return 0
