"""The cross-robot section of `reproduce --robots`: the same matrix on several humanoids, side by side.

OUT/robots.md, .html and .json hold, for every robot, controller and scenario of the matrix: the outcome (ok, or
fell and why, at which simulated time), the mean ZMP tracking error, the cost of transport (C_mt, the mechanical
one) and the controller's compute time per tick (median); the 20 cm walk's key-frame strips of every robot, one
row per robot and one column per controller; and, per robot, which top-level keys of its profile `wbcbench robot
init` wrote and which were tuned by hand (`wbcbench.robots.profile.profile_provenance`).
"""

from __future__ import annotations

import html
import json
import math
import os
from pathlib import Path

from .._markdown import markdown_body
from .runs import OK, RunOutcome

__all__ = ["KEYFRAME_SCENARIO", "robot_comparison", "to_html", "to_markdown", "write"]

KEYFRAME_SCENARIO = "walk-20cm"
"""The scenario whose key frames the section shows for every robot."""


def _num(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def _cell(robot: str, o: RunOutcome, out_dir: Path) -> dict:
    m = o.metrics or {}
    zmp = m.get("zmp_error_m") or {}
    zx, zy = (_num((zmp.get(a) or {}).get("mean")) for a in ("x", "y"))
    strip = o.keyframes or (str(Path(o.run_dir) / "keyframes.png")
                            if o.run_dir and (Path(o.run_dir) / "keyframes.png").is_file() else None)
    return {"robot": robot, "section": o.section, "controller": o.controller, "scenario": o.scenario,
            "scenario_run": o.scenario_run, "status": o.status, "reason": o.reason,
            "sim_time_s": _num((o.summary or {}).get("sim_time_s")),
            "zmp_error_mean_m": None if zx is None or zy is None else {"x": zx, "y": zy},
            "cost_of_transport": _num(m.get("C_mt")),
            "compute_time_us": _num((m.get("compute_time_us") or {}).get("median")),
            "keyframes": None if strip is None
            else Path(os.path.relpath(Path(strip).resolve(), out_dir.resolve())).as_posix()}


def robot_comparison(outcomes: dict[str, list[RunOutcome]], profiles: dict[str, str | Path],
                     out_dir: str | Path) -> dict:
    """The section's content: `outcomes` (robot -> its cells), `profiles` (robot -> its profile YAML) and the
    directory the section is written to (the key frames' paths are relative to it)."""
    from ..robots.profile import profile_provenance

    out = Path(out_dir)
    cells = [_cell(r, o, out) for r, os_ in outcomes.items() for o in os_]
    robots = list(outcomes)
    summary = {}
    for r in robots:
        mine = [c for c in cells if c["robot"] == r and c["status"] != "missing"]
        summary[r] = {"cells": len(mine), "ok": sum(c["status"] == OK for c in mine)}
    return {"robots": robots, "cells": cells, "summary": summary,
            "provenance": {r: {**profile_provenance(p), "profile": str(p)} for r, p in profiles.items()}}


def _fmt(v: float | None, scale: float = 1.0, digits: int = 3) -> str:
    return "-" if v is None else f"{v * scale:.{digits}g}"


def _outcome(c: dict) -> str:
    if c["status"] == OK:
        return "ok"
    at = f" at {c['sim_time_s']:.1f} s" if c["sim_time_s"] is not None else ""
    return f"{c['status']}{at}" + (f": {c['reason']}" if c["reason"] else "")


def to_markdown(cmp: dict, title: str = "Robots") -> str:
    robots, cells = cmp["robots"], cmp["cells"]
    lines = [f"# {title}", "",
             f"The matrix on {len(robots)} robots ({', '.join(robots)}); each robot's full report is in its own "
             "folder. ZMP error: mean |error| along x / y [mm]; cost of transport: C_mt (mechanical); compute: "
             "the controller's median time per tick [us].", ""]
    if cmp.get("wall_time_s") is not None:
        lines += [f"Wall time {cmp['wall_time_s']:.0f} s.", ""]
    lines += ["| robot | cells ok |", "|---|---|"]
    lines += [f"| {r} | {s['ok']} of {s['cells']} |" for r, s in cmp["summary"].items()]
    lines += ["", "## Every cell", "",
              "| robot | controller | scenario | outcome | ZMP error x / y [mm] | cost of transport | compute [us] |",
              "|---|---|---|---|---|---|---|"]
    for c in cells:
        z = c["zmp_error_mean_m"]
        zs = "-" if z is None else f"{1e3 * z['x']:.1f} / {1e3 * z['y']:.1f}"
        run = c["scenario_run"] if c["scenario_run"] not in (None, c["scenario"]) else c["scenario"]
        lines.append(f"| {c['robot']} | {c['controller']} | {c['section']}: {run} | {_outcome(c)} | {zs} | "
                     f"{_fmt(c['cost_of_transport'])} | {_fmt(c['compute_time_us'], digits=4)} |")
    walk = [c for c in cells if c["scenario"] == KEYFRAME_SCENARIO and c["section"] == "paper"]
    controllers = list(dict.fromkeys(c["controller"] for c in walk))
    lines += ["", f"## Key frames: {KEYFRAME_SCENARIO}", ""]
    if walk:
        lines += ["| robot | " + " | ".join(controllers) + " |", "|---" * (len(controllers) + 1) + "|"]
        for r in robots:
            row = []
            for ctrl in controllers:
                c = next((c for c in walk if c["robot"] == r and c["controller"] == ctrl), None)
                if c is None:
                    row.append("-")
                elif c["keyframes"]:
                    row.append(f"![{r} {ctrl}]({c['keyframes']}) {_outcome(c)}")
                else:
                    row.append(f"no key frames; {_outcome(c)}")
            lines.append(f"| {r} | " + " | ".join(row) + " |")
    else:
        lines.append(f"{KEYFRAME_SCENARIO} was not in the matrix.")
    lines += ["", "## Profiles: generated and hand-tuned keys", "",
              "| robot | profile | generated by `wbcbench robot init` | tuned by hand |", "|---|---|---|---|"]
    for r in robots:
        p = cmp["provenance"].get(r) or {}
        kind = p.get("kind", "-")
        gen = ", ".join(p.get("generated") or []) or "-"
        tuned = "every key" if kind == "hand-written" else (", ".join(p.get("hand_tuned") or []) or "none")
        lines.append(f"| {r} | {kind} | {gen} | {tuned} |")
    return "\n".join(lines) + "\n"


def to_html(cmp: dict, title: str = "Robots") -> str:
    """The Markdown's content as a plain HTML page; the key-frame strips as images."""
    out = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
           "<style>body{font-family:sans-serif;max-width:1400px;margin:auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}img{max-width:420px}</style></head><body>"]
    md = to_markdown(cmp, title).splitlines()
    frames = md.index(f"## Key frames: {KEYFRAME_SCENARIO}")
    profiles = md.index("## Profiles: generated and hand-tuned keys")
    out += markdown_body(md[:frames])
    out.append(f"<h2>{html.escape(md[frames][3:])}</h2><table>")
    walk = [c for c in cmp["cells"] if c["scenario"] == KEYFRAME_SCENARIO and c["section"] == "paper"]
    for r in cmp["robots"]:
        row = [f"<td>{html.escape(r)}</td>"]
        for c in (c for c in walk if c["robot"] == r):
            img = f"<img src='{html.escape(c['keyframes'])}'><br>" if c["keyframes"] else ""
            row.append(f"<td>{img}{html.escape(c['controller'])}: {html.escape(_outcome(c))}</td>")
        out.append("<tr>" + "".join(row) + "</tr>")
    out.append("</table>")
    out += markdown_body(md[profiles:])
    return "\n".join(out) + "</body></html>"


def write(outcomes: dict[str, list[RunOutcome]], profiles: dict[str, str | Path], out_dir: str | Path, *,
          wall_time_s: float | None = None, stem: str = "robots") -> dict:
    """Write STEM.json, .md and .html into `out_dir`; returns the section's content."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cmp = robot_comparison(outcomes, profiles, out)
    cmp["wall_time_s"] = wall_time_s
    (out / f"{stem}.json").write_text(json.dumps(cmp, indent=1, allow_nan=False))
    (out / f"{stem}.md").write_text(to_markdown(cmp))
    (out / f"{stem}.html").write_text(to_html(cmp))
    return cmp
