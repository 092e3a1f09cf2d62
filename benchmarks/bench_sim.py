"""Simulator speed: median and p99 microseconds per MuJoCo step for a robot standing on its sole boxes, and the
real-time factor of the whole stand loop (controller + simulation + recording).

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
    with tempfile.TemporaryDirectory() as tmp:
        res = run("stand", "joint-pd", robot, mode="torque", duration=5.0, out=tmp)
    s = res.summary
    loop_us = s["wall_time_s"] / s["sim_time_s"]  # [ms of wall time per ms simulated]
    results["stand_loop"] = {"real_time_factor": s["real_time_factor"], "us_per_tick": loop_us * 1e3,
                             "controller_median_us": s["step_time_us"]["median"]}
    print(f"stand loop (joint-pd torque, 5 s, recording every tick): real-time factor {s['real_time_factor']:.2f}, "
          f"{loop_us * 1e3:.0f} us per 1 ms tick, of which controller median {s['step_time_us']['median']:.1f} us")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
