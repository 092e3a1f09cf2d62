"""Controller speed: median and p99 microseconds per control step for TALOS standing on two feet with the
paper's task set (task update + QP build + solve + command), and where the time goes (pinocchio, building the
QP, the solver). The controller is fed real measurements from the simulator in closed loop; only its
`step()` is timed.

    .venv/bin/python benchmarks/bench_controllers.py [--ticks 3000] [--json FILE] [--controllers a,b]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from wbcbench.controllers.base import available_controllers, make_controller
from wbcbench.qp._jit import JIT_ENABLED
from wbcbench.robots import load_robot
from wbcbench.sim.simulator import Simulator
from wbcbench.types import References


def set_compiled(ctrl, on: bool) -> None:
    """Switch a controller between the compiled kernels (wbcbench.qp._jit) and the numpy reference code."""
    if hasattr(ctrl, "jit"):
        ctrl.jit = on
    solver = getattr(ctrl, "solver", None)
    if solver is not None and hasattr(solver, "jit"):
        solver.jit = on


def bench(robot, name: str, ticks: int, compiled: bool = True) -> dict:
    ctrl = make_controller(name, robot, None, 1e-3)
    set_compiled(ctrl, compiled and JIT_ENABLED)
    sim = Simulator(robot, mode=ctrl.mode)
    refs = References(t=0.0)
    meas = sim.measure()
    ctrl.reset(meas, refs)
    total = np.empty(ticks)
    split = {}
    for k in range(ticks):
        t0 = time.perf_counter()
        cmd = ctrl.step(meas, refs)
        total[k] = (time.perf_counter() - t0) * 1e6
        if hasattr(ctrl, "last_timing_us"):
            for key, val in ctrl.last_timing_us.items():
                split.setdefault(key, []).append(val)
        sim.apply(cmd)
        sim.step()
        meas = sim.measure()
    warm = total[ticks // 10:]
    out = {"median_us": float(np.median(warm)), "p99_us": float(np.percentile(warm, 99))}
    for key, vals in split.items():
        out[f"{key}_median_us"] = float(np.median(vals[ticks // 10:]))
    if split:
        out["build_median_us"] = out["median_us"] - sum(out[f"{k}_median_us"] for k in split)
    return out


def _line(name: str, r: dict) -> str:
    line = f"  {name:24s} median {r['median_us']:7.1f} us   p99 {r['p99_us']:7.1f} us"
    if "solve_median_us" in r:
        line += (f"   [pinocchio {r['pinocchio_median_us']:.0f}, build {r['build_median_us']:.0f}, "
                 f"solver {r['solve_median_us']:.0f} us]")
    return line


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ticks", type=int, default=3000)
    p.add_argument("--json", default=None, help="write {controller: {median_us, p99_us, ...}} here")
    p.add_argument("--controllers", default=None, help="comma-separated names (default: all but joint-pd)")
    p.add_argument("--robot", default="talos")
    p.add_argument("--numpy", action="store_true",
                   help="also time the numpy reference path (kernels off) and print the ratio")
    args = p.parse_args()
    robot = load_robot(args.robot)
    names = args.controllers.split(",") if args.controllers else [n for n in available_controllers()
                                                                  if n != "joint-pd"]
    results = {}
    print(f"{robot!r}, standing on two feet, {args.ticks} closed-loop ticks (first 10% discarded)")
    print(f"  compiled kernels: {'on' if JIT_ENABLED else 'OFF (WBCBENCH_JIT=0 or numba missing)'}")
    for name in names:
        r = bench(robot, name, args.ticks)
        results[name] = r
        print(_line(name, r))
        if args.numpy and JIT_ENABLED:
            ref = bench(robot, name, args.ticks, compiled=False)
            r["numpy_median_us"], r["numpy_p99_us"] = ref["median_us"], ref["p99_us"]
            print(_line(f"{name} (numpy)", ref) + f"   compiled/numpy {r['median_us'] / ref['median_us']:.2f}")
    ref = "tsid-torque"
    if ref in results:
        for name, r in results.items():
            if name != ref:
                print(f"  ratio {name} / {ref}: {r['median_us'] / results[ref]['median_us']:.2f}")
        print("  for scale (same machine, README of the issue): C++ TSID via Python ~145 us, PlaCo ID ~90 us")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
