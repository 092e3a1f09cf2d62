"""The Controller protocol and the controller registry."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from ..catalogue import BUILTIN_CONTROLLERS  # the built-ins: name -> "module:Attr", imported when first used
from ..errors import ConfigError, UnknownNameError
from ..robots import Robot
from ..types import ActuationMode
from ..types import Command, Measurement, References


#: a hook around a controller's QP solves: ``hook(solver, args) -> QPResult`` (`Controller.set_solve_hook`)
SolveHook = Callable[[object, tuple], object]


class Controller(ABC):
    """A whole-body controller: `reset` once with the first measurement, then `step` every control tick.

    A controller sees only a `Measurement` (what a real robot gives) and the scenario's `References`.
    `log_channels()` names extra per-tick values it wants recorded (name -> component labels);
    `log_values()` returns them for the last step, in the same order.

    A controller that solves QPs calls each solve as ``self.solve_qp(solver, *args)`` (instead of
    ``solver.solve(*args)``): a solve hook set with `set_solve_hook` then sees every solve and may replace its
    result (fault injection's ``qp_failure`` makes them fail; a test or a profiler may count or time them). The
    measurement a controller sees is changed outside it, in the run loop's ``sense`` phase (`wbcbench.loop`).
    """

    #: the hook around this controller's QP solves (None: none; `set_solve_hook`)
    solve_hook: SolveHook | None = None

    name: str = ""
    modes: tuple[ActuationMode, ...] = ()
    default_mode: ActuationMode = ActuationMode.TORQUE

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float):
        if mode not in self.modes:
            raise ConfigError(f"controller '{self.name}' does not support mode '{mode.value}'; "
                              f"allowed: {', '.join(m.value for m in self.modes)}", key="--mode")
        self.robot = robot
        self.mode = mode
        self.dt = dt

    @abstractmethod
    def reset(self, meas: Measurement, refs: References) -> None: ...

    @abstractmethod
    def step(self, meas: Measurement, refs: References) -> Command: ...

    def log_channels(self) -> dict[str, list[str]]:
        return {}

    def log_values(self) -> list[np.ndarray | float]:
        return []

    def status(self) -> dict:
        """Counters for the run summary (e.g. QP failures)."""
        return {}

    def set_solve_hook(self, hook: SolveHook | None) -> None:
        """Call ``hook(solver, args)`` in place of each of this controller's QP solves ``solver.solve(*args)``
        (None: solve directly again). The hook returns the solve's `QPResult`: the solver's own (it calls
        ``solver.solve(*args)``) or another one, e.g. ``QPResult.failure(...)``; the controller then acts on it
        as on the solver's (its fallbacks, its status counters)."""
        self.solve_hook = hook

    def solve_qp(self, solver, *args):
        """``solver.solve(*args)``, through the solve hook when one is set (`set_solve_hook`)."""
        hook = self.solve_hook
        if hook is None:
            return solver.solve(*args)
        return hook(solver, args)


ControllerFactory = Callable[[Robot, ActuationMode, float], Controller]


GROUP = "wbcbench.controllers"

_REGISTRY: dict[str, type[Controller]] = {}
"""Controllers registered in Python (`register`), by name."""
_LOADED: dict[str, type[Controller]] = {}


def register(cls: type[Controller]) -> type[Controller]:
    """Class decorator adding a controller to the registry under `cls.name`, for a class defined in a script or a
    test (a package of yours registers through the `wbcbench.controllers` entry point instead:
    wbcbench/plugins.py). A built-in's name stays the built-in's."""
    _REGISTRY[cls.name] = cls
    return cls


def _builtin(name: str) -> type[Controller]:
    cls = _LOADED.get(name)
    if cls is None:
        from ..plugins import load

        cls = _LOADED[name] = load(BUILTIN_CONTROLLERS[name])
    return cls


def _plugins(taken) -> list:
    from ..plugins import discover

    return discover(GROUP, set(taken), Controller)


def builtin_controllers() -> dict[str, type[Controller]]:
    """The built-in controllers and those registered in Python (`register`), by name."""
    out = dict(_REGISTRY)
    out.update({name: _builtin(name) for name in BUILTIN_CONTROLLERS})
    return out


def available_controllers() -> dict[str, type[Controller]]:
    """Every usable controller by name: the built-in ones, those registered in Python and the
    `wbcbench.controllers` entry points of installed packages (wbcbench/plugins.py); broken plugins are left out
    (`controller_plugin_errors`)."""
    out = builtin_controllers()
    for p in _plugins(out):
        if p.error is None:
            out[p.name] = p.obj
    return dict(sorted(out.items()))


def controller_plugin_errors() -> dict[str, str]:
    """name -> one-line message, for the controller plugins that cannot be used."""
    from ..plugins import message

    return {p.name: message(p) for p in _plugins({*BUILTIN_CONTROLLERS, *_REGISTRY}) if p.error is not None}


def controller_class(name: str) -> type[Controller]:
    """The class of controller `name` (only its own module is imported); an unknown name is an `UnknownNameError`
    listing the known ones, a broken plugin a `PluginError`."""
    if name in BUILTIN_CONTROLLERS:
        return _builtin(name)
    if name in _REGISTRY:
        return _REGISTRY[name]
    for p in _plugins({*BUILTIN_CONTROLLERS, *_REGISTRY}):
        if p.name == name:
            if p.error is not None:
                from ..plugins import PluginError, message

                raise PluginError(message(p), key="--controller")
            return p.obj
    raise UnknownNameError("controller", name, available_controllers(), key="--controller")


def make_controller(name: str, robot: Robot, mode: ActuationMode | str | None, dt: float,
                    taskset: str | None = None) -> Controller:
    """A registered controller for `robot` at control period `dt` [s], in `mode` (None: its default), with the task
    set of file `taskset` when given (controllers with a task set only)."""
    cls = controller_class(name)
    if mode is None:
        mode = cls.default_mode
    try:
        mode = ActuationMode(mode)
    except ValueError:
        raise ConfigError(f"unknown mode '{mode}'; allowed: {', '.join(m.value for m in ActuationMode)}",
                          key="--mode") from None
    if taskset is None:
        return cls(robot, mode, dt)
    import inspect

    if "taskset" not in inspect.signature(cls).parameters:
        raise ConfigError(f"controller '{name}' takes no task set", key="--taskset")
    from pathlib import Path

    if not Path(taskset).is_file():
        raise ConfigError(f"no such file: {taskset}", key="--taskset")
    return cls(robot, mode, dt, taskset=taskset)
