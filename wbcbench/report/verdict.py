"""The report's verdict: where our numbers are ahead of or behind the paper's, which runs fell, and how the paper's
three controllers rank on each scene; and the same judgement per table cell (the markers and colours of
report.md and report.html).

A cell compares our number with the published one in the direction of its metric: lower is better for tracking
errors, energy and costs of transport, and compute time; higher is better for the PGM. Two numbers that print the
same (`render.fmt`, the precision of the tables) are equal. Compute times (Table 8) are judged apart: measured with
more than one job at once, they include the other jobs' interference, and are flagged instead of judged.
"""

from __future__ import annotations

from .paper import CONTROLLER_LABELS, CONTROLLERS, SCENARIO_LABELS, SCENARIOS
from .runs import FELL
from .tables import dig

BETTER, WORSE, EQUAL = "better", "worse", "equal"
MARKS = {BETTER: "▲", WORSE: "▼"}
"""The markers report.md puts after our number; report.html colours the cell instead."""

LEGEND = ("▲ ours better than the paper's, ▼ worse (lower is better for errors, energy, costs of transport and "
          "compute time; higher for the PGM); unmarked: equal at the printed precision, or nothing to compare.")

ACCURACY_TABLES = ("table2", "table3", "table4", "table5", "table6", "table7")
TIME_TABLE = "table8"


def higher_is_better(table_id: str) -> bool:
    return table_id == "table7"


def judge(ours, paper, unit: str, higher_better: bool) -> str | None:
    """better / worse / equal for two numbers, None when either is not a number."""
    from .render import fmt

    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (ours, paper)):
        return None
    if fmt(ours, unit) == fmt(paper, unit):
        return EQUAL
    return BETTER if (ours > paper) == higher_better else WORSE


def judge_text(ours: str, paper: str, higher_better: bool) -> str | None:
    """The same judgement from two printed cells (as they appear in a table)."""
    if ours == paper:
        return EQUAL if ours not in ("-", "n/a", "missing", "error") else None
    try:
        a, b = float(ours), float(paper)
    except ValueError:
        return None
    return BETTER if (a > b) == higher_better else WORSE


def timing_comparable(res: dict) -> bool:
    """Table 8 can be judged only when the runs were made one at a time."""
    return res.get("jobs") == 1


def _cells(res: dict, table_ids) -> dict[str, dict[str, int]]:
    """controller -> {better, worse, equal: number of cells}, over the given tables."""
    out: dict[str, dict[str, int]] = {}
    for tid in table_ids:
        t = (res.get("tables") or {}).get(tid)
        if not t:
            continue
        for controller, per_scen in t["values"].items():
            for row in per_scen.values():
                for key, leaf in row.items():
                    if not isinstance(leaf, dict) or key.endswith("_robot_mass"):
                        continue
                    j = judge(leaf.get("ours"), leaf.get("paper"), leaf.get("unit", ""), higher_is_better(tid))
                    if j is not None:
                        c = out.setdefault(controller, {BETTER: 0, WORSE: 0, EQUAL: 0})
                        c[j] += 1
    return out


def _zmp_mean(metrics: dict | None) -> float | None:
    vals = [dig(metrics or {}, f"zmp_error_m.{a}.mean") for a in ("x", "y")]
    vals = [v for v in vals if isinstance(v, (int, float))]
    return sum(vals) / len(vals) if len(vals) == 2 else None


def ranking(res: dict) -> dict[str, list[dict]]:
    """scenario -> the paper's controllers that ran it, best first: no fall before a fall, then the lower mean
    ZMP tracking error (x and y means averaged) [m]."""
    status = {(r["controller"], r["scenario"]): r["status"] for r in res.get("runs") or []
              if r.get("section") == "paper"}
    out = {}
    for scenario in SCENARIOS:
        entries = []
        for controller in CONTROLLERS:
            st = status.get((controller, scenario))
            z = _zmp_mean((res.get("metrics") or {}).get(controller, {}).get(scenario))
            if st is None or z is None:
                continue
            entries.append({"controller": controller, "fell": st == FELL, "zmp_error_mean_m": z})
        if entries:
            out[scenario] = sorted(entries, key=lambda e: (e["fell"], e["zmp_error_mean_m"]))
    return out


