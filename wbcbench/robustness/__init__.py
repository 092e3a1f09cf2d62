"""Robustness protocols: push recovery (push.py); imperfect sensing lives in `wbcbench.sensing`."""

from .._lazy import lazy_exports

# imported when first used, so that importing the package (or its `commands` module, for the command
# line's parser) stays light
__getattr__, __dir__ = lazy_exports(__name__, {
    **dict.fromkeys(("PushCell", "PushResult", "PushStudy", "phase_times", "run_study", "write_report"), "push"),
})

__all__ = ["PushCell", "PushResult", "PushStudy", "phase_times", "run_study", "write_report"]
