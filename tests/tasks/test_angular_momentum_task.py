"""AngularMomentumTask rows agree with pinocchio's centroidal momentum and its time variation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import AngularMomentumTask, TaskConfigError, acceleration_rows, velocity_rows

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_rows_agree_with_centroidal_momentum(erd_talos, seed):
    model = erd_talos.model
    data, ref = model.createData(), model.createData()
    task = AngularMomentumTask(model, kd=10.0, weight=2e-2)
    q, v = erd_talos.random_state(seed)
    erd_talos.at(data, q, v)
    h = pin.computeCentroidalMomentum(model, ref, q, v).angular
    np.testing.assert_allclose(task.velocity(model, data), h, atol=1e-10)
    np.testing.assert_allclose(task.jacobian(model, data) @ v, h, atol=1e-10)
    dh = pin.computeCentroidalMomentumTimeVariation(model, ref, q, v, np.zeros(model.nv)).angular
    np.testing.assert_allclose(task.drift(model, data), dh, atol=1e-8)

    A, b = acceleration_rows(task, model, data)
    np.testing.assert_allclose(A, pin.computeCentroidalMap(model, ref, q)[3:], atol=1e-12)
    np.testing.assert_allclose(b, -10.0 * h - dh, atol=1e-8)
    # The momentum rate for any dv is A dv + drift (pinocchio's dhg with that acceleration).
    dv = np.random.default_rng(seed).normal(size=model.nv)
    dhg = pin.computeCentroidalMomentumTimeVariation(model, ref, q, v, dv).angular
    np.testing.assert_allclose(A @ dv + task.drift(model, data), dhg, atol=1e-8)

    drift_fd = erd_talos.along(q, v, lambda qq: task.jacobian(model, erd_talos.at(data, qq)) @ v)
    np.testing.assert_allclose(dh, drift_fd, atol=1e-5 * (1 + np.abs(dh).max()))


def test_targets_and_velocity_level(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(4)
    data = erd_talos.at(model.createData(), q, v)
    task = AngularMomentumTask(model, kd=[1.0, 2.0, 3.0], mask=[1, 0, 1])
    target, rate = np.array([1.0, 2.0, 3.0]), np.array([0.5, 0.0, -0.5])
    task.set_reference(target, rate)
    h, drift = task.velocity(model, data), task.drift(model, data)
    A, b = acceleration_rows(task, model, data)
    assert A.shape == (2, model.nv)
    np.testing.assert_allclose(b, (rate + task.kd * (target - h) - drift)[[0, 2]], atol=1e-10)
    erd_talos.at(data, q)
    A, b = velocity_rows(task, model, data)
    np.testing.assert_allclose(b, target[[0, 2]])


def test_zero_momentum_at_rest(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0, np.zeros(model.nv))
    task = AngularMomentumTask(model, kd=10.0)
    np.testing.assert_allclose(acceleration_rows(task, model, data).b, 0.0, atol=1e-12)


def test_kp_is_refused(erd_talos):
    with pytest.raises(TaskConfigError, match="kd"):
        AngularMomentumTask(erd_talos.model, kd=10.0).kp = 10.0
    with pytest.raises(TaskConfigError, match="kd"):
        AngularMomentumTask(erd_talos.model, kd=-1.0)