def verdict(res: dict) -> dict:
    """The verdict as data (results.json "verdict"): per controller the cells ahead / behind / equal (Tables 2-7),
    Table 8's apart, the runs that fell, the ranking per scene, and whether the timings can be compared."""
    falls = [{"controller": r["controller"], "scenario": r["scenario"], "reason": r.get("reason")}
             for r in res.get("runs") or [] if r.get("status") == FELL]
    return {"cells": _cells(res, ACCURACY_TABLES), "timing_cells": _cells(res, (TIME_TABLE,)),
            "timing_comparable": timing_comparable(res), "jobs": res.get("jobs"), "falls": falls,
            "ranking": ranking(res), "legend": LEGEND}


def _label(controller: str) -> str:
    return CONTROLLER_LABELS.get(controller, controller)


def verdict_lines(res: dict) -> list[str]:
    """The verdict as Markdown list items (report.md; report.html renders the same lines)."""
    v = res.get("verdict") or verdict(res)
    lines = []
    if res.get("robot"):
        lines.append(f"Robot {res['robot'].get('name', '?')}: the published numbers are TALOS', so no cell is "
                     "compared with the paper; the falls and the ranking below are ours alone.")
    elif not v["cells"]:
        lines.append("No cell of the paper's Tables 2-7 was run: nothing to compare with the paper.")
    for controller, c in v["cells"].items():
        n = c[BETTER] + c[WORSE] + c[EQUAL]
        fell = [f for f in v["falls"] if f["controller"] == controller]
        falls = "no fall" if not fell else "fell on " + ", ".join(f["scenario"] for f in fell)
        lines.append(f"**{_label(controller)}**: ahead of the paper in {c[BETTER]} of {n} cells, behind in "
                     f"{c[WORSE]}, equal in {c[EQUAL]} (Tables 2-7); {falls}.")
    others = [f for f in v["falls"] if f["controller"] not in v["cells"]]
    if v["falls"]:
        lines.append("Falls: " + "; ".join(f"{_label(f['controller'])} on {f['scenario']}"
                                          + (f" ({f['reason']})" if f.get("reason") else "") for f in v["falls"])
                     + ".")
    elif not others:
        lines.append("No run fell.")
    for scenario, entries in v["ranking"].items():
        ranked = " > ".join(f"{_label(e['controller'])} ({e['zmp_error_mean_m'] * 1e3:.1f} mm"
                            + (", fell" if e["fell"] else "") + ")" for e in entries)
        lines.append(f"Ranking on {SCENARIO_LABELS.get(scenario, scenario)} (mean ZMP error, x and y; a fall "
                     f"ranks last): {ranked}.")
    if v["timing_cells"]:
        if v["timing_comparable"]:
            t = {k: sum(c[k] for c in v["timing_cells"].values()) for k in (BETTER, WORSE, EQUAL)}
            lines.append(f"Compute time (Table 8, one job at a time): faster than the paper in {t[BETTER]} cells, "
                         f"slower in {t[WORSE]}, equal in {t[EQUAL]}.")
        elif v["jobs"]:
            lines.append(f"Compute time (Table 8) is **not judged**: measured with {v['jobs']} parallel jobs, its "
                         "times include the other runs' interference on the shared cores. Run "
                         "`wbcbench reproduce --jobs 1` to compare them with the paper.")
        else:
            lines.append("Compute time (Table 8) is **not judged**: these runs were made elsewhere, with an "
                         "unknown number of parallel jobs.")
    if res.get("quick"):
        lines.append("Quick mode: shortened walks, not comparable with the paper's full runs; the counts say where "
                     "the tables stand, not whether the paper was reproduced.")
    return lines
