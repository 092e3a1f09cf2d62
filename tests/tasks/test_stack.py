"""TaskStack: the same rows as stacking the per-task formulations, through layout changes and new references."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import (
    AngularMomentumTask,
    CoMTask,
    Contact6D,
    FrameTask,
    PostureTask,
    TaskStack,
    acceleration_rows,
    velocity_rows,
)

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)


def _tasks(model, data):
    """Every task type of the library, some masked (slices and index arrays), references set at ``data``."""
    tasks = [
        Contact6D(model, "left_sole_link", length=0.2, width=0.1, kp=30.0, kd=11.0),
        CoMTask(model, name="com_xy", kp=[20.0, 30.0, 40.0], kd=3.0, weight=1e3, mask=[1, 1, 0]),
        CoMTask(model, name="com_xz", kp=20.0, weight=10.0, mask=[1, 0, 1]),
        FrameTask(model, "torso_2_link", name="waist", kp=100.0, kd=20.0, mask=[0, 0, 0, 1, 1, 1]),
        FrameTask(model, "gripper_left_base_link", name="hand", kp=50.0, weight=0.0),
        FrameTask(model, "arm_right_7_link", name="wrist", kp=50.0, mask=[1, 0, 1, 0, 1, 0]),
        AngularMomentumTask(model, kd=10.0, weight=0.02),
        PostureTask(model, kp=np.linspace(1.0, 100.0, model.nv - 6), weight=0.1),
    ]
    for t in tasks:
        if isinstance(t, PostureTask):
            t.set_reference(pin.neutral(model))
        elif isinstance(t, AngularMomentumTask):
            t.set_reference(np.array([0.1, -0.2, 0.3]))
        else:
            t.set_reference_to_current(model, data)
    return tasks


def _stacked(rows_of, tasks, model, data):
    rows = [rows_of(t, model, data) for t in tasks]
    return np.vstack([r.A for r in rows]), np.concatenate([r.b for r in rows])


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_rows_equal_the_per_task_formulations(erd_talos, seed):
    model = erd_talos.model
    data = model.createData()
    q0, v0 = erd_talos.random_state(seed)
    erd_talos.at(data, q0, v0)
    tasks = _tasks(model, data)
    stack = TaskStack(tasks, model.nv)
    for k in range(3):  # the references stay, the state moves: the buffers are refilled
        q, v = erd_talos.random_state(seed + k + 1, speed=0.5)
        erd_talos.at(data, q, v)
        A, b = stack.acceleration_rows(model, data)
        A_ref, b_ref = _stacked(acceleration_rows, tasks, model, data)
        np.testing.assert_array_equal(A, A_ref)
        np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-9)  # J v in one product: rounding only
        erd_talos.at(data, q)
        A, b = stack.velocity_rows(model, data)
        A_ref, b_ref = _stacked(velocity_rows, tasks, model, data)
        np.testing.assert_array_equal(A, A_ref)
        np.testing.assert_array_equal(b, b_ref)
    assert [s.stop - s.start for s in stack.slices] == [len(t.rows) for t in tasks]
    np.testing.assert_array_equal(stack.sqrt_weights, np.concatenate([np.full(len(t.rows), np.sqrt(t.weight))
                                                                      for t in tasks]))


def test_configuration_changes_and_new_references_are_followed(erd_talos):
    model = erd_talos.model
    data = model.createData()
    q, v = erd_talos.random_state(5)
    erd_talos.at(data, q, v)
    tasks = _tasks(model, data)
    stack = TaskStack(tasks, model.nv, skip_zero_weight=tasks[1:])
    hand, com, posture = tasks[4], tasks[1], tasks[7]
    assert hand not in stack.tasks and tasks[0] in stack.tasks  # zero weight left out (only where asked)

    def check():
        A, b = stack.acceleration_rows(model, data)
        A_ref, b_ref = _stacked(acceleration_rows, stack.tasks, model, data)
        np.testing.assert_array_equal(A, A_ref)
        np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-9)

    check()
    slices = stack.slices
    CoMTask(model, kp=1.0).weight = 3.0  # another task's configuration: the layout stays
    assert stack.slices is slices
    hand.weight = 2.0  # back in
    com.mask = [1, 1, 1]  # one more row
    com.kp = 7.0
    posture.mask = [i % 3 == 0 for i in range(model.nv - 6)]  # the constant Jacobian rows change
    check()
    assert hand in stack.tasks and stack.n_rows == sum(len(t.rows) for t in stack.tasks)
    com.set_reference(np.array([0.1, 0.2, 0.9]), np.array([0.3, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    tasks[3].set_reference(pin.SE3(pin.utils.rotate("z", 0.3), np.zeros(3)), np.arange(6.0), -np.arange(6.0))
    check()
    A, b = stack.acceleration_rows(model, data)
    with pytest.raises(ValueError):
        A[0, 0] = 1.0  # read-only views of the stack's buffers
