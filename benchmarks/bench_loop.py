"""Where a simulated tick goes: the controller's `step()`, the physics (`Simulator.step`, i.e. `mj_step` and the
push forces) and the rest of the run loop (measurement, references, ground truth, fall checks, recording, probes),
in microseconds per tick, and the real-time factor of the whole loop.

    .venv/bin/python benchmarks/bench_loop.py [--scenario walk-20cm] [--controller tsid-torque]
    .venv/bin/python benchmarks/bench_loop.py --against ../other-checkout [--rounds 3] [--core 0]
    .venv/bin/python benchmarks/bench_loop.py --scenario stand --realism talos-real [--rounds 3] [--also P.yaml]

`--realism PRESET` (without --against) times three runs, alternating round by round in this process: the switch
off, the preset with ideal sensors (`actuators`: the actuator model alone, i.e. the hidden joints, friction, torque
loop and hip flexibility, with their probe's channels) and the preset as it is (`preset`: with its sensor profile,
e.g. talos-like); it prints each part's ratio to the switch off (of the medians over rounds), and the median
and range of each round's own tick ratio. `--also PRESET` (repeatable) adds another preset's actuator model to
the same rounds (e.g. a copy with `stiction_impedance: 0.999`, the former friction model). Choose a scenario in which the robot does the
same thing in all three, e.g. stand (standing still: the same ticks, and the controller's QP meets the same
situations; a walk on the realistic robot moves differently, falls, and its controller's time is then not the
model's cost). The physics part is split further into `mj_step` itself (CPU time, with MuJoCo's mean Newton
iterations per step, `solver_niter`) and the rest of `Simulator.step` (the torque loop, pushes); the sensors' cost
(`preset` minus `actuators`) falls in `rest`, and through the noise they add, in the controller's time.

The run is a normal `wbcbench.run` (log written to a temporary directory), after a 0.3 s warm-up run of the same
pair in the same process (loading the compiled kernels is not a tick's cost); physics is timed by wrapping
`Simulator.step`, the controller from the log's `controller_time_us`; the rest is the loop's wall time minus both.
The same split in CPU time of the loop's thread (`time.thread_time`, from the end of the first tick to the end of
the last) is printed below it: on a shared machine, other processes on the same core inflate wall time, not CPU
time, so the CPU split is the one to compare across runs.
`--against DIR` runs the same with the wbcbench of another checkout (e.g. the previous main) in the same
invocation: the two alternate, each in its own process pinned to one core with OPENBLAS_NUM_THREADS=1, and the
median over rounds is reported with the ratio new / other.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from _alternate import alternate


class _Clock:
    """A probe that reads the thread's CPU clock at the end of the first and of the last tick (the loop's CPU
    time without set-up, planning and metrics)."""

    def __init__(self):
        self.first = self.last = None

    def attach(self, sim):
        return {}

    def values(self):
        now = time.thread_time()
        if self.first is None:
            self.first = now
        self.last = now
        return []

    def metrics(self, log):
        return {}


def measure(scenario: str, controller: str, realism: str | None = None, sensors: str | None = None) -> dict:
    """One run; the split per tick [us] and the real-time factor. Wall time as the run loop measures it, and
    CPU time of the loop's thread (`time.thread_time`: what another process on the same core does not add).
    `sensors` overrides the scenario's or the preset's sensor profile."""
    import mujoco

    from wbcbench.controllers.base import make_controller
    from wbcbench.robots import load_robot
    from wbcbench.runner import run
    from wbcbench.scenarios import load_scenario

    extra = {} if realism is None else {"realism": realism}  # (a checkout from before the switch has no keyword)
    if sensors is not None:
        extra["sensors"] = sensors
    from wbcbench.sim.simulator import Simulator

    with tempfile.TemporaryDirectory() as tmp:  # load the compiled kernels and warm the caches first
        run(scenario, controller, duration=0.3, out=Path(tmp) / "warm-up", **extra)
    robot = load_robot("talos")
    scen = load_scenario(scenario, robot)
    ctrl = make_controller(controller, robot, None, scen.spec.control_dt)
    clock = _Clock()
    physics, physics_cpu, ctrl_cpu, mj_cpu, niter, nstep = [0.0], [0.0], [0.0], [0.0], [0], [0]
    step, ctrl_step, mj_step = Simulator.step, ctrl.step, mujoco.mj_step

    def timed_step(self, n: int = 1) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        step(self, n)
        physics[0] += time.perf_counter() - t0
        if clock.first is not None:  # from the end of the first tick on, as the clock
            physics_cpu[0] += time.thread_time() - c0

    def timed_mj_step(m, d) -> None:
        c0 = time.thread_time()
        mj_step(m, d)
        if clock.first is not None:
            mj_cpu[0] += time.thread_time() - c0
            niter[0] += d.solver_niter[0]
            nstep[0] += 1

    def timed_ctrl(meas, refs):
        c0 = time.thread_time()
        out = ctrl_step(meas, refs)
        if clock.first is not None:
            ctrl_cpu[0] += time.thread_time() - c0
        return out

    ctrl.step = timed_ctrl
    Simulator.step = timed_step
    mujoco.mj_step = timed_mj_step
    try:
        with tempfile.TemporaryDirectory() as tmp:
            result = run(scen, ctrl, robot=robot, out=Path(tmp) / "run", probes=[clock], **extra)
    finally:
        Simulator.step = step
        mujoco.mj_step = mj_step
    s = result.summary
    ticks = len(result.log["t"])
    wall_us = s["wall_time_s"] * 1e6
    ctrl_us = float(np.nansum(result.log["controller_time_us"]))
    phys_us = physics[0] * 1e6
    n_cpu = ticks - 1
    loop_cpu = (clock.last - clock.first) * 1e6
    return {"ticks": ticks, "fell": s["fell"], "controller_us": ctrl_us / ticks, "physics_us": phys_us / ticks,
            "rest_us": (wall_us - ctrl_us - phys_us) / ticks, "tick_us": wall_us / ticks,
            "real_time_factor": s["real_time_factor"],
            "cpu_controller_us": ctrl_cpu[0] * 1e6 / n_cpu, "cpu_physics_us": physics_cpu[0] * 1e6 / n_cpu,
            "cpu_mj_step_us": mj_cpu[0] * 1e6 / n_cpu, "solver_niter": niter[0] / max(nstep[0], 1),
            "cpu_rest_us": (loop_cpu - (ctrl_cpu[0] + physics_cpu[0]) * 1e6) / n_cpu, "cpu_tick_us": loop_cpu / n_cpu,
            "cpu_real_time_factor": scen.spec.control_dt * 1e6 / (loop_cpu / n_cpu)}


def _line(label: str, r: dict) -> str:
    wall = (f"  {label:9s} wall  controller {r['controller_us']:6.1f}  physics {r['physics_us']:6.1f}  "
            f"rest {r['rest_us']:6.1f}  tick {r['tick_us']:6.1f} us   real-time factor {r['real_time_factor']:.2f}"
            f"{'   FELL' if r['fell'] else ''}")
    if "cpu_tick_us" not in r:  # a checkout whose benchmark measured wall time only
        return wall
    mj = (f" (mj_step {r['cpu_mj_step_us']:5.1f}, {r['solver_niter']:.2f} solver iterations)"
          if "cpu_mj_step_us" in r else "")
    return wall + (f"\n  {label:9s} CPU   controller {r['cpu_controller_us']:6.1f}  physics {r['cpu_physics_us']:6.1f}{mj}  "
                   f"rest {r['cpu_rest_us']:6.1f}  tick {r['cpu_tick_us']:6.1f} us   real-time factor "
                   f"{r['cpu_real_time_factor']:.2f}")


def against(args) -> None:
    rounds = alternate(__file__, ["--scenario", args.scenario, "--controller", args.controller], args.against,
                       args.rounds, args.core)
    print(f"{args.controller} on {args.scenario}; median over the rounds [us per tick]")
    med = {side: {k: float(np.median([x[k] for x in v])) for k in v[0] if k != "fell"} | {"fell": any(x["fell"] for x in v)}
           for side, v in rounds.items()}
    for side in med:
        print(_line(side, med[side]))
    print(f"  new/other: rest {med['new']['rest_us'] / med['other']['rest_us']:.2f}, "
          f"tick {med['new']['tick_us'] / med['other']['tick_us']:.2f} (wall)", end="")
    if all("cpu_rest_us" in m for m in med.values()):
        print(f"; rest {med['new']['cpu_rest_us'] / med['other']['cpu_rest_us']:.2f}, "
              f"tick {med['new']['cpu_tick_us'] / med['other']['cpu_tick_us']:.2f} (CPU)")
    else:
        print()


def realism_ratio(args) -> None:
    """The realism switch's cost: off, the actuator model alone (the preset with ideal sensors) and the whole
    preset, alternately; the median over the rounds and each part's ratio to the switch off (CPU time)."""
    legs = {"off": (None, None), "actuators": (args.realism, "ideal"), "preset": (args.realism, None)}
    for other in args.also:  # more presets' actuator models in the same rounds (e.g. a former friction model)
        legs[f"actuators:{Path(other).stem}"] = (other, "ideal")
    rounds = {side: [] for side in legs}
    for r in range(args.rounds):
        for side, (preset, sensors) in legs.items():
            rounds[side].append(measure(args.scenario, args.controller, preset, sensors))
        print(f"  round {r + 1}/{args.rounds} done", flush=True)
    med = {side: {k: float(np.median([x[k] for x in v])) for k in v[0] if k != "fell"} | {"fell": any(x["fell"] for x in v)}
           for side, v in rounds.items()}
    print(f"{args.controller} on {args.scenario}, realism {args.realism}; median over {args.rounds} rounds [us per tick]")
    for side in med:
        print(_line(side, med[side]))
    off = med["off"]
    for side in [k for k in legs if k != "off"]:
        on = med[side]
        print(f"  {side}/off (CPU): " + ", ".join(
            f"{part} {on[f'cpu_{part}_us'] / off[f'cpu_{part}_us']:.2f}"
            for part in ("controller", "physics", "mj_step", "rest", "tick")) +
            f"; tick {on['tick_us'] / off['tick_us']:.2f} (wall)")
        # each round's own ratio (its runs ran back to back, under the same load), then their median and range
        per = [x["cpu_tick_us"] / o["cpu_tick_us"] for x, o in zip(rounds[side], rounds["off"])]
        print(f"  {side}/off per round (CPU tick): median {np.median(per):.2f}, range {min(per):.2f}-{max(per):.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"median": med, "rounds": rounds}))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="walk-20cm")
    p.add_argument("--controller", default="tsid-torque")
    p.add_argument("--json", default=None, help="write the split here")
    p.add_argument("--against", default=None, help="another checkout to time in the same run (e.g. previous main)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--core", default="0", help="CPU core to pin to with --against ('' for none; default 0)")
    p.add_argument("--realism", default=None, help="time the run with this realism preset against the switch off")
    p.add_argument("--also", action="append", default=[],
                   help="with --realism: another preset's actuator model timed in the same rounds (repeatable)")
    args = p.parse_args()
    if args.realism and not args.against:
        realism_ratio(args)
        return
    if args.against:
        against(args)
        return
    r = measure(args.scenario, args.controller)
    print(f"{args.controller} on {args.scenario}, {r['ticks']} ticks")
    print(_line("", r))
    if args.json:
        Path(args.json).write_text(json.dumps(r))


if __name__ == "__main__":
    main()
