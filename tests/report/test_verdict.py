"""The report's verdict: cells judged against the paper in the direction of their metric, the falls, the ranking
of the paper's three controllers per scene, Table 8 flagged when measured with parallel jobs; markers in
report.md, coloured cells and a legend in report.html (and seen in a browser, when Chromium is there).

The synthetic outcomes below are test inputs (made-up metrics), not measurements."""

from __future__ import annotations

import os
import shutil

import pytest

from wbcbench.report import report
from wbcbench.report.figures import FigureInfo  # noqa: F401  (the renderers' signature)
from wbcbench.report.render import build_tables, to_html, to_markdown
from wbcbench.report.runs import FELL, OK, RunOutcome
from wbcbench.report.tables import build_results
from wbcbench.report.verdict import BETTER, EQUAL, WORSE, judge, verdict


def _zmp(x: float, y: float) -> dict:
    return {"zmp_error_m": {a: {"mean": v, "std": v, "peak": 4 * v} for a, v in (("x", x), ("y", y))},
            "compute_time_us": {"mean": 300.0, "max": 900.0}}


def _outcomes() -> list[RunOutcome]:
    return [
        # ahead of the paper's 0.026 / 0.011 (x / y mean) on the 20 cm walk
        RunOutcome("paper", "tsid-torque", "walk-20cm", OK, metrics=_zmp(0.002, 0.003)),
        # the paper's IK x mean 0.019 (equal at the printed precision), y far behind the paper's 0.022
        RunOutcome("paper", "ik", "walk-20cm", OK, metrics=_zmp(0.0191, 0.2)),
        RunOutcome("paper", "tsid-position", "walk-20cm", OK, metrics=_zmp(0.010, 0.010)),
        # a fall ranks last whatever its error
        RunOutcome("paper", "ik", "stairs", FELL, reason="base below 0.4 m", metrics=_zmp(0.001, 0.001)),
        RunOutcome("paper", "tsid-torque", "stairs", OK, metrics=_zmp(0.004, 0.004)),
    ]


def test_judge_follows_the_metric_direction_and_printed_precision():
    assert judge(0.01, 0.02, "m", higher_better=False) == BETTER
    assert judge(0.03, 0.02, "m", higher_better=False) == WORSE
    assert judge(0.95, 0.87, "", higher_better=True) == BETTER
    assert judge(0.0191, 0.019, "m", higher_better=False) == EQUAL
    assert judge("missing", 0.02, "m", higher_better=False) is None
    assert judge(None, 0.02, "m", higher_better=False) is None


def test_verdict_counts_falls_and_ranking():
    res = build_results(_outcomes(), command="test", quick=False, jobs=2)
    v = res["verdict"]
    assert v == verdict(res)
    torque = v["cells"]["tsid-torque"]
    assert torque[WORSE] == 0 and torque[BETTER] >= 6  # mean / std / peak x two axes, 20 cm and stairs
    ik = v["cells"]["ik"]
    assert ik[EQUAL] >= 1 and ik[WORSE] >= 3  # x mean equal; y mean, std, peak behind
    assert v["falls"] == [{"controller": "ik", "scenario": "stairs", "reason": "base below 0.4 m"}]
    assert [e["controller"] for e in v["ranking"]["walk-20cm"]] == ["tsid-torque", "tsid-position", "ik"]
    assert [e["controller"] for e in v["ranking"]["stairs"]] == ["tsid-torque", "ik"]
    assert v["ranking"]["stairs"][1]["fell"]
    assert not v["timing_comparable"] and v["timing_cells"]


