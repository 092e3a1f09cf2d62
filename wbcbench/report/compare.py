"""`compare`: two runs' summaries and metrics side by side (rich table), with B - A for numbers."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from rich.console import Console
from rich.table import Table

from .render import fmt
from .runs import load_run


class CompareRow(NamedTuple):
    """One line of the comparison: dotted key, value in run A, value in run B, B - A (numbers only)."""

    key: str
    a: object
    b: object
    diff: float | None


def _flatten(d: dict, prefix: str = "") -> dict[str, object]:
    out: dict[str, object] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        elif isinstance(v, list) and v and all(isinstance(x, (int, float)) for x in v) and len(v) <= 6:
            out.update({f"{key}[{i}]": x for i, x in enumerate(v)})
        else:
            out[key] = v
    return out


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def compare_rows(run_a: str | Path, run_b: str | Path) -> list[CompareRow]:
    """The comparison rows: summary fields, the scenario's own metrics (`summary.metrics.*`) and the benchmark
    metrics computed from each log (`metrics.*`).

    Raises:
        ReportError: a run directory or one of its files is missing or unreadable (names the file).
    """
    runs = [load_run(run_a), load_run(run_b)]
    flat = []
    for o in runs:
        summary = {k: v for k, v in o.summary.items() if k != "metrics"}
        f = {f"summary.{k}": v for k, v in _flatten(summary).items()}
        f.update({f"summary.metrics.{k}": v for k, v in _flatten(o.summary.get("metrics") or {}).items()})
        f.update({f"metrics.{k}": v for k, v in _flatten(o.metrics).items()})
        flat.append(f)
    keys = list(flat[0]) + [k for k in flat[1] if k not in flat[0]]
    rows = []
    for k in keys:
        a, b = flat[0].get(k), flat[1].get(k)
        rows.append(CompareRow(k, a, b, b - a if _number(a) and _number(b) else None))
    return rows


def compare(run_a: str | Path, run_b: str | Path, console: Console | None = None) -> list[CompareRow]:
    """Print a side-by-side table of two runs (A, B, B - A) and return its rows."""
    rows = compare_rows(run_a, run_b)
    console = console or Console()
    t = Table(title=f"A = {run_a}\nB = {run_b}", title_justify="left")
    t.add_column("key", style="bold")
    t.add_column("A", justify="right")
    t.add_column("B", justify="right")
    t.add_column("B - A", justify="right")
    for r in rows:
        if isinstance(r.a, list) or isinstance(r.b, list):
            a, b = str(r.a), str(r.b)
        else:
            a, b = fmt(r.a) if r.a is not None else "-", fmt(r.b) if r.b is not None else "-"
        diff = "" if r.diff is None else fmt(r.diff)
        style = "yellow" if r.a != r.b and not (_number(r.a) or _number(r.b)) else None  # e.g. fell, controller
        t.add_row(r.key, a, b, diff, style=style)
    console.print(t)
    return rows
