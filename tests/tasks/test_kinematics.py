"""update_kinematics fills everything the tasks read, identical to the separate pinocchio algorithms."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import update_kinematics, update_kinematics_velocity_level

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_compute_all_terms_covers_drifts_and_centroidal_terms(erd_talos, seed):
    model = erd_talos.model
    q, v = erd_talos.random_state(seed)
    data, ref = model.createData(), model.createData()
    update_kinematics(model, data, q, v)

    np.testing.assert_array_equal(data.q_in, q)
    np.testing.assert_array_equal(data.v_in, v)

    pin.forwardKinematics(model, ref, q, v, np.zeros(model.nv))
    for i in range(1, model.njoints):
        np.testing.assert_allclose(data.a[i].vector, ref.a[i].vector, atol=1e-10)
        np.testing.assert_allclose(data.v[i].vector, ref.v[i].vector, atol=1e-10)
        np.testing.assert_allclose(data.oMi[i].homogeneous, ref.oMi[i].homogeneous, atol=1e-12)

    pin.centerOfMass(model, ref, q, v, np.zeros(model.nv))
    mass = pin.computeTotalMass(model)
    np.testing.assert_allclose(data.com[0], ref.com[0], atol=1e-12)
    np.testing.assert_allclose(data.vcom[0], ref.vcom[0], atol=1e-10)
    np.testing.assert_allclose(data.dAg[:3] @ v / mass, ref.acom[0], atol=1e-9)

    pin.computeCentroidalMapTimeVariation(model, ref, q, v)
    np.testing.assert_allclose(data.Ag, ref.Ag, atol=1e-10)
    np.testing.assert_allclose(data.dAg @ v, ref.dAg @ v, atol=1e-8)
    dhg = pin.computeCentroidalMomentumTimeVariation(model, ref, q, v, np.zeros(model.nv))
    np.testing.assert_allclose(data.dAg @ v, dhg.vector, atol=1e-8)

    np.testing.assert_allclose(data.M, pin.crba(model, ref, q), atol=1e-10)
    np.testing.assert_allclose(data.nle, pin.nonLinearEffects(model, ref, q, v), atol=1e-8)
    pin.computeJointJacobians(model, ref, q)
    np.testing.assert_allclose(data.J, ref.J, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_velocity_level_update_gives_placements_jacobians_com_and_centroidal_map(erd_talos, seed):
    model = erd_talos.model
    q, _ = erd_talos.random_state(seed)
    data, ref = model.createData(), model.createData()
    update_kinematics_velocity_level(model, data, q)
    np.testing.assert_array_equal(data.q_in, q)
    pin.computeJointJacobians(model, ref, q)
    np.testing.assert_allclose(data.J, ref.J, atol=1e-12)
    for i in range(1, model.njoints):
        np.testing.assert_allclose(data.oMi[i].homogeneous, ref.oMi[i].homogeneous, atol=1e-12)
    np.testing.assert_allclose(data.com[0], pin.centerOfMass(model, ref, q), atol=1e-12)
    np.testing.assert_allclose(data.Ag, pin.computeCentroidalMap(model, ref, q), atol=1e-12)
