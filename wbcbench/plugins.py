"""Plugins: controllers, scenario kinds, robot profiles and plan corrections from other installed packages, through
entry points.

A package adds to wbcbench by declaring, in its pyproject.toml::

    [project.entry-points."wbcbench.controllers"]
    weighted-ik = "my_package:WeightedIK"          # a Controller subclass; the entry point's name is its name

    [project.entry-points."wbcbench.scenarios"]
    circle = "my_package.scenarios:CircleWalk"     # a Scenario subclass: a scenario kind (its `kind`)

    [project.entry-points."wbcbench.robots"]
    my-robot = "my_package:PROFILE"                # the path of a robot profile YAML (str or Path, or a callable
                                                   # returning one)

    [project.entry-points."wbcbench.corrections"]
    lateral_shift = "my_package:LateralShift"      # a Correction subclass: a plan correction stage, used in task
                                                   # sets as `corrections: [{type: lateral_shift, ...}]`

    [project.entry-points."wbcbench.engines"]
    my-engine = "my_package:MySimulator"           # a physics engine: a class with the interface of
                                                   # wbcbench.sim.simulator.Simulator (see wbcbench.sim.engines)

They appear in `wbcbench list`, `run`, `reproduce` and sweeps beside the built-in ones. A plugin that fails to
import, or that takes a name already taken (built-in or by another plugin), is reported with one line naming the
entry point and its distribution when that name is used (and by `wbcbench list`); nothing else is affected.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from .errors import ConfigError

__all__ = ["GROUPS", "Plugin", "PluginError", "discover"]

GROUPS = ("wbcbench.controllers", "wbcbench.scenarios", "wbcbench.robots", "wbcbench.corrections",
          "wbcbench.engines")


class PluginError(ConfigError):
    """A plugin that cannot be used: it fails to import, is not what its group expects, or takes a taken name."""


@dataclass(frozen=True)
class Plugin:
    """An entry point of one group: `name`, where it points (`value`), its distribution, and either the loaded
    object or the one-line error that makes it unusable."""

    group: str
    name: str
    value: str
    dist: str
    obj: Any = None
    error: str | None = None

    @property
    def origin(self) -> str:
        return f"{self.dist} ({self.value})"


_CACHE: dict[str, list[Plugin]] = {}


def _check(group: str, obj: Any) -> str | None:
    """Why `obj` cannot serve in `group` (None if it can)."""
    if group == "wbcbench.controllers":
        from .controllers.base import Controller

        if not (isinstance(obj, type) and issubclass(obj, Controller)):
            return "is not a Controller subclass"
    elif group == "wbcbench.scenarios":
        from .scenarios.base import Scenario

        if not (isinstance(obj, type) and issubclass(obj, Scenario)):
            return "is not a Scenario subclass"
    elif group == "wbcbench.corrections":
        from .controllers.corrections import Correction

        if not (isinstance(obj, type) and issubclass(obj, Correction)):
            return "is not a Correction subclass"
    elif group == "wbcbench.engines":
        if not callable(obj):
            return "is not a simulator class (called with robot, terrain, mode, options, pushes, model_error)"
    elif group == "wbcbench.robots":
        path = Path(obj() if callable(obj) else obj)
        if not path.is_file():
            return f"points to no file ({path})"
    return None


def discover(group: str, builtin: set[str] | frozenset[str] = frozenset()) -> list[Plugin]:
    """The plugins of `group` (cached per process), each loaded or with its error; a name taken by a built-in or
    by an earlier plugin makes the later one an error."""
    if group not in _CACHE:
        found = []
        for ep in sorted(metadata.entry_points(group=group), key=lambda e: (e.name, e.value)):
            dist = ep.dist.name if getattr(ep, "dist", None) is not None else "?"
            try:
                obj = ep.load()
            except Exception as exc:  # a plugin's import error must not take wbcbench down
                found.append(Plugin(group, ep.name, ep.value, dist, error=f"failed to import: "
                                    f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"))
                continue
            why = _check(group, obj)
            found.append(Plugin(group, ep.name, ep.value, dist, obj, why))
        _CACHE[group] = found
    out, seen = [], {}
    for p in _CACHE[group]:
        if p.error is None and (p.name in builtin or p.name in seen):
            other = "a built-in" if p.name in builtin else f"{seen[p.name].origin}"
            p = Plugin(p.group, p.name, p.value, p.dist, p.obj, f"registers the name '{p.name}' that {other} has")
        elif p.error is None:
            seen[p.name] = p
        out.append(p)
    return out


def message(p: Plugin) -> str:
    kind = p.group.split(".")[1][:-1]
    return f"{kind} plugin '{p.name}' from {p.origin} {p.error}"


def clear_cache() -> None:
    _CACHE.clear()
