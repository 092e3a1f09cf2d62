"""Robustness protocols: push recovery (push.py); imperfect sensing lives in `wbcbench.sensing`."""

from .push import PushCell, PushResult, PushStudy, phase_times, run_study, write_report

__all__ = ["PushCell", "PushResult", "PushStudy", "phase_times", "run_study", "write_report"]
