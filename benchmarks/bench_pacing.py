"""Can this machine hold a 1 kHz paced loop at all? A bare loop paced as `--realtime` paces a run (sleep until
the tick's start, the real-time class where the system allows), doing nothing but a given amount of work a tick:
spinning on the clock, and optionally writing one value in each page of a given amount of memory a tick, taken in
turn from a larger array. It counts the ticks that started more than 1 and 5 ms late and the stalls (runs of
ticks more than 5 ms late), with no simulation, controller, log or interpreter threads involved: stalls it finds
are the machine's (its kernel, or a virtual machine's host), not the program's.

    .venv/bin/python benchmarks/bench_pacing.py [--work-ms 0.7] [--seconds 30] [--core 1]
    .venv/bin/python benchmarks/bench_pacing.py --touch-mb 2 --span-mb 400     # also touch memory every tick
    .venv/bin/python benchmarks/bench_pacing.py --sweep                        # spans 0, 8, 40, 400 MB, in turn

`--sweep` alternates the loop without memory and with 2 MB a tick over spans of 8, 40 and 400 MB (`--rounds`
times), to see whether a machine's stalls grow with the memory a program touches (on a virtual machine, its host
may stall a processor on memory it has reclaimed or moved).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

PERIOD = 1e-3
PRIORITY = 10  # the paced run loop's (wbcbench/runner.py)
MAX_CATCH_UP = 5e-3  # after a longer stall the schedule resumes from the clock, as the run loop does


def paced_loop(work_s: float, seconds: float, touch_mb: float = 0.0, span_mb: float = 0.0) -> dict:
    """Run the loop in this thread; lateness statistics [ms] and the scheduling class it ran in."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        scheduling = f"real-time (SCHED_FIFO {PRIORITY})"
    except (AttributeError, OSError):
        scheduling = "normal (real-time class not permitted)"
    page = 4096 // 8
    per_tick = int(touch_mb * 2**20 / 4096)
    pages = max(int(span_mb * 2**20 / 4096), per_tick, 1)
    memory = np.zeros(pages * page)
    memory[::page] = 1.0  # every page mapped before the loop: only the host's handling of it is left
    firsts = memory[::page]
    n = int(round(seconds / PERIOD))
    late = np.zeros(n)
    clock = time.perf_counter
    start, at = clock(), 0
    for k in range(n):
        ahead = start + k * PERIOD - clock()
        if ahead > 0:
            time.sleep(ahead)
        else:
            late[k] = -ahead
            if -ahead > MAX_CATCH_UP:
                start -= ahead
        until = clock() + work_s
        if per_tick:
            idx = np.arange(at, at + per_tick) % pages
            firsts[idx] += 1.0
            at = (at + per_tick) % pages
        while clock() < until:
            pass
    ms = late * 1e3
    over5 = ms > 5.0
    stalls = int(np.count_nonzero(over5 & ~np.r_[False, over5[:-1]]))
    return {"ticks": n, "late_1ms": int(np.count_nonzero(ms > 1.0)), "late_5ms": int(np.count_nonzero(over5)),
            "stalls_5ms": stalls, "worst_ms": float(ms.max()), "median_ms": float(np.median(ms)),
            "scheduling": scheduling}


def _line(label: str, r: dict) -> str:
    return (f"{label:<34} ticks {r['ticks']:>6}  >1 ms {r['late_1ms']:>5}  >5 ms {r['late_5ms']:>4}  "
            f"stalls {r['stalls_5ms']:>3}  worst {r['worst_ms']:6.2f} ms  [{r['scheduling']}]")


def _one_process(args: argparse.Namespace, touch: float, span: float) -> dict:
    """One loop in its own process pinned to the core (a fresh interpreter, nothing else in it)."""
    cmd = [sys.executable, __file__, "--work-ms", str(args.work_ms), "--seconds", str(args.seconds),
           "--touch-mb", str(touch), "--span-mb", str(span), "--json"]
    if args.core is not None:
        cmd += ["--core", str(args.core)]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise SystemExit(f"bench_pacing: the loop's process failed (exit {done.returncode}): {last}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work-ms", type=float, default=0.7, help="work per 1 ms tick (a paced tsid-teleop tick: 0.7)")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--touch-mb", type=float, default=0.0, help="memory written a tick (one value per page)")
    ap.add_argument("--span-mb", type=float, default=0.0, help="the array those pages are taken from in turn")
    ap.add_argument("--sweep", action="store_true", help="no memory, then 2 MB a tick over 8, 40, 400 MB")
    ap.add_argument("--rounds", type=int, default=1, help="repetitions of the sweep (alternating)")
    ap.add_argument("--core", type=int, default=None, help="pin each loop to this core")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    for name in ("work_ms", "seconds", "touch_mb", "span_mb"):
        if getattr(args, name) < 0 or (name == "seconds" and args.seconds == 0):
            ap.error(f"--{name.replace('_', '-')} must be {'positive' if name == 'seconds' else '>= 0'}")
    if args.core is not None and hasattr(os, "sched_getaffinity") and args.core not in os.sched_getaffinity(0):
        ap.error(f"--core {args.core}: not one of this process's cores {sorted(os.sched_getaffinity(0))}")
    if args.work_ms >= PERIOD * 1e3:
        ap.error(f"--work-ms must be below the period ({PERIOD * 1e3:g} ms)")
    if args.json:
        if args.core is not None:
            try:
                os.sched_setaffinity(0, {args.core})
            except (AttributeError, OSError) as exc:
                ap.error(f"--core {args.core}: {exc}")
        print(json.dumps(paced_loop(args.work_ms * 1e-3, args.seconds, args.touch_mb, args.span_mb)))
        return 0
    cases = ([(0.0, 0.0), (2.0, 8.0), (2.0, 40.0), (2.0, 400.0)] if args.sweep
             else [(args.touch_mb, args.span_mb)])
    print(f"paced 1 kHz loop, {args.work_ms} ms of work a tick, {args.seconds:g} s a case"
          + (f", core {args.core}" if args.core is not None else ""))
    for rnd in range(args.rounds):
        for touch, span in cases:
            r = _one_process(args, touch, span)
            label = "no memory" if not touch else f"{touch:g} MB a tick over {span:g} MB"
            print(_line(f"{label}" + (f" (round {rnd + 1})" if args.rounds > 1 else ""), r), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
