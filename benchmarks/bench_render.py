"""Rendering speed: frames per second of `wbcbench render` (replay, overlays, MuJoCo's offscreen renderer,
H.264 encoding with PyAV) on a walk, for a whole video (loading the run and building the model included), and
whether a video at 30 frames/s renders faster than real time (more than 30 frames per wall-clock second).

    .venv/bin/python benchmarks/bench_render.py [--scenario walk-20cm-quick] [--controller tsid-torque] [--rounds 5]

Configurations, each timed `--rounds` times (median), alternating round by round so that slow phases of a shared
machine hit all alike; the script sets its own CPU affinity (inherited by the render processes):
  in turn, superfast, 1 core        the renderer before the encoding thread: each frame encoded (x264 preset
                                    superfast) before the next is drawn, pinned to one core
  1 process, 1 core                 the default (`wbcbench render`): frames encoded (x264 ultrafast) in a thread
                                    while the next is drawn, pinned to one core
  in turn, superfast, 2 cores       as the first, on both cores
  1 process, 2 cores                the default on both cores (llvmpipe rasterizes and x264 encodes in threads too)
  2 processes, 2 cores              2 render processes + the encoder, both cores
Software rendering (Mesa's llvmpipe through EGL) runs on the CPU: the machine's load matters, the script prints it.
On the 2 shared cores measured (README, "Watch a run"), the default on both cores renders faster than real time
(34-35 frames/s) at load averages up to about 2.5, not at 3 and more.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

CONFIGS = {  # name: (size, render_run keywords, cores)
    "in turn, superfast, 1 core": ("1280x720", dict(threaded=False, preset="superfast"), 1),
    "1 process, 1 core": ("1280x720", dict(), 1),
    "in turn, superfast, 2 cores": ("1280x720", dict(threaded=False, preset="superfast"), 2),
    "1 process, 2 cores": ("1280x720", dict(), 2),
    "2 processes, 2 cores": ("1280x720", dict(workers=2), 2),
}


def _cpu_seconds() -> float:
    """User + system CPU time of this process and of its finished children (the render processes) [s]."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="walk-20cm-quick")
    p.add_argument("--controller", default="tsid-torque")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--run-dir", default=None, help="render this run directory instead of running the scenario")
    p.add_argument("--only", default=None, help="';'-separated configuration names (default: all)")
    args = p.parse_args()
    from wbcbench.viz.render import _render_replay, render_run

    cores = sorted(os.sched_getaffinity(0))
    only = None if args.only is None else [name.strip() for name in args.only.split(";")]
    unknown = sorted(set(only or ()) - set(CONFIGS))
    if unknown:
        p.error(f"unknown configuration(s) {unknown}; known: {list(CONFIGS)}")
    configs = {k: v for k, v in CONFIGS.items() if only is None or k in only}
    with tempfile.TemporaryDirectory() as tmp:
        if args.run_dir:
            run_dir = Path(args.run_dir)
        else:
            from wbcbench.runner import run

            run_dir = run(args.scenario, args.controller, out=Path(tmp) / "run").run_dir
        t0 = time.perf_counter()
        duration = _render_replay(run_dir).duration
        load = time.perf_counter() - t0
        n = int(np.floor(duration * 30 + 1e-9)) + 1
        print(f"{run_dir.name}: {duration:.2f} s of run, {n} frames at 30 frames/s; loading the run and building "
              f"the model: {load:.2f} s (first time, caches cold)")
        render_run(run_dir, Path(tmp) / "warm.mp4", size="320x240", fps=5, workers=1)
        walls: dict[str, list[float]] = {k: [] for k in configs}
        cpus: dict[str, list[float]] = {k: [] for k in configs}
        for r in range(args.rounds):
            for name, (size, kwargs, ncores) in configs.items():
                os.sched_setaffinity(0, cores[-ncores:])
                c0 = _cpu_seconds()
                t0 = time.perf_counter()
                render_run(run_dir, Path(tmp) / "v.mp4", size=size, fps=30, **kwargs)
                walls[name].append(time.perf_counter() - t0)
                cpus[name].append(_cpu_seconds() - c0)
                os.sched_setaffinity(0, cores)
            print(f"  round {r + 1}/{args.rounds}, load average {os.getloadavg()[0]:.2f}", flush=True)
        size_mb = (Path(tmp) / "v.mp4").stat().st_size / 1e6
        print(f"whole video, wall time median of {args.rounds} (min, max), CPU time of all its processes; last "
              f"video {size_mb:.1f} MB")
        for name, w in walls.items():
            wall = float(np.median(w))
            fps = n / wall
            print(f"  {configs[name][0]:9s} {name:30s} {wall:6.2f} s ({min(w):.2f}, {max(w):.2f}): {fps:5.1f} "
                  f"frames/s, {'faster' if fps > 30 else 'slower'} than real time (x{fps / 30:.2f}); CPU "
                  f"{1e3 * float(np.median(cpus[name])) / n:5.1f} ms per frame")


if __name__ == "__main__":
    main()
