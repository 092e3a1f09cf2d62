"""Engine sensitivity: the paper's tables reproduced on several physics engines, side by side (and, with the same
comparison, the ideal robot beside a realistic one: `reproduce --realism`).

`reproduce --engines mujoco,dart` runs the whole matrix once per engine (each a complete report in OUT/<engine>/)
and then writes OUT/engine-sensitivity.md, .html and .json from the engines' results.json: every table cell on
each engine, the relative difference to the first engine, the ranking of the controllers per scenario on each
engine, and per table which rankings hold on every engine and which flip.

Rankings (a fallen or missing cell ranks last, ties by name):
- Tables 2, 4, 5 (ZMP error): by mean |error| x + y, lower first;
- Table 6 (energy): by E_m, lower first;
- Table 7 (PGM): by the mean of the three stages, higher first;
- Tables 3 and 8 have no ranking (one controller; compute time is the controllers', not the engine's);
- the fallen cells of a scene rank after its complete ones, among themselves by how long they stood.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

from .._markdown import markdown_body

__all__ = ["RANKINGS", "engine_sensitivity", "to_markdown", "to_html", "write"]

#: table -> (the metrics a controller is ranked by (their mean), lower is better)
RANKINGS = {"table2": (("zmp_error_m.x.mean", "zmp_error_m.y.mean"), True),
            "table4": (("zmp_error_m.x.mean", "zmp_error_m.y.mean"), True),
            "table5": (("zmp_error_m.x.mean", "zmp_error_m.y.mean"), True),
            "table6": (("E_m",), True),
            "table7": (("pgm.double_support", "pgm.single_support", "pgm.flying_foot"), False)}


def _ours(cell: dict, metric: str) -> float | None:
    v = cell.get(metric)
    v = v.get("ours") if isinstance(v, dict) else v
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None


def _score(cell: dict | None, metrics: tuple[str, ...]) -> float | None:
    if not cell or cell.get("status") != "ok":
        return None
    vals = [_ours(cell, m) for m in metrics]
    return None if any(v is None for v in vals) else sum(vals) / len(vals)


def _ranking(values: dict, scenario: str, metrics: tuple[str, ...], lower: bool,
             survived: dict | None = None) -> list[str]:
    """The controllers of one scenario of a table, best first; a fallen or missing cell after every complete one,
    the fallen among themselves by how long they stayed up (`survived`: (controller, scenario) -> simulated
    seconds, from results["runs"])."""
    scored = []
    for controller, by_scenario in values.items():
        cell = by_scenario.get(scenario)
        if cell is None:
            continue
        s = _score(cell, metrics)
        if s is not None:
            scored.append((0, s if lower else -s, controller))
        else:
            scored.append((1, -float((survived or {}).get((controller, scenario)) or 0.0), controller))
    return [c for *_, c in sorted(scored)]


def _survived(results: dict) -> dict:
    """(controller, scenario) -> the simulated time of the paper-section run [s] (how long a fallen one stood)."""
    return {(r["controller"], r["scenario"]): r.get("sim_time_s") for r in results.get("runs", [])
            if r.get("section") == "paper"}


def engine_sensitivity(results: dict[str, dict]) -> dict:
    """The comparison of several engines' results.json (engine -> results, the first the reference)."""
    engines = list(results)
    ref = engines[0]
    tables = {}
    for key, table in results[ref]["tables"].items():
        rows = []
        for controller, by_scenario in table["values"].items():
            for scenario, cell in by_scenario.items():
                for metric in cell:
                    if metric == "status":
                        continue
                    vals = {}
                    for e in engines:
                        other = results[e]["tables"].get(key, {}).get("values", {}).get(controller, {}).get(scenario)
                        vals[e] = _ours(other, metric) if other and other.get("status") == "ok" else None
                    base = vals[ref]
                    rel = {e: ((v - base) / abs(base) if v is not None and base not in (None, 0.0) else None)
                           for e, v in vals.items() if e != ref}
                    status = {e: (results[e]["tables"].get(key, {}).get("values", {}).get(controller, {})
                                  .get(scenario, {}).get("status", "missing")) for e in engines}
                    rows.append({"controller": controller, "scenario": scenario, "metric": metric, "values": vals,
                                 "relative_difference": rel, "status": status})
        rank = {}
        if key in RANKINGS:
            metrics, lower = RANKINGS[key]
            scenarios = sorted({s for by_s in table["values"].values() for s in by_s})
            for s in scenarios:
                rank[s] = {e: _ranking(results[e]["tables"].get(key, {}).get("values", {}), s, metrics, lower,
                                       _survived(results[e])) for e in engines}
        holds = [s for s, r in rank.items() if len({tuple(v) for v in r.values()}) == 1]
        flips = [s for s, r in rank.items() if s not in holds]
        tables[key] = {"title": table.get("title", key), "rows": rows, "ranking": rank, "holds": holds,
                       "flips": flips, "summary": _summary(key, rank, holds, flips, rows, engines)}
    return {"engines": engines, "reference": ref, "tables": tables}


