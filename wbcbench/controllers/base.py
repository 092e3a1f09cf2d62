"""The Controller protocol and the controller registry."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

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
_REGISTRY: dict[str, type[Controller]] = {}


def register(cls: type[Controller]) -> type[Controller]:
    """Class decorator adding a controller to the built-in registry under `cls.name` (a package of yours
    registers through the `wbcbench.controllers` entry point instead: wbcbench/plugins.py)."""
    _REGISTRY[cls.name] = cls
    return cls


def builtin_controllers() -> dict[str, type[Controller]]:
    from . import ik, inverse_dynamics, joint_pd, teleop  # noqa: F401  (registration side effect of importing the modules)
    return dict(_REGISTRY)


def available_controllers() -> dict[str, type[Controller]]:
    """Every usable controller by name: the built-in registry and the `wbcbench.controllers` entry points of
    installed packages (wbcbench/plugins.py); broken plugins are left out (`controller_plugin_errors`)."""
    from ..plugins import discover

    out = builtin_controllers()
    for p in discover("wbcbench.controllers", set(out)):
        if p.error is None:
            out[p.name] = p.obj
    return dict(sorted(out.items()))


def controller_plugin_errors() -> dict[str, str]:
    """name -> one-line message, for the controller plugins that cannot be used."""
    from ..plugins import discover, message

    return {p.name: message(p) for p in discover("wbcbench.controllers", set(builtin_controllers()))
            if p.error is not None}


def make_controller(name: str, robot: Robot, mode: ActuationMode | str | None, dt: float,
                    taskset: str | None = None) -> Controller:
    """A registered controller for `robot` at control period `dt` [s], in `mode` (None: its default), with the task
    set of file `taskset` when given (controllers with a task set only)."""
    ctrls = available_controllers()
    if name not in ctrls:
        broken = controller_plugin_errors().get(name)
        if broken is not None:
            from ..plugins import PluginError

            raise PluginError(broken, key="--controller")
        raise UnknownNameError("controller", name, ctrls, key="--controller")
    cls = ctrls[name]
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
