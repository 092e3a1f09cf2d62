"""The task registry: YAML `type:` -> task class. Each task class names its type and parses its own options.

A task set entry such as ``{name: waist, type: frame, frame: base, mask: [0, 0, 0, 1, 1, 1], weight: 1.0,
kp: 300.0}`` is read in two parts: the keys every task has (name, weight, kp, kd, mask, hard, level; parsed by
`wbcbench.controllers.taskset`) and the options of its type, parsed by the class registered for that type
(`parse_options`), which also says how many axes the task has (for the lengths of gains and masks). The task is
then built by the class from the parsed `TaskSpec` (`from_spec`).

To add a task type: subclass `Task`, set `yaml_type`, implement `axes`, `parse_options` (if it has options) and
`from_spec`, and decorate the class with `register_task`. Nothing else in wbcbench changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..catalogue import BUILTIN_TASKS  # the built-ins: name -> "module:Attr", imported when first used
from ..errors import UnknownNameError

if TYPE_CHECKING:  # pragma: no cover
    from .task import Task

__all__ = ["BUILTIN_TASKS", "TaskSpec", "build_task", "register_task", "resolve_frame", "task_class", "task_types"]


@dataclass(frozen=True)
class TaskSpec:
    """One task of a task set, as parsed from YAML (or built in Python).

    kp / kd: per-axis gains (posture: per joint); kd None means 2 sqrt(kp). mask: one bool per axis, None for
    all. hard: an equality constraint of the inverse-dynamics QP instead of a weighted cost. level: the task's
    strict-priority level in a hierarchical (IK) formulation (1 is the highest after the feet; tasks of one
    level are weighted against each other); a weighted QP has a single level. options: the type's own options
    (e.g. `frame`, resolved to a model frame name; `repulsors` of a self_collision task).
    """

    name: str
    type: str
    weight: float
    kp: np.ndarray
    kd: np.ndarray | None
    mask: tuple[bool, ...] | None = None
    hard: bool = False
    level: int = 1
    options: dict = field(default_factory=dict)

    @property
    def frame(self) -> str | None:
        """The model frame of a frame task (None for other types)."""
        return self.options.get("frame")


_TYPES: dict[str, type[Task]] = {}
"""Task types registered in Python (`register_task`), by YAML name."""
_LOADED: dict[str, type[Task]] = {}


def _builtin(name: str) -> type[Task]:
    cls = _LOADED.get(name)
    if cls is None:
        from ..plugins import load

        cls = _LOADED[name] = load(BUILTIN_TASKS[name])
    return cls


def register_task(cls: type[Task]) -> type[Task]:
    """Class decorator: make `cls` available as `type: <cls.yaml_type>` in task sets."""
    name = getattr(cls, "yaml_type", None)
    if not name:
        raise TypeError(f"{cls.__name__} has no `yaml_type`")
    if name in BUILTIN_TASKS:
        if BUILTIN_TASKS[name] == f"{cls.__module__}:{cls.__qualname__}":
            return cls
        raise TypeError(f"task type '{name}' is already registered by {BUILTIN_TASKS[name].replace(':', '.')}")
    other = _TYPES.get(name)
    if other is not None and other is not cls:
        raise TypeError(f"task type '{name}' is already registered by {other.__module__}.{other.__qualname__}")
    _TYPES[name] = cls
    return cls


def task_types() -> dict[str, type[Task]]:
    """The task types by YAML name: the built-in ones and those registered in Python."""
    out = dict(_TYPES)
    out.update({name: _builtin(name) for name in BUILTIN_TASKS})
    return dict(sorted(out.items()))


def task_class(name: str, *, file: str | None = None, key: str | None = None) -> type[Task]:
    """The class of a task type; an unknown name is a `ConfigError` naming the file, key and known types."""
    if name in BUILTIN_TASKS:
        return _builtin(name)
    if name not in _TYPES:
        raise UnknownNameError("task type", name, task_types(), file=file, key=key)
    return _TYPES[name]


def build_task(robot: Any, spec: TaskSpec) -> Task:
    """A task object of the task library from its spec (through the registry), for any formulation."""
    return task_class(spec.type).from_spec(robot, spec)


def resolve_frame(robot: Any, frame: str) -> str:
    """A frame name of the model from a symbolic one of the robot profile (`base`, `torso`, `head`, `left_hand`,
    `right_hand`, `left_foot`, `right_foot`); any other string is returned as is."""
    from ..side import Side

    p = robot.profile
    symbolic = {"base": p.base_frame, "torso": p.torso_frame, "head": p.head_frame,
                "left_hand": p.hands[Side.LEFT], "right_hand": p.hands[Side.RIGHT],
                "left_foot": p.feet[Side.LEFT].frame, "right_foot": p.feet[Side.RIGHT].frame}
    return symbolic.get(frame, frame)
