"""The engine-sensitivity section: cells side by side with their relative difference, rankings per scenario on
each engine, which hold and which flip, and fallen cells ranked last."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from wbcbench.errors import WbcError
from wbcbench.report import engines as sens


def _cell(x: float, y: float, status: str = "ok") -> dict:
    return {"status": status, "zmp_error_m.x.mean": {"ours": x, "paper": 0.02},
            "zmp_error_m.y.mean": {"ours": y, "paper": 0.02}}


def _results(cells: dict) -> dict:
    return {"tables": {"table2": {"title": "ZMP error", "values": cells}}}


def test_rankings_hold_flip_and_fallen_cells_rank_last(tmp_path):
    a = _results({"ik": {"walk": _cell(0.02, 0.02)}, "tsid-torque": {"walk": _cell(0.004, 0.002)},
                  "tsid-position": {"walk": _cell(0.015, 0.015)}})
    b = _results({"ik": {"walk": _cell(0.06, 0.02)}, "tsid-torque": {"walk": _cell(0.005, 0.002)},
                  "tsid-position": {"walk": _cell(0.2, 0.1, status="fell")}})
    out = sens.write({"mujoco": a, "dart": b}, tmp_path, notes={"dart": "no armature"})
    t = out["tables"]["table2"]
    assert t["ranking"]["walk"]["mujoco"] == ["tsid-torque", "tsid-position", "ik"]
    assert t["ranking"]["walk"]["dart"] == ["tsid-torque", "ik", "tsid-position"]  # fallen: last
    assert t["flips"] == ["walk"] and t["holds"] == []
    row = next(r for r in t["rows"] if r["controller"] == "ik" and r["metric"] == "zmp_error_m.x.mean")
    assert row["values"] == {"mujoco": 0.02, "dart": 0.06}
    assert row["relative_difference"]["dart"] == pytest.approx(2.0)
    fallen = next(r for r in t["rows"] if r["controller"] == "tsid-position" and r["metric"].endswith("x.mean"))
    assert fallen["values"]["dart"] is None and fallen["status"]["dart"] == "fell"
    assert "tsid-position on walk (dart)" in t["summary"] and "flips" in t["summary"]
    md = (tmp_path / "engine-sensitivity.md").read_text()
    assert "| walk | tsid-torque > tsid-position > ik | tsid-torque > ik > tsid-position |" in md
    assert "+200 %" in md and "dart: no armature" in md
    assert json.loads((tmp_path / "engine-sensitivity.json").read_text())["reference"] == "mujoco"
    assert "<table>" in (tmp_path / "engine-sensitivity.html").read_text()


def test_same_ranking_holds():
    a = _results({"ik": {"walk": _cell(0.02, 0.02)}, "tsid-torque": {"walk": _cell(0.004, 0.002)}})
    b = _results({"ik": {"walk": _cell(0.03, 0.02)}, "tsid-torque": {"walk": _cell(0.006, 0.002)}})
    t = sens.engine_sensitivity({"mujoco": a, "dart": b})["tables"]["table2"]
    assert t["holds"] == ["walk"] and t["flips"] == []
    assert t["summary"].startswith("The ranking holds on mujoco, dart for walk")


def test_reproduce_engines_needs_two_known_engines(tmp_path):
    from wbcbench.report.reproduce import reproduce_engines

    with pytest.raises(WbcError, match="two or more different engines"):
        reproduce_engines(tmp_path, ["mujoco"])
    with pytest.raises(WbcError, match="unknown engine 'odee'"):
        reproduce_engines(tmp_path, ["mujoco", "odee"])


def test_reproduce_realism_puts_the_ideal_and_the_realistic_robot_side_by_side(tmp_path):
    """`reproduce --realism talos-real` on one cell: both reports, the comparison's files, the preset in the
    realistic runs' config and command; an unknown preset fails before anything runs."""
    from wbcbench.report.reproduce import reproduce_realism

    reports, sens = reproduce_realism(tmp_path, "talos-real", posture_gains=False, quick=True, jobs=1,
                                      progress=False, sanity=False,
                                      controllers=["tsid-torque"], scenarios=["walk-20cm"], keyframes=False)
    ideal, real = reports
    assert sens["engines"] == ["ideal", "talos-real"] and (tmp_path / "real-robot.md").exists()
    assert "--realism talos-real" in real.results["command"] and "--realism" not in ideal.results["command"]
    cfg = json.loads((Path(real.outcomes[0].run_dir) / "config.json").read_text())
    assert "realism" in cfg
    assert "realism" not in json.loads((Path(ideal.outcomes[0].run_dir) / "config.json").read_text())
    rows = [r for r in sens["tables"]["table2"]["rows"] if r["controller"] == "tsid-torque"]
    assert rows and all(r["status"]["ideal"] == "ok" for r in rows)
    with pytest.raises(WbcError):
        reproduce_realism(tmp_path / "bad", "no-such-preset", quick=True, jobs=1, progress=False, sanity=False,
                          controllers=["tsid-torque"], scenarios=["walk-20cm"], keyframes=False)


def test_fallen_cells_rank_by_how_long_they_stood():
    a = _results({"ik": {"walk": _cell(0.02, 0.02)}, "tsid-torque": {"walk": _cell(0.004, 0.002)}})
    b = _results({"ik": {"walk": _cell(0.1, 0.1, status="fell")},
                  "tsid-torque": {"walk": _cell(0.1, 0.1, status="fell")}})
    b["runs"] = [{"section": "paper", "controller": "ik", "scenario": "walk", "sim_time_s": 4.3},
                 {"section": "paper", "controller": "tsid-torque", "scenario": "walk", "sim_time_s": 3.1}]
    t = sens.engine_sensitivity({"ideal": a, "real": b})["tables"]["table2"]
    assert t["ranking"]["walk"] == {"ideal": ["tsid-torque", "ik"], "real": ["ik", "tsid-torque"]}
