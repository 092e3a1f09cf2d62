"""Physics engines: the built-in ones in one table, others from installed packages (entry point group
`wbcbench.engines`), chosen by name (`--engine`, `run(..., engine=...)`).

An engine is a class called as ``Engine(robot, terrain, mode, options, pushes, model_error)`` whose instances
offer what the run loop, the sensor model, faults and pushes use of `wbcbench.sim.simulator.Simulator`:

- ``measure() -> Measurement`` and ``measurement(state)``: what a real robot gives (encoders, base, IMU, ankle F/T);
- ``apply(command)``, ``step(n)``: the command held over n physics steps, in the engine's actuation mode;
- ``read_tick(row, dst) -> (state, fall_status)``: the state after a step, and the ground truth written into a
  log row (q, v, applied torque, the soles' contact wrenches, the F/T readings at the columns ``dst``);
- ``true_q()``, ``true_v()``, ``contact_wrench_array()``, ``applied_torque()``, ``fall_status()``;
- ``set_pushes(pushes)``, ``pushes``, ``set_joint_fault(joint, kind)``, ``model_error`` (a dict of what was
  applied), ``dt``, ``tick``, ``reset(q, v)``.

A MuJoCo-only feature (the MuJoCo model and data used by renders, the live view and self-collision probes) is
refused by the other engines with a one-line error.
"""

from __future__ import annotations

import importlib
import importlib.util

from ..catalogue import BUILTIN_ENGINES as ENGINES  # the built-ins: name -> ("module:Attr", what it needs)
from ..errors import ConfigError, UnknownNameError

__all__ = ["ENGINES", "available_engines", "engine_class", "engine_plugin_errors", "make_simulator"]


def _plugins():
    from ..plugins import discover

    return discover("wbcbench.engines", frozenset(ENGINES))


def available_engines() -> list[str]:
    """The engines' names: built-in, then the usable plugins'."""
    return list(ENGINES) + [p.name for p in _plugins() if p.error is None]


def engine_plugin_errors() -> dict[str, str]:
    """Each unusable engine plugin's one-line error, by name."""
    from ..plugins import message

    return {p.name: message(p) for p in _plugins() if p.error is not None}


def engine_label(name: str) -> str:
    """An engine's name as `wbcbench list` shows it: a plugin's with its distribution, a built-in not installed
    with what it needs."""
    if name in ENGINES:
        needs = ENGINES[name][1]
        return name if needs is None or importlib.util.find_spec(needs) else f"{name} (needs {needs})"
    dist = next((p.dist for p in _plugins() if p.name == name), "?")
    return f"{name} [{dist}]"


def engine_class(name: str):
    """The simulator class of engine `name`; a clear error when it is unknown or not installed."""
    if name in ENGINES:
        target, needs = ENGINES[name]
        if needs is not None and importlib.util.find_spec(needs) is None:
            raise ConfigError(f"engine '{name}' needs the package '{needs}': pip install 'wbcbench[{name}]'",
                              key="--engine")
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)
    for p in _plugins():
        if p.name == name:
            if p.error is not None:
                from ..plugins import message

                raise ConfigError(message(p), key="--engine")
            return p.obj
    raise UnknownNameError("engine", name, available_engines(), key="--engine")


def make_simulator(engine: str, robot, terrain, mode, options, pushes=(), model_error=None):
    """The simulator of `engine` for a robot in a terrain (see the module docstring)."""
    return engine_class(engine)(robot, terrain, mode, options, pushes, model_error)
