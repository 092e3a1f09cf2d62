"""Reports: the paper's numbers as data, report/compare from run directories, reproduce on a tiny matrix."""

import importlib
import io
import json
import shutil

import pytest
from rich.console import Console

from wbcbench.cli import main
from wbcbench.report import PAPER_TABLES, compare, compare_rows, paper_value, report, reproduce
from wbcbench.report import matrix
from wbcbench.report.paper import CONTROLLERS, SCENARIOS

reproduce_module = importlib.import_module("wbcbench.report.reproduce")  # (the package exports the function)


def strict_json(path):
    def no_constants(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(path.read_text(), parse_constant=no_constants)


# ------------------------------------------------------------------------------------------ paper data
def test_paper_tables_are_complete_and_consistent():
    assert sorted(PAPER_TABLES) == [f"table{i}" for i in range(2, 9)]
    for t in PAPER_TABLES.values():
        assert t.cells(), t.id
        for c, s in t.cells():
            assert c in CONTROLLERS and s in SCENARIOS
            assert set(t.values[c][s]) == {m.key for m in t.metrics}, (t.id, c, s)
    # ZMP, CoM and feet statistics: mean and std never above the peak
    for tid in ("table2", "table3", "table4", "table5"):
        t = PAPER_TABLES[tid]
        for c, s in t.cells():
            v = t.values[c][s]
            for key in v:
                if key.endswith(".mean") or key.endswith(".std"):
                    assert v[key] <= v[key.rsplit(".", 1)[0] + ".peak"], (tid, c, s, key)
    # the published costs of transport are E / (m g D) with m g = 981 N (D = 1.2 m and 3.6 m walks)
    t6 = PAPER_TABLES["table6"]
    for c, s in t6.cells():
        d = {"walk-20cm": 1.2, "walk-60cm": 3.6}.get(s)
        if d:
            v = t6.values[c][s]
            assert v["E_m"] / (981 * d) == pytest.approx(v["C_et"], abs=0.006), (c, s)
            assert v["E_m_plus"] / (981 * d) == pytest.approx(v["C_mt"], abs=0.006), (c, s)
    assert paper_value("table2", "tsid-torque", "walk-20cm", "zmp_error_m.y.mean") == 0.011
    assert paper_value("table8", "tsid-torque", "walk-60cm", "compute_time_ms.peak") == 6.0
    assert paper_value("table7", "ik", "walk-60cm", "pgm.double_support") is None  # "-" in the paper


# ------------------------------------------------------------------------------------------ report
def test_report_from_two_run_dirs(two_runs, tmp_path):
    out = tmp_path / "rep"
    res = report(list(two_runs), out)
    assert res.errors == []
    md = (out / "report.md").read_text()
    assert "ours" in md and "paper" in md and "missing" in md
    assert "| 0.019 |" in md  # Table 2, IK x mean, the paper's number
    assert "<table>" in (out / "report.html").read_text()
    results = strict_json(out / "results.json")
    leaf = results["tables"]["table2"]["values"]["ik"]["walk-20cm"]["zmp_error_m.x.mean"]
    assert leaf == {"ours": "missing", "paper": 0.019, "unit": "m"}
    assert set(results["sanity"]["joint-pd"]) == {"stand", "sway"}
    assert results["metrics"]["joint-pd"]["sway"]["com_error_m"]["y"]["peak"] > 0
    assert (out / "figures" / "sanity_sway.png").stat().st_size > 1000


def test_truncated_or_missing_log_is_one_line_and_others_still_report(two_runs, tmp_path, capsys):
    good, src = two_runs
    bad = tmp_path / "bad-run"
    shutil.copytree(src, bad)
    log = bad / "log.parquet"
    log.write_bytes(log.read_bytes()[: log.stat().st_size // 2])
    out = tmp_path / "rep"
    assert main(["report", str(good), str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(log) in err[0] and "truncated" in err[0] and "Traceback" not in err[0]
    results = strict_json(out / "results.json")
    assert [r["scenario"] for r in results["runs"]] == ["stand"]
    assert str(log) in results["errors"][0]

    log.unlink()
    assert main(["compare", str(good), str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(log) in err[0] and "missing" in err[0]


def test_compare_two_runs(two_runs):
    a, b = two_runs
    rows = {r.key: r for r in compare_rows(a, b)}
    assert (rows["summary.scenario"].a, rows["summary.scenario"].b) == ("stand", "sway")
    e = rows["metrics.E_m"]
    assert e.diff == pytest.approx(e.b - e.a)
    buf = io.StringIO()
    compare(a, b, Console(file=buf, width=200))
    assert "metrics.E_m" in buf.getvalue() and "B - A" in buf.getvalue()


# ------------------------------------------------------------------------------------------ reproduce
@pytest.mark.parametrize("jobs", [1, 2], ids=["inline", "2-processes"])
def test_reproduce_tiny_matrix_marks_absent_scenarios_missing(monkeypatch, tmp_path, jobs):
    monkeypatch.setattr(matrix, "PAPER_MATRIX", (("tsid-torque", "walk-20cm"), ("ik", "stairs")))
    monkeypatch.setattr(matrix, "FAST_MATRIX", ())
    monkeypatch.setattr(matrix, "SANITY_SCENARIOS", ("stand", "push"))
    monkeypatch.setattr(matrix, "SANITY_CONTROLLERS", ("joint-pd",))
    monkeypatch.setattr(matrix, "QUICK_SANITY_CAP_S", 0.2)
    # whatever exists in the registry by now, the walks are absent here
    monkeypatch.setattr(matrix, "available_scenarios", lambda: ["stand", "push"])
    res = reproduce(tmp_path / "rep", quick=True, jobs=jobs, progress=jobs == 1)
    results = strict_json(tmp_path / "rep" / "results.json")
    assert results["wall_time_s"] == pytest.approx(res.wall_time_s) and res.wall_time_s > 0
    status = {(r["controller"], r["scenario"]): (r["status"], r["reason"]) for r in results["runs"]}
    assert status[("tsid-torque", "walk-20cm")] == ("missing", "scenario 'walk-20cm' does not exist yet")
    assert status[("ik", "stairs")][0] == "missing"
    assert status[("joint-pd", "stand")] == ("ok", None) and status[("joint-pd", "push")][0] == "ok"
    t2 = results["tables"]["table2"]["values"]
    assert t2["tsid-torque"]["walk-20cm"]["zmp_error_m.x.mean"] == {"ours": "missing", "paper": 0.026, "unit": "m"}
    assert results["sanity"]["joint-pd"]["stand"]["metrics"]["duration_s"] == pytest.approx(0.2)
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "missing" in md and "wall time of the full run" in md
    assert (tmp_path / "rep" / "runs" / "sanity-stand-joint-pd" / "log.parquet").exists()


def test_cli_lists_report_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for name in ("reproduce", "report", "compare"):
        assert name in out
    assert main(["reproduce", "--jobs", "0", "--out", "x"]) == 2
    assert "--jobs" in capsys.readouterr().err


def test_reproduce_sensing_section_beside_the_ideal_runs(monkeypatch, tmp_path):
    """`reproduce --sensors talos-like`: the sensing cell runs with the profile and is reported beside the ideal
    cell of the same controller and scenario, without replacing it in the paper's tables."""
    from wbcbench.report import matrix
    from wbcbench.report.reproduce import reproduce

    monkeypatch.setattr(matrix, "PAPER_MATRIX", (("tsid-torque", "walk-20cm"),))
    monkeypatch.setattr(matrix, "FAST_MATRIX", ())
    monkeypatch.setattr(matrix, "SENSING_MATRIX", (("tsid-torque", "walk-20cm"),))
    res = reproduce(tmp_path, quick=True, jobs=1, progress=False, sanity=False, sensors="talos-like",
                    keyframes=False)
    sec = res.results["sensing"]
    cell = sec["values"]["tsid-torque"]["walk-20cm"]
    assert sec["profile"] == "talos-like" and cell["status"] == "ok" and cell["ideal_status"] == "ok"
    assert cell["base_estimate_error"]["position_max_m"] > 0.0
    zmp = cell["metrics"]["zmp x mean [m]"]
    assert zmp["sensed"] != zmp["ideal"] and zmp["ideal"] == res.results["metrics"]["tsid-torque"]["walk-20cm"][
        "zmp_error_m"]["x"]["mean"]
    assert "Under 'talos-like' sensing" in (tmp_path / "report.md").read_text()
    assert res.results["command"] == "reproduce --quick --sensors talos-like --no-keyframes"


def test_sanity_section_pairs_controllers_with_the_scenarios_they_are_meant_for():
    jobs = matrix.plan_jobs(quick=True)
    sanity = {(j.controller, j.scenario) for j in jobs if j.section == "sanity"}
    for pair in (("joint-pd", "one-foot"), ("joint-pd", "sway"), ("tsid-teleop", "sway")):
        assert pair not in sanity and matrix.SANITY_NOT_PAIRED[pair]
    assert {("joint-pd", "stand"), ("joint-pd", "push"), ("tsid-teleop", "stand"), ("tsid-torque", "one-foot"),
            ("ik", "sway")} <= sanity


# ------------------------------------------------------------------------------------------ key frames
def _tiny_paper_matrix(monkeypatch):
    monkeypatch.setattr(matrix, "PAPER_MATRIX", (("joint-pd", "stand"),))
    monkeypatch.setattr(matrix, "FAST_MATRIX", ())
    monkeypatch.setattr(matrix, "QUICK_WALK_CAP_S", 0.6)


def test_reproduce_shows_key_frames_and_links_videos(monkeypatch, tmp_path):
    """Each table cell gets a key-frame strip in report.md / report.html, rendered where the cell ran, showing
    the robot; --video adds the clip, linked."""
    import av
    import numpy as np
    from PIL import Image

    from wbcbench.sim.model import VISUAL_GROUP
    from wbcbench.viz.render import Overlays, _Renderer, _render_replay

    _tiny_paper_matrix(monkeypatch)
    res = reproduce(tmp_path, quick=True, jobs=1, progress=False, sanity=False, video=True)
    (cell,) = res.results["key_frames"]
    assert cell["keyframes"] == "runs/paper-stand-joint-pd/keyframes.png" and cell["error"] is None
    md, page = (tmp_path / "report.md").read_text(), (tmp_path / "report.html").read_text()
    assert "## Key frames" in md and f"]({cell['keyframes']})" in md and "[video](runs/paper-stand-joint-pd/video.mp4)" in md
    assert f"<img src='{cell['keyframes']}'" in page and "href='runs/paper-stand-joint-pd/video.mp4'" in page
    strip = np.asarray(Image.open(tmp_path / cell["keyframes"]).convert("RGB"))
    w, h = (int(v) for v in reproduce_module.KEYFRAME_SIZE.split("x"))
    assert strip.shape == (h, reproduce_module.KEYFRAMES * w, 3)
    # the first key frame against the same view without the robot
    r = _Renderer(_render_replay(tmp_path / "runs" / "paper-stand-joint-pd"), w, h, "follow", Overlays.none())
    r.options.geomgroup[VISUAL_GROUP] = 0
    empty = r.frame(0.0)
    r.close()
    robot = np.abs(strip[:, :w].astype(int) - empty.astype(int)).max(axis=2) > 40
    assert robot.mean() > 0.05
    with av.open(str(tmp_path / "runs" / "paper-stand-joint-pd" / "video.mp4")) as c:
        assert sum(1 for _ in c.decode(video=0)) == 19  # 0.6 s at 30 frames/s


def test_a_cell_whose_rendering_fails_keeps_its_report(monkeypatch, tmp_path):
    from wbcbench.viz import render as viz_render

    def no_gl(*args, **kwargs):
        raise viz_render.RenderError("cannot create an OpenGL context with MUJOCO_GL='egl' (no EGL device)")

    _tiny_paper_matrix(monkeypatch)
    monkeypatch.setattr(viz_render, "keyframe_strip", no_gl)
    res = reproduce(tmp_path, quick=True, jobs=1, progress=False, sanity=False)
    (o,) = res.outcomes
    assert o.status == "ok" and o.keyframes is None
    assert o.media_error == "key frames not rendered: cannot create an OpenGL context with MUJOCO_GL='egl' (no EGL device)"
    md = (tmp_path / "report.md").read_text()
    assert o.media_error in md and "Table 2" in md
    assert res.results["runs"][0]["media_error"] == o.media_error


def test_the_workers_take_each_scenes_first_cell_first():
    """The pool's order: every scene's first cell before any scene's second (so that two workers do not both make
    a multi-contact scene's plan), each scene's cells in the matrix's order, every cell once."""
    from wbcbench.report import matrix
    from wbcbench.report.reproduce import _submission_order

    jobs = matrix.plan_jobs()
    order = _submission_order(jobs)
    assert sorted(map(id, order)) == sorted(map(id, jobs))
    rank = {}
    seen: dict[str, int] = {}
    for j in order:
        rank[id(j)] = seen.get(j.scenario_run, 0)
        seen[j.scenario_run] = rank[id(j)] + 1
    assert [rank[id(j)] for j in order] == sorted(rank[id(j)] for j in order)  # first cells, then second ones ...
    for scene in seen:
        assert [j for j in order if j.scenario_run == scene] == [j for j in jobs if j.scenario_run == scene]
    first = [j.scenario_run for j in order[:len(seen)]]
    assert "platforms" in first and "stairs" in first
