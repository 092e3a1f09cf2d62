"""Controller speed: median and p99 microseconds per control step for TALOS standing on two feet with the
paper's task set (task update + QP build + solve + command), and where the time goes (pinocchio, building the
QP, the solver). The controller is fed real measurements from the simulator in closed loop; only its
`step()` is timed. The references hold the CoM where it starts with the ZMP under it (what `stand` gives), so
the position schemes run with their stabilizer. For a controller with plan corrections (base feedback, stabilizer,
...: `controller.corrections.apply`), their time is measured too, and "core" is the step without them (the
formulation and solve alone, per tick: step minus corrections).

    .venv/bin/python benchmarks/bench_controllers.py [--ticks 3000] [--json FILE] [--controllers a,b]
    .venv/bin/python benchmarks/bench_controllers.py --against ../other-checkout [--rounds 3]

`--against DIR` times the same controllers with the wbcbench of another checkout (e.g. the previous main) in the
same run: the two alternate, each in its own process pinned to one core with OPENBLAS_NUM_THREADS=1, and the
median of each round's medians is reported with the ratio new / other.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import pinocchio as pin

from _alternate import alternate
from wbcbench import types as _types
from wbcbench.controllers.base import available_controllers, make_controller
from wbcbench.robots import load_robot
from wbcbench.side import Side
from wbcbench.sim.simulator import Simulator


def standing_references(robot, q):
    """Both feet down, the CoM held where it is, the ZMP under it (with either version of `References`)."""
    data = robot.model.createData()
    com = pin.centerOfMass(robot.model, data, q).copy()
    pin.framesForwardKinematics(robot.model, data, q)
    ground = min(data.oMf[robot.sole_frame_id(s)].translation[2] for s in Side)
    zmp = np.array([com[0], com[1], ground])
    if hasattr(_types, "PointReference"):
        return _types.References(t=0.0, com=_types.PointReference(com), zmp=zmp)
    return _types.References(t=0.0, com=com, com_vel=np.zeros(3), com_acc=np.zeros(3), zmp=zmp)


def bench(robot, name: str, ticks: int) -> dict:
    ctrl = make_controller(name, robot, None, 1e-3)
    sim = Simulator(robot, mode=ctrl.mode)
    meas = sim.measure()
    refs = standing_references(robot, meas.q)
    ctrl.reset(meas, refs)
    total = np.empty(ticks)
    corrections = np.zeros(ticks)
    split = {}
    timed = _time_corrections(ctrl, corrections)
    for k in range(ticks):
        timed[0] = k
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
    if timed[1]:
        out["corrections_median_us"] = float(np.median(corrections[ticks // 10:]))
        out["core_median_us"] = float(np.median((total - corrections)[ticks // 10:]))
    return out


def _time_corrections(ctrl, times: np.ndarray) -> list:
    """Wrap the controller's `corrections.apply` (if it has plan corrections) so that its time at tick k goes to
    `times[k]`; returns [the current tick (set by the caller), whether wrapped]."""
    state = [0, False]
    corr = getattr(ctrl, "corrections", None)
    if corr is None or not getattr(corr, "stages", ()):
        return state
    apply = corr.apply

    def timed_apply(*args, **kwargs):
        t0 = time.perf_counter()
        out = apply(*args, **kwargs)
        times[state[0]] = (time.perf_counter() - t0) * 1e6
        return out

    corr.apply = timed_apply
    state[1] = True
    return state


def _line(name: str, r: dict) -> str:
    line = f"  {name:24s} median {r['median_us']:7.1f} us   p99 {r['p99_us']:7.1f} us"
    if "solve_median_us" in r:
        line += (f"   [pinocchio {r['pinocchio_median_us']:.0f}, build {r['build_median_us']:.0f}, "
                 f"solver {r['solve_median_us']:.0f} us]")
    if "core_median_us" in r:
        line += (f"   [corrections {r['corrections_median_us']:.0f}, core (step without them) "
                 f"{r['core_median_us']:.0f} us]")
    return line


def against(args, names: list[str]) -> None:
    """Alternate this checkout and `args.against`, one process per round and side, pinned to one core."""
    rounds = alternate(__file__, ["--ticks", str(args.ticks), "--controllers", ",".join(names), "--robot", args.robot],
                       args.against, args.rounds, args.core)
    print(f"{args.ticks} ticks per run; median of the rounds' medians [us] (p99 likewise)")
    for name in names:
        med = {k: float(np.median([x[name]["median_us"] for x in v])) for k, v in rounds.items()}
        p99 = {k: float(np.median([x[name]["p99_us"] for x in v])) for k, v in rounds.items()}
        print(f"  {name:14s} new {med['new']:7.1f} (p99 {p99['new']:7.1f})   other {med['other']:7.1f} "
              f"(p99 {p99['other']:7.1f})   new/other {med['new'] / med['other']:.3f}")
        for key, label in (("core_median_us", "core"), ("corrections_median_us", "corrections")):
            if all(key in x[name] for v in rounds.values() for x in v):
                m = {k: float(np.median([x[name][key] for x in v])) for k, v in rounds.items()}
                print(f"  {'':4s}{label:10s} new {m['new']:7.1f}                other {m['other']:7.1f}"
                      f"                new/other {m['new'] / m['other']:.3f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ticks", type=int, default=3000)
    p.add_argument("--json", default=None, help="write {controller: {median_us, p99_us, ...}} here")
    p.add_argument("--controllers", default=None, help="comma-separated names (default: all but joint-pd)")
    p.add_argument("--robot", default="talos")
    p.add_argument("--against", default=None, help="another checkout to time in the same run (e.g. previous main)")
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds with --against (default 3)")
    p.add_argument("--core", default="1", help="CPU core to pin to with --against ('' for none; default 1)")
    args = p.parse_args()
    names = args.controllers.split(",") if args.controllers else [n for n in available_controllers()
                                                                  if n != "joint-pd"]
    if args.against:
        against(args, names)
        return
    robot = load_robot(args.robot)
    results = {}
    print(f"{robot!r}, standing on two feet, {args.ticks} closed-loop ticks (first 10% discarded)")
    jit = os.environ.get("WBCBENCH_JIT", "1").strip().lower() not in ("0", "false", "no", "off")
    print(f"  compiled kernels: {'on' if jit else 'OFF (WBCBENCH_JIT=0: the kernels run as plain Python)'}")
    for name in names:
        r = bench(robot, name, args.ticks)
        results[name] = r
        print(_line(name, r))
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
