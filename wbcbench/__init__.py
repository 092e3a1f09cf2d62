"""wbcbench: run, compare, watch and teleoperate whole-body controllers on humanoid robots in simulation.

The public API, imported lazily (``import wbcbench`` stays light and imports no simulator):

    from wbcbench import run, load_robot, load_scenario, make_scenario, Controller, register
    from wbcbench import References, PointReference, PoseReference, Measurement, Command, ActuationMode
"""

from __future__ import annotations

import importlib
import os
import sys

# MuJoCo picks its OpenGL backend when it is imported; without a display, rendering (wbcbench.viz) needs EGL
# (headless; Mesa's works in software). A value the user set is kept.
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")


_EXPORTS = {
    # running
    "run": "wbcbench.runner", "RunResult": "wbcbench.runner", "RunConfig": "wbcbench.runner",
    "Hook": "wbcbench.loop", "Tick": "wbcbench.loop", "EndRun": "wbcbench.loop",
    "load_robot": "wbcbench.robots", "Robot": "wbcbench.robots",
    "load_scenario": "wbcbench.scenarios", "make_scenario": "wbcbench.scenarios", "Scenario": "wbcbench.scenarios",
    "ScenarioSpec": "wbcbench.scenarios", "register_kind": "wbcbench.scenarios",
    # controllers and their building blocks
    "Controller": "wbcbench.controllers.base", "register": "wbcbench.controllers.base",
    "available_controllers": "wbcbench.controllers.base", "make_controller": "wbcbench.controllers.base",
    "InverseDynamicsFormulation": "wbcbench.controllers.id_formulation",
    "KinematicHierarchy": "wbcbench.controllers.ik_formulation",
    "TaskReferences": "wbcbench.controllers.task_references",
    "PlanCorrections": "wbcbench.controllers.plan_corrections",
    "Correction": "wbcbench.controllers.corrections", "CorrectionContext": "wbcbench.controllers.corrections",
    "register_correction": "wbcbench.controllers.corrections",
    "Stabilizer": "wbcbench.stabilizers.base", "register_stabilizer": "wbcbench.stabilizers.base",
    "register_task": "wbcbench.tasks",
    # vocabulary
    "References": "wbcbench.types", "PointReference": "wbcbench.types", "PoseReference": "wbcbench.types",
    "Measurement": "wbcbench.types", "Command": "wbcbench.types", "ModelFeedback": "wbcbench.types",
    "ActuationMode": "wbcbench.types", "Side": "wbcbench.side",
    # errors
    "WbcError": "wbcbench.errors", "ConfigError": "wbcbench.errors", "UnknownNameError": "wbcbench.errors",
    "PluginError": "wbcbench.plugins",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def _version() -> str:
    """The installed version: written by setuptools-scm at build time (wbcbench/_version.py), else the
    distribution's metadata, else unknown (a source tree neither built nor installed)."""
    try:
        from ._version import version

        return version
    except Exception:  # not built here (ImportError), or being rewritten by a build at this moment
        pass
    from importlib import metadata

    try:
        return metadata.version("wbcbench")
    except metadata.PackageNotFoundError:
        return "0.0.0+unknown"


def __getattr__(name: str):
    if name == "__version__":
        globals()["__version__"] = value = _version()
        return value
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'wbcbench' has no attribute '{name}'")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
