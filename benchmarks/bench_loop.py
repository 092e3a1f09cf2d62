"""Where a simulated tick goes: the controller's `step()`, the physics (`Simulator.step`, i.e. `mj_step` and the
push forces) and the rest of the run loop (measurement, references, ground truth, fall checks, recording, probes),
in microseconds per tick, and the real-time factor of the whole loop.

    .venv/bin/python benchmarks/bench_loop.py [--scenario walk-20cm] [--controller tsid-torque]
    .venv/bin/python benchmarks/bench_loop.py --against ../other-checkout [--rounds 3] [--core 0]

The run is a normal `wbcbench.run` (log written to a temporary directory), after a 0.3 s warm-up run of the same
pair in the same process (loading the compiled kernels is not a tick's cost); physics is timed by wrapping
`Simulator.step`, the controller from the log's `controller_time_us`; the rest is the loop's wall time minus both.
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


def measure(scenario: str, controller: str) -> dict:
    """One run; the split per tick [us] and the real-time factor."""
    from wbcbench.runner import run
    from wbcbench.sim.simulator import Simulator

    with tempfile.TemporaryDirectory() as tmp:  # load the compiled kernels and warm the caches first
        run(scenario, controller, duration=0.3, out=Path(tmp) / "warm-up")
    physics = [0.0]
    step = Simulator.step

    def timed_step(self, n: int = 1) -> None:
        t0 = time.perf_counter()
        step(self, n)
        physics[0] += time.perf_counter() - t0

    Simulator.step = timed_step
    try:
        with tempfile.TemporaryDirectory() as tmp:
            result = run(scenario, controller, out=Path(tmp) / "run")
    finally:
        Simulator.step = step
    s = result.summary
    ticks = len(result.log["t"])
    wall_us = s["wall_time_s"] * 1e6
    ctrl_us = float(np.nansum(result.log["controller_time_us"]))
    phys_us = physics[0] * 1e6
    return {"ticks": ticks, "fell": s["fell"], "controller_us": ctrl_us / ticks, "physics_us": phys_us / ticks,
            "rest_us": (wall_us - ctrl_us - phys_us) / ticks, "tick_us": wall_us / ticks,
            "real_time_factor": s["real_time_factor"]}


def _line(label: str, r: dict) -> str:
    return (f"  {label:8s} controller {r['controller_us']:6.1f}  physics {r['physics_us']:6.1f}  "
            f"rest {r['rest_us']:6.1f}  tick {r['tick_us']:6.1f} us   real-time factor {r['real_time_factor']:.2f}"
            f"{'   FELL' if r['fell'] else ''}")


def against(args) -> None:
    rounds = alternate(__file__, ["--scenario", args.scenario, "--controller", args.controller], args.against,
                       args.rounds, args.core)
    print(f"{args.controller} on {args.scenario}; median over the rounds [us per tick]")
    med = {side: {k: float(np.median([x[k] for x in v])) for k in v[0] if k != "fell"} | {"fell": any(x["fell"] for x in v)}
           for side, v in rounds.items()}
    for side in med:
        print(_line(side, med[side]))
    print(f"  new/other: rest {med['new']['rest_us'] / med['other']['rest_us']:.2f}, "
          f"tick {med['new']['tick_us'] / med['other']['tick_us']:.2f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="walk-20cm")
    p.add_argument("--controller", default="tsid-torque")
    p.add_argument("--json", default=None, help="write the split here")
    p.add_argument("--against", default=None, help="another checkout to time in the same run (e.g. previous main)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--core", default="0", help="CPU core to pin to with --against ('' for none; default 0)")
    args = p.parse_args()
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
