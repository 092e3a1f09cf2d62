"""`wbcbench sweep-report DIR`: tables and plots of a sweep's results.parquet, queried with DuckDB.

report.md / report.html in DIR: per value of every varied parameter the number of cells, success rate and the
metric's mean and spread over the other parameters (seeds); metric-vs-parameter plots (mean +- std); a success-rate
heat map over the first two varied parameters; the best cells.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from .._markdown import markdown_body
from ..errors import ConfigError

DEFAULT_METRICS = ("metrics.zmp_error_m.x.mean", "metrics.E_m")


def _q(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _md_table(header: list[str], rows: list[tuple]) -> list[str]:
    def f(v):
        return f"{v:.4g}" if isinstance(v, float) else ("" if v is None else str(v))
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + \
        ["| " + " | ".join(f(v) for v in r) + " |" for r in rows] + [""]


def _robot_line(manifest: dict) -> str:
    """The cells' engines and simulated robots (ideal or a realism preset), from the manifest."""
    from ..sim.realism import realism_label

    cells = [c.get("params", {}) for c in manifest.get("cells", [])]
    engines = sorted({str(p.get("engine") or "mujoco") for p in cells}) or ["mujoco"]
    robots = sorted({realism_label(p.get("realism")) for p in cells}) or ["ideal"]
    return (f"Engine: {', '.join(engines)}. Robot: "
            + ", ".join(r if r == "ideal" else f"realism preset {r}" for r in robots) + ".")


def sweep_report(sweep_dir: str | Path, metric: str | None = None) -> str:
    """Write report.md, report.html and PNG plots into `sweep_dir`; returns the markdown."""
    import duckdb

    d = Path(sweep_dir)
    res = d / "results.parquet"
    if not res.exists():
        raise ConfigError("no results.parquet (run `wbcbench sweep` first)", file=str(d))
    manifest = json.loads((d / "manifest.json").read_text()) if (d / "manifest.json").exists() else {}
    con = duckdb.connect()
    con.execute(f"CREATE VIEW r AS SELECT * FROM read_parquet('{res.as_posix()}')")
    cols = [c[0] for c in con.execute("DESCRIBE r").fetchall()]
    if metric is None:
        metric = next((m for m in DEFAULT_METRICS if m in cols), None)
        if metric is None:
            metric = next(c for c in cols if c.startswith("metrics."))
    elif metric not in cols:
        allowed = ", ".join(c for c in cols if c.startswith("metrics."))[:400]
        raise ConfigError(f"no metric column '{metric}'; some of: {allowed}", key="--metric")
    varied = [f"param.{v}" for v in manifest.get("varied", [])] or [c for c in cols if c.startswith("param.")]
    varied = [v for v in varied if v in cols]
    m = _q(metric)
    ok = "CAST(status = 'ok' AS DOUBLE)"
    n, n_ok, n_fell, n_err = con.execute(
        f"SELECT count(*), sum({ok}), sum(CAST(status='fell' AS INT)), sum(CAST(status='error' AS INT)) FROM r"
    ).fetchone()
    versions = [v[0] for v in con.execute("SELECT DISTINCT code_version FROM r").fetchall()]
    lines = [f"# Sweep report: {d.name}", "",
             f"{n} cells: {int(n_ok or 0)} ok, {int(n_fell or 0)} fell, {int(n_err or 0)} error. "
             f"Metric: `{metric}` (over cells that did not fall or crash). Code: {', '.join(versions)}. "
             f"{_robot_line(manifest)}", ""]
    figures = []
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for p in varied:
        rows = con.execute(
            f"SELECT {_q(p)}, count(*), avg({ok}), avg(CASE WHEN status='ok' THEN {m} END), "
            f"stddev_samp(CASE WHEN status='ok' THEN {m} END), min(CASE WHEN status='ok' THEN {m} END), "
            f"max(CASE WHEN status='ok' THEN {m} END) FROM r GROUP BY 1 ORDER BY 1").fetchall()
        lines += [f"## {metric} by {p}", ""]
        lines += _md_table([p, "cells", "success rate", "mean", "std", "min", "max"], rows)
        xs = [r[0] for r in rows]
        if all(isinstance(x, (int, float)) for x in xs) and any(r[3] is not None for r in rows):
            fig, ax = plt.subplots(figsize=(5, 3.2))
            mean = [r[3] if r[3] is not None else float("nan") for r in rows]
            std = [r[4] or 0.0 for r in rows]
            ax.errorbar(xs, mean, yerr=std, marker="o", capsize=3)
            ax.set_xlabel(p)
            ax.set_ylabel(metric)
            ax.set_title("mean +- std over the other parameters")
            fig.tight_layout()
            name = f"metric-vs-{p.removeprefix('param.').replace('.', '_')}.png"
            fig.savefig(d / name, dpi=90)
            plt.close(fig)
            figures.append((f"{metric} vs {p}", name))
    if len(varied) >= 2:
        a, b = varied[:2]
        rows = con.execute(f"SELECT {_q(a)}, {_q(b)}, avg({ok}) FROM r GROUP BY 1, 2 ORDER BY 1, 2").fetchall()
        xa = sorted({r[0] for r in rows}, key=str)
        xb = sorted({r[1] for r in rows}, key=str)
        grid = [[float("nan")] * len(xb) for _ in xa]
        for ra, rb, v in rows:
            grid[xa.index(ra)][xb.index(rb)] = v
        fig, ax = plt.subplots(figsize=(5, 4))
        im = ax.imshow(grid, vmin=0, vmax=1, cmap="RdYlGn", origin="lower", aspect="auto")
        ax.set_xticks(range(len(xb)), [str(x) for x in xb], rotation=45)
        ax.set_yticks(range(len(xa)), [str(x) for x in xa])
        ax.set_xlabel(b)
        ax.set_ylabel(a)
        fig.colorbar(im, label="success rate")
        fig.tight_layout()
        fig.savefig(d / "success-heatmap.png", dpi=90)
        plt.close(fig)
        figures.append((f"success rate over {a} x {b}", "success-heatmap.png"))
    sel = ", ".join(_q(v) for v in varied)
    best = con.execute(f"SELECT cell_id, {sel + ', ' if sel else ''}{m} FROM r WHERE status = 'ok' "
                       f"AND {m} IS NOT NULL ORDER BY {m} ASC LIMIT 10").fetchall()
    lines += ["## Best cells (lowest metric, no fall)", ""]
    lines += _md_table(["cell", *varied, metric], best)
    errs = con.execute("SELECT cell_id, error FROM r WHERE status = 'error'").fetchall()
    if errs:
        lines += ["## Crashed cells", ""] + _md_table(["cell", "error"], errs)
    lines += ["## Figures", ""] + [f"### {t}\n\n![{t}]({f})\n" for t, f in figures]
    md = "\n".join(lines)
    (d / "report.md").write_text(md)
    out = markdown_body(lines)
    out += [f"<h3>{html.escape(t)}</h3><img src='{f}'>" for t, f in figures]
    css = "body{font-family:sans-serif;max-width:1100px;margin:2em auto}td{border:1px solid #bbb;padding:2px 6px}" \
          "table{border-collapse:collapse}"
    (d / "report.html").write_text(f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>sweep {d.name}</title>"
                                   f"<style>{css}</style></head><body>" + "\n".join(out) + "</body></html>")
    return md
