"""The one-screen terminal summary of a run."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.table import Table


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def pacing_text(rt: dict) -> str:
    """One line on a wall-clock-paced run (the summary's `realtime` section)."""
    verdict = "[green]kept up[/green]" if rt["kept_up"] else "[red]could not keep up[/red]"
    text = (f"{verdict}: {rt['late_ticks']} ticks late by more than one period, worst "
            f"{rt['worst_lateness_ms']:.1f} ms")
    if "worst_oversleep_ms" in rt:  # the causes apart (summaries written before they were measured lack them)
        text += (f"; ticks longer than the period {rt['slow_ticks']} (longest {rt['worst_tick_ms']:.1f} ms), "
                 f"a sleep overran by up to {rt['worst_oversleep_ms']:.1f} ms")
        if not rt["kept_up"] and rt["worst_oversleep_ms"] > 5.0 and rt["worst_tick_ms"] <= 5.0:
            text += " (the machine's scheduling, not the loop's work)"
    return text


def summary_table(s: dict) -> Table:
    """A run summary's key-value table, titled with the scenario, controller, mode, robot (and realism preset) and
    whether the run completed or fell; the rows are the caller's."""
    status = f"[red]FELL: {s['fall_reason']}[/red]" if s["fell"] else "[green]completed[/green]"
    t = Table(title=f"{s['scenario']} / {s['controller']} ({s['mode']}) on {s['robot']}"
              + (f" (realism {s['realism']})" if s.get("realism") else "") + f": {status}",
              show_header=False, title_justify="left")
    t.add_column("key", style="bold")
    t.add_column("value")
    return t


def render_summary(console: Console, s: dict, run_dir: Path) -> None:
    t = summary_table(s)
    t.add_row("simulated", f"{s['sim_time_s']:.3f} s of {s['duration_s']:.3f} s")
    rtf = s.get("real_time_factor")
    t.add_row("wall time", f"{s['wall_time_s']:.2f} s (real-time factor {rtf:.2f})" if rtf else f"{s['wall_time_s']:.2f} s")
    st = s["step_time_us"]
    if st["median"] is not None:
        t.add_row("controller step", f"median {st['median']:.1f} us, p99 {st['p99']:.1f} us, max {st['max']:.1f} us")
    if s.get("realtime"):
        t.add_row("wall-clock pacing", pacing_text(s["realtime"]))
    for k, v in s.get("controller_status", {}).items():
        t.add_row(k, _fmt(v))
    for k, v in s.get("metrics", {}).items():
        if isinstance(v, dict):
            if k in ("zmp_error_m", "com_error_m") and all(isinstance(x, dict) for x in v.values()):
                t.add_row(k + " (mean/std/peak)", "  ".join(
                    f"{ax} {_fmt(st.get('mean'))}/{_fmt(st.get('std'))}/{_fmt(st.get('peak'))}" for ax, st in v.items()))
            elif k == "pgm":
                t.add_row("PGM (double/single/flying)", "/".join(_fmt(v.get(x)) for x in
                                                                 ("double_support", "single_support", "flying_foot")))
            continue
        if k in ("n_ticks", "mass_kg", "duration_s", "distance_planned_m"):
            continue
        t.add_row(k, _fmt(v))
    t.add_row("run directory", str(run_dir))
    console.print(t)
