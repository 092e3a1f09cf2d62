"""A teleoperation session: :class:`TeleopReferenceSource` (operator poses -> the controller's references at time
t, through retargeting, the link and the safety filter), the Table II metrics from a run's log, and the
``wbcbench teleop`` command (:func:`run_session`, the CLI)."""

from . import commands, metrics, source
from .commands import run_session
from .metrics import teleop_errors_from_log, teleop_metrics_from_log
from .source import TeleopReferenceSource, TeleopSourceConfig

__all__ = ["TeleopReferenceSource", "TeleopSourceConfig", "run_session", "teleop_errors_from_log",
           "teleop_metrics_from_log"]
