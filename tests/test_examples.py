"""The examples/ folder, installed and run as a user would: a controller plugin and a plan-correction plugin
(pip-installed, found through their entry points), a scenario built in Python, a third robot by YAML alone.

Plugins are pip-installed into a directory of their own that the commands under test get on their PYTHONPATH
(`pip install --target`): the installed distribution and its entry points are found exactly as in site-packages,
and the test environment shared with the rest of the suite (which runs in parallel workers) never sees them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _cli(*args, check_rc=None, plugins: Path | None = None):
    env = None
    if plugins is not None:
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(plugins),
                                                                          os.environ.get("PYTHONPATH")]))}
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", *args], capture_output=True, text=True, env=env)
    if check_rc is not None:
        assert out.returncode == check_rc, out.stderr + out.stdout
    return out


def _pip_install(package: Path, target: Path) -> Path:
    """`pip install` a plugin package into `target` (a directory put on the PYTHONPATH of the commands)."""
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "install", "--no-deps",
                    "--no-build-isolation", "--target", str(target), str(package)],
                   check=True, capture_output=True, text=True)
    return target


@pytest.fixture(scope="module")
def weighted_ik(tmp_path_factory):
    """examples/weighted_ik pip-installed for the module: (controller name, its install directory)."""
    return "weighted-ik", _pip_install(EXAMPLES / "weighted_ik", tmp_path_factory.mktemp("weighted-ik"))


def test_the_example_controller_is_at_most_40_lines():
    src = EXAMPLES / "weighted_ik" / "src" / "wbcbench_weighted_ik" / "__init__.py"
    assert len(src.read_text().splitlines()) <= 40


def test_plugin_controller_is_listed_and_keeps_talos_up_through_sway(weighted_ik, tmp_path):
    weighted_ik, plugins = weighted_ik
    out = _cli("list", check_rc=0, plugins=plugins)
    line = next(l for l in out.stdout.splitlines() if l.startswith("controllers:"))
    assert "weighted-ik [wbcbench_weighted_ik]" in line
    _cli("run", "sway", "-c", weighted_ik, "--out", str(tmp_path / "sway"), "--quiet", check_rc=0, plugins=plugins)
    s = json.loads((tmp_path / "sway" / "summary.json").read_text())
    assert not s["fell"] and s["metrics"]["com_rms_error_m"] < 0.02 and s["mode"] == "position"


def test_plugin_controller_joins_the_reproduce_report(weighted_ik, tmp_path):
    weighted_ik, plugins = weighted_ik
    out = tmp_path / "rep"
    _cli("reproduce", "--quick", "--controllers", weighted_ik, "--scenarios", "walk-20cm,sway", "--jobs", "1",
         "--quiet", "--out", str(out), check_rc=0, plugins=plugins)
    res = json.loads((out / "results.json").read_text())
    cell = res["tables"]["table2"]["values"][weighted_ik]["walk-20cm"]
    assert cell["status"] in ("ok", "fell") and cell["zmp_error_m.x.mean"]["paper"] is None
    assert isinstance(cell["zmp_error_m.x.mean"]["ours"], float)
    assert res["sanity"][weighted_ik]["sway"]["status"] == "ok"
    assert {(r["controller"], r["scenario"]) for r in res["runs"]} == {(weighted_ik, "walk-20cm"),
                                                                       (weighted_ik, "sway")}
    assert "Weighted" in (out / "report.md").read_text() or weighted_ik in (out / "report.md").read_text()


@pytest.fixture(scope="module")
def lateral_shift(tmp_path_factory):
    """examples/lateral_shift pip-installed for the module: its install directory."""
    return _pip_install(EXAMPLES / "lateral_shift", tmp_path_factory.mktemp("lateral-shift"))


def _log(run_dir: Path) -> dict:
    import pyarrow.parquet as pq

    table = pq.read_table(run_dir / "log.parquet")
    return {n: table.column(n).to_numpy() for n in table.column_names}


def test_the_example_correction_is_about_20_lines():
    src = EXAMPLES / "lateral_shift" / "src" / "wbcbench_lateral_shift" / "__init__.py"
    assert len([ln for ln in src.read_text().splitlines() if ln.strip()]) <= 30


def test_plugin_correction_shifts_the_walks_references_by_its_offset(lateral_shift, tmp_path):
    """examples/lateral_shift, found by its `wbcbench.corrections` entry point and declared first in an IK task
    set's `corrections:` list: the CoM reference it hands on is the plan's (the logged com_ref) shifted by exactly its
    offset (0.02 m along y, faded in over its first second), the robot walks the shifted plan (its CoM about 2 cm to
    the left of the unshifted run's) and does not fall."""
    taskset = EXAMPLES / "lateral_shift" / "ik-shifted.yaml"
    out = _cli("list", check_rc=0, plugins=lateral_shift)
    assert "lateral_shift [wbcbench-lateral-shift]" in next(ln for ln in out.stdout.splitlines()
                                                           if ln.startswith("corrections:"))
    runs = {}
    for name, extra in (("shifted", ["--taskset", str(taskset)]), ("plan", [])):
        _cli("run", "walk-20cm-quick", "-c", "ik", *extra, "--duration", "4.0", "--out", str(tmp_path / name),
             "--quiet", check_rc=0, plugins=lateral_shift)
        s = json.loads((tmp_path / name / "summary.json").read_text())
        assert not s["fell"], s["fall_reason"]
        runs[name] = _log(tmp_path / name)
    a, b = runs["shifted"], runs["plan"]
    t = a["t"] - 1e-3  # the log's time is the end of the tick; the references are the tick's start's
    shift = np.stack([a[f"correction_lateral_shift.{k}"] - a[f"com_ref.{k}"] for k in "xyz"], axis=1)
    expected = np.zeros_like(shift)
    expected[:, 1] = 0.02 * np.minimum(t / 1.0, 1.0)
    np.testing.assert_allclose(shift, expected, rtol=0.0, atol=1e-12)
    np.testing.assert_array_equal(a["com_ref.y"], b["com_ref.y"])  # the plan itself is the same
    late = t > 1.5  # after the fade-in: standing, shifting the weight, the first step
    dy = a["com.y"][late] - b["com.y"][late]
    assert 0.015 < dy.mean() < 0.03 and np.abs(dy - 0.02).max() < 0.012, (dy.mean(), np.abs(dy - 0.02).max())
    assert np.abs(a["com.x"][late] - b["com.x"][late]).max() < 0.005


def test_a_task_set_naming_a_correction_that_is_not_installed_is_one_line(tmp_path):
    out = _cli("run", "walk-20cm-quick", "-c", "ik", "--taskset", str(EXAMPLES / "lateral_shift" / "ik-shifted.yaml"),
               "--duration", "0.01", "--out", str(tmp_path / "r"), check_rc=2)
    err = out.stderr.strip().splitlines()
    assert len(err) == 1 and "ik-shifted.yaml" in err[0] and "corrections[0].type" in err[0], err
    assert "unknown correction type 'lateral_shift'" in err[0] and "plan_lead" in err[0]


def test_python_scenario_example(tmp_path):
    out = subprocess.run([sys.executable, str(EXAMPLES / "python_scenario.py"), str(tmp_path / "run")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr + out.stdout
    assert "slow-sway-and-push: fell=False" in out.stdout
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert cfg["scenario_file"] == "<python:slow-sway-and-push>" and len(cfg["pushes"]) == 1


def test_third_robot_by_yaml_alone(tmp_path):
    profile = EXAMPLES / "robots" / "romeo.yaml"
    _cli("run", "stand", "-c", "joint-pd", "--robot", str(profile), "--mode", "torque", "--duration", "2",
         "--quiet", "--out", str(tmp_path / "r"), check_rc=0)
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["robot"] == "romeo" and not s["fell"] and abs(s["metrics"]["base_height_change_m"]) < 0.005


def test_broken_plugins_are_one_line_and_break_nothing_else(tmp_path):
    """A plugin that fails to import, and one that takes a built-in's name: `list` names both (exit 2) and still
    lists the rest; using the broken name is one line, exit 2; the built-in still runs."""
    pkg = tmp_path / "badplugins"
    (pkg / "src" / "wbcbench_badplugins").mkdir(parents=True)
    (pkg / "src" / "wbcbench_badplugins" / "__init__.py").write_text(
        "import this_module_does_not_exist\n")
    (pkg / "src" / "wbcbench_badplugins_dup.py").write_text(
        "from wbcbench.controllers.joint_pd import JointPD\n\nclass Dup(JointPD):\n    name = 'joint-pd'\n")
    (pkg / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=77"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "wbcbench-badplugins"\nversion = "0.0.1"\n'
        '[project.entry-points."wbcbench.controllers"]\nbroken = "wbcbench_badplugins:Nothing"\n'
        'joint-pd = "wbcbench_badplugins_dup:Dup"\n'
        '[tool.setuptools]\npackage-dir = {"" = "src"}\npy-modules = ["wbcbench_badplugins_dup"]\n'
        '[tool.setuptools.packages.find]\nwhere = ["src"]\n')
    plugins = _pip_install(pkg, tmp_path / "site")
    out = _cli("list", check_rc=2, plugins=plugins)
    assert "controllers:" in out.stdout and "tsid-torque" in out.stdout
    errors = out.stderr.strip().splitlines()
    assert len(errors) == 2
    assert any("'broken'" in e and "wbcbench-badplugins" in e and "failed to import" in e for e in errors)
    assert any("'joint-pd'" in e and "built-in" in e for e in errors)
    out = _cli("run", "stand", "-c", "broken", "--duration", "0.01", "--out", str(tmp_path / "r"), check_rc=2,
               plugins=plugins)
    assert len(out.stderr.strip().splitlines()) == 1 and "ModuleNotFoundError" in out.stderr
    _cli("run", "stand", "-c", "joint-pd", "--duration", "0.05", "--quiet", "--out", str(tmp_path / "ok"),
         check_rc=0, plugins=plugins)
