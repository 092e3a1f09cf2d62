"""`wbcbench teleop`: a whole-body teleoperation session in simulation (paper 004), from a recording or a live
UDP stream.

    wbcbench teleop --mocap FILE|NAME|udp://127.0.0.1:PORT [--controller tsid-teleop] [--mode spd|position|torque]
                    [--speed FACTOR] [--no-repulsors] [--no-stabilizer] [--no-reach-cap]
                    [--anchor rest|absolute|offset] [--duration S] [--out DIR] [--net SPEC]
                    [--predict none|velocity|spline]
    wbcbench teleop --list

`--net SPEC` impairs the operator's stream (wbcbench/teleop/link/network.py): a recording is replayed through the
link in simulated time, a udp:// stream passes through a loopback relay listening on HOST:PORT; `--predict`
extrapolates the newest received pose over its age (wbcbench/teleop/link/prediction.py).

The session is a `teleop` scenario (wbcbench/scenarios/teleop_kind.py) run by the usual runner, with the
self-collision geoms of the robot profile checked every tick (`SimOptions.self_collision = "detect"`, or
`--self-collision physical` to make them act). The run directory is the usual one; `hand_errors.npz` adds the
per-tick hand errors (position [m], rotation, both hands) behind Table II's statistics.

Exit codes: 0 completed, 1 the robot fell, 2 bad input (unreadable or malformed recording, bad option): one line
on stderr.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ...errors import ConfigError, UnknownNameError, WbcError

COMMAND = "teleop"
DEFAULT_CONTROLLER = "tsid-teleop"
#: the task set `--locomotion stepping` runs the teleoperation controller with (tasksets/<robot>/<name>.yaml)
STEPPING_TASKSET = "teleop-stepping"


def add_subcommand(sub: argparse._SubParsersAction) -> None:
    """Register `wbcbench teleop` on the CLI's subparsers."""
    p = sub.add_parser(COMMAND, help="whole-body teleoperation from a recording or a live UDP pose stream",
                       description="Whole-body teleoperation (paper 004): the operator's hands and head from "
                                   "motion capture drive the robot's grippers and head; feet in contact, CoM held.")
    p.add_argument("--mocap", "-i", default=None,
                   help="a shipped recording (see --list), a .bvh/.mvnx/.csv/.c3d/.trc file, or udp://HOST:PORT")
    p.add_argument("--list", action="store_true", help="list the shipped recordings and exit")
    p.add_argument("--controller", "-c", default=DEFAULT_CONTROLLER, help=f"default {DEFAULT_CONTROLLER}")
    p.add_argument("--robot", "-r", default="talos", help="robot name or profile YAML path (default: talos)")
    p.add_argument("--engine", default="mujoco", help="physics engine: mujoco (default), dart, a plugin's")
    p.add_argument("--realism", default=None, metavar="PRESET",
                   help="the simulated robot's hidden hardware: talos-real or a preset YAML (wbcbench/sim/realism); "
                        "needs --mode torque or position")
    p.add_argument("--mode", "-m", default=None, help="spd (default), position or torque")
    p.add_argument("--speed", type=float, default=1.0, help="replay speed factor for recordings (default 1)")
    p.add_argument("--no-repulsors", action="store_true", help="drop the self-collision repulsor tasks")
    p.add_argument("--no-stabilizer", action="store_true", help="disable the force-based stabilizer (Eq. 2-7)")
    p.add_argument("--no-reach-cap", action="store_true",
                   help="tsid-teleop: do not cap the hands' and head's commanded accelerations while their targets "
                        "are out of reach and moving (the paper's controller)")
    p.add_argument("--duration", "-d", type=float, default=None,
                   help="seconds to simulate (default: the recording's length / speed; required for udp://)")
    p.add_argument("--self-collision", choices=["detect", "physical", "off"], default="detect",
                   help="gripper-body contacts: counted only (default), counted and acting, or not checked")
    p.add_argument("--on-loss", choices=["hold", "reference"], default="hold",
                   help="while the source is invalid: hold the last targets (default) or return to the reference")
    p.add_argument("--anchor", choices=["absolute", "offset", "rest"], default="rest",
                   help="rest (default): the operator at rest overlaid on the robot at rest, reaching hands overlaid "
                        "absolutely; absolute: the paper's plain overlay (TALOS' hips take the resting hands); "
                        "offset: every position shifted by the calibration offset (relative teleoperation)")
    p.add_argument("--locomotion", default="auto",
                   help="an operator who walks: auto (default: the walk taken out of the references when the "
                        "operator moves, the robot stands), feet_fixed (always), off (never), or stepping "
                        "(recordings: the robot steps where the operator steps, through the walking stack; the "
                        "controller then uses its teleop-stepping task set, position mode by default)")
    p.add_argument("--out", "-o", default=None, help="run directory (default: runs/teleop-<source>-...)")
    p.add_argument("--length-unit", default="auto",
                   help="a BVH file's length unit: auto (detected from the skeleton, default), m, cm, mm, in, ft "
                        "or metres per unit")
    p.add_argument("--up-axis", default="auto", choices=["auto", "x", "y", "z"],
                   help="the recording's vertical axis for the unit detection (default auto)")
    p.add_argument("--segment-map", default=None, metavar="FILE.yaml",
                   help="canonical MVN segment name -> the file's segment name, when the names and the skeleton's "
                        "chains do not tell")
    p.add_argument("--realtime", action="store_true",
                   help="pace the replay to the wall clock (live streams are always paced); late ticks and the "
                        "worst lateness are counted in the summary (`realtime`) and logged (`lateness_ms`)")
    p.add_argument("--no-filter", action="store_true",
                   help="pass the operator's references to the controller unfiltered (no garbage, body, jump or "
                        "speed filter; wbcbench/teleop/safety/command_filter.py)")
    p.add_argument("--net", default=None, metavar="SPEC",
                   help="impair the operator's stream, e.g. latency=50ms,jitter=5ms,loss=5%%,burst=3,reorder=2%%,"
                        "duplicate=1%%,corrupt=1%%,stall=0.5s@3s,seed=1: a recording is replayed through the link "
                        "in simulated time (reproducible); a udp:// stream passes through a loopback relay that "
                        "listens on HOST:PORT (wbcbench/teleop/link/network.py)")
    p.add_argument("--predict", default="none", choices=["none", "velocity", "spline"],
                   help="extrapolate the newest received operator pose over its age (streams and --net): "
                        "constant velocity, or a quadratic over the last frames (default none)")
    p.add_argument("--predict-horizon", type=float, default=0.15, metavar="S",
                   help="cap on the extrapolation [s] (default 0.15: a stalled stream does not fly away)")
    p.add_argument("--predict-latency", type=float, default=0.0, metavar="S",
                   help="live streams: the one-way latency the receiver cannot observe, added to the frames' "
                        "age (e.g. half the round trip) [s] (default 0)")
    p.add_argument("--overwrite", action="store_true", help="replace a run already in the --out directory")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    from ...viz.commands import add_view_options

    add_view_options(p)  # --view: the robot and the operator's hand / head targets in the browser as it runs


