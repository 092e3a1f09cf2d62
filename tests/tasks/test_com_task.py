"""CoMTask agrees with pinocchio's CoM; Jacobian and drift against finite differences; split masks."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import CoMTask, ReferenceNotSetError, TaskConfigError, acceleration_rows, velocity_rows

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_com_quantities_agree_with_pinocchio_and_finite_differences(erd_talos, seed):
    model = erd_talos.model
    data, ref = model.createData(), model.createData()
    task = CoMTask(model, kp=1.0)
    q, v = erd_talos.random_state(seed)
    erd_talos.at(data, q, v)
    np.testing.assert_allclose(task.position(model, data), pin.centerOfMass(model, ref, q), atol=1e-12)
    np.testing.assert_allclose(task.jacobian(model, data), pin.jacobianCenterOfMass(model, ref, q), atol=1e-12)
    pin.centerOfMass(model, ref, q, v, np.zeros(model.nv))
    np.testing.assert_allclose(task.velocity(model, data), ref.vcom[0], atol=1e-12)
    np.testing.assert_allclose(task.drift(model, data), ref.acom[0], atol=1e-9)

    J_fd = erd_talos.numerical_jacobian(q, lambda qq: pin.centerOfMass(model, ref, qq))
    np.testing.assert_allclose(task.jacobian(model, data), J_fd, atol=1e-7)
    drift_fd = erd_talos.along(q, v, lambda qq: task.jacobian(model, erd_talos.at(data, qq)) @ v)
    erd_talos.at(data, q, v)
    np.testing.assert_allclose(task.drift(model, data), drift_fd, atol=1e-6)

    task.set_reference(np.zeros(3))
    de_fd = erd_talos.numerical_jacobian(q, lambda qq: task.error(model, erd_talos.at(data, qq)))
    np.testing.assert_allclose(de_fd, -J_fd, atol=1e-7)

    # Velocity-level update: the same position and Jacobian.
    erd_talos.at(data, q)
    np.testing.assert_allclose(task.jacobian(model, data), J_fd, atol=1e-7)
    np.testing.assert_allclose(task.error(model, data), -pin.centerOfMass(model, ref, q), atol=1e-12)


def test_height_and_xy_tasks_split_the_rows(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(7)
    data = erd_talos.at(model.createData(), q, v)
    full = CoMTask(model, kp=[100, 100, 1000], kd=[20, 20, 300])
    height = CoMTask(model, name="com_height", kp=1000, kd=300, weight=1e3, mask=[0, 0, 1])
    xy = CoMTask(model, name="com_xy", kp=100, kd=20, weight=1e3, mask=[1, 1, 0])
    p_ref, v_ref, a_ref = np.array([0.0, 0.1, 0.8]), np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, 0.5])
    for task in (full, height, xy):
        task.set_reference(p_ref, v_ref, a_ref)
    A, b = acceleration_rows(full, model, data)
    Ah, bh = acceleration_rows(height, model, data)
    Axy, bxy = acceleration_rows(xy, model, data)
    assert Ah.shape == (1, model.nv) and Axy.shape == (2, model.nv)
    np.testing.assert_allclose(np.vstack([Axy, Ah]), A, atol=1e-15)
    np.testing.assert_allclose(np.r_[bxy, bh], b, atol=1e-12)
    expected = a_ref + full.kd * (v_ref - full.velocity(model, data)) + full.kp * (p_ref - data.com[0])
    np.testing.assert_allclose(b, expected - full.drift(model, data), atol=1e-12)
    erd_talos.at(data, q)
    np.testing.assert_allclose(velocity_rows(height, model, data).b, v_ref[2:] + 1000 * (p_ref - data.com[0])[2:])


def test_rows_vanish_at_rest_on_the_reference(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0, np.zeros(model.nv))
    task = CoMTask(model, kp=1000.0, kd=300.0)
    task.set_reference_to_current(model, data)
    np.testing.assert_allclose(acceleration_rows(task, model, data).b, 0.0, atol=1e-12)


def test_bad_inputs(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0)
    task = CoMTask(model, kp=1.0)
    with pytest.raises(ReferenceNotSetError):
        task.error(model, data)
    with pytest.raises(TaskConfigError, match="position"):
        task.set_reference([0.0, 1.0])
    with pytest.raises(TaskConfigError, match="acceleration"):
        task.set_reference([0.0, 1.0, 0.8], acceleration=[np.nan, 0, 0])
    assert task.reference is None  # nothing stored by a failed call
    with pytest.raises(TaskConfigError, match="mask"):
        CoMTask(model, kp=1.0, mask=[1, 1])
    with pytest.raises(TaskConfigError, match="kd"):
        CoMTask(model, kp=1.0, kd=-3.0)
