"""The shared formulations apply the documented laws to any task, through the task contract only."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import wbcbench.tasks as tasks
from wbcbench.tasks import Rows, Task, acceleration_rows, velocity_rows

FINITE = st.floats(-10.0, 10.0)


class ToyTask(Task):
    """A task with fixed numbers, to check the formulations independently of any robot."""

    def __init__(self, J, e, Jv, drift, **kwargs):
        super().__init__(axis_names=[f"a{i}" for i in range(len(e))], units=["m"] * len(e), **kwargs)
        self._J, self._e, self._Jv, self._drift = J, e, Jv, drift

    def error(self, model, data):
        return self._e.copy()

    def jacobian(self, model, data):
        return self._J.copy()

    def velocity(self, model, data):
        return self._Jv.copy()

    def drift(self, model, data):
        return self._drift.copy()

    def set_reference(self, velocity, acceleration):
        self._store_derivatives(self._check_derivatives(velocity, acceleration))


@settings(max_examples=40, deadline=None)
@given(data=st.data(), dim=st.integers(1, 6))
def test_laws_and_masks(data, dim):
    vec = hnp.arrays(np.float64, dim, elements=FINITE)
    J = data.draw(hnp.arrays(np.float64, (dim, 5), elements=FINITE))
    e, Jv, drift, v_ref, a_ref = (data.draw(vec) for _ in range(5))
    kp = data.draw(hnp.arrays(np.float64, dim, elements=st.floats(0.0, 100.0)))
    kd = data.draw(hnp.arrays(np.float64, dim, elements=st.floats(0.0, 100.0)))
    mask = data.draw(hnp.arrays(bool, dim).filter(np.any))
    task = ToyTask(J, e, Jv, drift, name="toy", weight=1.0, kp=kp, kd=kd, mask=list(mask))
    task.set_reference(v_ref, a_ref)

    A, b = acceleration_rows(task, None, None)
    np.testing.assert_array_equal(A, J[mask])
    np.testing.assert_allclose(b, (a_ref + kd * (v_ref - Jv) + kp * e - drift)[mask], rtol=1e-12, atol=1e-12)
    rows = velocity_rows(task, None, None)
    assert isinstance(rows, Rows)
    np.testing.assert_array_equal(rows.A, J[mask])
    np.testing.assert_allclose(rows.b, (v_ref + kp * e)[mask], rtol=1e-12, atol=1e-12)


def test_scalar_gains_broadcast_and_mask_properties():
    z = np.zeros(3)
    task = ToyTask(np.eye(3), z, z, z, name="toy", weight=0.0, kp=2.0, kd=None, mask=[True, False, True])
    np.testing.assert_array_equal(task.kp, [2.0, 2.0, 2.0])
    np.testing.assert_allclose(task.kd, 2.0 * np.sqrt(2.0))
    np.testing.assert_array_equal(task.rows, [0, 2])
    assert not task.all_selected and task.weight == 0.0
    task.mask = [1, 1, 1]
    assert task.all_selected and task.selection == slice(0, 3)
    with pytest.raises(ValueError):
        task.mask[0] = False


def test_public_api_is_curated():
    for name in tasks.__all__:
        assert hasattr(tasks, name), name
    assert {"FrameTask", "CoMTask", "PostureTask", "AngularMomentumTask", "Contact6D"} <= set(tasks.__all__)
