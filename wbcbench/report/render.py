"""report.md and report.html from results.json content: the paper's tables with our number beside the
paper's ("ours" / "paper"), the fast walk, the sanity section, the figures and the list of runs."""

from __future__ import annotations

import html
import re
from dataclasses import dataclass, field

from .figures import FigureInfo
from .paper import CONTROLLER_LABELS, SCENARIO_LABELS
from .tables import ERROR_VALUE, MISSING_VALUE, dig


@dataclass
class RenderTable:
    """A table ready to print: title, header cells, rows of cells (strings), notes under it."""

    title: str
    header: list[str]
    rows: list[list[str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: the paper's table it reproduces ("table2" ...), whose cells are judged against the paper; "" for others
    table_id: str = ""
    #: a warning printed above the table (Table 8 measured with parallel jobs)
    flag: str = ""

    def judgements(self, judge_timing: bool = True) -> list[list[str | None]]:
        """Per cell: better / worse / equal than the paper for an "X ours" cell followed by its "X paper" cell,
        else None (`verdict.judge_text`; Table 8's only when `judge_timing`)."""
        from .verdict import TIME_TABLE, higher_is_better, judge_text

        out = [[None] * len(self.header) for _ in self.rows]
        if not self.table_id or (self.table_id == TIME_TABLE and not judge_timing):
            return out
        pairs = [i for i, h in enumerate(self.header[:-1])
                 if h.endswith(" ours") and self.header[i + 1] == h[:-len(" ours")] + " paper"]
        for r, row in enumerate(self.rows):
            for i in pairs:
                out[r][i] = judge_text(row[i], row[i + 1], higher_is_better(self.table_id))
        return out


def fmt(v, unit: str = "") -> str:
    """A value in a table cell: numbers to a precision fit for their unit, states as words."""
    if v is None:
        return "n/a"
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return "yes" if v else "no"
    v = float(v)
    if unit == "J":
        return f"{v:.1f}"
    if unit == "m":
        return f"{v:.3f}" if abs(v) >= 0.001 or v == 0 else f"{v:.1e}"
    if unit in ("ms",):
        return f"{v:.2f}" if abs(v) >= 0.01 else f"{v:.1e}"
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:.0f}"
    if v == int(v) and abs(v) < 1000:
        return f"{v:.1f}"
    if abs(v) >= 0.01:
        return f"{v:.3g}"
    return f"{v:.2e}"


def _ctrl(controller: str, status: str) -> str:
    name = CONTROLLER_LABELS.get(controller, controller)
    if status in (MISSING_VALUE, "ok"):
        return name
    return f"{name} [{status}]"


def _pair(leaf: dict | None) -> list[str]:
    if leaf is None:
        return ["-", "-"]
    return [fmt(leaf["ours"], leaf.get("unit", "")), fmt(leaf["paper"], leaf.get("unit", ""))]


def _stats_table(res: dict, tid: str, groups: list[tuple[str, str]]) -> RenderTable:
    """ZMP / CoM / feet tables: rows (controller or body, axis), columns Average / Std / Peaks x ours / paper.

    groups: (label, metric prefix), e.g. ("CoM", "com_error_m"); empty label = the controller.
    """
    t = res["tables"][tid]
    first = "Body" if any(g for g, _ in groups) else "Control scheme"
    header = [first, "Axis"] + [f"{c} {w}" for c in ("Average", "Std", "Peaks") for w in ("ours", "paper")]
    table = RenderTable(f"Table {t['number']}: {t['title']} [m]", header, table_id=tid)
    for controller, per_scen in t["values"].items():
        for scenario, row in per_scen.items():
            for label, prefix in groups:
                for axis in ("x", "y"):
                    cells = []
                    for stat in ("mean", "std", "peak"):
                        cells += _pair(row.get(f"{prefix}.{axis}.{stat}"))
                    who = label if label else _ctrl(controller, row["status"])
                    if label and row["status"] != "ok":
                        who += f" [{row['status']}]"
                    table.rows.append([who, f"{axis}-axis", *cells])
    if t.get("notes"):
        table.notes.append(t["notes"])
    return table


def _energy_table(res: dict) -> RenderTable:
    t = res["tables"]["table6"]
    metrics = [("E_m", "E_m [J]"), ("E_m_plus", "E_m+ [J]"), ("C_et", "C_et [J/kg/m]"), ("C_mt", "C_mt [J/kg/m]")]
    header = ["Control scheme", "Simulation"] + [f"{lab} {w}" for _, lab in metrics for w in ("ours", "paper")]
    header += ["C_et ours (model mass)", "C_mt ours (model mass)"]
    # the electrical energy beside E_m, when the runs had a realism preset with motors (ours only)
    electric = [k for k in ("E_el", "C_el_paper_mass")
                if any(k in row for per_scen in t["values"].values() for row in per_scen.values())]
    header += [{"E_el": "E_el ours [J]", "C_el_paper_mass": "C_el ours [J/kg/m]"}[k] for k in electric]
    table = RenderTable(f"Table {t['number']}: {t['title']}", header, table_id="table6")
    for label, vals in t["paper_reference_rows"].items():
        cells = []
        for key, _ in metrics:
            cells += ["-", fmt(vals.get(key, "-"))]
        table.rows.append([f"{label} (paper only)", "-", *cells, "-", "-", *["-"] * len(electric)])
    for controller, per_scen in t["values"].items():
        for scenario, row in per_scen.items():
            cells = []
            for key, _ in metrics:
                cells += _pair(row.get(key))
            cells += [fmt(row["C_et_robot_mass"]["ours"]), fmt(row["C_mt_robot_mass"]["ours"])]
            cells += [fmt(row[k]["ours"]) if k in row else "-" for k in electric]
            table.rows.append([_ctrl(controller, row["status"]), SCENARIO_LABELS.get(scenario, scenario), *cells])
    table.notes.append(t["notes"])
    if electric:
        table.notes.append("E_el: the electrical energy drawn by the motors (the realism preset's motor model: "
                           "torque constant, gear ratio, winding resistance; wbcbench/metrics/energy.py), "
                           "C_el = E_el / (m g D) with m g = 981 N as the paper's columns. Not in the paper.")
    return table


def _pgm_table(res: dict) -> RenderTable:
    t = res["tables"]["table7"]
    metrics = [("pgm.double_support", "Double S."), ("pgm.single_support", "Single S."),
               ("pgm.flying_foot", "Flying F.")]
    header = ["Control scheme", "Simulation"] + [f"{lab} {w}" for _, lab in metrics for w in ("ours", "paper")]
    table = RenderTable(f"Table {t['number']}: {t['title']}", header, table_id="table7")
    for label, vals in t["paper_reference_rows"].items():
        cells = []
        for key, _ in metrics:
            cells += ["-", fmt(vals.get(key, "-"))]
        table.rows.append([f"{label} (paper only)", "-", *cells])
    for controller, per_scen in t["values"].items():
        for scenario, row in per_scen.items():
            cells = []
            for key, _ in metrics:
                cells += _pair(row.get(key))
            table.rows.append([_ctrl(controller, row["status"]), SCENARIO_LABELS.get(scenario, scenario), *cells])
    table.notes.append("PGM = 1 - RMS(stance/flying ankle torque) / RMS(all joint torques) per gait stage of the "
                       "scenario's contact schedule; ankles = the two joints above each sole.")
    return table


def _time_table(res: dict) -> RenderTable:
    t = res["tables"]["table8"]
    scen = ["walk-20cm", "walk-60cm", "platforms", "stairs"]
    header = ["Control scheme", "Statistic"] + [f"{SCENARIO_LABELS[s]} {w}" for s in scen for w in ("ours", "paper")]
    table = RenderTable(f"Table {t['number']}: {t['title']} [ms]", header, table_id="table8")
    from .verdict import timing_comparable

    if not timing_comparable(res):
        table.flag = (f"Measured with {res['jobs']} parallel jobs: these times include the other runs' "
                      "interference and are not compared with the paper's (wbcbench reproduce --jobs 1 for that)."
                      if res.get("jobs") else
                      "The parallelism of these runs is not known: their times are not compared with the paper's.")
    for controller, per_scen in t["values"].items():
        for stat, key in (("Average", "compute_time_ms.mean"), ("Peaks", "compute_time_ms.peak")):
            cells = []
            for s in scen:
                cells += _pair(per_scen[s].get(key)) if s in per_scen else ["-", "-"]
            table.rows.append([CONTROLLER_LABELS.get(controller, controller), stat, *cells])
    table.notes.append(t["notes"])
    return table


def _fast_table(res: dict) -> RenderTable:
    fw = res["fast_walk"]
    header = ["Control scheme", "Status", "ZMP x Average ours", "ZMP x Peaks ours", "ZMP y Average ours",
              "ZMP y Peaks ours", "paper"]
    table = RenderTable("Fast 20 cm walk (single/double support 0.711/0.089 s)", header)
    for controller, v in fw["values"].items():
        z = v.get("zmp_error_m") or {}
        status = v["status"] + (f": {v['reason']}" if v.get("reason") else "")
        table.rows.append([CONTROLLER_LABELS.get(controller, controller), status,
                           fmt(dig(z, "x.mean"), "m"), fmt(dig(z, "x.peak"), "m"),
                           fmt(dig(z, "y.mean"), "m"), fmt(dig(z, "y.peak"), "m"), v["paper"]])
    table.notes.append(fw["note"])
    return table


def _sanity_table(res: dict) -> RenderTable:
    header = ["Controller", "Scenario", "Status", "Simulated [s]", "CoM y error Average [m]", "CoM y error Peaks [m]",
              "ZMP F/T vs contact peak [m]", "E_m [J]", "PGM double S.", "Compute mean [ms]",
              "Compute p99 [ms]", "Compute max [ms]"]
    table = RenderTable("Sanity: standing scenarios with every available controller (no published numbers)",
                        header)
    runs = {(r["controller"], r["scenario"]): r for r in res["runs"]}
    for controller, per_scen in res["sanity"].items():
        for scenario, v in per_scen.items():
            m = v.get("metrics") or {}
            r = runs.get((controller, scenario), {})
            status = v["status"] + (f": {v['reason']}" if v.get("reason") else "")
            zv = [dig(m, f"zmp_ft_vs_contact_m.{a}.peak") for a in ("x", "y")]
            zv = [z for z in zv if z is not None]
            ct = m.get("compute_time_us") or {}
            table.rows.append([
                controller, scenario, status, fmt(r.get("sim_time_s")),
                fmt(dig(m, "com_error_m.y.mean"), "m"), fmt(dig(m, "com_error_m.y.peak"), "m"),
                fmt(max(zv) if zv else None, "m"), fmt(m.get("E_m"), "J"), fmt(dig(m, "pgm.double_support")),
                *(fmt(ct[k] * 1e-3 if ct.get(k) is not None else None, "ms") for k in ("mean", "p99", "max"))])
    table.notes.append("'ZMP F/T vs contact' is the largest difference between the ZMP from the ankle F/T sensors "
                       "and the ZMP of MuJoCo's ground-truth contact forces: how far the estimate can be trusted.")
    return table


def _sensing_table(res: dict) -> RenderTable | None:
    sec = res.get("sensing")
    if not sec:
        return None
    labels = [lab for lab, _ in next(iter(next(iter(sec["values"].values())).values()))["metrics"].items()]
    header = ["Controller", "Scenario", "Status (ideal)", "Base error rms/max [m]"]
    for lab in labels:
        header += [f"{lab} {sec['profile']}", f"{lab} ideal"]
    table = RenderTable(f"Under '{sec['profile']}' sensing, beside ideal sensing", header)
    for controller, per in sec["values"].items():
        for scenario, v in per.items():
            be = v.get("base_estimate_error") or {}
            status = v["status"] + (f": {v['reason']}" if v.get("reason") else "") + f" ({v.get('ideal_status')})"
            row = [CONTROLLER_LABELS.get(controller, controller), scenario, status,
                   f"{fmt(be.get('position_rms_m'), 'm')} / {fmt(be.get('position_max_m'), 'm')}"]
            for lab in labels:
                m = v["metrics"][lab]
                row += [fmt(m["sensed"]), fmt(m["ideal"])]
            table.rows.append(row)
    table.notes.append(sec["note"])
    return table


def _teleop_table(res: dict) -> RenderTable | None:
    runs = res.get("teleop")
    if not runs:
        return None
    header = ["Run", "Controller", "Status", "Hand position error mean/std/max [m]",
              "Hand rotation error mean/std/max", "Reference inside the body", "Head position error mean [m]"]
    table = RenderTable("Teleoperation: paper 004 Table II statistics, recomputed from the logs", header)

    def msm(s, unit=""):
        return " / ".join(fmt((s or {}).get(k), unit) for k in ("mean", "std", "max"))

    for name, v in runs.items():
        table.rows.append([name, v["controller"], v["status"], msm(v["hand_position_error_m"], "m"),
                           msm(v["hand_rotation_error"]), fmt(v.get("hand_reference_inside_body_fraction")),
                           fmt((v.get("head_position_error_m") or {}).get("mean"), "m")])
    table.notes.append("Hand errors over both hands and every tick: the ground-truth gripper pose against the "
                       "target the controller was handed (log channels target_*); rotation error ||I - R_ref R^T||_F.")
    return table


def _runs_table(res: dict) -> RenderTable:
    table = RenderTable("Runs", ["Section", "Controller", "Scenario", "Run as", "Status", "Reason", "Simulated [s]",
                                 "Wall [s]", "Run directory"])
    for r in res["runs"]:
        run_as = r["scenario_run"] or "-"
        if r.get("duration_cap_s"):
            run_as += f" (capped at {r['duration_cap_s']:g} s)"
        table.rows.append([r["section"], r["controller"], r["scenario"], run_as, r["status"], r["reason"] or "",
                           fmt(r.get("sim_time_s")), fmt(r.get("wall_time_s")), r["run_dir"] or "-"])
    return table


def build_tables(res: dict) -> list[RenderTable]:
    """All tables of the report, in order."""
    zmp = [("", "zmp_error_m")]
    return [
        _stats_table(res, "table2", zmp),
        _stats_table(res, "table3", [("CoM", "com_error_m"), ("Left foot", "feet_error_m.left"),
                                     ("Right foot", "feet_error_m.right")]),
        _stats_table(res, "table4", zmp),
        _stats_table(res, "table5", zmp),
        _energy_table(res),
        _pgm_table(res),
        _time_table(res),
        _fast_table(res),
        _sanity_table(res),
        *([t] if (t := _sensing_table(res)) is not None else []),
        *([t] if (t := _teleop_table(res)) is not None else []),
    ]


def _preamble(res: dict) -> list[str]:
    lines = [f"Paper: {res['paper']}.", "",
             "Every table keeps the paper's layout; each number has two columns: **ours** (computed by wbcbench "
             "from our MuJoCo runs) and **paper** (published). 'missing': that scenario or controller does not "
             "exist in wbcbench yet, nothing was run. 'error': the run left no usable log. 'n/a': the run exists "
             "but the metric is undefined or its inputs were not logged. [fell]: our run fell; its numbers cover "
             "the log up to the fall.", ""]
    meta = [f"command: {res['command']}"]
    if res.get("quick") is not None:
        meta.append(f"quick: {'yes' if res['quick'] else 'no'}")
    if res.get("jobs"):
        meta.append(f"parallel jobs: {res['jobs']}")
    if res.get("wall_time_s") is not None:
        what = "wall time of the full run" if res["command"].startswith("reproduce") else "time to remake the report"
        meta.append(f"{what}: {res['wall_time_s']:.1f} s")
    meta.append(f"generated: {res['generated_at']}")
    lines.append("; ".join(meta) + ".")
    if res.get("robot"):
        lines += ["", _robot_line(res["robot"])]
    if res.get("quick"):
        lines += ["", "Quick mode: walks use their '-quick' scenario when one exists, else are cut at a duration "
                  "cap; the numbers are therefore NOT comparable with the paper's full runs."]
    return lines


def _robot_line(robot: dict) -> str:
    """What a report of another robot than TALOS says first: our numbers only, and the sizes its scenarios ran at."""
    sizes = "; ".join(f"{name}: " + ", ".join(f"{k} {v}" for part in entry.values() for k, v in part.items())
                      for name, entry in robot["scenario_sizes"].items())
    return (f"Robot: {robot['name']} ({robot['description']}). The published numbers are TALOS': every 'paper' "
            "column is n/a, the numbers are ours only. "
            + (f"Scenario sizes from its profile (the rest as in the scenario files): {sizes}." if sizes else
               "Every scenario at the size of its file."))


KEY_FRAMES_NOTE = ("Six frames per run at equal times from its start to its end (follow camera; green: planned "
                   "footholds, orange / white: CoM and its reference, blue / red: planned and measured ZMP, yellow: "
                   "contact forces).")


def _key_frame_groups(res: dict) -> list[tuple[str, list[dict]]]:
    """results["key_frames"] grouped by scenario (first-seen order): [(scenario label, cells)]."""
    groups: dict[str, list[dict]] = {}
    for k in res.get("key_frames") or []:
        label = k["scenario"]
        if k["scenario"] in SCENARIO_LABELS:
            label = f"{SCENARIO_LABELS[k['scenario']]} ({label})"
        groups.setdefault(label, []).append(k)
    return list(groups.items())


def _key_frame_caption(k: dict) -> str:
    name = CONTROLLER_LABELS.get(k["controller"], k["controller"])
    return name if k["status"] == "ok" else f"{name} [{k['status']}]"


def to_markdown(res: dict, figures: list[FigureInfo]) -> str:
    def esc(s: str) -> str:
        return s.replace("|", "\\|").replace("\n", " ")

    from .verdict import LEGEND, MARKS, timing_comparable, verdict_lines

    out = ["# wbcbench: reproduction of the TALOS whole-body controller benchmark", "",
           "## Verdict", "", *[f"- {line}" for line in verdict_lines(res)], "", f"_{LEGEND}_", "",
           *_preamble(res), ""]
    if res.get("errors"):
        out += ["## Errors", ""] + [f"- {esc(e)}" for e in res["errors"]] + [""]
    for t in build_tables(res) + [_runs_table(res)]:
        out += [f"## {t.title}", ""]
        if t.flag:
            out += [f"**Not judged.** {esc(t.flag)}", ""]
        if t.rows:
            marks = t.judgements(judge_timing=timing_comparable(res))
            out.append("| " + " | ".join(esc(h) for h in t.header) + " |")
            out.append("|" + "---|" * len(t.header))
            out += ["| " + " | ".join(esc(c) + (f" {MARKS[m]}" if m in MARKS else "") for c, m in zip(row, mk))
                    + " |" for row, mk in zip(t.rows, marks)]
        else:
            out.append("(no runs)")
        out += [""] + [f"_{esc(n)}_" for n in t.notes] + ([""] if t.notes else [])
    groups = _key_frame_groups(res)
    if groups:
        out += ["## Key frames", "", f"_{KEY_FRAMES_NOTE}_", ""]
        for label, cells in groups:
            out += [f"### {label}", ""]
            for k in cells:
                video = f" ([video]({k['video']}))" if k.get("video") else ""
                out.append(f"**{esc(_key_frame_caption(k))}**{video}")
                out.append("")
                if k.get("keyframes"):
                    out += [f"![{esc(_key_frame_caption(k))}, {label}]({k['keyframes']})", ""]
                if k.get("error"):
                    out += [esc(k["error"]), ""]
    out += ["## Figures", ""]
    if not figures:
        out += ["(no figure: none of their runs exist yet)", ""]
    for f in figures:
        out += [f"### {f.title}", "", f"![{f.title}]({f.file})", "", f.caption, ""]
    return "\n".join(out)


def to_html(res: dict, figures: list[FigureInfo]) -> str:
    e = html.escape
    css = ("body{font-family:sans-serif;max-width:1400px;margin:2em auto;padding:0 1em}"
           "table{border-collapse:collapse;margin:0.5em 0;font-size:13px}"
           "th,td{border:1px solid #bbb;padding:3px 7px;text-align:right}"
           "td:first-child,th:first-child,td.txt{text-align:left}"
           "th.ours,td.ours{background:#eef6ee}th.paper,td.paper{background:#f2f2f8}"
           "td.missing{color:#a33}p.note{font-size:12px;color:#444}img{max-width:100%}"
           "td.better{background:#c8ecc8;font-weight:bold}td.worse{background:#f6cccc}"
           "div.verdict{border:2px solid #446;border-radius:6px;padding:0.3em 1em;background:#f7f7fb}"
           "p.flag{background:#fff3cd;border-left:4px solid #d9a400;padding:4px 8px}"
           "span.swatch{display:inline-block;width:1.2em;margin:0 0.3em}")
    out = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>",
           "<title>wbcbench reproduction report</title>", f"<style>{css}</style></head><body>",
           "<h1>wbcbench: reproduction of the TALOS whole-body controller benchmark</h1>"]
    from .verdict import timing_comparable, verdict_lines

    def bold(text: str) -> str:  # the verdict's Markdown **bold** and `code`, escaped
        return re.sub(r"`([^`]+)`", r"<code>\1</code>", re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", e(text)))

    out += ["<div class='verdict' id='verdict'><h2>Verdict</h2><ul>"]
    out += [f"<li>{bold(line)}</li>" for line in verdict_lines(res)]
    out += ["</ul><p class='note legend'>Cells: <span class='swatch' style='background:#c8ecc8'>&nbsp;</span>ours "
            "better than the paper's, <span class='swatch' style='background:#f6cccc'>&nbsp;</span>worse (lower is "
            "better for errors, energy, costs of transport and compute time; higher for the PGM); uncoloured: "
            "equal at the printed precision, or nothing to compare.</p></div>"]
    out += [f"<p>{e(line)}</p>".replace("**ours**", "<b>ours</b>").replace("**paper**", "<b>paper</b>")
            for line in _preamble(res) if line]
    if res.get("errors"):
        out += ["<h2>Errors</h2><ul>"] + [f"<li>{e(x)}</li>" for x in res["errors"]] + ["</ul>"]
    for t in build_tables(res) + [_runs_table(res)]:
        out.append(f"<h2>{e(t.title)}</h2>")
        if t.flag:
            out.append(f"<p class='flag'><b>Not judged.</b> {e(t.flag)}</p>")
        if not t.rows:
            out.append("<p>(no runs)</p>")
        else:
            out.append("<table><tr>")
            for h in t.header:
                cls = "ours" if h.endswith(" ours") else "paper" if h.endswith(" paper") else ""
                out.append(f"<th class='{cls}'>{e(h)}</th>")
            out.append("</tr>")
            marks = t.judgements(judge_timing=timing_comparable(res))
            for row, mk in zip(t.rows, marks):
                out.append("<tr>")
                for h, c, m in zip(t.header, row, mk, strict=True):
                    cls = "ours" if h.endswith(" ours") else "paper" if h.endswith(" paper") else "txt"
                    if c in (MISSING_VALUE, ERROR_VALUE):
                        cls += " missing"
                    if m in ("better", "worse"):
                        cls += f" {m}"
                    out.append(f"<td class='{cls}'>{e(c)}</td>")
                out.append("</tr>")
            out.append("</table>")
        out += [f"<p class='note'>{e(n)}</p>" for n in t.notes]
    groups = _key_frame_groups(res)
    if groups:
        out += ["<h2>Key frames</h2>", f"<p class='note'>{e(KEY_FRAMES_NOTE)}</p>"]
        for label, cells in groups:
            out.append(f"<h3>{e(label)}</h3>")
            for k in cells:
                video = f" (<a href='{e(k['video'])}'>video</a>)" if k.get("video") else ""
                out.append(f"<p><b>{e(_key_frame_caption(k))}</b>{video}</p>")
                if k.get("keyframes"):
                    out.append(f"<img src='{e(k['keyframes'])}' alt='{e(_key_frame_caption(k))}, {e(label)}'>")
                if k.get("error"):
                    out.append(f"<p class='note'>{e(k['error'])}</p>")
    out.append("<h2>Figures</h2>")
    if not figures:
        out.append("<p>(no figure: none of their runs exist yet)</p>")
    for f in figures:
        out += [f"<h3>{e(f.title)}</h3>", f"<img src='{e(f.file)}' alt='{e(f.title)}'>",
                f"<p class='note'>{e(f.caption)}</p>"]
    out.append("</body></html>")
    return "\n".join(out)


__all__ = ["RenderTable", "build_tables", "fmt", "to_html", "to_markdown"]
