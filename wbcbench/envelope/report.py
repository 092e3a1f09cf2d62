"""The envelope report: envelope.md and envelope.html (a table controller x axis: the limit, the first failing value
and its failure mode, the resolution), envelope.json (written by the search), radar-<robot>.png (one polygon
per controller, each axis's limit as the fraction of its range passed), and keyframes/ (per controller and axis,
the key frames of the last passing trial and of the first failing one: what the failure looks like)."""

from __future__ import annotations

import html
import math
from pathlib import Path

__all__ = ["write_report"]


def _cell(r: dict) -> str:
    sign = ">=" if r["largest"] else "<="
    if r["first_failure"] is None:
        return f"{sign} {r['hard']:g} (limit reached)"
    if r["limit"] is None:
        return f"fails at {r['easy']:g} ({r['mode']})"
    return f"{r['limit']:g} (fails at {r['first_failure']:g}: {r['mode']})"


def _fraction(r: dict) -> float:
    """How far into its range the limit lies, 0 (easy value failed) .. 1 (hard value passed)."""
    if r["limit"] is None:
        return 0.0
    return max(0.0, min(1.0, (r["limit"] - r["easy"]) / (r["hard"] - r["easy"])))


def _radar(results: list[dict], robot: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = list(dict.fromkeys(r["axis"] for r in results))
    ctrls = list(dict.fromkeys(r["controller"] for r in results))
    by = {(r["controller"], r["axis"]): r for r in results}
    n = len(axes)
    ang = [2 * math.pi * k / n for k in range(n)] + [0.0]
    fig = plt.figure(figsize=(7, 7))
    ax = fig.add_subplot(projection="polar")
    for c in ctrls:
        vals = [_fraction(by[(c, a)]) if (c, a) in by else 0.0 for a in axes]
        ax.plot(ang, vals + vals[:1], marker="o", label=c)
        ax.fill(ang, vals + vals[:1], alpha=0.1)
    first = {a: next(r for r in results if r["axis"] == a) for a in axes}
    ax.set_xticks(ang[:-1])
    ax.set_xticklabels([f"{a}\n{first[a]['easy']:g}..{first[a]['hard']:g} {first[a]['unit']}" for a in axes],
                       fontsize=8)
    ax.set_ylim(0, 1)
    ax.set_yticks([0.25, 0.5, 0.75, 1.0])
    ax.set_rlabel_position(180.0 / n)   # the fraction labels between the first two axes, off their labels
    ax.set_title(f"Capability envelope, {robot} (fraction of each axis's range passed)")
    ax.legend(loc="lower right", bbox_to_anchor=(1.15, -0.1))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _trial_dir(r: dict, value) -> Path | None:
    """The run directory of the trial of `r` at `value` (None: not run, or no log: e.g. the planner refused)."""
    if value is None:
        return None
    for v, _passed, _mode, _reason, d in r["trials"]:
        if math.isclose(v, value, rel_tol=1e-9, abs_tol=1e-12):
            run = Path(d) / "run"
            return run if (run / "log.parquet").exists() else None
    return None


def _keyframes(results: list[dict], out: Path, frames: int = 4) -> dict:
    """(controller, axis) -> {"pass": png or None, "fail": png or None, "note": why one is missing}: the key frames
    of the last passing and the first failing trial. A run that cannot be rendered (no OpenGL) says so once."""
    from ..viz.render import keyframe_strip

    kdir = out / "keyframes"
    kdir.mkdir(parents=True, exist_ok=True)
    shots, broken = {}, None
    for r in results:
        entry, notes = {}, []
        for kind, value in (("pass", r["limit"]), ("fail", r["first_failure"])):
            run = _trial_dir(r, value)
            entry[kind] = None
            if run is None:
                if value is not None:
                    notes.append(f"no run to show at {value:g} ({r['mode']})" if kind == "fail"
                                 else f"no run to show at {value:g}")
                continue
            if broken is not None:
                continue
            png = kdir / f"{r['controller']}-{r['axis']}-{kind}.png"
            try:
                entry[kind] = keyframe_strip(run, png, frames=frames, size="240x300")
            except Exception as e:  # noqa: BLE001 - rendering is optional: the table stands without it
                broken = f"key frames not rendered: {type(e).__name__}: {e}"
        entry["note"] = "; ".join(notes + ([broken] if broken else []))
        shots[(r["controller"], r["axis"])] = entry
    return shots


def write_report(study, results: list[dict], out_dir, *, keyframes: bool = False) -> Path:
    """The report's files (module docstring); `keyframes`: render the last success and first failure of each
    cell (a few seconds each)."""
    from .axes import AXES

    out = Path(out_dir)
    axes = list(dict.fromkeys(r["axis"] for r in results))
    ctrls = list(dict.fromkeys(r["controller"] for r in results))
    by = {(r["controller"], r["axis"]): r for r in results}
    radar = out / f"radar-{study.robot}.png"
    _radar(results, study.robot, radar)
    head = ["axis", "unit", "range (easy -> hard)", "resolution", *ctrls]
    rows = []
    for a in axes:
        r0 = by[(ctrls[0], a)]
        rows.append([a, r0["unit"] or "-", f"{r0['easy']:g} -> {r0['hard']:g}", f"{r0['resolution']:g}",
                     *[_cell(by[(c, a)]) if (c, a) in by else "" for c in ctrls]])
    desc = [f"- `{a}`: {AXES[a].description}" + (" (random: seed %d)" % study.seed if AXES[a].random else "")
            for a in axes if a in AXES]
    from ..sim.realism import realism_label

    robot = "ideal" if study.realism is None else f"realism preset {realism_label(study.realism)}"
    intro = (f"Robot {study.robot} ({robot}), engine {study.engine}. Each cell: the value nearest the hard end of "
             f"the range "
             f"at which the controller completed the scenario (no fall, no error, final CoM within "
             f"{study.tolerance} m of the planned CoM), found by bisection to the stated resolution; in brackets "
             f"the first failing value and its failure mode. Trials: `trials/<robot>/<controller>/<axis>/<value>/`.")
    md = [f"# Capability envelope: {study.robot}", "", intro, "",
          "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    md += ["| " + " | ".join(r) + " |" for r in rows]
    md += ["", "Axes:", *desc, "", f"![radar]({radar.name})", "", "Wall time per search:", ""]
    md += [f"- {r['controller']} / {r['axis']}: {r['wall_s']:.1f} s, {len(r['trials'])} trials" for r in results]
    shots = _keyframes(results, out) if keyframes else {}
    if shots:
        md += ["", "## The last success and the first failure", ""]
        for r in results:
            e = shots[(r["controller"], r["axis"])]
            passed = "-" if r["limit"] is None else f"{r['limit']:g}"
            failed = "-" if r["first_failure"] is None else f"{r['first_failure']:g} ({r['mode']})"
            md.append(f"**{r['controller']}, {r['axis']}**: last success {passed}, first failure {failed}"
                      + (f"; {e['note']}" if e["note"] else ""))
            md += [f"![{r['controller']} {r['axis']} {kind}]({e[kind].relative_to(out)})" for kind in ("pass", "fail")
                   if e[kind] is not None]
            md.append("")
    path = out / "envelope.md"
    path.write_text("\n".join(md) + "\n")
    esc = html.escape
    table = ("<table border=1 cellpadding=4><tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"
             + "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>" for r in rows) + "</table>")
    (out / "envelope.html").write_text(
        f"<!doctype html><meta charset=utf-8><title>Capability envelope: {esc(study.robot)}</title>"
        f"<h1>Capability envelope: {esc(study.robot)}</h1><p>{esc(intro)}</p>{table}"
        f"<ul>{''.join(f'<li>{esc(d[2:])}</li>' for d in desc)}</ul><img src='{radar.name}' width=600>"
        + "".join(f"<h3>{esc(c)}, {esc(a)}</h3><p>{esc(e['note'])}</p>"
                  + "".join(f"<p>{k}<br><img src='{esc(str(e[k].relative_to(out)))}'></p>" for k in ("pass", "fail")
                            if e[k] is not None) for (c, a), e in shots.items()))
    return path


QUICK_AXES = ("push", "payload", "friction", "sensor-delay")
"""The axes `reproduce --envelope` measures (coarse resolution: each axis's default bracket x4)."""
DEFAULT_CONTROLLERS = ("tsid-torque", "tsid-position", "ik")


def reproduce_section(report_dir, robot: str = "talos", controllers: str | None = None, jobs: int = 1,
                      ray: str | None = None, engine: str = "mujoco", realism: str | None = None) -> Path:
    """`reproduce --envelope`: the envelopes of QUICK_AXES at coarse resolution into REPORT_DIR/envelope, and their
    table appended to report.md and linked from report.html (`realism`: every trial on that preset's robot, as
    `reproduce --realism` gives its realistic report). Returns the envelope report."""
    from ..study.execute import make_executor
    from .axes import get_axis
    from .search import EnvelopeStudy, run_envelope

    out = Path(report_dir) / "envelope"
    ctrls = tuple(controllers.split(",")) if controllers else DEFAULT_CONTROLLERS
    study = EnvelopeStudy(axes=QUICK_AXES, controllers=ctrls, robot=robot, engine=engine, realism=realism,
                          resolutions={a: 4 * get_axis(a).resolution for a in QUICK_AXES})
    with make_executor(jobs, ray) as ex:
        results = run_envelope(study, out, executor=ex)
    md = write_report(study, results, out)
    body = md.read_text().split("\n", 1)[1].replace("](radar-", "](envelope/radar-")
    report_md = Path(report_dir) / "report.md"
    if report_md.exists():
        report_md.write_text(report_md.read_text().rstrip() + "\n\n## Capability envelopes (quick)\n" + body)
    report_html = Path(report_dir) / "report.html"
    if report_html.exists():
        text = report_html.read_text()
        link = ("<h2>Capability envelopes (quick)</h2><p><a href='envelope/envelope.html'>envelope table</a></p>"
                f"<img src='envelope/radar-{robot}.png' width=600>")
        report_html.write_text(text.replace("</body>", link + "</body>") if "</body>" in text else text + link)
    return md
