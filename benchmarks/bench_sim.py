"""Simulator speed: median and p99 microseconds per MuJoCo step for a robot standing on its sole boxes, the same
for DART's step (the `dart` engine, when dartpy is installed) with its ratio to MuJoCo's in this run, and the
real-time factor of the whole stand loop (controller + simulation + recording) on each engine.

    .venv/bin/python benchmarks/bench_sim.py [--robot talos] [--steps 5000] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time

import mujoco
import numpy as np

from wbcbench.robots import load_robot
from wbcbench.runner import run
from wbcbench.sim.model import SimOptions
from wbcbench.sim.simulator import Simulator
from wbcbench.types import Command


def time_steps(robot, mode: str, steps: int, noslip: int = 0) -> np.ndarray:
    sim = Simulator(robot, mode=mode, options=SimOptions(noslip_iterations=noslip))
    sim.apply(Command(tau=np.zeros(robot.na), q=robot.q0[7:].copy(), v=np.zeros(robot.na)))
    m, d = sim.model, sim.data
    out = np.empty(steps)
    for i in range(steps):
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        out[i] = time.perf_counter() - t0
    return out * 1e6


def time_dart_steps(robot, mode: str, steps: int) -> np.ndarray:
    """One DART physics step (`DartSimulator.step(1)`: the actuators' torque, pushes, the IMU's finite
    difference and DART's own step) of the robot standing on its sole boxes."""
    from wbcbench.sim.dart_engine import DartSimulator

    sim = DartSimulator(robot, mode=mode)
    sim.apply(Command(tau=np.zeros(robot.na), q=robot.q0[7:].copy(), v=np.zeros(robot.na)))
    out = np.empty(steps)
    for i in range(steps):
        t0 = time.perf_counter()
        sim.step(1)
        out[i] = time.perf_counter() - t0
    return out * 1e6


def _stand_loop(robot, engine: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        res = run("stand", "joint-pd", robot, mode="torque", duration=5.0, out=tmp, engine=engine)
    s = res.summary
    loop_us = s["wall_time_s"] / s["sim_time_s"]  # [ms of wall time per ms simulated]
    print(f"stand loop on {engine} (joint-pd torque, 5 s, recording every tick): real-time factor "
          f"{s['real_time_factor']:.2f}, {loop_us * 1e3:.0f} us per 1 ms tick, of which controller median "
          f"{s['step_time_us']['median']:.1f} us")
    return {"real_time_factor": s["real_time_factor"], "us_per_tick": loop_us * 1e3,
            "controller_median_us": s["step_time_us"]["median"]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="talos")
    p.add_argument("--steps", type=int, default=5000)
    p.add_argument("--json", default=None)
    args = p.parse_args()
    robot = load_robot(args.robot)
    results = {}
    print(f"{robot!r}: one mj_step, sole-box collisions only, timestep 1 ms")
    for mode, noslip in (("torque", 0), ("position", 0), ("torque", 10)):
        us = time_steps(robot, mode, args.steps, noslip)
        key = f"mj_step_{mode}" + (f"_noslip{noslip}" if noslip else "")
        results[key] = {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99))}
        print(f"  {key:28s} median {np.median(us):7.1f} us   p99 {np.percentile(us, 99):7.1f} us")
    base = results["mj_step_torque"]["median_us"]
    print(f"  ratio noslip10 / default: {results['mj_step_torque_noslip10']['median_us'] / base:.2f}")
    try:
        import dartpy  # noqa: F401
    except ImportError:
        dartpy = None
    if dartpy is not None:
        for mode in ("torque", "position"):
            us = time_dart_steps(robot, mode, args.steps)
            key = f"dart_step_{mode}"
            ratio = float(np.median(us)) / results[f"mj_step_{mode}"]["median_us"]
            results[key] = {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)),
                            "ratio_to_mujoco": ratio}
            print(f"  {key:28s} median {np.median(us):7.1f} us   p99 {np.percentile(us, 99):7.1f} us   "
                  f"{ratio:.1f}x MuJoCo's")
    results["stand_loop"] = _stand_loop(robot, "mujoco")
    if dartpy is not None:
        results["stand_loop_dart"] = _stand_loop(robot, "dart")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
