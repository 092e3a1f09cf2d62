"""Sweep throughput: cells per minute with 1 and 2 workers on the process pool and on a local Ray instance.

    PYTHONPATH=. python benchmarks/sweep_scaling.py [--cells 8] [--duration 1.0]

Cells: `stand` with joint-pd for `duration` s, varied over seeds (each cell loads the robot, builds the
scenario and writes a full run directory, as a real sweep does). Executor start-up (worker spawn, ray.init) is
included in the wall time.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from wbcbench.study.execute import PoolExecutor, RayExecutor
from wbcbench.study.sweep import run_sweep


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=8)
    ap.add_argument("--duration", type=float, default=1.0)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "scaling.yaml"
        f.write_text(f"base: {{scenario: stand, controller: joint-pd, duration: {a.duration}}}\n"
                     f"grid: {{seed: [{', '.join(str(i) for i in range(a.cells))}]}}\n")
        setups = [("pool", 1, lambda: PoolExecutor(1)), ("pool", 2, lambda: PoolExecutor(2)),
                  ("ray", 1, lambda: RayExecutor("auto", 1)), ("ray", 2, lambda: RayExecutor("auto", 2))]
        for name, workers, make in setups:
            t0 = time.perf_counter()
            with make() as ex:
                _, table, n = run_sweep(f, Path(tmp) / f"{name}-{workers}", ex)
            wall = time.perf_counter() - t0
            print(f"{name:6s} {workers} worker(s): {n} cells in {wall:6.1f} s = {60 * n / wall:6.1f} cells/min")


if __name__ == "__main__":
    main()