def list_text() -> str:
    from ..human.registry import list_recordings

    rows = [f"{r.name:<16} {r.duration:5.1f} s @ {r.frame_rate:g} Hz  operator {r.operator:<10} {r.description}"
            for r in list_recordings()]
    return "\n".join(rows)


def _check_controller(name: str) -> None:
    from ...controllers.base import available_controllers
    from ...controllers.teleop import TSIDTeleop

    ctrls = available_controllers()
    teleop = [n for n, c in ctrls.items() if issubclass(c, TSIDTeleop)]
    if name not in ctrls:
        raise UnknownNameError("controller", name, ctrls, key="--controller")
    if name not in teleop:
        raise ConfigError(f"controller '{name}' has no teleoperation task set; use one of: {', '.join(teleop)}",
                          key="--controller")


def run_session(mocap, *, robot="talos", controller: str = DEFAULT_CONTROLLER, mode: str | None = None,
                speed: float = 1.0, repulsors: bool = True, stabilizer: bool = True, reach_cap: bool = True,
                duration: float | None = None,
                out: str | Path | None = None, self_collision: str = "detect", on_loss: str = "hold",
                quiet: bool = True, progress=None, overwrite: bool = False, realtime: bool = False, view=None,
                engine: str = "mujoco", realism=None, **params):
    """Run one teleoperation session; returns the runner's `RunResult`.

    `view`: a live view (`wbcbench.viz.live.LiveView`) to show the robot and the retargeted targets in, or None.

    `mocap`: a recording name, a file path, `udp://HOST:PORT`, or a `MocapRecording` / `UdpPoseReceiver`.
    `reach_cap`: False turns tsid-teleop's out-of-reach caps off. `engine`: the physics engine
    (`wbcbench.sim.engines`). `realism`: a realism preset (`wbcbench.sim.realism`: name, YAML file or `Realism`),
    None for the ideal robot; it needs torque or position mode.
    Other keyword arguments are `teleop` scenario params (e.g. `proportion`, `engage_time`, `feedforward`).

    Raises:
        WbcError (ConfigError): bad input, before anything is simulated.
    """
    import time as _time

    import numpy as np

    from ...controllers.base import available_controllers
    from ...robots import Robot, load_robot
    from ...runner import run
    from ...scenarios.teleop_kind import TeleopScenario
    from ...sim.model import ActuationMode, SimOptions
    from ...sim.self_collision import SelfCollisionProbe

    if not (np.isfinite(speed) and speed > 0):
        raise ConfigError(f"--speed must be a finite number > 0, got {speed}", key="--speed")
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise ConfigError(f"--duration must be > 0, got {duration}", key="--duration")
    if isinstance(mocap, str) and mocap.startswith("udp://") and duration is None:
        raise ConfigError("a live stream needs --duration", key="--duration")
    _check_controller(controller)
    from ..human.locomotion import LOCOMOTION_MODES

    locomotion = params.get("locomotion", "auto")
    if locomotion not in LOCOMOTION_MODES:
        raise ConfigError(f"unknown locomotion '{locomotion}'; allowed: {', '.join(LOCOMOTION_MODES)}",
                          key="--locomotion")
    stepping = locomotion == "stepping"
    robot = load_robot(robot) if not isinstance(robot, Robot) else robot
    cls = available_controllers()[controller]
    try:
        # stepping: the walking task set's mode (position) unless one is asked for
        default_mode = ActuationMode.POSITION if stepping else cls.default_mode
        mode_ = ActuationMode(mode) if mode is not None else default_mode
    except ValueError:
        raise ConfigError(f"unknown mode '{mode}'; allowed: {', '.join(m.value for m in cls.modes)}",
                          key="--mode") from None
    if realism is not None:  # a bad preset fails before anything runs
        from ...sim.realism import check_realism

        realism = check_realism(realism, robot, engine)
        if mode_ is ActuationMode.SPD:
            raise ConfigError("a realism preset needs --mode torque or position (the SPD law assumes the nominal "
                              "joints)", key="--mode")
    scen = TeleopScenario.from_source(robot, mocap, duration=duration or 0.0, speed=speed, on_loss=on_loss,
                                      name=f"teleop-{_label(mocap)}", **params)
    kw = {}
    if stepping:  # the lower body walks: the robot's walking task set with the hands and head
        from ...controllers.taskset import load_taskset, taskset_path

        kw["taskset"] = load_taskset(taskset_path(robot, STEPPING_TASKSET), robot)
    ctrl = cls(robot, mode_, scen.spec.control_dt, repulsors=repulsors, stabilizer=stabilizer, reach_cap=reach_cap,
               **kw)
    probes = [SelfCollisionProbe()] if self_collision != "off" else []
    if view is not None:
        probes.append(view)
    if out is None:
        stamp = _time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"teleop-{_label(mocap)}-x{speed:g}-{controller}-{mode_.value}-{stamp}"
    try:
        result = run(scen, ctrl, robot=robot, out=out, progress=progress, overwrite=overwrite, realtime=realtime,
                     sim_options=SimOptions(self_collision=self_collision), probes=probes, engine=engine,
                     realism=realism)
    finally:
        close = getattr(scen.source, "close", None)
        if scen.live and close is not None:
            close()
        if scen.relay is not None:
            scen.relay.close()
    errors = getattr(scen, "hand_error_samples", None)
    if errors:
        np.savez_compressed(Path(result.run_dir) / "hand_errors.npz", **errors)
    return result