def test_report_md_and_html_carry_the_verdict_markers_and_table8_flag():
    res = build_results(_outcomes(), command="test", quick=False, jobs=2)
    md = to_markdown(res, [])
    head = md.split("## Table 2", 1)[0]
    assert "## Verdict" in head and "**TSID torque**: ahead of the paper in" in head
    assert "Falls: IK on stairs (base below 0.4 m)" in head
    assert "Ranking on 20 cm" in head and "TSID torque (2.5 mm) > TSID position (10.0 mm) > IK" in head
    assert "**not judged**: measured with 2 parallel jobs" in head and "▲ ours better" in head
    t2 = md.split("## Table 2", 1)[1].split("## Table 3", 1)[0]
    assert "| TSID torque | x-axis | 0.002 ▲ | 0.026 |" in t2
    assert "| IK | x-axis | 0.019 | 0.019 |" in t2  # equal: no marker
    assert "| IK | y-axis | 0.200 ▼ | 0.022 |" in t2
    t8 = md.split("## Table 8", 1)[1].split("## ", 1)[0]
    assert "**Not judged.** Measured with 2 parallel jobs" in t8 and "▲" not in t8 and "▼" not in t8

    html = to_html(res, [])
    assert html.index("id='verdict'") < html.index("Table 2")
    assert "class='ours better'>0.002<" in html and "class='ours worse'>0.200<" in html
    assert "class='legend'" in html.replace("note legend", "legend") and "p class='flag'" in html

    one_job = build_results(_outcomes(), command="test", quick=False, jobs=1)
    md1 = to_markdown(one_job, [])
    assert "Compute time (Table 8, one job at a time): faster than the paper in" in md1
    t8 = md1.split("## Table 8", 1)[1].split("## ", 1)[0]
    assert "Not judged" not in t8 and "▲" in t8  # 0.30 ms against the paper's 1.0 ms
    assert next(t for t in build_tables(one_job) if t.table_id == "table8").flag == ""


def test_report_of_runs_outside_the_paper_matrix_says_so(two_runs, tmp_path):
    """A report of standing runs (no paper cell): the verdict says there is nothing to compare, no marker."""
    out = tmp_path / "rep"
    report(list(two_runs), out)
    md = (out / "report.md").read_text()
    assert "No cell of the paper's Tables 2-7 was run" in md and "No run fell." in md
    assert "▲" not in md.split("_▲", 1)[1].split("\n", 1)[1]


CHROMIUM = next((p for p in (os.environ.get("WBCBENCH_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium"),
                             shutil.which("chromium-browser")) if p and os.path.isfile(p)), None)


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium executable (/usr/bin/chromium, or WBCBENCH_CHROMIUM): "
                                             "apt-get install chromium")
def test_verdict_and_coloured_cells_seen_in_a_browser(tmp_path):
    """report.html in headless Chromium: the verdict is on screen at the top, and a cell ahead of the paper is
    painted green, one behind red (computed style, and the screenshot's pixels)."""
    import io

    import numpy as np
    from PIL import Image

    sync_api = pytest.importorskip("playwright.sync_api", reason="the Python package playwright is not installed")
    page_file = tmp_path / "report.html"
    page_file.write_text(to_html(build_results(_outcomes(), command="test", quick=False, jobs=2), []))
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 800})
            page.goto(page_file.as_uri())
            verdict_box = page.locator("#verdict")
            assert verdict_box.is_visible() and verdict_box.bounding_box()["y"] < 200
            assert "ahead of the paper" in verdict_box.inner_text()
            colours = {}
            for cls in ("better", "worse"):
                cell = page.locator(f"td.ours.{cls}").first
                cell.scroll_into_view_if_needed()
                colours[cls] = cell.evaluate("e => getComputedStyle(e).backgroundColor")
                box = cell.bounding_box()
                img = np.asarray(Image.open(io.BytesIO(page.screenshot(clip={
                    "x": box["x"] + 1, "y": box["y"] + 1, "width": 4, "height": 4}))).convert("RGB"), dtype=int)
                r, g, b = img.reshape(-1, 3).mean(axis=0)
                assert (g > r + 20) if cls == "better" else (r > g + 20), (cls, r, g, b)
            assert colours == {"better": "rgb(200, 236, 200)", "worse": "rgb(246, 204, 204)"}
        finally:
            browser.close()


def test_another_robot_is_not_compared_with_the_paper(g1):
    res = build_results(_outcomes(), command="test", quick=False, jobs=1, robot=g1)
    assert res["verdict"]["cells"] == {}  # no published number to compare with
    md = to_markdown(res, [])
    head = md.split("## Table 2", 1)[0]
    assert "Robot g1: the published numbers are TALOS'" in head and "ahead of the paper" not in head
    assert "Ranking on 20 cm" in head
    tables = md.split("_▲", 1)[1].split("\n", 1)[1]
    assert "▲" not in tables and "▼" not in tables
