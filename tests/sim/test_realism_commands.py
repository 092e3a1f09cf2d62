"""The realism switch composes with the study commands: robustness push, sweep, tune, teleop and envelope pass the
preset to every run (its config.json has "realism"), name it in their report headers, and refuse a bad preset in
one line with exit 2 before anything runs. Runs are 0.1-0.2 s long."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from wbcbench.cli import main

BAD_PRESET = "actuators:\n  \"leg_*\": {coulomb: -1.0}\n"


def _realism_of(run_dir: Path) -> dict:
    return json.loads((run_dir / "config.json").read_text()).get("realism")


def _bad(tmp_path: Path) -> Path:
    f = tmp_path / "bad-preset.yaml"
    f.write_text(BAD_PRESET)
    return f


def _one_line_exit_2(capsys, argv, *needles) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for n in needles:
        assert n in err, err


# ---- robustness push
def test_push_trials_run_the_preset(tmp_path):
    """A push at 0.05 s into standing, 0.05 s of settling: both ways a trial is run (from the start, and branched
    from one approach) build the realistic robot, and the report header names the preset and its sensors."""
    from wbcbench.robustness.push import PushCell, PushStudy, _bisect, _bisect_group, write_report

    study = PushStudy("stand", ("tsid-position",), directions=1, iterations=0, max_impulse=2.0, push_duration=0.05,
                      settle=0.05, realism="talos-real")
    cell = PushCell("tsid-position", 0.0, "ds", 0, 0.05)
    alone = _bisect(study, cell, tmp_path / "alone")
    grouped = _bisect_group(study, [cell], tmp_path / "branched")
    for d in (tmp_path / "alone", tmp_path / "branched"):
        [trial] = list((d / "runs").iterdir())
        real = _realism_of(trial)
        assert real["name"] == "talos-real" and real["hip_flexibility"]["stiffness"] == 973.0
        assert json.loads((trial / "config.json").read_text())["sensors"]["name"] == "talos-like"
    assert alone.trials[0][1] is True and grouped[0] == alone   # a 2 N s push is survived either way
    md = write_report(study, [alone], tmp_path).read_text()
    assert "Robot: realism preset talos-real" in md and "Sensors: talos-like" in md


def test_push_bad_preset_is_one_line_before_any_trial(tmp_path, capsys):
    out = tmp_path / "o"
    _one_line_exit_2(capsys, ["robustness", "push", "stand", "-c", "tsid-position", "--realism",
                              str(_bad(tmp_path)), "--out", str(out), "-q"], "bad-preset.yaml", "coulomb")
    _one_line_exit_2(capsys, ["robustness", "push", "stand", "-c", "tsid-position", "--realism", "talos-fake",
                              "--out", str(out), "-q"], "--realism", "talos-real")
    assert not out.exists()


# ---- sweep and tune
def test_sweep_cells_run_their_preset_on_a_pool(tmp_path):
    """`realism` as a grid parameter: the ideal cell's run has no realism in its config, the other has the preset
    (a file relative to the sweep file, run by pool workers); the report header names both."""
    from wbcbench.study.execute import PoolExecutor
    from wbcbench.study.report import sweep_report
    from wbcbench.study.sweep import run_sweep

    (tmp_path / "presets").mkdir()
    (tmp_path / "presets" / "stiff.yaml").write_text("actuators:\n  \"leg_*\": {coulomb: 1.0, viscous: 0.5}\n")
    f = tmp_path / "sweep.yaml"
    f.write_text("base: {scenario: stand, controller: tsid-position, duration: 0.1}\n"
                 "grid: {realism: [null, presets/stiff.yaml]}\n")
    with PoolExecutor(2) as ex:
        out, table, n = run_sweep(f, tmp_path / "sw", ex)
    assert n == 2 and table.column("status").to_pylist() == ["ok", "ok"]
    by_preset = {}
    for cell in (out / "cells").iterdir():
        real = _realism_of(cell / "run")
        by_preset[None if real is None else real["name"]] = real
    assert set(by_preset) == {None, "stiff"}
    assert by_preset["stiff"]["joints"]["leg_left_4_joint"]["coulomb"] == 1.0
    assert by_preset["stiff"]["joints"]["arm_left_4_joint"]["coulomb"] == 0.0
    md = sweep_report(out)
    assert "Robot: ideal, realism preset stiff." in md


@pytest.mark.parametrize("grid, needles", [
    ("{realism: [talos-real, %s]}", ("bad-preset.yaml", "coulomb")),
    ("{realism: [talos-fake]}", ("unknown realism preset 'talos-fake'",)),
    ("{sim.realism: [talos-real]}", ("top-level parameter 'realism'",)),
    ("{realism: [talos-real], engine: [dart]}", ("needs the mujoco engine",)),
])
def test_sweep_bad_preset_is_one_line_before_any_cell(tmp_path, capsys, grid, needles):
    f = tmp_path / "sweep.yaml"
    f.write_text("base: {scenario: stand, controller: tsid-position, duration: 0.1}\n"
                 f"grid: {grid % _bad(tmp_path) if '%s' in grid else grid}\n")
    _one_line_exit_2(capsys, ["sweep", str(f), "--out", str(tmp_path / "o"), "-q"], *needles)
    assert not (tmp_path / "o" / "cells").exists()


def test_sweep_spd_controller_with_a_preset_is_refused(tmp_path, capsys):
    f = tmp_path / "sweep.yaml"
    f.write_text("base: {scenario: stand, controller: tsid-position, duration: 0.1, realism: talos-real}\n"
                 "grid: {mode: [position, spd]}\n")
    _one_line_exit_2(capsys, ["sweep", str(f), "--out", str(tmp_path / "o"), "-q"], "mode", "spd")


def test_tune_trials_run_the_preset(tmp_path, capsys):
    from wbcbench.study.tune import tune

    f = tmp_path / "tune.yaml"
    f.write_text("base: {scenario: stand, controller: ik, duration: 0.1, realism: talos-real}\n"
                 "params: {taskset.tasks.com_xy.kp: {min: 20, max: 200, log: true}}\n"
                 "objective: {metrics.E_m: 1.0}\n")
    res = tune(f, 1, tmp_path / "t")
    assert res["n_trials"] == 1
    for run_dir in (tmp_path / "t" / "baseline" / "run", tmp_path / "t" / "trials" / "trial-0000" / "run"):
        assert _realism_of(run_dir)["name"] == "talos-real"
    assert "Robot: realism preset talos-real." in (tmp_path / "t" / "report.md").read_text()
    g = tmp_path / "bad-tune.yaml"
    g.write_text(f.read_text().replace("realism: talos-real", f"realism: {_bad(tmp_path)}"))
    _one_line_exit_2(capsys, ["tune", str(g), "--trials", "1", "--out", str(tmp_path / "t2")], "bad-preset.yaml",
                     "coulomb")
    assert not (tmp_path / "t2" / "baseline").exists()


# ---- teleop
def test_teleop_runs_the_preset(tmp_path, capsys):
    from rich.console import Console

    from wbcbench.teleop.session.commands import render, run_session

    res = run_session("reach_forward", mode="position", duration=0.1, out=tmp_path / "tp", realism="talos-real")
    assert _realism_of(res.run_dir)["name"] == "talos-real" and not res.summary["fell"]
    assert res.summary["realism"] == "talos-real"
    console = Console(record=True, width=200)
    render(console, res.summary, res.run_dir)
    assert "(realism talos-real)" in console.export_text().splitlines()[0]
    argv = ["teleop", "--mocap", "reach_forward", "--duration", "0.1", "--out", str(tmp_path / "t2"), "-q"]
    _one_line_exit_2(capsys, [*argv, "--mode", "position", "--realism", str(_bad(tmp_path))], "bad-preset.yaml",
                     "coulomb")
    _one_line_exit_2(capsys, [*argv, "--realism", "talos-real"], "--mode", "torque or position")
    assert not (tmp_path / "t2").exists()


# ---- envelope
def _short_stand(data: dict, v: float):
    data.pop("pushes", None)
    data["duration"] = 0.1
    return data, {}


def test_envelope_trials_run_the_preset(tmp_path, capsys):
    from wbcbench.envelope.axes import AXES, register_axis
    from wbcbench.envelope.report import write_report
    from wbcbench.envelope.search import EnvelopeStudy, run_trial, validate

    axis = register_axis(replace(AXES["payload"], name="short-stand", scenario="push", easy=0.0, hard=1.0,
                                 resolution=1.0, build=_short_stand))
    try:
        study = EnvelopeStudy(axes=("short-stand",), controllers=("tsid-position",), realism="talos-real")
        validate(study)
        v = run_trial(study, "tsid-position", "short-stand", 0.0, tmp_path / "env")
        assert v["passed"], v
        assert _realism_of(Path(v["dir"]) / "run")["name"] == "talos-real"
        fake = [{"controller": "tsid-position", "axis": "short-stand", "unit": "kg", "largest": True, "easy": 0.0,
                 "hard": 1.0, "resolution": 1.0, "limit": 1.0, "first_failure": None, "mode": "limit reached",
                 "reason": "", "trials": [], "wall_s": 1.0}]
        md = write_report(study, fake, tmp_path).read_text()
        assert "Robot talos (realism preset talos-real)" in md
        _one_line_exit_2(capsys, ["envelope", "short-stand", "-c", "tsid-position", "--realism",
                                  str(_bad(tmp_path)), "--out", str(tmp_path / "o")], "bad-preset.yaml", "coulomb")
        assert not (tmp_path / "o" / "trials").exists()
    finally:
        AXES.pop(axis.name, None)
