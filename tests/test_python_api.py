"""The public Python API: `import wbcbench` is light, every exported name resolves, scenarios build in Python
with the same validation as files."""

from __future__ import annotations

import subprocess
import sys

import pytest

import wbcbench
from wbcbench.errors import ConfigError


def test_import_is_light_and_exports_resolve():
    out = subprocess.run([sys.executable, "-c", "import sys, wbcbench; print('mujoco' in sys.modules, "
                                                "'pinocchio' in sys.modules)"], capture_output=True, text=True)
    assert out.stdout.split() == ["False", "False"], out.stderr
    for name in wbcbench.__all__:
        assert getattr(wbcbench, name) is not None, name


def test_make_scenario_validates_like_a_file(talos):
    scen = wbcbench.make_scenario("walk", talos, name="w", params={"steps": 2, "step_length": 0.1,
                                                                   "single_support": 0.9, "double_support": 0.1})
    assert scen.spec.file == "<python:w>" and scen.spec.duration == 0.0
    with pytest.raises(ConfigError, match=r"<python:x>.*params.amplitud"):
        wbcbench.make_scenario("sway", talos, name="x", duration=1.0, params={"amplitud": [0, 0.05, 0]})
    with pytest.raises(ConfigError, match="unknown scenario kind 'swya'.*did you mean 'sway'"):
        wbcbench.make_scenario("swya", talos, duration=1.0)
    with pytest.raises(ConfigError, match="duration > 0"):
        wbcbench.make_scenario("sway", talos)
