"""A/B timing of two checkouts in one invocation: the same benchmark script runs with this checkout's wbcbench
and with another's (e.g. the previous main), alternating round by round, each run in its own process pinned to
one core with OPENBLAS_NUM_THREADS=1, so slow phases of a shared machine hit both sides alike."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def alternate(script: str, script_args: list[str], other: str, rounds: int, core: str) -> dict[str, list[dict]]:
    """{"new": [...], "other": [...]}: per round, the JSON `script script_args --json FILE` wrote with each side's
    wbcbench first on PYTHONPATH (``core``: the CPU to pin to, '' for none)."""
    here = Path(script).resolve().parents[1]
    sides = {"new": here, "other": Path(other).resolve()}
    env0 = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    pin_cmd = ["taskset", "-c", core] if core else []
    results: dict[str, list[dict]] = {k: [] for k in sides}
    for r in range(rounds):
        for side, root in sides.items():
            with tempfile.NamedTemporaryFile(suffix=".json") as f:
                cmd = pin_cmd + [sys.executable, str(Path(script).resolve()), *script_args, "--json", f.name]
                subprocess.run(cmd, env={**env0, "PYTHONPATH": str(root)}, check=True, stdout=subprocess.DEVNULL)
                results[side].append(json.loads(Path(f.name).read_text()))
        print(f"  round {r + 1}/{rounds} done", flush=True)
    print(f"new: {sides['new']}\nother: {sides['other']}\n{rounds} alternating rounds, core {core or 'any'}")
    return results
