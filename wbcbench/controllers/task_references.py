"""References -> task targets: the one path by which a tick's `References` reach a formulation's tasks, shared by
the inverse-dynamics and the kinematic formulations (a velocity-level task ignores the accelerations)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ..side import Side
from ..tasks import CoMTask, FrameTask, Task
from ..types import References

__all__ = ["TaskReferences"]


class TaskReferences:
    """Hands references to tasks: the CoM plan to every CoM task, each named target to the task of that name
    (unknown names are ignored: a scenario may serve several controllers), each swing-foot reference to the
    free-motion task of that foot. A pose reference without a rotation keeps the task's current one."""

    def __init__(self, tasks: Sequence[Task], free_tasks: Mapping[Side, FrameTask]):
        self.com_tasks = tuple(t for t in tasks if isinstance(t, CoMTask))
        self.by_name = {t.name: t for t in tasks}
        self.free_tasks = dict(free_tasks)

    def apply(self, refs: References) -> None:
        com = refs.com
        if com is not None:
            for task in self.com_tasks:
                task.set_reference(com.position, com.velocity, com.acceleration)
        for name, target in refs.targets.items():
            task = self.by_name.get(name)
            if task is not None:
                task.set_pose(target.position, target.rotation, target.velocity, target.acceleration)
        for side, foot in refs.feet.items():
            self.free_tasks[side].set_pose(foot.position, foot.rotation, foot.velocity, foot.acceleration)
