"""The command line: `wbcbench run SCENARIO --controller NAME [--robot R] [--mode M] [--duration S] [--out DIR]`,
`wbcbench list`, and the report commands `reproduce`, `report`, `compare` (wbcbench/report/commands.py)."""

from __future__ import annotations

import argparse
import sys

from .errors import WbcError


def _lists() -> tuple[list[str], list[str], list[str], list[str]]:
    from .controllers.base import available_controllers
    from .robots import available_robots
    from .scenarios import available_scenarios
    from .sim.model import ActuationMode

    return (available_scenarios(), list(available_controllers()), available_robots(),
            [m.value for m in ActuationMode])


def build_parser() -> argparse.ArgumentParser:
    scenarios, controllers, robots, modes = _lists()
    catalogue = (f"scenarios: {', '.join(scenarios)}\ncontrollers: {', '.join(controllers)}\n"
                 f"robots: {', '.join(robots)}\nmodes: {', '.join(modes)}")
    p = argparse.ArgumentParser(prog="wbcbench", formatter_class=argparse.RawDescriptionHelpFormatter,
                                description="Run, compare and teleoperate whole-body controllers in MuJoCo.",
                                epilog=catalogue)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run one scenario with one controller", epilog=catalogue,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("scenario", help="scenario name or path to a scenario YAML")
    r.add_argument("--controller", "-c", required=True, help="controller name")
    r.add_argument("--robot", "-r", default="talos", help="robot name or profile YAML path (default: talos)")
    r.add_argument("--mode", "-m", default=None, help="actuation mode (default: the controller's)")
    r.add_argument("--duration", "-d", type=float, default=None, help="override the scenario duration [s]")
    r.add_argument("--out", "-o", default=None, help="run directory (default: runs/<scenario>-<controller>-...)")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    sub.add_parser("list", help="list scenarios, controllers, robots and modes")
    from .report.commands import add_subcommands
    add_subcommands(sub)
    from .teleop.commands import add_subcommand as add_teleop
    add_teleop(sub)
    from .study.commands import add_subcommands as add_study
    add_study(sub)
    return p


def _cmd_run(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from .runner import run
    from .summary import render_summary

    console = Console()
    if args.duration is not None and args.duration <= 0:
        raise WbcError(f"--duration must be > 0, got {args.duration}")
    if args.quiet:
        result = run(args.scenario, args.controller, args.robot, args.mode, args.duration, args.out)
    else:
        with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                      TimeElapsedColumn(), console=console, transient=True) as prog:
            task = prog.add_task(f"{args.scenario} / {args.controller}", total=1.0)
            result = run(args.scenario, args.controller, args.robot, args.mode, args.duration, args.out,
                         progress=lambda f: prog.update(task, completed=f))
    render_summary(console, result.summary, result.run_dir)
    return 1 if result.summary["fell"] else 0


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.command == "list":
            s, c, r, m = _lists()
            print(f"scenarios:   {', '.join(s)}\ncontrollers: {', '.join(c)}\nrobots:      {', '.join(r)}\n"
                  f"modes:       {', '.join(m)}")
            return 0
        if args.command == "run":
            return _cmd_run(args)
        from .report.commands import COMMANDS, run_command
        if args.command in COMMANDS:
            return run_command(args)
        from .study.commands import COMMANDS as STUDY_COMMANDS
        if args.command in STUDY_COMMANDS:
            from .study.commands import run_command as run_study
            return run_study(args)
        if args.command == "teleop":
            from .teleop.commands import run_command as run_teleop
            return run_teleop(args)
    except WbcError as exc:
        print(f"wbcbench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("wbcbench: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
