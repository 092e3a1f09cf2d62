"""The task registry: each task class names its YAML type and parses its own options; a user's task type is
available in task sets without editing wbcbench."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from wbcbench.controllers.inverse_dynamics import TSIDTorque
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.tasks import FrameTask, register_task, task_types
from wbcbench.types import ActuationMode


def test_builtin_types_are_registered_by_their_classes():
    types = task_types()
    assert set(types) >= {"com", "frame", "posture", "angular_momentum", "self_collision"}
    assert all(cls.yaml_type == name for name, cls in types.items())


@register_task
class HeightTask(FrameTask):
    """A user's task type: a frame's height only (one axis), from `frame` and `height_only: true`."""

    yaml_type = "test-frame-height"

    @classmethod
    def parse_options(cls, sec: Any, robot: Any) -> dict:
        options = FrameTask.parse_options(sec, robot)
        options["scale"] = sec.float("scale", 1.0, positive=True)
        return options

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return 6

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> "HeightTask":
        return cls(robot.model, spec.options["frame"], name=spec.name, weight=spec.weight * spec.options["scale"],
                   kp=spec.kp, kd=spec.kd, mask=(False, False, True, False, False, False))


def test_a_user_task_type_works_in_a_task_set(talos, tmp_path):
    data = yaml.safe_load(taskset_path(talos, "tsid-torque").read_text())
    data["tasks"].append({"name": "hand_height", "type": "test-frame-height", "frame": "left_hand", "scale": 2.0,
                          "weight": 5.0, "kp": 100.0})
    p = tmp_path / "t.yaml"
    p.write_text(yaml.safe_dump(data))
    spec = load_taskset(p, talos)
    ctrl = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3, spec)
    task = ctrl.task_by_name["hand_height"]
    assert isinstance(task, HeightTask) and task.weight == 10.0 and task.mask.tolist() == [0, 0, 1, 0, 0, 0]
    data["tasks"][-1]["scale"] = -1.0
    p.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"tasks\[\d+\]\.scale"):
        load_taskset(p, talos)


def test_hard_task_is_an_equality_constraint(talos, tmp_path):
    """`hard: true` puts the waist task in the equality constraints: its rows are met exactly by the QP."""
    data = yaml.safe_load(taskset_path(talos, "tsid-torque").read_text())
    for t in data["tasks"]:
        if t["name"] == "waist":
            t["hard"] = True
    p = tmp_path / "hard.yaml"
    p.write_text(yaml.safe_dump(data))
    spec = load_taskset(p, talos)
    assert [t.name for t in spec.tasks if t.hard] == ["waist"]
    ctrl = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3, spec)
    F = ctrl.formulation
    q = talos.q0.copy()
    q[7:] += 0.02
    F.update(q, np.zeros(talos.nv))
    F.reset_references(talos.q0, set(F.names))
    waist = F.task_by_name["waist"]
    waist.set_reference(pin.SE3(pin.rpy.rpyToMatrix(0.05, -0.03, 0.02), np.zeros(3)))
    P = F.problem()
    from wbcbench.qp import make_solver
    x = make_solver("daqp").solve(P).unwrap()
    from wbcbench.tasks import acceleration_rows
    A, b = acceleration_rows(waist, F.model, F.data)
    np.testing.assert_allclose(A @ x[:F.nv], b, atol=1e-7)
    assert waist in F.hard_tasks and waist not in F.tasks