def _label(mocap) -> str:
    if isinstance(mocap, str):
        if mocap.startswith("udp://"):
            return "udp"
        return Path(mocap).stem or "mocap"
    return Path(getattr(mocap, "source", "") or "mocap").stem or "mocap"


def conventions_line(mocap: str, length_unit="auto", up_axis: str = "auto", segment_map: str | None = None) -> str:
    """What is detected in a recording file's data (unit, axes, rest pose, names: one line), "" for a shipped
    recording's name or a live stream. Errors in the file propagate (one line, exit 2)."""
    from ..io.loader import RECORDING_SUFFIXES, load_recording

    path = Path(mocap)
    if mocap.startswith("udp://") or path.suffix.lower() not in RECORDING_SUFFIXES:
        return ""
    line = load_recording(path, length_unit=length_unit, up_axis=up_axis).conventions.get("line", "")
    if line and segment_map:
        line += f"; segments from {segment_map} (given)"
    return line


def run_command(args: argparse.Namespace) -> int:
    """Execute `wbcbench teleop`. Domain errors propagate to the CLI (one line, exit 2)."""
    import numpy as np
    from rich.console import Console

    console = Console()
    if args.list:
        print(list_text())
        return 0
    if args.mocap is None:
        raise WbcError("give --mocap FILE|NAME|udp://HOST:PORT (or --list)")
    kwargs = dict(robot=args.robot, engine=args.engine, realism=args.realism, controller=args.controller,
                  mode=args.mode,
                  speed=args.speed,
                  repulsors=not args.no_repulsors, stabilizer=not args.no_stabilizer,
                  reach_cap=not args.no_reach_cap, duration=args.duration,
                  out=args.out, self_collision=args.self_collision, on_loss=args.on_loss, anchor=args.anchor,
                  overwrite=args.overwrite, realtime=args.realtime)
    if args.locomotion != "auto":  # the default is the scenario's own (and keeps the params as they were)
        kwargs["locomotion"] = args.locomotion
    if args.no_filter:
        kwargs["safety"] = {"enabled": False}
    kwargs.update(length_unit=args.length_unit, up_axis=args.up_axis)
    if args.segment_map:
        kwargs["segment_map"] = str(Path(args.segment_map).resolve())
    if args.net is not None:
        from ..link.network import parse_impairment

        kwargs["network"] = parse_impairment(args.net, where="--net")
    for key, value in (("--predict-horizon", args.predict_horizon), ("--predict-latency", args.predict_latency)):
        if not (np.isfinite(value) and value >= 0):
            raise ConfigError(f"must be a duration >= 0 s, got {value}", key=key)
    kwargs.update(predict=args.predict, predict_horizon=args.predict_horizon, predict_latency=args.predict_latency)
    line = conventions_line(args.mocap, args.length_unit, args.up_axis, args.segment_map)
    if line:
        print(line, flush=True)
    from ...viz.commands import live_view_from

    kwargs["view"] = live_view_from(args)
    try:
        if args.quiet:
            result = run_session(args.mocap, **kwargs)
        else:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                          TimeElapsedColumn(), console=console, transient=True) as prog:
                task = prog.add_task(f"teleop {args.mocap}", total=1.0)
                result = run_session(args.mocap, progress=lambda f: prog.update(task, completed=f), **kwargs)
    finally:
        if kwargs["view"] is not None:
            kwargs["view"].close()
    render(console, result.summary, result.run_dir)
    return 1 if result.summary["fell"] else 0