def _summary(key: str, rank: dict, holds: list, flips: list, rows: list, engines: list[str]) -> str:
    """One paragraph: which rankings hold on every engine, which flip, which cells fell on one engine only."""
    parts = []
    if rank:
        if holds:
            parts.append(f"The ranking holds on {', '.join(engines)} for {', '.join(holds)}")
        for s in flips:
            parts.append(f"on {s} it flips: " + "; ".join(f"{e} {' > '.join(rank[s][e])}" for e in engines))
    else:
        parts.append("No ranking (one controller, or a measure of the controller alone)")
    fell = sorted({(r["controller"], r["scenario"], e) for r in rows for e, st in r["status"].items()
                   if st != "ok" and any(v == "ok" for v in r["status"].values())})
    if fell:
        parts.append("not ok on one engine only: " + ", ".join(f"{c} on {s} ({e})" for c, s, e in fell))
    rel = [abs(v) for r in rows for v in r["relative_difference"].values() if v is not None]
    if rel:
        parts.append(f"median relative difference to {engines[0]} {100 * sorted(rel)[len(rel) // 2]:.0f} %")
    return "; ".join(parts) + "."


def _fmt(v) -> str:
    if v is None:
        return "-"
    return f"{v:.4g}"


def to_markdown(sens: dict, title: str = "Engine sensitivity") -> str:
    engines, ref = sens["engines"], sens["reference"]
    lines = [f"# {title}", "",
             f"The paper's tables on {', '.join(engines)} (each one's full report in its own folder). "
             f"Relative differences are to {ref}. Rankings: best first; a fallen cell ranks last.", ""]
    for name, note in sens.get("notes", {}).items():
        lines += [f"{name}: {note}", ""]
    for key, t in sens["tables"].items():
        lines += [f"## {key}: {t['title']}", "", t["summary"], ""]
        if t["ranking"]:
            lines += ["| scenario | " + " | ".join(engines) + " |", "|---" * (len(engines) + 1) + "|"]
            for s, r in t["ranking"].items():
                lines.append(f"| {s} | " + " | ".join(" > ".join(r[e]) for e in engines) + " |")
            lines.append("")
        others = [e for e in engines if e != ref]
        lines += ["| controller | scenario | metric | " + " | ".join(engines) + " | "
                  + " | ".join(f"{e} vs {ref}" for e in others) + " |",
                  "|---" * (3 + len(engines) + len(others)) + "|"]
        for r in t["rows"]:
            vals = " | ".join(_fmt(r["values"][e]) + ("" if r["status"][e] == "ok" else f" ({r['status'][e]})")
                              for e in engines)
            rel = " | ".join("-" if r["relative_difference"].get(e) is None
                             else f"{100 * r['relative_difference'][e]:+.0f} %" for e in others)
            lines.append(f"| {r['controller']} | {r['scenario']} | {r['metric']} | {vals} | {rel} |")
        lines.append("")
    return "\n".join(lines)


def to_html(sens: dict, title: str = "Engine sensitivity") -> str:
    """The Markdown's content as a plain HTML page (tables as tables)."""
    out = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
           "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}</style></head><body>"]
    out += markdown_body(to_markdown(sens, title).splitlines())
    return "\n".join(out) + "</body></html>"


def write(results: dict[str, dict], out_dir: str | Path, *, stem: str = "engine-sensitivity",
          title: str = "Engine sensitivity", notes: dict[str, str] | None = None) -> dict:
    """Write STEM.json, .md and .html into `out_dir`; returns the comparison. The same comparison serves any set
    of variants of the matrix (engines; the ideal and a realistic robot: `reproduce --realism`)."""
    out = Path(out_dir)
    sens = engine_sensitivity(results)
    if notes:  # what differs between the variants beside the numbers (e.g. an engine's model limits)
        sens["notes"] = dict(notes)
    (out / f"{stem}.json").write_text(json.dumps(sens, indent=1, allow_nan=False))
    (out / f"{stem}.md").write_text(to_markdown(sens, title))
    (out / f"{stem}.html").write_text(to_html(sens, title))
    return sens
