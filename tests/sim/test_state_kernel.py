"""The run loop's compiled reads give what the simulator's numpy reads give: the state in pinocchio's conventions
(`StateBridge`), the sensors, the fall check's numbers, and the ground truth written into a log row; TALOS
standing under tsid-torque while a push makes the feet slide and the load move."""

import math

import numpy as np
import pinocchio as pin

from wbcbench.controllers.base import make_controller
from wbcbench.robots import Side
from wbcbench.sim.contact_kernel import ContactRecords
from wbcbench.sim.push import Push
from wbcbench.sim.simulator import Simulator
from wbcbench.sim.state_kernel import fall_numbers
from wbcbench.types import PointReference, References


def numpy_measurement(sim):
    """The measurement as the simulator made it with numpy (the bridge's conversions and sensor slices)."""
    d, adr = sim.data, sim._sensor_adr
    sd = d.sensordata
    a = adr["imu_quat"]
    w, x, y, z = sd[a:a + 4]

    def s3(name):
        return sd[adr[name]:adr[name] + 3]
    return {"q": sim.true_q(), "v": sim.true_v(), "imu_quat": np.array([x, y, z, w]), "gyro": s3("gyro"),
            "accelerometer": s3("accelerometer"),
            "ft": np.concatenate([s3("force_left"), s3("torque_left"), s3("force_right"), s3("torque_right")])}


def numpy_fall_numbers(sim):
    d = sim.data
    q, a = d.qpos, sim.bridge.root_qadr
    finite = math.isfinite(q.sum()) and math.isfinite(d.qvel.sum())
    gl, gr = sim._sole_ids
    height = float(q[a + 2]) - min(float(d.geom_xpos[gl, 2]), float(d.geom_xpos[gr, 2]))
    w, x, y, z = q[a + 3:a + 7].tolist()
    return finite, height, (1 - 2 * (x * x + y * y)) / (w * w + x * x + y * y + z * z)


def test_read_tick_matches_the_numpy_reads(talos):
    ctrl = make_controller("tsid-torque", talos, None, 1e-3)
    sim = Simulator(talos, mode=ctrl.mode, pushes=(Push("base", (0.0, 150.0, 0.0), 0.1, 0.2),))
    na, nq, nv = talos.na, talos.nq, talos.nv
    # a row laid out as the run loop's: q | v | tau | wrenches | F/T, with gaps, in a column-major block
    block = np.full((3, nq + nv + na + 12 + 12 + 10), np.nan, order="F")
    dst = np.array([2, 2 + nq, 3 + nq + nv, 5 + nq + nv + na, 7 + nq + nv + na + 12], dtype=np.int64)
    meas = sim.measure()
    com = pin.centerOfMass(talos.model, talos.model.createData(), meas.q).copy()
    refs = References(t=0.0, com=PointReference(com), zmp=np.array([com[0], com[1], 0.0]))
    ctrl.reset(meas, refs)
    checked = 0
    for k in range(300):
        sim.apply(ctrl.step(meas, refs))
        sim.step()
        row = block[1]
        row[:] = np.nan
        state, fs = sim.read_tick(row, dst)
        meas = sim.measurement(state)
        if k % 25 != 24:
            continue
        checked += 1
        ref = numpy_measurement(sim)
        np.testing.assert_array_equal(meas.q, ref["q"])
        np.testing.assert_allclose(meas.v, ref["v"], rtol=0, atol=1e-15)  # R^T v: numpy may fuse or reorder
        for name in ("imu_quat", "gyro", "accelerometer"):
            np.testing.assert_array_equal(getattr(meas, name), ref[name])
        for i, s in enumerate(Side):
            np.testing.assert_array_equal(meas.ft_force[s], ref["ft"][6 * i:6 * i + 3])
            np.testing.assert_array_equal(meas.ft_torque[s], ref["ft"][6 * i + 3:6 * i + 6])
        # the row: what the separate calls give, where dst says, and nothing written elsewhere
        np.testing.assert_array_equal(row[dst[0]:dst[0] + nq], meas.q)
        np.testing.assert_array_equal(row[dst[1]:dst[1] + nv], meas.v)
        np.testing.assert_array_equal(row[dst[2]:dst[2] + na], sim.applied_torque())
        cw = sim.contact_wrenches()
        np.testing.assert_array_equal(row[dst[3]:dst[3] + 12], np.concatenate([cw[Side.LEFT], cw[Side.RIGHT]]))
        np.testing.assert_array_equal(row[dst[4]:dst[4] + 12], ref["ft"])
        written = np.zeros(row.size, bool)
        for start, n in zip(dst, (nq, nv, na, 12, 12)):
            written[start:start + n] = True
        assert np.isnan(row[~written]).all() and not np.isnan(row[written]).any()
        assert np.isnan(block[0]).all() and np.isnan(block[2]).all()
        assert fs == sim.fall_status() and not fs.fell
        d = sim.data
        assert fall_numbers(d.qpos, d.qvel, d.geom_xpos, sim.bridge.root_qadr, *sim._soles2) == numpy_fall_numbers(sim)
        # the contact records viewed in place are still where MuJoCo keeps the contacts
        assert sim._contacts is not None and sim._contacts.matches(sim.data)
        assert sum(cw[s][2] for s in Side) > 0.5 * talos.mass * 9.81  # loaded contacts were read
    assert checked == 12


def test_fall_numbers_see_a_diverged_state_and_a_tilt(talos):
    sim = Simulator(talos)
    assert not sim.fall_status().fell
    a = sim.bridge.root_qadr
    sim.data.qpos[a + 3:a + 7] = [np.cos(0.4), np.sin(0.4), 0.0, 0.0]  # 0.8 rad about x
    fs = sim.fall_status()
    assert fs.fell and "tilted 0.80 rad" in fs.reason
    sim.data.qvel[10] = np.nan
    assert sim.fall_status().reason == "simulation diverged (non-finite state)"


def test_contact_records_need_a_contact(talos):
    sim = Simulator(talos)
    sim.data.qpos[sim.bridge.root_qadr + 2] += 1.0  # lifted: no contact after a forward pass
    import mujoco
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.data.ncon == 0
    try:
        ContactRecords(sim.data)
    except ValueError as exc:
        assert "there is none" in str(exc)
    else:
        raise AssertionError("located contact records without a contact")
    np.testing.assert_array_equal(sim.contact_wrench_array(), 0.0)
