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

import importlib
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from .errors import ConfigError

__all__ = ["GROUPS", "Plugin", "PluginError", "discover", "load"]

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


def load(target: str) -> Any:
    """The object a "package.module:Attr" string names, its module imported now (the registries' tables of
    built-ins hold such strings, so that no registry imports its built-ins before one is used)."""
    module, _, attr = target.partition(":")
    obj = importlib.import_module(module)
    for part in attr.split(".") if attr else ():
        obj = getattr(obj, part)
    return obj


#: what each group's objects must be, named as in the group's registry (checked with `issubclass`)
_BASES = {"wbcbench.controllers": "Controller", "wbcbench.scenarios": "Scenario",
          "wbcbench.corrections": "Correction"}


def _check(group: str, obj: Any, base: type | None) -> str | None:
    """Why `obj` cannot serve in `group` (None if it can); `base`: the class its objects must subclass."""
    if base is not None:
        if not (isinstance(obj, type) and issubclass(obj, base)):
            return f"is not a {_BASES.get(group, base.__name__)} subclass"
    elif group == "wbcbench.engines":
        if not callable(obj):
            return "is not a simulator class (called with robot, terrain, mode, options, pushes, model_error)"
    elif group == "wbcbench.robots":
        path = Path(obj() if callable(obj) else obj)
        if not path.is_file():
            return f"points to no file ({path})"
    return None


def discover(group: str, builtin: set[str] | frozenset[str] = frozenset(), base: type | None = None) -> list[Plugin]:
    """The plugins of `group` (cached per process), each loaded or with its error; a name taken by a built-in or
    by an earlier plugin makes the later one an error. `base`: the class the group's objects must subclass (the
    registry asking passes it, so that this module imports no registry)."""
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
            found.append(Plugin(group, ep.name, ep.value, dist, obj))
        _CACHE[group] = found
    out, seen = [], {}
    for p in _CACHE[group]:
        why = _check(group, p.obj, base) if p.error is None else None
        if why is not None:
            p = Plugin(p.group, p.name, p.value, p.dist, p.obj, why)
        elif p.error is None and (p.name in builtin or p.name in seen):
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