def render(console, summary: dict, run_dir) -> None:
    """The teleoperation summary: status, Table II statistics, self-collisions, source health."""
    from ...summary import pacing_text, summary_table

    s, m = summary, summary.get("metrics", {})
    t = summary_table(s)
    t.add_row("simulated", f"{s['sim_time_s']:.3f} s of {s['duration_s']:.3f} s (wall {s['wall_time_s']:.1f} s)")
    sk = m.get("teleop", {}).get("skeleton") or {}
    if sk.get("length_unit") or sk.get("mapping") not in (None, "names"):
        t.add_row("skeleton", f"segments by {sk.get('mapping')}; length unit {sk.get('length_unit') or 'metres'}; "
                              f"up {sk.get('up_axis')}")
    if s.get("realtime"):
        t.add_row("wall-clock pacing", pacing_text(s["realtime"]))
    st = s["step_time_us"]
    if st["median"] is not None:
        t.add_row("controller step", f"median {st['median']:.0f} us, p99 {st['p99']:.0f} us")
    for key, label in (("hand_position_error_m", "hand position error [m]"),
                       ("hand_rotation_error", "hand rotation error ||I - R_ref R^-1||_F")):
        v = m.get(key)
        if v and v.get("mean") is not None:
            t.add_row(label, f"mean {v['mean']:.4f}  std {v['std']:.4f}  min {v['min']:.2e}  max {v['max']:.4f}")
    if m.get("hand_reachable_fraction") is not None:
        r, o = m["hand_position_error_reachable_m"], m["hand_position_error_out_of_reach_m"]
        f = (lambda v: f"{v:.4f}" if v is not None else "-")
        t.add_row("hand error, reachable / out of reach [m]",
                  f"mean {f(r['mean'])} ({100 * m['hand_reachable_fraction']:.0f} % of the hand samples) / "
                  f"{f(o['mean'])}")
        if m.get("hand_reachable_in_time_fraction") is not None:
            it = m["hand_position_error_reachable_in_time_m"]
            t.add_row("hand error, reachable in time [m]",
                      f"mean {f(it['mean'])} ({100 * m['hand_reachable_in_time_fraction']:.0f} % of the hand "
                      f"samples: where an arm at its joints' speed limits could have followed)")
    if "self_collisions" in m:
        pairs = ", ".join(f"{k} ({n} ticks)" for k, n in m.get("self_collision_pairs", {}).items())
        t.add_row("self-collisions", f"{m['self_collisions']} contact events, {m['self_collision_ticks']} ticks"
                  + (f": {pairs}" if pairs else ""))
    tele = m.get("teleop", {})
    if tele:
        t.add_row("source", f"{tele.get('source')} {tele.get('mocap')} x{tele.get('speed')}, "
                            f"{tele.get('invalid_ticks')} invalid ticks, {tele.get('loss_events')} losses")
        if tele.get("invalid_ticks"):
            t.add_row("[yellow]safe posture[/yellow]",
                      f"held ({tele.get('on_loss')}) for {tele.get('invalid_time_s'):.3f} s in total, "
                      f"longest {tele.get('longest_invalid_s'):.3f} s")
        stream = tele.get("stream")
        if stream:
            t.add_row("stream", ", ".join(f"{k} {v}" for k, v in stream.items() if v not in ("", None)))
        net = tele.get("network")
        if net:
            link = net.get("link") or {}
            t.add_row("network", f"{net['spec']} ({net['path']})"
                      + (": " + ", ".join(f"{k} {v}" for k, v in link.items() if v) if link else ""))
        pred = tele.get("prediction")
        if pred and pred.get("method") != "none":
            h = pred.get("horizon_ms") or {}
            t.add_row("prediction", f"{pred['method']}, horizon mean {h.get('mean') or 0:.1f} ms, max "
                                    f"{h.get('max') or 0:.1f} ms (cap {1e3 * pred['max_horizon_s']:.0f} ms)")
        for key, label in (("hand_position_error_true_m", "hand error vs the undelayed reference [m]"),
                           ("hand_reference_lag_m", "reference lag behind the undelayed one [m]")):
            v = m.get(key)
            if v and v.get("mean") is not None:
                t.add_row(label, f"mean {v['mean']:.4f}  max {v['max']:.4f}")
        clamped = {k: v for k, v in tele.get("clamped_ticks", {}).items() if v}
        if clamped:
            t.add_row("targets out of reach", ", ".join(f"{k} {v} ticks (clamped)" for k, v in clamped.items()))
    for k, v in s.get("controller_status", {}).items():
        t.add_row(k, str(v))
    if s.get("metrics_error"):
        t.add_row("[red]metrics error[/red]", s["metrics_error"])
    t.add_row("run directory", str(run_dir))
    console.print(t)
