"""The simulator's per-tick reads in one compiled call each (see :mod:`wbcbench.jit`): MuJoCo's state and sensors
into pinocchio's conventions (what `StateBridge.q_from_mj` / `v_from_mj` and the sensor slices do), and the
numbers of the fall check.

Both are `exact` kernels: the same IEEE operations in the same order as the numpy code they replace, so a run's
log does not change with them. A test checks them against that code.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .contact_kernel import sole_wrenches

__all__ = ["read_state", "read_tick", "tick_aux", "fall_numbers", "state_layout", "state_size", "STATE_SENSORS"]

#: the sensors `read_state` copies, in this order, after q and v (imu_quat is reordered to x, y, z, w)
STATE_SENSORS = ("imu_quat", "gyro", "accelerometer", "force_left", "torque_left", "force_right", "torque_right")


def state_layout(root_q: int, root_v: int, nq: int, mj_q, pin_q, mj_v, pin_v, sensor_adr) -> np.ndarray:
    """`read_state`'s index argument: root_q, root_v, nq, the number of joints and of sensors, then the joints'
    addresses in qpos (``mj_q``), q (``pin_q``), qvel (``mj_v``), v (``pin_v``) and the sensors' in sensordata
    (`STATE_SENSORS` order)."""
    nj = len(mj_q)
    if not len(pin_q) == len(mj_v) == len(pin_v) == nj or len(sensor_adr) != len(STATE_SENSORS):
        raise ValueError("read_state layout: one address per joint in each of mj_q, pin_q, mj_v, pin_v")
    return np.concatenate([[root_q, root_v, nq, nj, len(sensor_adr)], mj_q, pin_q, mj_v, pin_v,
                           sensor_adr]).astype(np.int64)


@njit(exact=True)
def read_state(qpos, qvel, sensordata, layout, out):
    """Fill ``out`` with q (nq) | v (nv) | IMU quaternion (x, y, z, w) | gyro (3) | accelerometer (3) |
    force_left, torque_left, force_right, torque_right (3 each), pinocchio's conventions: base position, then
    its quaternion (x, y, z, w) and the joints in pinocchio's order; base linear velocity in the base frame
    (MuJoCo's is in the world), angular velocity as MuJoCo's (local), joints. ``layout``: `state_layout`."""
    a, b, nq, nj, ns = layout[0], layout[1], layout[2], layout[3], layout[4]
    mj_q, pin_q, mj_v, pin_v = 5, 5 + nj, 5 + 2 * nj, 5 + 3 * nj
    sens = 5 + 4 * nj
    out[0] = qpos[a]
    out[1] = qpos[a + 1]
    out[2] = qpos[a + 2]
    out[3] = qpos[a + 4]
    out[4] = qpos[a + 5]
    out[5] = qpos[a + 6]
    out[6] = qpos[a + 3]
    for i in range(nj):
        out[layout[pin_q + i]] = qpos[layout[mj_q + i]]
    # base linear velocity: R^T v_world with R the base rotation from its (not necessarily unit) quaternion
    w, x, y, z = qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6]
    n = w * w + x * x + y * y + z * z
    s = 2.0 / n
    r00, r01, r02 = 1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)
    r10, r11, r12 = s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)
    r20, r21, r22 = s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)
    u0, u1, u2 = qvel[b], qvel[b + 1], qvel[b + 2]
    out[nq] = r00 * u0 + r10 * u1 + r20 * u2
    out[nq + 1] = r01 * u0 + r11 * u1 + r21 * u2
    out[nq + 2] = r02 * u0 + r12 * u1 + r22 * u2
    out[nq + 3] = qvel[b + 3]
    out[nq + 4] = qvel[b + 4]
    out[nq + 5] = qvel[b + 5]
    for i in range(nj):
        out[nq + layout[pin_v + i]] = qvel[layout[mj_v + i]]
    k = nq + 6 + nj
    q0 = layout[sens]
    out[k] = sensordata[q0 + 1]
    out[k + 1] = sensordata[q0 + 2]
    out[k + 2] = sensordata[q0 + 3]
    out[k + 3] = sensordata[q0]
    k += 4
    for j in range(1, ns):
        adr = layout[sens + j]
        out[k] = sensordata[adr]
        out[k + 1] = sensordata[adr + 1]
        out[k + 2] = sensordata[adr + 2]
        k += 3


@njit(exact=True)
def fall_numbers(qpos, qvel, geom_xpos, root_q, sole_a, sole_b):
    """(finite, base height above the lower sole, cosine of the base tilt) for the fall check: whether every
    entry of the state is finite, the base's z minus the lower of the two sole geoms' z, and the cosine of the
    angle between the base's z axis and the world's."""
    finite = True
    for i in range(qpos.shape[0]):
        if not math.isfinite(qpos[i]):
            finite = False
    for i in range(qvel.shape[0]):
        if not math.isfinite(qvel[i]):
            finite = False
    a = root_q
    height = qpos[a + 2] - min(geom_xpos[sole_a, 2], geom_xpos[sole_b, 2])
    w, x, y, z = qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6]
    cos_tilt = (1 - 2 * (x * x + y * y)) / (w * w + x * x + y * y + z * z)
    return finite, height, cos_tilt


def state_size(nq: int, nv: int) -> int:
    """Length of `read_state`'s output for a robot with nq, nv."""
    return nq + nv + 4 + 3 * (len(STATE_SENSORS) - 1)



@njit(exact=True)
def read_tick(qpos, qvel, sensordata, actuator_force, geom_xpos, efc_force, ncon, floats, ints, pyramidal, layout, aux,
              state, wrench, row, dst):
    """Everything the run loop reads after a step, in one call: `read_state` into ``state``, the soles' contact
    wrenches (`contact_kernel.sole_wrenches`) into ``wrench``, and the ground truth copied into the log row
    ``row`` where ``dst`` says (q, v, applied torque, both soles' wrenches, both ankles' F/T readings: the first
    column of each, consecutive columns). ``aux``: `tick_aux`. Returns `fall_numbers`."""
    read_state(qpos, qvel, sensordata, layout, state)
    nq, nj = layout[2], layout[3]
    nv = 6 + nj
    if ncon > 0:
        sole_wrenches(ncon, efc_force, floats, ints, aux[2:8], aux[0:2], pyramidal, wrench)
    else:
        wrench[:] = 0.0
    d_q, d_v, d_tau, d_cw, d_ft = dst[0], dst[1], dst[2], dst[3], dst[4]
    for i in range(nq):
        row[d_q + i] = state[i]
    for i in range(nv):
        row[d_v + i] = state[nq + i]
    for i in range(aux.shape[0] - 8):
        row[d_tau + i] = actuator_force[aux[8 + i]]
    for k in range(wrench.shape[0]):
        for j in range(6):
            row[d_cw + 6 * k + j] = wrench[k, j]
    ft = nq + nv + 10
    for i in range(12):
        row[d_ft + i] = state[ft + i]
    return fall_numbers(qpos, qvel, geom_xpos, layout[0], aux[0], aux[1])


def tick_aux(soles, record_offsets, actuators) -> np.ndarray:
    """`read_tick`'s ``aux``: the two sole geoms, the contact records' six field offsets (zeros until a contact
    located them), the joints' actuators (pinocchio joint order)."""
    if len(soles) != 2 or len(record_offsets) != 6:
        raise ValueError("read_tick aux: two sole geoms and six record offsets")
    return np.concatenate([soles, record_offsets, actuators]).astype(np.int64)
