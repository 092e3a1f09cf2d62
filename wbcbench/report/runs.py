"""One run as the report sees it: where it came from, how it ended and its metrics.

A `RunOutcome` is built either by running a job (`reproduce`) or by reading an existing run directory
(`load_run`). Reading never simulates; a missing or unreadable file raises `ReportError`, one line naming it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import WbcError
from ..metrics.from_log import compute_run_metrics

OK, FELL, ERROR, MISSING = "ok", "fell", "error", "missing"
"""Run statuses: completed; fell (log up to the fall, metrics on it); error (no usable log); missing (the
scenario or controller does not exist yet, nothing was run)."""

QUICK_SUFFIX = "-quick"


class ReportError(WbcError):
    """A run directory cannot be reported (missing or unreadable file); the message names the file."""


@dataclass
class RunOutcome:
    """A cell of the reproduction matrix, or one run directory given to `report`.

    Attributes:
        section: "paper", "fast" (the 20 cm fast walk, no published numbers) or "sanity".
        controller: controller registry name.
        scenario: scenario key in the report (a "-quick" variant is reported under its full name).
        status: OK, FELL, ERROR or MISSING.
        reason: why it is not OK (fall reason, error message, what is missing).
        scenario_run: the scenario actually run (e.g. "walk-20cm-quick"), if any.
        duration_cap_s: the duration override used, if any [s].
        run_dir: the run directory, if a run happened.
        summary: the run's summary.json.
        metrics: `compute_run_metrics` of its log (JSON-ready).
        keyframes: its key-frame strip (PNG), if one was rendered.
        video: its video (MP4), if one was rendered.
        media_error: why a strip or video asked for was not rendered (one line).
        media_wall_s: wall time spent rendering the strip and video [s].
    """

    section: str
    controller: str
    scenario: str
    status: str
    reason: str | None = None
    scenario_run: str | None = None
    duration_cap_s: float | None = None
    run_dir: str | None = None
    summary: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    keyframes: str | None = None
    video: str | None = None
    media_error: str | None = None
    media_wall_s: float | None = None

    @property
    def has_metrics(self) -> bool:
        return self.status in (OK, FELL) and bool(self.metrics)

    def brief(self) -> dict:
        """JSON-ready description for results.json (without the metrics)."""
        s = self.summary
        return {"section": self.section, "controller": self.controller, "scenario": self.scenario,
                "scenario_run": self.scenario_run, "status": self.status, "reason": self.reason,
                "duration_cap_s": self.duration_cap_s, "run_dir": self.run_dir,
                "mode": s.get("mode"), "fell": s.get("fell"), "sim_time_s": s.get("sim_time_s"),
                "duration_s": s.get("duration_s"), "wall_time_s": s.get("wall_time_s"),
                "keyframes": self.keyframes, "video": self.video, "media_error": self.media_error,
                "media_wall_s": self.media_wall_s}


def scenario_key(name: str) -> str:
    """The report's name for a scenario: a "-quick" variant counts as its full scenario."""
    return name[: -len(QUICK_SUFFIX)] if name.endswith(QUICK_SUFFIX) else name


@lru_cache(maxsize=8)
def cached_robot(name_or_path: str):
    from ..robots import load_robot

    return load_robot(name_or_path)


def _read_json(path: Path) -> dict:
    if not path.is_file():
        raise ReportError(f"{path}: missing")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ReportError(f"{path}: unreadable JSON ({exc})") from None


def read_run_log(run_dir: str | Path) -> dict[str, np.ndarray]:
    """The log of a run directory; ReportError naming the file if it is missing, truncated or not Parquet."""
    from ..recorder import read_log

    path = Path(run_dir) / "log.parquet"
    if not path.is_file():
        raise ReportError(f"{path}: missing (no log to report)")
    try:
        log = read_log(path)
    except Exception as exc:  # pyarrow raises ArrowInvalid / OSError on truncated files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ReportError(f"{path}: truncated or not a Parquet log ({type(exc).__name__}: {msg})") from None
    if not log or "t" not in log:
        raise ReportError(f"{path}: no 't' column, not a wbcbench run log")
    return log


def planned_distance(summary: dict) -> float | None:
    """The scenario's planned travel [m] from a summary: `distance_planned_m` or `planned_distance_m`, at the top
    level or under `metrics`; None if the scenario gave none."""
    for where in (summary, summary.get("metrics") or {}):
        for key in ("distance_planned_m", "planned_distance_m"):
            v = where.get(key)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v):
                return float(v)
    return None


def run_metrics(run_dir: str | Path, summary: dict, config: dict, log: dict[str, np.ndarray] | None = None) -> dict:
    """`compute_run_metrics` for a run directory (robot and control period from its config)."""
    log = read_run_log(run_dir) if log is None else log
    robot = cached_robot(str(config.get("robot_profile") or summary.get("robot") or "talos"))
    dt = float(config.get("control_dt_s") or 1e-3)
    motors = (config.get("realism") or {}).get("motors")   # a realism preset's motor model: electrical metrics
    metrics = compute_run_metrics(log, robot, dt=dt, distance_planned_m=planned_distance(summary), motors=motors)
    from ..teleop.metrics import has_targets, teleop_metrics_from_log

    if has_targets(log):  # a teleoperation run: paper 004 Table II statistics from the logged targets
        metrics["teleop"] = teleop_metrics_from_log(log, robot)
    return metrics


def load_run(run_dir: str | Path, section: str | None = None) -> RunOutcome:
    """Read a run directory (summary.json, config.json, log.parquet) and compute its metrics.

    Raises:
        ReportError: a file is missing or unreadable; the message names it.
    """
    d = Path(run_dir)
    if not d.is_dir():
        raise ReportError(f"{d}: not a run directory")
    summary = _read_json(d / "summary.json")
    config = _read_json(d / "config.json") if (d / "config.json").is_file() else {}
    metrics = run_metrics(d, summary, config)
    scen = str(summary.get("scenario", config.get("scenario", "?")))
    key = scenario_key(scen)
    from .matrix import section_of

    fell = bool(summary.get("fell"))
    if section is None and (summary.get("sensors") or {}).get("profile") not in (None, "ideal"):
        section = "sensing"  # a run under a sensor profile is reported beside the ideal ones
    return RunOutcome(section=section or section_of(key), controller=str(summary.get("controller", "?")),
                      scenario=key, status=FELL if fell else OK, reason=summary.get("fall_reason") if fell else None,
                      scenario_run=scen, run_dir=str(d), summary=summary, metrics=metrics)
