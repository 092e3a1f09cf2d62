"""What the live view (`wbcbench run ... --view`) costs the control loop: the wall time of the same run with and
without the `LiveView` probe, alternated, with a headless browser (Debian's chromium through Playwright, when
installed) connected to the live view so that every frame is really serialised and sent.

    .venv/bin/python benchmarks/bench_live_view.py [--scenario walk-20cm-quick] [--controller tsid-torque]
        [--duration 2] [--rounds 3] [--loop-core 1] [--browser-core 0]

The Python process (control loop, viser's server thread, the publishing thread) is pinned to `--loop-core`, the
browser to `--browser-core` (it is another program, on a real set-up another machine). Use
OPENBLAS_NUM_THREADS=1.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import tempfile
from pathlib import Path

import numpy as np


class _CpuClock:
    """A probe that reads the process' CPU time (every thread: loop, viser's server, the publisher) when attached
    (after the live view built its model) and when the run's metrics are asked for (after the loop): on one
    core, what the loop pays for the view is this CPU time's increase, whatever else runs on the machine."""

    def attach(self, sim) -> dict:
        self.start = _cpu()
        return {}

    def values(self) -> tuple:
        return ()

    def metrics(self, log) -> dict:
        self.seconds = _cpu() - self.start
        return {}


def _cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _view_cpu_share(browser, rate: float, seconds: float = 10.0) -> float:
    """The fraction of one core the live view takes when every joint moves in every frame (its worst case): the
    process' CPU time per wall-clock second while a loop hands it `rate` snapshots a second of a TALOS whose
    joints all turn, minus the same loop's without the view."""
    import time

    from wbcbench.robots import load_robot
    from wbcbench.sim.simulator import Simulator
    from wbcbench.viz.live import LiveView

    sim = Simulator(load_robot("talos"))
    view = LiveView(port=_free_port(), rate=rate)
    page = None

    def share(publish: bool) -> float:
        c0, w0 = _cpu(), time.perf_counter()
        while time.perf_counter() - w0 < seconds:
            sim.data.qpos[7:] += 1e-3 * (-1) ** view.published  # every joint turns between two frames
            if publish:
                view.values()
            time.sleep(0.002)
        return (_cpu() - c0) / (time.perf_counter() - w0)

    try:
        view.attach(sim)
        if browser is not None:
            page = browser.new_page(viewport={"width": 800, "height": 500})
            page.goto(view.url)
            page.locator("canvas").first.wait_for(timeout=120_000)
        time.sleep(2.0)  # the meshes sent
        return share(True) - share(False)
    finally:
        view.close()
        if page is not None:
            page.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="walk-20cm-quick")
    p.add_argument("--controller", default="tsid-torque")
    p.add_argument("--duration", type=float, default=2.0)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--rate", type=float, default=30.0, help="display rate of the live view [frames/s]")
    p.add_argument("--loop-core", type=int, default=1)
    p.add_argument("--browser-core", type=int, default=0)
    p.add_argument("--no-browser", action="store_true")
    args = p.parse_args()
    from wbcbench.runner import run
    from wbcbench.viz.live import LiveView

    chromium = None if args.no_browser else (shutil.which("chromium") or shutil.which("chromium-browser"))
    pw = browser = None
    if chromium:
        from playwright.sync_api import sync_playwright

        os.sched_setaffinity(0, {args.browser_core})  # the driver and the browser inherit it
        pw = sync_playwright().start()
        browser = pw.chromium.launch(executable_path=chromium, headless=True,
                                     args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
    os.sched_setaffinity(0, {args.loop_core})
    walls = {"without": [], "with": []}
    cpus = {"without": [], "with": []}
    frames = []
    with tempfile.TemporaryDirectory() as tmp:
        run(args.scenario, args.controller, duration=0.2, out=Path(tmp) / "warm")  # JIT and caches
        for r in range(args.rounds):
            for case in ("without", "with"):
                out = Path(tmp) / f"{case}-{r}"
                clock = _CpuClock()
                if case == "without":
                    res = run(args.scenario, args.controller, duration=args.duration, out=out, probes=[clock])
                else:
                    view = LiveView(port=_free_port(), rate=args.rate)
                    page = None
                    try:
                        if browser is not None:
                            page = browser.new_page(viewport={"width": 800, "height": 500})
                            page.goto(view.url)
                            page.locator("canvas").first.wait_for(timeout=120_000)
                        res = run(args.scenario, args.controller, duration=args.duration, out=out, probes=[view, clock])
                    finally:
                        view.close()
                        if page is not None:
                            page.close()
                    frames.append(view.shown / res.summary["wall_time_s"])
                walls[case].append(res.summary["wall_time_s"])
                cpus[case].append(clock.seconds)
                print(f"round {r + 1} {case:>7} the view: {res.summary['wall_time_s']:.2f} s wall, "
                      f"{clock.seconds:.2f} s CPU", flush=True)
    share = _view_cpu_share(browser, args.rate)
    if browser is not None:
        browser.close()
        pw.stop()
    w0, w1 = np.median(walls["without"]), np.median(walls["with"])
    print(f"\n{args.controller} on {args.scenario}, {args.duration:g} s simulated, {args.rounds} rounds, loop on core "
          f"{args.loop_core}, browser {'on core ' + str(args.browser_core) if chromium else 'none'}")
    print(f"wall time median: without the view {w0:.2f} s, with it {w1:.2f} s: {100 * (w1 / w0 - 1):+.1f} %")
    c0, c1 = np.median(cpus["without"]), np.median(cpus["with"])
    print(f"CPU time median (all threads, one core): without {c0:.2f} s, with {c1:.2f} s: {100 * (c1 / c0 - 1):+.1f} %")
    print(f"the live view alone, every joint moving in every frame, {args.rate:g} frames/s: {100 * share:.1f} % of one "
          "core's CPU time, the most it takes from a loop on that core")
    print(f"frames shown per wall-clock second (median): {np.median(frames):.1f} (display rate {args.rate:g})")


if __name__ == "__main__":
    main()
