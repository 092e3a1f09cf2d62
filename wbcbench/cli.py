"""The command line: `wbcbench run SCENARIO --controller NAME [--robot R] [--mode M] [--duration S] [--out DIR]`,
`wbcbench list`, and the report commands `reproduce`, `report`, `compare` (wbcbench/report/commands.py)."""

from __future__ import annotations

import argparse
import sys

from .errors import WbcError


def _lists() -> tuple[list[str], list[str], list[str], list[str]]:
    from . import catalogue

    if not catalogue.has_plugins():  # the shipped names alone, without importing the registries (fast --help)
        return (catalogue.scenarios(), list(catalogue.BUILTIN_CONTROLLERS), catalogue.robots(),
                list(catalogue.MODES))
    from .controllers.base import available_controllers
    from .robots import available_robots
    from .scenarios import available_scenarios
    from .types import ActuationMode

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
    r.add_argument("--taskset", "-t", default=None,
                   help="task-set YAML for the controller (default: tasksets/<robot>/<controller>.yaml)")
    r.add_argument("--sensors", "-s", default=None,
                   help="sensor profile: ideal (default), talos-like, or a profile YAML (overrides the scenario's)")
    r.add_argument("--seed", type=int, default=0, help="random seed of the sensor model (default 0)")
    r.add_argument("--model-error", default=None, metavar="FILE.yaml",
                   help="how the simulated robot differs from the controller's model (masses, payloads, friction, "
                        "ground softness; see wbcbench/sim/model_error.py)")
    r.add_argument("--realism", default=None, metavar="PRESET",
                   help="the simulated robot's hidden hardware: actuator chains (friction, drive elasticity, torque "
                        "loop), hip flexibility, sensors; talos-real or a preset YAML (wbcbench/sim/realism)")
    r.add_argument("--predict-falls", action="store_true",
                   help="log the predicted-fall signal (capture point vs support polygon, tilt rate) every tick")
    r.add_argument("--safe-stop", action="store_true",
                   help="on a predicted fall, switch to joint damping about the current posture (implies "
                        "--predict-falls)")
    r.add_argument("--fault", action="append", default=[], metavar="TYPE[:TARGET]@START[+DURATION]",
                   help="inject a fault, e.g. sensor_nan:ft_left@1.0+0.2, qp_failure@2+0.05, "
                        "joint_locked:leg_left_4_joint@1.5 (repeatable; see wbcbench/faults.py)")
    r.add_argument("--realtime", action="store_true",
                   help="pace the simulation to the wall clock; late ticks are counted (summary `realtime`, log "
                        "`lateness_ms`)")
    r.add_argument("--engine", default="mujoco",
                   help="physics engine: mujoco (default), dart (pip install 'wbcbench[dart]'), or a plugin's")
    r.add_argument("--video", action="store_true",
                   help="render the run to RUN_DIR/video.mp4 when it ends (see `wbcbench render`)")
    from .viz.commands import add_view_options
    add_view_options(r)
    r.add_argument("--out", "-o", default=None, help="run directory (default: runs/<scenario>-<controller>-...)")
    r.add_argument("--overwrite", action="store_true", help="replace a run already in the --out directory")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    r.add_argument("--step-adjustment", action="store_true",
                   help="walks: re-plan the next foothold and step time when the measured DCM leaves its region")
    sub.add_parser("list", help="list scenarios, controllers, robots and modes")
    from .report.commands import add_subcommands
    add_subcommands(sub)
    from .teleop.commands import add_subcommand as add_teleop
    add_teleop(sub)
    from .robustness.commands import add_subcommand as add_robustness
    add_robustness(sub)
    from .study.commands import add_subcommands as add_study
    add_study(sub)
    from .viz.commands import add_subcommand as add_render, add_view_subcommand
    add_render(sub)
    add_view_subcommand(sub)
    from .doctor import add_subcommand as add_doctor
    add_doctor(sub)
    from .envelope.commands import add_subcommand as add_envelope
    add_envelope(sub)
    rb = sub.add_parser("robot", help="robot tools: `robot init SOURCE --out PROFILE.yaml` writes a first profile")
    rb.add_argument("action", choices=["init"], help="init: generate a profile from a humanoid's model")
    rb.add_argument("source", help="a URDF path, an example-robot-data model or a fourier-robot-descriptions model")
    rb.add_argument("--out", "-o", required=True, help="the profile YAML to write")
    rb.add_argument("--name", default=None, help="the robot's name (default: the model's)")
    rb.add_argument("--knee", type=float, default=0.6, help="knee bend of the standing posture [rad] (0.6)")
    rb.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    return p


