"""What a position-controlled humanoid's balance stabilizer needs, estimated from a robot's sensors:
the ZMP measured by the ankle F/T sensors, and the CoM (position, velocity) anchored on the support foot.

Anchoring (as the TALOS balance stack does, SIM-NOTES "Position mode"): on soft contacts the whole robot rocks
on its feet while the joints track their references, and feeding that rocking back through a world-frame CoM
diverges. The CoM is therefore computed from the measured joint angles with the robot placed so that its loaded
feet sit exactly where the controller's model puts them (one correction per foot, averaged with the feet's normal
forces as weights, so that the estimate stays continuous when the load passes from one foot to the other). The ZMP
stays measured in the world.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..jit import c_view, njit
from ..robots import Robot
from ..side import Side
from ..tasks.placements import CenterOfMass, frame_placements, subtree_sums
from ..types import Measurement
from ._memo import joints_placing, memo_arrays, memo_joint_placements, placement_memo
from .wrench import GRAVITY_WORLD, FootMass, contact_wrench_from_ft
from .zmp import DEFAULT_MIN_NORMAL_FORCE, zmp_from_wrenches

_LEFT, _RIGHT = Side.LEFT, Side.RIGHT


class _OutputView:
    """An estimate of `BalanceEstimator`: the slice [lo, hi) of the compiled update's output array (`_take`), a view
    made when read, or the array the numpy `update` (or a user) set. Kept in the instance as ``_<name>``."""

    def __init__(self, lo: int, hi: int, doc: str):
        self.lo, self.hi, self.__doc__ = lo, hi, doc

    def __set_name__(self, owner, name: str) -> None:
        self.attr = "_" + name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        v = getattr(obj, self.attr)
        return obj._out[self.lo:self.hi] if v is None else v

    def __set__(self, obj, value: np.ndarray) -> None:
        setattr(obj, self.attr, value)


class BalanceEstimator:
    """Measured ZMP and support-foot-anchored CoM of a robot, one `update` per control tick.

    Args:
        robot: the robot (its profile gives the sole and F/T sensor frames; the foot masses below the sensors
            come from the model).
        dt: control period [s] (CoM velocity by finite difference).
        velocity_cutoff_hz: first-order low-pass on that finite difference; None: unfiltered.
        min_normal_force: per-foot normal-force threshold for the ZMP [N].
        state: a float (7,) array to keep the compiled update's state in (e.g. a view of its owner's buffer, so
            that a compiled call of the owner takes one array for both); None: its own.
    """

    def __init__(self, robot: Robot, dt: float, velocity_cutoff_hz: float | None = 50.0,
                 min_normal_force: float = DEFAULT_MIN_NORMAL_FORCE, state: np.ndarray | None = None):
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.model_data = robot.model.createData()
        self.dt = dt
        self.min_normal_force = min_normal_force
        self.sensor_ids = {s: robot.model.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
        self.sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        self.feet = {}
        for s in Side:
            m, c = robot.foot_below_sensor(s)
            self.feet[s] = FootMass(m, c)
        self.alpha = 1.0 if velocity_cutoff_hz is None else 1 - np.exp(-2 * np.pi * velocity_cutoff_hz * dt)
        # the whole update in one compiled call (`_balance_step`) where the compiled kinematics applies (its
        # placements and CoM are pinocchio's to rounding): the numpy and pinocchio calls of `update` took about
        # half of an IK step
        com = CenterOfMass(robot.model)
        self._step_args = None
        if com.supported:
            fk = com.fk
            frames = [self.sensor_ids[Side.LEFT], self.sensor_ids[Side.RIGHT], self.sole_ids[Side.LEFT],
                      self.sole_ids[Side.RIGHT]]
            feet = (self.feet[Side.LEFT], self.feet[Side.RIGHT])
            memo = placement_memo(robot.model, fk)
            frame_parents, R_frames, t_frames = fk.frame_arrays(frames)
            # the kernel's floats in one buffer (`_balance_arrays` views them; its scratch too, instead of arrays
            # allocated each call): an argument of a compiled call costs it ~40 ns
            floats = np.concatenate([np.ravel(a) for a in (
                R_frames, t_frames, com._mass, com._lever, com._msub, com._csub, np.array([f.mass for f in feet]),
                np.array([f.p_sensor_com for f in feet]), GRAVITY_WORLD, np.zeros(_SCRATCH),
                (min_normal_force, self.alpha, dt))])
            self._step_args = (memo.ints, memo.floats, frame_parents, floats)
        # has a previous CoM (0 / 1), that CoM (3), the filtered velocity (3); zeroed by `reset`
        self._state = np.zeros(7) if state is None else state
        self.reset()

    def reset(self) -> None:
        self._com_prev = None
        self._state[:] = 0.0
        self.com_vel = np.zeros(3)
        self.com = np.zeros(3)
        self.zmp = np.full(3, np.nan)
        self.normal_force = {s: 0.0 for s in Side}
        self.support = Side.LEFT

    def update(self, meas: Measurement, q_model: np.ndarray | None = None) -> None:
        """Update ZMP (world) and CoM from one measurement; `q_model` is the controller's model
        configuration whose support foot anchors the CoM (default: the measurement itself)."""
        if self._step_args is not None:
            self._update_compiled(meas, q_model)
            return
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, meas.q)
        wrenches = []
        for s in Side:
            M = pin.updateFramePlacement(m, d, self.sensor_ids[s])
            w = contact_wrench_from_ft(meas.ft_force[s], meas.ft_torque[s], M.rotation, M.translation, self.feet[s])
            wrenches.append(w)
            self.normal_force[s] = float(w.force[2])
        self.support = max(Side, key=lambda s: self.normal_force[s])
        ground = pin.updateFramePlacement(m, d, self.sole_ids[self.support]).translation[2]
        self.zmp = zmp_from_wrenches(wrenches, ground, min_normal_force=self.min_normal_force)
        # anchored CoM: joints as measured, each loaded foot where the model has it, blended by normal force
        com_world = pin.centerOfMass(m, d, meas.q, False)
        if q_model is not None:
            com_world = self._anchored(com_world, q_model)
        self.com = com_world.copy()
        if self._com_prev is None:
            self.com_vel = np.zeros(3)
        else:
            raw = (self.com - self._com_prev) / self.dt
            self.com_vel = self.com_vel + self.alpha * (raw - self.com_vel)
        self._com_prev = self.com.copy()

    def _anchored(self, com_world: np.ndarray, q_model: np.ndarray) -> np.ndarray:
        """`com_world` (from the measured configuration) moved so that the loaded feet sit where the model has
        them: one rigid correction per foot, averaged with the feet's normal forces as weights. A single-foot
        anchor would jump whenever the load passes from one foot to the other and the two feet's errors differ
        (feet on two opposite slopes, a foot that slid): at 0.9 m above the sole a 0.05 rad difference is a
        4.5 cm CoM step, i.e. a velocity spike of tens of m/s in the DCM."""
        m, d, md = self.model, self.data, self.model_data
        pin.forwardKinematics(m, md, q_model)
        forces = {s: (f if f > self.min_normal_force else 0.0) for s, f in self.normal_force.items()}
        total = forces[Side.LEFT] + forces[Side.RIGHT]
        if total <= 0.0:
            forces, total = {self.support: 1.0}, 1.0
        out = np.zeros(3)
        for s, f in forces.items():
            if f <= 0.0:
                continue
            fid = self.sole_ids[s]
            T_meas = pin.updateFramePlacement(m, d, fid)
            T_model = pin.updateFramePlacement(m, md, fid)
            out += (f / total) * (T_model * T_meas.inverse()).act(com_world)
        return out

    def _update_compiled(self, meas: Measurement, q_model: np.ndarray | None) -> None:
        """`update` by `_balance_step`: its outputs are views of one new array per tick (the last tick's arrays,
        which callers may keep, are not overwritten)."""
        out = np.empty(11)
        force, torque = meas.ft_force, meas.ft_torque
        anchor = q_model is not None
        support = _balance_step(meas.q, q_model if anchor else meas.q, anchor, force[_LEFT], torque[_LEFT],
                                force[_RIGHT], torque[_RIGHT], *self._step_args, self._state, out)
        self._take(out, support)

    def _take(self, out: np.ndarray, support: int) -> None:
        """The outputs of `_balance_step` (``out``, the support foot 0 / 1) as the estimate (`zmp`, `com`,
        `com_vel` views of it made when read: a stabilizer's compiled step reads ``out`` itself)."""
        self._normal_force = out  # the dict `normal_force` made from it when asked for
        self.support = _RIGHT if support else _LEFT
        self._out = out
        self._zmp = self._com = self._com_vel = None

    _out = _zmp = _com = _com_vel = None
    zmp = _OutputView(2, 5, "The measured ZMP (3,) [m], world, at the last update (NaN without a loaded foot).")
    com = _OutputView(5, 8, "The anchored CoM (3,) [m], world, at the last update.")
    com_vel = _OutputView(8, 11, "Its filtered velocity (3,) [m/s].")

    @property
    def normal_force(self) -> dict:
        """The feet's normal forces [N] at the last update, by side."""
        nf = self._normal_force
        if type(nf) is not dict:
            nf = self._normal_force = {_LEFT: float(nf[0]), _RIGHT: float(nf[1])}
        return nf

    @normal_force.setter
    def normal_force(self, value: dict) -> None:
        self._normal_force = value


#: the scratch of `_balance_step` in its buffer: the frames' placements Rf (6, 3, 3), tf (6, 3), the feet's ground
#: forces F and moments M (2, 3 each), a foot's CoM lever c (3), the anchor's weights w (2)
_SCRATCH = 54 + 18 + 6 + 6 + 3 + 2


@njit(inline=True)
def _balance_arrays(n, frame_parents, floats):
    """The floats of `_balance_step` (``n`` joints; as `BalanceEstimator` lays them out in one buffer):
    ``(R_frames, t_frames, mass, lever, msub, csub, foot_mass, foot_com, gravity, Rf, tf, F, M, c, w)`` (views;
    from ``Rf`` on its scratch, `_SCRATCH`) and the scalars ``(min_normal_force, alpha, dt)``."""
    k = frame_parents.shape[0]
    R_frames = c_view(floats[0:9 * k], (k, 3, 3))
    o = 9 * k
    t_frames = c_view(floats[o:o + 3 * k], (k, 3))
    o += 3 * k
    mass = floats[o:o + n]
    o += n
    lever = c_view(floats[o:o + 3 * n], (n, 3))
    o += 3 * n
    msub = floats[o:o + n]
    o += n
    csub = c_view(floats[o:o + 3 * n], (n, 3))
    o += 3 * n
    foot_mass = floats[o:o + 2]
    foot_com = c_view(floats[o + 2:o + 8], (2, 3))
    gravity = floats[o + 8:o + 11]
    o += 11
    Rf = c_view(floats[o:o + 54], (6, 3, 3))
    tf = c_view(floats[o + 54:o + 72], (6, 3))
    F = c_view(floats[o + 72:o + 78], (2, 3))
    M = c_view(floats[o + 78:o + 84], (2, 3))
    c, w = floats[o + 84:o + 87], floats[o + 87:o + 89]
    o += _SCRATCH
    return (R_frames, t_frames, mass, lever, msub, csub, foot_mass, foot_com, gravity, Rf, tf, F, M, c, w), (
        floats[o], floats[o + 1], floats[o + 2])


@njit
def _balance_step(q_meas, q_model, anchor, f_left, m_left, f_right, m_right, memo_ints, memo_floats, frame_parents,
                  floats, state, out):
    """`BalanceEstimator.update` in one call. Placements of the frames ``frame_parents`` (sensor left, right,
    sole left, right) for ``q_meas`` into ``Rf[:4]``, ``tf[:4]`` (the soles for ``q_model`` into rows 4, 5);
    `contact_wrench_from_ft` per foot, the ZMP of the loaded feet on the horizontal plane through the support
    sole (`zmp_from_wrenches`), the CoM of ``q_meas`` anchored on the loaded feet (`_anchor_on_feet`, when
    ``anchor``) and the filtered velocity (``state``: has a previous CoM, that CoM, the velocity; updated).
    ``out`` (11,): normal forces left, right | ZMP (NaN without a loaded foot) | CoM | CoM velocity. Returns
    the support foot (0 left, 1 right: the larger normal force, left on a tie). The joint placements come from
    the model's memo (`_memo.memo_joint_placements`: computed once a tick for both configurations), given as its two
    buffers; the other arrays, the scratch and the scalars (the ZMP's normal-force threshold, the velocity filter's
    gain, dt) as one buffer (`_balance_arrays`)."""
    kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work = memo_arrays(memo_ints, memo_floats)
    arrays, (min_normal_force, alpha, dt) = _balance_arrays(kinds.shape[0], frame_parents, floats)
    R_frames, t_frames, mass, lever, msub, csub, foot_mass, foot_com, gravity, Rf, tf, F, M, c, w = arrays
    j = memo_joint_placements(q_meas, kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work,
                              kinds.shape[0])  # every joint: the CoM
    R, t = memo_R[j], memo_t[j]
    frame_placements(R, t, frame_parents, R_frames, t_frames, Rf[:4], tf[:4])
    subtree_sums(R, t, parents, mass, lever, msub, csub)
    # each foot's ground wrench from its F/T reading: F = -R f_s - m g, M = -R m_s - (R c) x m g at the sensor
    for k in range(2):
        fs, ms = (f_left, m_left) if k == 0 else (f_right, m_right)
        w0, w1, w2 = foot_mass[k] * gravity[0], foot_mass[k] * gravity[1], foot_mass[k] * gravity[2]
        for a in range(3):
            F[k, a] = -(Rf[k, a, 0] * fs[0] + Rf[k, a, 1] * fs[1] + Rf[k, a, 2] * fs[2]) - foot_mass[k] * gravity[a]
            c[a] = Rf[k, a, 0] * foot_com[k, 0] + Rf[k, a, 1] * foot_com[k, 1] + Rf[k, a, 2] * foot_com[k, 2]
        M[k, 0] = -(Rf[k, 0, 0] * ms[0] + Rf[k, 0, 1] * ms[1] + Rf[k, 0, 2] * ms[2]) - (c[1] * w2 - c[2] * w1)
        M[k, 1] = -(Rf[k, 1, 0] * ms[0] + Rf[k, 1, 1] * ms[1] + Rf[k, 1, 2] * ms[2]) - (c[2] * w0 - c[0] * w2)
        M[k, 2] = -(Rf[k, 2, 0] * ms[0] + Rf[k, 2, 1] * ms[1] + Rf[k, 2, 2] * ms[2]) - (c[0] * w1 - c[1] * w0)
        out[k] = F[k, 2]
    support = 1 if out[1] > out[0] else 0
    ground = tf[2 + support, 2]
    # ZMP: moments of the loaded feet about (0, 0, ground), p = o + n x M_o / (n . F) with n = +z
    fn = mx = my = 0.0
    loaded = False
    for k in range(2):
        if F[k, 2] >= min_normal_force:
            rx, ry, rz = tf[k, 0], tf[k, 1], tf[k, 2] - ground
            fn += F[k, 2]
            mx += M[k, 0] + (ry * F[k, 2] - rz * F[k, 1])
            my += M[k, 1] + (rz * F[k, 0] - rx * F[k, 2])
            loaded = True
    if loaded and fn > 0.0:
        out[2], out[3], out[4] = -my / fn, mx / fn, ground
    else:
        out[2] = out[3] = out[4] = np.nan
    total = msub[0]
    cx, cy, cz = csub[0, 0] / total, csub[0, 1] / total, csub[0, 2] / total
    if anchor:
        # each loaded foot moved to where the model has it, weighted by its normal force
        j = memo_joint_placements(q_model, kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work,
                                  joints_placing(frame_parents[2:]))  # the model's soles only
        frame_placements(memo_R[j], memo_t[j], frame_parents[2:], R_frames[2:], t_frames[2:], Rf[4:], tf[4:])
        cx, cy, cz = _anchor_on_feet(cx, cy, cz, out, Rf, tf, w, min_normal_force, support)
    out[5], out[6], out[7] = cx, cy, cz
    if state[0] == 0.0:
        state[4] = state[5] = state[6] = 0.0
    else:
        for a in range(3):
            raw = (out[5 + a] - state[1 + a]) / dt
            state[4 + a] = state[4 + a] + alpha * (raw - state[4 + a])
    state[0] = 1.0
    for a in range(3):
        state[1 + a] = out[5 + a]
        out[8 + a] = state[4 + a]
    return support


@njit(inline=True)
def _anchor_on_feet(cx, cy, cz, out, Rf, tf, w, min_normal_force, support):
    """`_balance_step`'s anchoring: the CoM (cx, cy, cz) of the measured configuration with each loaded foot
    moved to where the model has it (the soles' placements ``Rf``, ``tf``: rows 2, 3 measured, 4, 5 the model's),
    averaged with the normal forces ``out[:2]`` as weights (into the scratch ``w``; none loaded: the support
    foot's alone; as `BalanceEstimator._anchored`). Inlined: its compiled callers are all reassociating (not
    `exact`), as it is."""
    w[0] = w[1] = 0.0
    for k in range(2):
        if out[k] > min_normal_force:
            w[k] = out[k]
    wsum = w[0] + w[1]
    if wsum <= 0.0:
        w[:] = 0.0
        w[support] = 1.0
        wsum = 1.0
    ax = ay = az = 0.0
    for k in range(2):
        if w[k] <= 0.0:
            continue
        # R_model R_meas^T (c - t_meas) + t_model
        d0, d1, d2 = cx - tf[2 + k, 0], cy - tf[2 + k, 1], cz - tf[2 + k, 2]
        l0 = Rf[2 + k, 0, 0] * d0 + Rf[2 + k, 1, 0] * d1 + Rf[2 + k, 2, 0] * d2
        l1 = Rf[2 + k, 0, 1] * d0 + Rf[2 + k, 1, 1] * d1 + Rf[2 + k, 2, 1] * d2
        l2 = Rf[2 + k, 0, 2] * d0 + Rf[2 + k, 1, 2] * d1 + Rf[2 + k, 2, 2] * d2
        s = w[k] / wsum
        ax += s * (Rf[4 + k, 0, 0] * l0 + Rf[4 + k, 0, 1] * l1 + Rf[4 + k, 0, 2] * l2 + tf[4 + k, 0])
        ay += s * (Rf[4 + k, 1, 0] * l0 + Rf[4 + k, 1, 1] * l1 + Rf[4 + k, 1, 2] * l2 + tf[4 + k, 1])
        az += s * (Rf[4 + k, 2, 0] * l0 + Rf[4 + k, 2, 1] * l1 + Rf[4 + k, 2, 2] * l2 + tf[4 + k, 2])
    return ax, ay, az


balance_step = _balance_step
"""`BalanceEstimator`'s compiled update, for a kernel of another package that runs it with more (the balance
stabilizer's estimate and DCM step in one call); its arguments are those of `_balance_step`, the estimator's
`_step_args` after the measurement's and the anchor's, then its state and output."""
