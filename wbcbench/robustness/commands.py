"""`wbcbench robustness push SCENARIO --controller C [...]`: the push-recovery protocol from the command line;
`wbcbench robustness posture-gains [--realism P]`: paper 000's Tables 9-10 experiment (`posture.py`)."""

from __future__ import annotations

import argparse
import os

from ..errors import ConfigError


def add_subcommand(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser("robustness", help="robustness protocols (push recovery, posture gains)")
    rs = r.add_subparsers(dest="protocol", required=True)
    p = rs.add_parser("push", help="largest impulse survived per push direction and gait phase (bisection)")
    p.add_argument("scenario", help="scenario name or YAML (e.g. stand, walk-20cm)")
    p.add_argument("--controller", "-c", action="append", required=True,
                   help="controller (repeat, or comma-separated, for several)")
    p.add_argument("--directions", type=int, default=8, help="push directions around the robot (default 8)")
    p.add_argument("--phases", default=None,
                   help="comma-separated among ds, ss-early, ss-mid, ss-late (default: ds for standing scenarios, "
                        "all four for walking ones)")
    p.add_argument("--seeds", type=int, default=None, help="seeds per cell (default 1; 3 when --sensors is noisy)")
    p.add_argument("--push-duration", type=float, default=0.1, help="[s] (default 0.1)")
    p.add_argument("--max-impulse", type=float, default=60.0, help="[N s] top of the bisection (default 60)")
    p.add_argument("--iterations", type=int, default=None, help="bisection steps (default 5; 3 with --quick)")
    p.add_argument("--tolerance", type=float, default=0.10, help="[m] CoM back within this of the plan")
    p.add_argument("--sensors", default=None, help="sensor profile (default ideal)")
    p.add_argument("--robot", "-r", default="talos")
    p.add_argument("--engine", default="mujoco", help="physics engine of every trial: mujoco (default), dart, a plugin's")
    p.add_argument("--realism", default=None, metavar="PRESET",
                   help="the simulated robot's hidden hardware in every trial: talos-real or a preset YAML "
                        "(wbcbench/sim/realism); its sensor profile unless --sensors names one")
    p.add_argument("--quick", action="store_true",
                   help="3 bisection steps from half the top (7.5 N s resolution at 60 N s), the scenario's "
                        "-quick variant when there is one")
    p.add_argument("--step-adjustment", action="store_true",
                   help="walks: re-plan the next foothold and step time when the measured DCM leaves its region")
    p.add_argument("--jobs", "-j", type=int, default=None, help="parallel processes (default: the cores)")
    p.add_argument("--out", "-o", required=True, help="output directory (report, polar plot, raw runs)")
    p.add_argument("--quiet", "-q", action="store_true")
    g = rs.add_parser("posture-gains",
                      help="paper 000 Tables 9-10: the Success and Fail posture gains on the ideal and a realistic "
                           "robot, what it takes to diverge, the largest safe gain per body part")
    g.add_argument("--realism", default="talos-actuation", metavar="PRESET",
                   help="the realistic robot: a preset name or YAML (default talos-actuation: talos-real's "
                        "actuators and hip flexibility, ideal sensing)")
    g.add_argument("--robot", "-r", default="talos", help="a robot with a tsid-torque-posture task set (talos)")
    g.add_argument("--parts", default=",".join(("legs", "torso", "arms", "head")),
                   help="body parts to bisect, comma-separated (default: legs,torso,arms,head)")
    g.add_argument("--iterations", type=int, default=4,
                   help="bisection steps per part, log scale between the Success and Fail gains (default 4; 0: none)")
    g.add_argument("--no-ablation", action="store_true", help="skip the mechanism table")
    g.add_argument("--no-com-task", action="store_true",
                   help="skip the Success gains with a CoM task under model and calibration errors")
    g.add_argument("--ranges", action="store_true",
                   help="also the preset's unpublished values (drive stiffness and friction, torque loop, hip "
                        "damping) one at a time at the ends of their ranges, both gain sets")
    g.add_argument("--duration", "-d", type=float, default=None, help="[s] override the scenario's (8 s)")
    g.add_argument("--jobs", "-j", type=int, default=None, help="parallel processes (default: the cores)")
    g.add_argument("--out", "-o", required=True, help="output directory (report, task sets, raw runs)")


def run_command(args: argparse.Namespace) -> int:
    if args.protocol == "posture-gains":
        return _posture_gains(args)
    return _push(args)


def _posture_gains(args: argparse.Namespace) -> int:
    from rich.console import Console

    from .posture import PostureStudy, run_study, validate, write_report

    if args.jobs is not None and args.jobs < 1:
        raise ConfigError(f"must be >= 1, got {args.jobs}", key="--jobs")
    study = PostureStudy(realism=args.realism, robot=args.robot, duration=args.duration,
                         iterations=args.iterations, ablation=not args.no_ablation, com_task=not args.no_com_task,
                         ranges=args.ranges,
                         parts=tuple(p.strip() for p in args.parts.split(",") if p.strip()))
    validate(study)
    result = run_study(study, args.out, jobs=args.jobs)
    md = write_report(result, args.out)
    Console().print(md.read_text())
    print(f"report: {md}, raw runs: {md.parent / 'runs'}")
    return 0


def _push(args: argparse.Namespace) -> int:
    from rich.console import Console

    from ..sensing import load_sensor_profile
    from .push import PHASES, PushStudy, phase_times, run_study, write_report

    controllers = tuple(c for arg in args.controller for c in arg.split(",") if c)
    from ..controllers.base import available_controllers
    from ..errors import UnknownNameError

    from ..sim.engines import engine_class

    engine_class(args.engine)  # an unknown or missing engine fails before anything runs
    preset = None
    if args.realism is not None:  # a bad preset fails before anything runs
        from ..robots import load_robot
        from ..sim.realism import check_realism

        preset = check_realism(args.realism, load_robot(args.robot), args.engine)
    known = available_controllers()
    for c in controllers:
        if c not in known:
            raise UnknownNameError("controller", c, known, key="--controller")
    for key, val in (("--directions", args.directions), ("--iterations", args.iterations), ("--jobs", args.jobs),
                     ("--seeds", args.seeds)):
        if val is not None and val < 1:
            raise ConfigError(f"must be >= 1, got {val}", key=key)
    for key, val in (("--push-duration", args.push_duration), ("--max-impulse", args.max_impulse),
                     ("--tolerance", args.tolerance)):
        if not val > 0:
            raise ConfigError(f"must be > 0, got {val}", key=key)
    sensors = args.sensors if args.sensors is not None else getattr(preset, "sensors", None)
    noisy = sensors is not None and not load_sensor_profile(sensors).ideal
    from ..scenarios import available_scenarios

    scenario = args.scenario
    if args.quick and scenario + "-quick" in available_scenarios():
        scenario += "-quick"
    times = phase_times(scenario, args.robot)
    if args.phases:
        phases = tuple(p.strip() for p in args.phases.split(","))
        bad = [p for p in phases if p not in PHASES]
        if bad:
            raise ConfigError(f"unknown phase(s) {', '.join(bad)}; allowed: {', '.join(PHASES)}", key="--phases")
    else:
        phases = tuple(times)
    study = PushStudy(scenario, controllers, directions=args.directions, phases=phases,
                      seeds=args.seeds or (3 if noisy else 1), push_duration=args.push_duration,
                      max_impulse=args.max_impulse, iterations=args.iterations or (3 if args.quick else 5),
                      tolerance=args.tolerance, robot=args.robot, sensors=args.sensors, probe_max=not args.quick,
                      engine=args.engine, realism=args.realism,
                      step_adjustment=args.step_adjustment)
    console = Console()
    jobs = args.jobs or os.cpu_count() or 1
    if args.quiet:
        results = run_study(study, args.out, jobs=jobs)
    else:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("[bold]push cells"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      console=console, transient=True) as prog:
            task = prog.add_task("cells", total=None)
            results = run_study(study, args.out, jobs=jobs,
                                progress=lambda k, n: prog.update(task, completed=k, total=n))
    md = write_report(study, results, args.out)
    console.print(md.read_text())
    console.print(f"report: {md}, polar plot: {md.parent / 'push_polar.png'}, raw runs: {md.parent / 'runs'}")
    return 0