def _cmd_run(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from .runner import run
    from .summary import render_summary

    console = Console()
    if args.duration is not None and args.duration <= 0:
        raise WbcError(f"--duration must be > 0, got {args.duration}")
    faults = []
    if args.fault:
        from .faults import parse_fault_option
        from .robots import load_robot

        joints = load_robot(args.robot).joint_names
        faults = [parse_fault_option(f, joints) for f in args.fault]
    if args.step_adjustment:  # the scenario loaded here so that its step adjustment can be switched on
        from .robots import load_robot
        from .scenarios import load_scenario

        robot = load_robot(args.robot)
        scen = load_scenario(args.scenario, robot, args.duration)
        enable = getattr(scen, "enable_step_adjustment", None)
        if enable is None:
            raise WbcError(f"--step-adjustment: scenario '{args.scenario}' (kind {scen.kind}) has no step "
                           "adjustment; allowed: kind walk")
        enable()
        args.scenario, args.robot, args.duration = scen, robot, None
    from .viz.commands import live_view_from

    view = live_view_from(args)
    kwargs = dict(taskset=args.taskset, sensors=args.sensors, seed=args.seed, model_error=args.model_error,
                  faults=faults, predict_falls=args.predict_falls, safe_stop=args.safe_stop,
                  overwrite=args.overwrite, realtime=args.realtime, probes=[view] if view else [],
                  engine=args.engine, realism=args.realism)
    try:
        if args.quiet:
            result = run(args.scenario, args.controller, args.robot, args.mode, args.duration, args.out, **kwargs)
        else:
            with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                          TimeElapsedColumn(), console=console, transient=True) as prog:
                name = args.scenario if isinstance(args.scenario, str) else args.scenario.spec.name
                task = prog.add_task(f"{name} / {args.controller}", total=1.0)
                result = run(args.scenario, args.controller, args.robot, args.mode, args.duration, args.out,
                             progress=lambda f: prog.update(task, completed=f), **kwargs)
    finally:
        if view is not None:
            view.close()
    render_summary(console, result.summary, result.run_dir)
    if args.video:
        from .viz.render import render_run

        console.print(f"video: {render_run(result.run_dir)}")
    return 1 if result.summary["fell"] else 0


