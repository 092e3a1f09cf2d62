"""Cold start of the command line: wall time of whole processes `wbcbench --help`, `wbcbench list` and
`wbcbench run --help` (median, min and max of N runs each; the target is a median under 0.3 s). The processes run
this checkout's package (`python -m wbcbench.cli`), as the installed `wbcbench` script would.

    .venv/bin/python benchmarks/bench_cli.py [--runs 10] [--json FILE]

A timing on a machine busy with other work measures that work too: read the minimum beside the median.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = (("--help",), ("list",), ("run", "--help"))


def time_command(args: tuple[str, ...], runs: int) -> list[float]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "wbcbench.cli", *args], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--json", default=None, help="also write the results to this file")
    args = ap.parse_args()
    time_command(("--help",), 1)  # warm the file cache (bytecode, site-packages) once, as a second launch would be
    results = {}
    for cmd in COMMANDS:
        t = time_command(cmd, args.runs)
        name = "wbcbench " + " ".join(cmd)
        results[name] = {"median_s": statistics.median(t), "min_s": min(t), "max_s": max(t), "runs": len(t)}
        print(f"{name:22s} median {statistics.median(t):.3f} s  min {min(t):.3f} s  max {max(t):.3f} s  "
              f"({len(t)} runs)")
    try:
        load = os.getloadavg()[0]
        print(f"load average at the end: {load:.1f} on {os.cpu_count()} cores")
        results["load_average_1min"] = load
    except OSError:
        pass
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
