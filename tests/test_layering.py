"""Layering: lower layers never import higher ones (DESIGN.md). Checked in fresh interpreters."""

from __future__ import annotations

import subprocess
import sys

import pytest


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_controllers_do_not_import_mujoco():
    mods = _modules_after("import wbcbench.controllers\nfrom wbcbench.controllers.base import available_controllers\n"
                          "available_controllers()")
    assert "wbcbench.controllers.inverse_dynamics" in mods and "wbcbench.controllers.ik" in mods
    assert "mujoco" not in mods
    assert not any(m.startswith("wbcbench.sim") for m in mods)


@pytest.mark.parametrize("package", ["wbcbench.planning", "wbcbench.tasks", "wbcbench.qp", "wbcbench.stabilizers",
                                     "wbcbench.estimation", "wbcbench.types"])
def test_lower_layers_do_not_import_the_simulator(package):
    mods = _modules_after(f"import {package}")
    assert "mujoco" not in mods and not any(m.startswith("wbcbench.sim") for m in mods), package
