"""Rendering speed: frames per second of `wbcbench render` (replay, overlays, MuJoCo's offscreen renderer,
H.264 encoding with PyAV) on a walk, at 1280x720 and 640x480, and whether a video at 30 frames/s renders faster
than real time (more than 30 frames per wall-clock second).

    .venv/bin/python benchmarks/bench_render.py [--scenario walk-20cm-quick] [--controller tsid-torque]

Pin it to one core (taskset -c 0) with OPENBLAS_NUM_THREADS=1 for comparable numbers; software rendering (Mesa
EGL) uses the CPU.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="walk-20cm-quick")
    p.add_argument("--controller", default="tsid-torque")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    from wbcbench.runner import run
    from wbcbench.viz.render import render_run

    with tempfile.TemporaryDirectory() as tmp:
        res = run(args.scenario, args.controller, out=Path(tmp) / "run")
        duration = res.summary["sim_time_s"]
        n = int(np.floor(duration * 30)) + 1
        print(f"{args.controller} on {args.scenario}: {duration:.2f} s of run, {n} frames at 30 fps")
        render_run(res.run_dir, Path(tmp) / "warm.mp4", size="320x240", fps=5)
        for size in ("1280x720", "640x480"):
            walls = []
            for _ in range(args.rounds):
                t0 = time.perf_counter()
                render_run(res.run_dir, Path(tmp) / f"{size}.mp4", size=size, fps=30)
                walls.append(time.perf_counter() - t0)
            wall = float(np.median(walls))
            fps = n / wall
            print(f"  {size:9s} {wall:6.2f} s ({1e3 / fps:5.1f} ms per frame, {fps:5.1f} frames/s, median of "
                  f"{args.rounds}): {'faster' if fps > 30 else 'slower'} than real time at 30 frames/s "
                  f"(x{fps / 30:.2f})")


if __name__ == "__main__":
    main()
