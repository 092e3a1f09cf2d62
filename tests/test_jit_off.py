"""The physics with the compiled kernels off (WBCBENCH_JIT=0: the same kernels run as plain Python): the robot
behaves the same, to rounding (the compiled sums are reassociated)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest


def _run(tmp_path, controller, scenario, duration, jit: str):
    out = tmp_path / f"{controller}-{jit}"
    env = {**os.environ, "WBCBENCH_JIT": jit}
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", scenario, "-c", controller, "--duration",
                           str(duration), "--quiet", "--out", str(out)], env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("controller", ["tsid-torque", "ik"])
def test_same_physics_with_and_without_the_compiled_kernels(tmp_path, controller):
    on = _run(tmp_path, controller, "sway", 0.15, "1")
    off = _run(tmp_path, controller, "sway", 0.15, "0")
    assert not on["fell"] and not off["fell"]
    for a, b in zip(on["metrics"]["com_final_m"], off["metrics"]["com_final_m"]):
        assert a == pytest.approx(b, abs=1e-7)
    assert on["metrics"]["com_rms_error_m"] == pytest.approx(off["metrics"]["com_rms_error_m"], rel=1e-5, abs=1e-8)