def _cmd_list() -> int:
    """The registries, each entry with where it comes from; broken plugins one line each on stderr (exit 2)."""
    from . import catalogue

    if not catalogue.has_plugins():  # the shipped names alone, without importing the registries
        print(_list_text(catalogue.scenarios(), catalogue.BUILTIN_KINDS, catalogue.BUILTIN_CONTROLLERS,
                         catalogue.robots(), catalogue.MODES, catalogue.TASK_TYPES, catalogue.STABILIZERS,
                         catalogue.sensor_profiles(), catalogue.CORRECTIONS, catalogue.engines()))
        return 0
    from .controllers.base import available_controllers, builtin_controllers, controller_plugin_errors
    from .controllers.corrections import BUILTIN_CORRECTIONS, available_corrections, correction_plugin_errors
    from .robots.profile import builtin_robots, plugin_robots, robot_plugin_errors
    from .scenarios.base import available_kinds, builtin_kinds, kind_plugin_errors
    from .sensing import available_profiles
    from .sim.engines import available_engines, engine_label, engine_plugin_errors
    from .stabilizers.base import available_stabilizers
    from .tasks import task_types

    def origin(module: str) -> str:
        return "" if module.startswith("wbcbench.") else f" [{module.split('.')[0]}]"

    s, _, _, m = _lists()
    builtin = builtin_controllers()
    ctrls = [n + ("" if n in builtin else origin(c.__module__)) for n, c in available_controllers().items()]
    builtin_k = builtin_kinds()
    kinds = [n + ("" if n in builtin_k else origin(k.__module__)) for n, k in sorted(available_kinds().items())]
    corrections = [n + ("" if n in BUILTIN_CORRECTIONS else f" [{o.split(' ')[0].split('.')[0].split(':')[0]}]")
                   for n, o in available_corrections().items()]
    plug = plugin_robots()
    robots = builtin_robots() + [f"{n} [{p}]" for n, p in sorted(plug.items())]
    print(_list_text(s, kinds, ctrls, robots, m, task_types(), available_stabilizers(), available_profiles(),
                     corrections, [engine_label(e) for e in available_engines()]))
    errors = [*controller_plugin_errors().values(), *kind_plugin_errors().values(), *robot_plugin_errors().values(),
              *correction_plugin_errors().values(), *engine_plugin_errors().values()]
    for e in errors:
        print(f"wbcbench: error: {e}", file=sys.stderr)
    return 2 if errors else 0


def _list_text(scenarios, kinds, controllers, robots, modes, tasks, stabilizers, sensors, corrections,
               engines) -> str:
    return (f"scenarios:   {', '.join(scenarios)}\nkinds:       {', '.join(kinds)}\n"
            f"controllers: {', '.join(controllers)}\nrobots:      {', '.join(robots)}\n"
            f"modes:       {', '.join(modes)}\ntasks:       {', '.join(tasks)}\n"
            f"stabilizers: {', '.join(stabilizers)}\ncorrections: {', '.join(corrections)}\n"
            f"sensors:     {', '.join(sensors)}\nengines:     {', '.join(engines)}")


def _check_mujoco() -> None:
    """MuJoCo picks its OpenGL backend at import: a MUJOCO_GL whose library is missing breaks the import itself."""
    try:
        import mujoco  # noqa: F401
    except Exception as exc:
        import os

        raise WbcError(f"MuJoCo cannot be imported with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
                       f"({type(exc).__name__}: {exc}); unset MUJOCO_GL or use MUJOCO_GL=egl") from None


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.command == "list":
            return _cmd_list()
        if args.command == "doctor":
            from .doctor import run_command as run_doctor
            return run_doctor(args)
        if args.command == "robot":
            from .robots.generate import run_command as run_robot
            return run_robot(args)
        _check_mujoco()
        if args.command == "run":
            return _cmd_run(args)
        from .report.commands import COMMANDS, run_command
        if args.command in COMMANDS:
            return run_command(args)
        if args.command == "envelope":
            from .envelope.commands import run_command as run_envelope
            return run_envelope(args)
        if args.command == "robustness":
            from .robustness.commands import run_command as run_robustness
            return run_robustness(args)
        from .study.commands import COMMANDS as STUDY_COMMANDS
        if args.command in STUDY_COMMANDS:
            from .study.commands import run_command as run_study
            return run_study(args)
        if args.command == "teleop":
            from .teleop.commands import run_command as run_teleop
            return run_teleop(args)
        if args.command == "render":
            from .viz.commands import run_command as run_render
            return run_render(args)
        if args.command == "view":
            from .viz.commands import run_view
            return run_view(args)
    except WbcError as exc:
        from .errors import one_line

        print(f"wbcbench: error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"wbcbench: {exc}" if str(exc) else "wbcbench: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
