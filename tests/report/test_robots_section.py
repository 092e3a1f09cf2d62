"""`reproduce --robots`: the matrix on several robots on one process pool, each robot's report in its folder and
the cross-robot section (outcome, ZMP error, cost of transport, compute time per cell; the 20 cm walk's key frames
of every robot; generated and hand-tuned profile keys), on a tiny matrix: two robots, tsid-torque, the quick 20 cm
walk."""

from __future__ import annotations

import json

import pytest

from wbcbench.cli import main
from wbcbench.errors import WbcError
from wbcbench.report.reproduce import reproduce_robots, robot_names


def test_two_robots_side_by_side(tmp_path):
    reports, cmp = reproduce_robots(tmp_path, "g1,alexander", controllers=["tsid-torque"], scenarios=["walk-20cm"],
                                    quick=True, sanity=False, jobs=2, progress=False)
    assert [r.out_dir.name for r in reports] == ["g1", "alexander"]
    for r in reports:  # each robot's own complete report, its runs in its folder
        assert (r.out_dir / "report.md").is_file()
        (o,) = r.outcomes
        assert o.run_dir.startswith(str(r.out_dir / "runs"))
        assert json.loads((r.out_dir.parent / r.out_dir.name / "runs" / "paper-walk-20cm-tsid-torque"
                           / "summary.json").read_text())["robot"] == r.out_dir.name
    cells = {c["robot"]: c for c in cmp["cells"]}
    for robot in ("g1", "alexander"):
        c = cells[robot]
        assert c["status"] == "ok" and c["scenario_run"] == "walk-20cm-quick"  # walked without falling
        assert 0 < c["zmp_error_mean_m"]["x"] < 0.03 and 0 < c["zmp_error_mean_m"]["y"] < 0.03
        assert 0 < c["cost_of_transport"] < 5 and c["compute_time_us"] > 0
    assert cmp["provenance"]["g1"]["kind"] == "hand-written"
    prov = cmp["provenance"]["alexander"]
    assert prov["kind"] == "generated" and "feet" in prov["generated"] and prov["hand_tuned"] == []
    md = (tmp_path / "robots.md").read_text()
    assert "| g1 | tsid-torque | paper: walk-20cm-quick | ok |" in md
    assert "| alexander | generated |" in md and "## Key frames: walk-20cm" in md
    section = md.split("## Key frames: walk-20cm")[1].split("## Profiles")[0]
    for robot in ("g1", "alexander"):  # a strip, or the line saying why there is none
        frames = next(ln for ln in section.splitlines() if ln.startswith(f"| {robot} | "))
        assert f"{robot}/runs/paper-walk-20cm-tsid-torque/keyframes.png" in frames or "no key frames" in frames
    assert "<table>" in (tmp_path / "robots.html").read_text()
    assert json.loads((tmp_path / "robots.json").read_text())["robots"] == ["g1", "alexander"]


def test_robots_all_and_bad_names(tmp_path, capsys):
    from wbcbench.robots.profile import available_robots

    assert robot_names("all") == available_robots() and len(robot_names("all")) >= 10
    assert robot_names("g1, talos") == ["g1", "talos"]
    with pytest.raises(WbcError, match="'all' or different robot names"):
        robot_names("all,g1")
    # an unknown robot: one line naming it, exit 2, nothing run
    assert main(["reproduce", "--robots", "g1,nobot", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "nobot" in err
    assert not (tmp_path / "o" / "g1" / "runs").exists() or not any((tmp_path / "o" / "g1" / "runs").iterdir())
    assert main(["reproduce", "--robots", "g1", "--robot", "gr3", "--out", str(tmp_path / "p"), "--quiet"]) == 2
    assert "--robots" in capsys.readouterr().err
