"""A teleoperation session: :class:`TeleopReferenceSource` (operator poses -> the controller's references at time
t, through retargeting, the link and the safety filter), the Table II metrics from a run's log, and the
``wbcbench teleop`` command (:func:`run_session`, the CLI). Names are imported when first used, so that the
command line's parser (`commands`) stays light."""

from ..._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "run_session": "commands", "teleop_errors_from_log": "metrics", "teleop_metrics_from_log": "metrics",
    "TeleopReferenceSource": "source", "TeleopSourceConfig": "source"})

__all__ = ["TeleopReferenceSource", "TeleopSourceConfig", "run_session", "teleop_errors_from_log",
           "teleop_metrics_from_log"]
