"""Capability envelopes (wbcbench.envelope): limits found by bisection are reproducible, trials resume, bad input is
one line and exit 2. Short standing scenes with joint-pd keep this cheap."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from wbcbench.cli import main
from wbcbench.envelope.axes import AXES, _model_error, register_axis
from wbcbench.envelope.search import EnvelopeStudy, run_envelope, run_trial


def _payload_stand(data: dict, v: float):
    """3 s of standing with a point mass 0.3 m in front of the torso."""
    data.pop("pushes", None)
    data["duration"] = 3.0
    return _model_error(data, payloads=[{"link": "@torso", "mass": v, "offset": [0.3, 0.0, 0.0]}]
                        if v > 0 else []), {}


@pytest.fixture
def payload_stand():
    """A user axis added to the registry: the payload axis on a standing scene."""
    axis = register_axis(replace(AXES["payload"], name="payload-stand", scenario="push", easy=0.0, hard=40.0,
                                 resolution=10.0, build=_payload_stand))
    yield axis
    AXES.pop(axis.name, None)


def test_limits_reproducible_and_resumed(tmp_path, payload_stand):
    study = EnvelopeStudy(axes=("push", "payload-stand"), controllers=("joint-pd",),
                          resolutions={"push": 15.0})
    results = run_envelope(study, tmp_path / "env")
    for r in results:
        # a limit inside the range, bracketed to the resolution, the first failure a fall
        assert r["limit"] is not None and r["first_failure"] is not None, r
        assert 0 < abs(r["first_failure"] - r["limit"]) <= r["resolution"] + 1e-9
        assert r["mode"] == "fell"
        # reproducible: fresh runs at the limit pass and at the first failing value fail
        fresh = tmp_path / f"again-{r['axis']}"
        assert run_trial(study, "joint-pd", r["axis"], r["limit"], fresh)["passed"]
        again = run_trial(study, "joint-pd", r["axis"], r["first_failure"], fresh)
        assert not again["passed"] and again["mode"] == "fell"
        # each trial a normal run directory
        trial = tmp_path / "env" / "trials" / "talos" / "joint-pd" / r["axis"] / f"{r['limit']:.6g}"
        assert (trial / "run" / "summary.json").exists() and (trial / "envelope-scenario.yaml").exists()
        if r["axis"] == "push":   # its trials share their start: branched from it, the same runs as from the start
            assert json.loads((trial / "cell.json").read_text())["branched_at"] == 1.0
            from wbcbench.recorder import read_log

            branched = read_log(trial / "run" / "log.parquet")
            direct = read_log(fresh / "trials" / "talos" / "joint-pd" / "push" / f"{r['limit']:.6g}" / "run"
                              / "log.parquet")
            assert branched.keys() == direct.keys()
            for k in branched:
                if k != "controller_time_us":
                    np.testing.assert_array_equal(branched[k], direct[k], err_msg=k)
    assert results[0]["axis"] == "push" and results[0]["limit"] == 30.0   # 0..60 N s at 15: 60 fell, 0, 30, 45 fell
    # resumed: a second search re-runs nothing (every trial has its verdict)
    again = run_envelope(study, tmp_path / "env")
    assert [r["limit"] for r in again] == [r["limit"] for r in results]
    assert all(r["wall_s"] < 1.0 for r in again)
    saved = json.loads((tmp_path / "env" / "envelope.json").read_text())
    assert [r["limit"] for r in saved["results"]] == [r["limit"] for r in results]
    # the report's key frames: the last success and the first failure of each cell, rendered from their runs
    from PIL import Image

    from wbcbench.envelope.report import write_report

    md = write_report(study, results[:1], tmp_path / "env", keyframes=True).read_text()
    assert "last success 30, first failure 45 (fell)" in md
    for kind in ("pass", "fail"):
        png = tmp_path / "env" / "keyframes" / f"joint-pd-push-{kind}.png"
        assert f"](keyframes/{png.name})" in md and Image.open(png).size == (4 * 240, 300)


def test_report(tmp_path, payload_stand):
    from wbcbench.envelope.report import write_report

    study = EnvelopeStudy(axes=("push",), controllers=("joint-pd",))
    fake = [{"controller": c, "axis": a, "unit": "N s", "largest": True, "easy": 0.0, "hard": 60.0,
             "resolution": 2.0, "limit": lim, "first_failure": ff, "mode": mode, "reason": "", "trials": [],
             "wall_s": 1.0}
            for c, a, lim, ff, mode in (("ik", "push", 30.0, 32.0, "fell"), ("ik", "payload-stand", 40.0, None,
                                                                             "limit reached"))]
    md = write_report(study, fake, tmp_path).read_text()
    assert "30 (fails at 32: fell)" in md and ">= 60 (limit reached)" in md
    assert (tmp_path / "radar-talos.png").stat().st_size > 1000 and (tmp_path / "envelope.html").exists()


@pytest.mark.parametrize("argv, words", [
    (["pushx", "-c", "joint-pd"], "unknown envelope axis 'pushx'"),
    (["friction", "-c", "joint-pd", "--range", "friction=1:-0.2"], "outside what the axis can take"),
    (["stair-up", "-c", "joint-pd", "--range", "stair-up=0.05:1.5"], "outside what the axis can take"),
    (["push", "-c", "nope"], "unknown controller 'nope'"),
])
def test_bad_input_one_line(argv, words, tmp_path, capsys):
    assert main(["envelope", *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1


def test_controller_that_cannot_run_the_axis(tmp_path, capsys):
    """tsid-teleop crashes on a walk's first lift-off: at the axis's easy value, so one line and exit 2."""
    def walk_soon(data, v):
        data["params"].update(steps=1, initial_double_support=0.2, final_double_support=0.2)
        return _model_error(data, friction=v), {}

    axis = register_axis(replace(AXES["friction"], name="friction-short", build=walk_soon))
    try:
        assert main(["envelope", axis.name, "-c", "tsid-teleop", "--out", str(tmp_path / "o")]) == 2
    finally:
        AXES.pop(axis.name)
    err = capsys.readouterr().err.strip()
    assert "controller 'tsid-teleop' cannot run axis 'friction-short'" in err and len(err.splitlines()) == 1


def test_reproduce_section(tmp_path, monkeypatch):
    """`reproduce --envelope` appends the envelope table to the flagship report."""
    from wbcbench.envelope import report

    monkeypatch.setattr(report, "QUICK_AXES", ("push",))
    (tmp_path / "report.md").write_text("# Report\n")
    (tmp_path / "report.html").write_text("<html><body><h1>Report</h1></body></html>")
    md = report.reproduce_section(tmp_path, controllers="joint-pd")
    assert md == tmp_path / "envelope" / "envelope.md"
    text = (tmp_path / "report.md").read_text()
    assert "## Capability envelopes (quick)" in text and "| push | N s | 0 -> 60 | 8 |" in text
    assert "envelope/radar-talos.png" in text and "envelope/envelope.html" in (tmp_path / "report.html").read_text()


def test_resume_refuses_other_settings(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "settings.json").write_text('{"tolerance": 0.2, "seed": 0, "engine": "mujoco"}')
    assert main(["envelope", "push", "-c", "joint-pd", "--out", str(out)]) == 2


def test_failure_modes():
    from wbcbench.envelope.search import _mode

    assert _mode({"status": "fell"}, {"controller_status": {}}) == "fell"
    assert _mode({"status": "error", "error": "CentroidalPlanError: centroidal QP: PRIMAL_INFEASIBLE"}, None) \
        == "planner refused"
    assert _mode({"status": "error", "error": "QPError: level 0: infeasible"}, {"fell": True}) == "QP infeasible"
    assert _mode({"status": "error", "error": "KeyError: 'x'"}, {"fell": True}) == "error"
    assert _mode({"status": "ok"}, {}) == "off the plan"


def test_generated_scenarios():
    """Trials are the base scenario as the robot's profile sizes it, changed by the value: at walk-fast-0.8's speed
    the walk-speed axis gives walk-fast-0.8's gait; the pitch axis at 15 deg gives the paper's platforms."""
    from wbcbench.config import load_yaml
    from wbcbench.envelope.axes import get_axis
    from wbcbench.scenarios.base import scenario_path

    data, _ = get_axis("walk-speed").trial(0.8, "talos")
    base = load_yaml(scenario_path("walk-fast-0.8-quick"))["params"]
    assert {k: data["params"][k] for k in ("step_length", "single_support", "double_support")} == \
        {k: base[k] for k in ("step_length", "single_support", "double_support")}
    assert get_axis("walk-speed").trial(0.8, "g1")[0]["params"]["com_height"] == 0.58   # the G1's profile sizes it
    boxes = get_axis("platform-pitch").trial(15.0, "talos")[0]["terrain"]["boxes"]
    assert boxes == load_yaml(scenario_path("platforms"))["terrain"]["boxes"]


def test_stair_down_and_rough_ground_terrain():
    """stair-down: the treads of stairs-quick each `v` lower than the last, the robot's landing at z = 0, no floor;
    rough: six tilted tiles, none below the floor at its lowest top edge, raised by at most `v` above that, drawn
    from the seed (the same seed the same ground)."""
    import math

    import numpy as np

    from wbcbench.envelope.axes import ROUGH_TILE, get_axis

    data, _ = get_axis("stair-down").trial(0.12, "talos")
    t = data["terrain"]
    tops = [b["center"][2] + b["size"][2] / 2 for b in t["boxes"]]
    assert not t["floor"] and tops[0] == pytest.approx(0.0) and np.allclose(np.diff(tops), -0.12)
    assert data["params"]["max_step_height"] >= 0.14
    a, _ = get_axis("rough").trial(0.06, "talos", seed=3)
    b, _ = get_axis("rough").trial(0.06, "talos", seed=3)
    c, _ = get_axis("rough").trial(0.06, "talos", seed=4)
    assert a["terrain"] == b["terrain"] and a["terrain"] != c["terrain"]
    for box in a["terrain"]["boxes"]:
        roll, pitch, _ = box["rpy"]
        drop = ROUGH_TILE / 2 * math.sin(abs(pitch)) + 0.5 * math.sin(abs(roll))
        rise = box["center"][2] + box["size"][2] / 2 - drop
        assert -1e-6 <= rise <= 0.06 + 1e-6 and abs(pitch) <= math.atan(0.06 / ROUGH_TILE) / 2 + 1e-9


@pytest.mark.parametrize("axis, value", [("stair-down", 0.10), ("rough", 0.05)])
def test_new_axes_walk_at_an_easy_value(tmp_path, axis, value):
    """At an easy value TSID torque completes the generated terrain: descends 2 x 10 cm (the CoM ends 0.2 m lower)
    or crosses 5 cm rough ground to the third tile."""
    study = EnvelopeStudy(axes=(axis,), controllers=("tsid-torque",))
    from wbcbench.envelope.search import trial_dir

    v = run_trial(study, "tsid-torque", axis, value, tmp_path)
    assert v["passed"], v
    summary = json.loads((trial_dir(tmp_path, "talos", "tsid-torque", axis, value) / "run" / "summary.json")
                         .read_text())
    assert not summary["fell"]
    if axis == "stair-down":
        assert summary["metrics"]["com_final_m"][2] < 0.7


def test_reproduce_section_takes_the_realism_preset(tmp_path, monkeypatch):
    """`reproduce --realism P --envelope`: the realistic report's envelope runs every trial on P (the study the
    section searches carries it; the search itself is replaced here: nothing runs)."""
    from wbcbench.envelope import report, search

    seen = []

    def fake_run_envelope(study, out, executor=None, progress=None):
        seen.append(study)
        out.mkdir(parents=True, exist_ok=True)
        return [{"controller": "joint-pd", "axis": "push", "unit": "N s", "largest": True, "easy": 0.0,
                 "hard": 60.0, "resolution": 8.0, "limit": 30.0, "first_failure": 38.0, "mode": "fell",
                 "reason": "", "trials": [], "wall_s": 0.0}]

    monkeypatch.setattr(search, "run_envelope", fake_run_envelope)
    monkeypatch.setattr(report, "QUICK_AXES", ("push",))
    report.reproduce_section(tmp_path, controllers="joint-pd", realism="talos-actuation")
    assert seen[0].realism == "talos-actuation"
    assert "realism preset talos-actuation" in (tmp_path / "envelope" / "envelope.md").read_text()
