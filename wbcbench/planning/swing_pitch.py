"""A swing-foot pitch that follows the leg: the plan's offer of a swing in which the foot's pitch is shaped so
that the swing ankle's pitch joint accelerates less than it must to hold the foot at its planned orientation.

Why: with the leaving foot unloaded, a swing ankle's torque is mostly its rotor's (TALOS carries an armature on
every actuated joint), I_rotor q_a_ddot. In the sagittal plane the ankle pitch is q_a = theta_foot - theta_shank,
so holding the foot level makes the ankle take every acceleration of the shank, which swings through about a
radian while the pelvis moves on. A foot that pitches a little with the shank (toe down after lift-off, up
before touch-down, as a human's) takes part of it.

The shank's pitch over a swing is predicted from the plan: the hip follows the CoM plan at its offset from the
CoM at the start (turned with the walk's heading), the ankle the sole plan at its offset in the sole frame, and
a two-link leg (thigh and shank lengths of the model) in the foot's sagittal plane gives the shank. The pitch
offset about the sole's lateral axis,

    delta(s) = s^3 (1 - s)^3 sum_k c_k P_k(2 s - 1),   s = (t - t_lift-off) / T_swing,

(P_k Legendre polynomials; zero value, rate and acceleration at lift-off and touch-down: the foot leaves and
lands at its planned orientation, at rest) minimises

    int (q_a_ddot)^2 dt,   q_a_ddot = theta_foot_ddot - theta_shank_ddot + delta_ddot,

(a small QP) with |delta| <= max_pitch and the sole's lower end (toe or heel, at the sole's half length plus
its centre offset) above the lower end of the swing (to 0.1 mm). It is an offer: a controller whose
task set asks for it (`swing_foot.pitch_with_leg`) adds it to the planned orientation; the others ignore it.

A walk's toe-off (`SwingPitchConfig.toe_off`, `toe_off_offsets`) plans instead one pitch about the sole's toe edge
from a roll before the lift-off (the foot on the ground, heel up) to the touch-down, minimising the predicted ankle
torque; the swing's planned positions then carry that turn (`about_edge_offset`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as _legendre

from ..errors import PlanningError
from ..qp.problem import QPProblem
from ..qp.registry import make_solver
from ..side import Side
from ..types import GRAVITY
from .swing import quintic_from_state

__all__ = ["LegGeometry", "SwingPitchConfig", "swing_pitch_offsets", "plan_swing_pitch"]


@dataclass(frozen=True)
class LegGeometry:
    """What the prediction of a swing shank needs of a robot, per side.

    Attributes:
        hip_offset: side -> (3,) hip (the leg's root joint) relative to the CoM at the start, in the walking frame [m].
        ankle_in_sole: side -> (3,) ankle joint in the sole frame [m].
        thigh, shank: side -> lengths hip-knee and knee-ankle [m].
        lever: distance from the sole origin to its farther end along the foot [m] (toe or heel clearance).
        toe: x of the sole's front edge in the sole frame [m]; sole_length: the sole's length [m] (a toe-off).
        foot_mass [kg], foot_com (side -> (3,) in the sole frame [m]), foot_inertia [kg m^2]: the bodies the ankle
            pitch joint carries (its own and the ankle roll's, the roll at zero), their CoM and inertia about the
            lateral axis through it; armature: the ankle pitch joint's rotor inertia [kg m^2] (a toe-off's plan
            minimises the ankle's torque with them: `toe_off_offsets`).
    """

    hip_offset: Mapping
    ankle_in_sole: Mapping
    thigh: Mapping
    shank: Mapping
    lever: float
    toe: float = 0.0
    sole_length: float = 0.0
    foot_mass: float = 0.0
    foot_com: Mapping | None = None
    foot_inertia: float = 0.0
    armature: float = 0.0

    @classmethod
    def from_robot(cls, robot, q0: np.ndarray, com0: np.ndarray, yaw0: float = 0.0) -> "LegGeometry":
        """From the model at the initial configuration q0 (CoM com0, walking heading yaw0 [rad]): the ankle is the
        sole frame's parent joint, the knee the first joint up the chain at least 0.1 m from it, the hip the leg's
        root (the joint on the floating base)."""
        import pinocchio as pin

        model = robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, q0)
        c, s = np.cos(yaw0), np.sin(yaw0)
        Rz_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        hip, ankle, thigh, shank, fcom = {}, {}, {}, {}, {}
        fmass = finertia = arm = 0.0
        for side in Side:
            fid = robot.sole_frame_id(side)
            M = data.oMf[fid]
            j = model.frames[fid].parentJoint
            chain = [j]
            while model.parents[chain[-1]] > 1:  # up to the leg's root (its parent: the floating base)
                chain.append(model.parents[chain[-1]])
            pos = [data.oMi[k].translation for k in chain]
            knee = next((k for k in range(1, len(chain) - 1) if np.linalg.norm(pos[k] - pos[0]) >= 0.1), None)
            if knee is None:
                raise PlanningError(f"swing pitch: no ankle-knee-hip chain above the {side.value} sole")
            a, kn, h = pos[0], pos[knee], pos[-1]
            # the bodies the ankle pitch joint carries (the joint above the sole's: its own and the sole's body)
            bodies = chain[:2] if len(chain) > 2 else chain[:1]
            m_tot, c_w, I_yy = 0.0, np.zeros(3), 0.0
            for k in bodies:
                Y = model.inertias[k]
                m_tot += Y.mass
                c_w += Y.mass * data.oMi[k].act(Y.lever)
            c_w /= max(m_tot, 1e-12)
            y = M.rotation[:, 1]
            for k in bodies:
                Y = model.inertias[k]
                R = data.oMi[k].rotation
                r = data.oMi[k].act(Y.lever) - c_w
                I_yy += float(y @ R @ Y.inertia @ R.T @ y) + Y.mass * float(r @ r - (r @ y) ** 2)
            fmass, finertia = m_tot, I_yy
            fcom[side] = M.rotation.T @ (c_w - M.translation)
            arm = float(model.armature[model.joints[bodies[-1]].idx_v]) if hasattr(model, "armature") else 0.0
            hip[side] = Rz_t @ (h - com0)
            ankle[side] = M.rotation.T @ (a - M.translation)
            thigh[side] = float(np.linalg.norm(kn - h))
            shank[side] = float(np.linalg.norm(a - kn))
        sole = robot.profile.sole
        return cls(hip, ankle, thigh, shank, float(sole.length / 2 + abs(sole.center[0])),
                   float(sole.center[0] + sole.length / 2), float(sole.length), fmass, fcom, finertia, arm)


@dataclass(frozen=True)
class SwingPitchConfig:
    """max_pitch: bound of |delta| [rad]; clearance: the height [m] the sole's lower end keeps above the swing's
    lower end wherever the foot pitches (none below it); n_basis: polynomials P_0 .. P_{n-1}; toe_off [s]: the
    longest roll of a leaving foot about its toe before its lift-off (0: none; `toe_off_offsets`)."""

    max_pitch: float = 0.3
    clearance: float = 0.005
    n_basis: int = 8
    toe_off: float = 0.0

    def __post_init__(self):
        if not np.isfinite(self.max_pitch) or self.max_pitch < 0.0:
            raise PlanningError(f"SwingPitchConfig.max_pitch must be >= 0 [rad], got {self.max_pitch!r}")
        if not np.isfinite(self.clearance) or self.clearance < 0.0:
            raise PlanningError(f"SwingPitchConfig.clearance must be >= 0 [m], got {self.clearance!r}")
        if not np.isfinite(self.toe_off) or self.toe_off < 0.0:
            raise PlanningError(f"SwingPitchConfig.toe_off must be >= 0 [s], got {self.toe_off!r}")
        if int(self.n_basis) != self.n_basis or self.n_basis < 1:
            raise PlanningError(f"SwingPitchConfig.n_basis must be a positive integer, got {self.n_basis!r}")


_SOLVER = make_solver("daqp")


def _basis(n_basis: int) -> tuple[list, list]:
    """The basis polynomials in s and their second derivatives."""
    w = Polynomial([0.0, 0.0, 0.0, 1.0]) * Polynomial([1.0, -1.0]) ** 3  # s^3 (1 - s)^3
    out = []
    for k in range(n_basis):
        coef = np.zeros(k + 1)
        coef[k] = 1.0
        pk = Polynomial(_legendre.leg2poly(coef))(Polynomial([-1.0, 2.0]))  # P_k(2 s - 1)
        out.append(w * pk)
    return out, [p.deriv(1) for p in out], [p.deriv(2) for p in out]


def _pitch(R: np.ndarray) -> np.ndarray:
    """Pitch of rotations (n, 3, 3) about their own lateral axis: the angle of the x axis below the horizontal."""
    x = R[:, :, 0]
    return np.arctan2(-x[:, 2], np.hypot(x[:, 0], x[:, 1]))


def swing_pitch_offsets(t: np.ndarray, p_world_com: np.ndarray, yaw: np.ndarray, p_world_sole: np.ndarray,
                        R_world_sole: np.ndarray, side: Side, legs: LegGeometry,
                        config: SwingPitchConfig = SwingPitchConfig()) -> tuple[np.ndarray, np.ndarray]:
    """One swing: the offset (n, 3) [delta, delta_dot, delta_ddot] [rad, rad/s, rad/s^2] at the times t (lift-off
    first, touch-down last), and the predicted ankle pitch acceleration without it (n,) [rad/s^2].

    p_world_com (n, 3), yaw (n,) the walk's CoM and heading; p_world_sole (n, 3), R_world_sole (n, 3, 3) the
    planned sole."""
    n = len(t)
    T = float(t[-1] - t[0])
    if n < 8 or T <= 0.0:
        z = np.zeros((n, 3))
        return z, np.zeros(n)
    ankle = p_world_sole + R_world_sole @ legs.ankle_in_sole[side]
    q_ankle = _ankle_pitch(p_world_com, yaw, ankle, R_world_sole, side, legs, _pitch(R_world_sole))
    dt = T / (n - 1)
    acc = np.gradient(np.gradient(q_ankle, dt), dt)
    # the foot pitches while its sole is `clearance` above the swing's lower end, |delta| bounded by max_pitch and
    # by the room of the sole's lower end (toe or heel) above that height
    z_low = min(p_world_sole[0, 2], p_world_sole[-1, 2])
    room = (p_world_sole[:, 2] - z_low - config.clearance) / legs.lever
    inside = np.flatnonzero(room > 0.0)
    out = np.zeros((n, 3))
    if len(inside) < 8 or config.max_pitch == 0.0:
        return out, acc
    i0, i1 = inside[0] - 1, inside[-1] + 1  # the pitch window [t[i0], t[i1]]: delta = 0 at both ends, at rest
    w = slice(i0, i1 + 1)
    Tw = float(t[i1] - t[i0])
    s = (t[w] - t[i0]) / Tw
    P, dP, ddP = _basis(config.n_basis)
    B = np.column_stack([p(s) for p in P])
    B1 = np.column_stack([p(s) for p in dP]) / Tw
    B2 = np.column_stack([p(s) for p in ddP]) / Tw**2
    bound = np.minimum(config.max_pitch, np.arcsin(np.clip(room[w], 0.0, 1.0)))
    # min ||acc + B2 c||^2 dt over the window (+ a small ridge), |B c| <= bound on every tick inside it
    H = dt * (B2.T @ B2) + 1e-9 * np.eye(len(P))
    g = dt * (B2.T @ acc[w])
    rows = slice(1, len(s) - 1)
    res = _SOLVER.solve(QPProblem(H, g, C=B[rows], l=-bound[rows], u=bound[rows]))
    if not res.ok:
        return out, acc
    coef = res.x
    out[w] = np.column_stack([B @ coef, B1 @ coef, B2 @ coef])
    return out, acc


def plan_swing_pitch(walk, legs: LegGeometry, config: SwingPitchConfig = SwingPitchConfig(),
                     previous: tuple[int, Mapping] | None = None) -> dict:
    """Per side, (n_ticks, 3) [delta, delta_dot, delta_ddot] over the walk (`WalkTrajectory`): each swing's
    `swing_pitch_offsets`, zero in contact. The heading is the mean yaw of the two planned soles.

    previous: (tick, offsets) when `walk` replaces another from that tick on (an online re-plan, e.g. step
    adjustment): the swing under way at the tick keeps the previous offsets up to it and goes from their state
    there back to level and at rest by its touch-down (a quintic, no jump in the reference); no other swing
    pitches (measured: pitching the re-planned steps lowered the largest push TSID torque survives with step
    adjustment, forwards 75 -> 67.5 and backwards 67.5 -> 60 N s)."""
    n = walk.n_ticks
    dt = walk.dt
    yaws = np.unwrap(np.stack([np.arctan2(walk.feet[s].R_world_sole[:n, 1, 0], walk.feet[s].R_world_sole[:n, 0, 0])
                               for s in Side]), axis=1)
    yaw = yaws.mean(axis=0)
    toe_off = config.toe_off > 0.0 and legs.sole_length > 0.0
    out = {}
    for side in Side:
        f = walk.feet[side]
        air = ~np.asarray(f.in_contact[:n], dtype=bool)
        offs = np.zeros((n, 4 if toe_off else 3))
        edges = np.flatnonzero(np.diff(np.concatenate([[0], air.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            # the swing from the last tick in contact to the first tick back in contact
            lo, hi = max(a - 1, 0), min(b, n - 1)
            sl = slice(lo, hi + 1)
            if previous is not None:
                k, old = previous[0], previous[1].get(side)
                if old is not None and lo < k <= hi and k < len(old):
                    offs[lo:k] = old[lo:k]
                    if hi > k:
                        offs[k:hi + 1, :3] = np.hstack(quintic_from_state(*old[k, :3], 0.0, (hi - k) * dt,
                                                                          np.arange(hi + 1 - k) * dt))
                continue
            if toe_off:
                r0 = _roll_start(walk, side, lo, int(round(config.toe_off / dt)), legs.toe)
                if hi - r0 >= 8:
                    sl = slice(r0, hi + 1)
                    t = np.arange(r0, hi + 1) * dt
                    d, _ = toe_off_offsets(t, walk.p_world_com[sl], yaw[sl], f.p_world_sole[sl], f.R_world_sole[sl],
                                           side, legs, legs.toe, legs.sole_length, config, n_roll=lo + 1 - r0)
                    offs[sl, :3] = d
                    offs[r0:hi, 3] = legs.toe  # the pivot, up to the touch-down (then the whole sole again)
                continue
            t = np.arange(lo, hi + 1) * dt
            d, _ = swing_pitch_offsets(t, walk.p_world_com[sl], yaw[sl], f.p_world_sole[sl], f.R_world_sole[sl],
                                       side, legs, config)
            offs[sl] = d
        out[side] = offs
    return out


def _roll_start(walk, side: Side, lo: int, n_roll: int, toe_x: float) -> int:
    """The tick a toe-off before the lift-off after tick `lo` (the foot's last tick in contact) starts: `n_roll`
    ticks before it, but not before the double support began (the other foot's touch-down) nor before the planned
    ZMP has passed the foot's toe edge (the foot on its toe can no longer hold the ZMP behind it)."""
    f = walk.feet[side]
    other = walk.feet[Side.RIGHT if side is Side.LEFT else Side.LEFT]
    k = lo
    start = max(lo - n_roll, 0)
    in_other = np.asarray(other.in_contact, dtype=bool)
    while k > start and in_other[k - 1]:
        k -= 1
    # k: the first tick of the double support (or `start`); then the first tick with the ZMP ahead of the toe
    toe = f.p_world_sole[lo] + f.R_world_sole[lo] @ np.array([toe_x, 0.0, 0.0])
    fwd = f.R_world_sole[lo][:, 0]
    ahead = (walk.p_world_zmp_ref[k:lo + 1] - toe) @ fwd >= 0.0
    return k + int(np.argmax(ahead)) if ahead.any() else lo


#: knot spacing [s] of the toe-off's pitch (quintic B-splines): a roll of a tenth of a second is a few of them
_KNOT_SPACING = 0.04


def _spline_basis(t: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic B-splines on uniform knots over [0, T] (at most `_KNOT_SPACING` apart), without the three at each
    end: every combination is zero with its rate and acceleration at both ends. Values, first and second
    derivatives at t (n,) -> three (n, m)."""
    from scipy.interpolate import BSpline

    k = 5
    m = max(1, int(np.ceil(T / _KNOT_SPACING)))
    knots = np.concatenate([np.zeros(k), np.linspace(0.0, T, m + 1), np.full(k, T)])
    nb = len(knots) - k - 1
    cols = range(3, nb - 3)
    out = []
    for nu in (0, 1, 2):
        M = np.empty((len(t), len(cols)))
        for j, i in enumerate(cols):
            c = np.zeros(nb)
            c[i] = 1.0
            spl = BSpline(knots, c, k, extrapolate=False)
            M[:, j] = np.nan_to_num(spl.derivative(nu)(t) if nu else spl(t))
        out.append(M)
    return out[0], out[1], out[2]


def _ankle_pitch(p_world_com, yaw, ankle, R_world_sole, side, legs, pitch_foot):
    """The predicted ankle pitch (n,) [rad]: foot pitch `pitch_foot` minus the shank's (the two-link leg from the
    hip, at its start offset from the CoM, to `ankle` (n, 3); the shank's pitch is -(psi - beta))."""
    n = len(yaw)
    c, s_ = np.cos(yaw), np.sin(yaw)
    h = legs.hip_offset[side]
    hip = p_world_com + np.column_stack([c * h[0] - s_ * h[1], s_ * h[0] + c * h[1], np.full(n, h[2])])
    fwd = R_world_sole[:, :, 0].copy()
    fwd[:, 2] = 0.0
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    d = ankle - hip
    dx, dz = np.einsum("ij,ij->i", d, fwd), d[:, 2]
    l1, l2 = legs.thigh[side], legs.shank[side]
    r = np.clip(np.hypot(dx, dz), abs(l1 - l2) + 1e-6, l1 + l2 - 1e-6)
    psi = np.arctan2(dx, -dz)
    beta = np.arccos(np.clip((l2 * l2 + r * r - l1 * l1) / (2.0 * l2 * r), -1.0, 1.0))
    return pitch_foot + (psi - beta)


def _turned(R_world_sole: np.ndarray, delta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A point v (3,) of the sole frame, relative to the pivot edge, turned by delta (n,) about the sole's lateral
    axis, in world axes (n, 3) (the planned rotations R_world_sole (n, 3, 3))."""
    c, s_ = np.cos(delta), np.sin(delta)
    local = np.column_stack([c * v[0] + s_ * v[2], np.full(len(delta), v[1]), -s_ * v[0] + c * v[2]])
    return np.einsum("nij,nj->ni", R_world_sole, local)


def toe_off_offsets(t: np.ndarray, p_world_com: np.ndarray, yaw: np.ndarray, p_world_sole: np.ndarray,
                    R_world_sole: np.ndarray, side: Side, legs: LegGeometry, toe_x: float, length: float,
                    config: SwingPitchConfig = SwingPitchConfig(), iterations: int = 3, n_roll: int = 0,
                    roll_weight: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A swing that starts with a toe-off: the pitch delta about the sole's front edge (x = toe_x [m] in the sole
    frame; delta > 0 lifts the heel) from the first time of `t` (the foot flat and at rest on the ground, its
    roll about the toe starting) to the last (touch-down, flat and at rest), that minimises the predicted ankle
    pitch torque over the whole window (`_toe_off_by_torque`: the rotor's and the foot's own, when `legs` has the
    foot's inertia; otherwise the ankle's acceleration): the foot leaves the ground already turned with its shank.

    delta is a sum of quintic B-splines on knots `_KNOT_SPACING` apart, zero with its rate and acceleration at
    both ends (a roll of a tenth of a second takes a few knots); delta <= max_pitch, and the heel (`length`
    [m] behind the toe) `clearance` above the swing's lower end or delta >= 0 while the sole is lower (on the
    ground: the foot turns about its toe only heel up). The first `n_roll` ticks (the roll, the foot on the
    ground) weigh `roll_weight` in the sum. The ankle moves with the turn (about the toe), so the
    prediction of the shank is iterated `iterations` times from delta = 0. Returns (n, 3) [delta, delta_dot,
    delta_ddot] and the predicted ankle pitch acceleration (n,) [rad/s^2] of the flat foot."""
    n = len(t)
    T = float(t[-1] - t[0])
    out = np.zeros((n, 3))
    if n < 8 or T <= 0.0:
        return out, np.zeros(n)
    dt = T / (n - 1)
    pe = np.array([toe_x, 0.0, 0.0])
    toe = p_world_sole + R_world_sole @ pe
    a_rel = legs.ankle_in_sole[side] - pe
    pitch0 = _pitch(R_world_sole)
    B, B1, B2 = _spline_basis(t - t[0], T)
    z_low = min(p_world_sole[0, 2], p_world_sole[-1, 2])
    room = (p_world_sole[:, 2] - z_low - config.clearance) / length
    lower = -np.arcsin(np.clip(room, 0.0, 1.0))
    upper = np.full(n, config.max_pitch)
    rows = slice(1, n - 1)
    wt = np.full(n, dt)
    wt[:n_roll] *= roll_weight  # the roll's ankle acceleration weighs less: the foot still carries (a little)
    if legs.foot_com is not None and legs.foot_mass > 0.0:  # minimise the ankle's torque, its rotor and its foot
        return _toe_off_by_torque(t, dt, p_world_com, yaw, toe, R_world_sole, side, legs, pe, pitch0, B, B1, B2, wt,
                                  lower, upper, rows, iterations)
    H = (B2.T * wt) @ B2 + 1e-9 * np.eye(B.shape[1])
    delta = np.zeros(n)
    acc_flat = None
    for _ in range(max(1, iterations)):
        ankle = toe + _turned(R_world_sole, delta, a_rel)
        q_a = _ankle_pitch(p_world_com, yaw, ankle, R_world_sole, side, legs, pitch0)  # without delta's own
        acc = np.gradient(np.gradient(q_a, dt), dt)
        if acc_flat is None:
            acc_flat = acc
        res = _SOLVER.solve(QPProblem(H, (B2.T * wt) @ acc, C=B[rows], l=lower[rows], u=upper[rows]))
        if not res.ok:
            return np.zeros((n, 3)), acc_flat
        delta = B @ res.x
    out[:] = np.column_stack([B @ res.x, B1 @ res.x, B2 @ res.x])
    return out, acc_flat


_GRAVITY = np.array([0.0, 0.0, -GRAVITY])


def _toe_off_by_torque(t, dt, p_world_com, yaw, toe, R_world_sole, side, legs, pe, pitch0, B, B1, B2, wt, lower,
                       upper, rows, iterations):
    """`toe_off_offsets` minimising the predicted ankle pitch torque, the rotor's (armature times the ankle's
    acceleration) and the foot's (the bodies below the joint: their inertia and weight, the acceleration of their
    CoM), by Gauss-Newton steps on the spline coefficients (the torque's Jacobian by finite differences)."""
    n = len(t)
    a_rel = legs.ankle_in_sole[side] - pe
    c_rel = legs.foot_com[side] - pe
    y = R_world_sole[:, :, 1]
    m, I_f, arm = legs.foot_mass, legs.foot_inertia, legs.armature

    def d2(x):
        return np.gradient(np.gradient(x, dt, axis=0), dt, axis=0)

    def torque(coef):
        delta = B @ coef
        ankle = toe + _turned(R_world_sole, delta, a_rel)
        com = toe + _turned(R_world_sole, delta, c_rel)
        q_a = _ankle_pitch(p_world_com, yaw, ankle, R_world_sole, side, legs, pitch0 + delta)
        f = m * (d2(com) - _GRAVITY)
        moment = np.einsum("ni,ni->n", np.cross(com - ankle, f), y)
        return arm * d2(q_a) + I_f * d2(pitch0 + delta) + moment

    sw = np.sqrt(wt)
    nc = B.shape[1]
    coef = np.zeros(nc)
    tau0 = torque(coef)
    flat = tau0.copy()
    h = 1e-4
    for _ in range(max(1, iterations) + 1):
        J = np.empty((n, nc))
        for j in range(nc):
            e = coef.copy()
            e[j] += h
            J[:, j] = (torque(e) - tau0) / h
        Jw = J * sw[:, None]
        H = Jw.T @ Jw + 1e-9 * np.eye(nc)
        g = Jw.T @ (sw * (tau0 - J @ coef))
        res = _SOLVER.solve(QPProblem(H, g, C=B[rows], l=lower[rows], u=upper[rows]))
        if not res.ok:
            break
        coef = res.x
        tau0 = torque(coef)
    out = np.column_stack([B @ coef, B1 @ coef, B2 @ coef])
    return out, flat


def about_edge_offset(R_world_sole: np.ndarray, pitch: np.ndarray, where: np.ndarray) -> tuple:
    """Where a sole turned by delta about its edge at x (`pitch` (n, 4) [delta, delta_dot, delta_ddot, x], the
    planned rotations R_world_sole (n, 3, 3) taken at rest) moves its origin, on the ticks `where` (n,) (zero
    elsewhere): the offset R (pe - R_y(delta) pe), pe = (x, 0, 0), and its first and second derivatives, three
    (n, 3) [m, m/s, m/s^2]."""
    d, rate, acc, x = pitch[:, 0], pitch[:, 1], pitch[:, 2], np.where(where, pitch[:, 3], 0.0)
    c, s = np.cos(d), np.sin(d)
    z = np.zeros_like(d)
    o = np.column_stack([x * (1.0 - c), z, x * s])
    do = np.column_stack([x * s * rate, z, x * c * rate])
    ddo = np.column_stack([x * (c * rate**2 + s * acc), z, x * (-s * rate**2 + c * acc)])
    R = R_world_sole
    return tuple(np.einsum("nij,nj->ni", R, w) for w in (o, do, ddo))
