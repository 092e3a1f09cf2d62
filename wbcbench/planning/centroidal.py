"""Centroidal trajectory on (possibly tilted, non-coplanar) contacts by one convex QP over a time grid.

Given a footstep plan (the contact poses and when each foot is on the ground), find the CoM trajectory and
the contact forces, dynamically consistent with

    m c_ddot = sum_i f_i + m g                        (g = (0, 0, -gravity))

and with every contact force inside its friction cone.

Discretisation. Knots at every contact change (lift-off, touch-down) and, within each phase, at most
`knot_dt` apart (integer numbers of ticks). Unknowns per knot j: the CoM c_j and its velocity v_j, and the
force at each corner of each contact rectangle active on both sides of the knot (3 components in the contact
frame). A contact active on one side of a knot only (a lift-off or touch-down knot) has zero force there: the
foot unloads (loads) linearly over the last (first) interval of its contact, so forces are continuous.
Between knots the corner forces are linear in time (first-order hold), hence so is the CoM acceleration
a(t) = sum f(t) / m + g, and the CoM is its exact double integral, a cubic per interval:

    v_{j+1} = v_j + h (a_j + a_{j+1}) / 2,      c_{j+1} = c_j + h v_j + h^2 (a_j / 3 + a_{j+1} / 6)

These are the QP's equality constraints; the per-tick resampling evaluates the same polynomials, so
m c_ddot(t) = sum f(t) + m g holds at every tick to rounding error, and every tick's forces, convex
combinations of two knots' forces in the same cone, stay inside it.

Friction: each corner force in the contact frame (t1, t2, n) satisfies |t1| <= mu' n and |t2| <= mu' n with
mu' = mu / sqrt(2): the pyramid inscribed in the cone ||t|| <= mu n, so the true cone holds (n >= 0 follows).
Corners are those of the sole rectangle shrunk by `cop_margin`, so each foot's centre of pressure stays that
far inside its sole. The contact wrench (force, and moment about the sole origin) is the sum of the corners'.

Angular momentum. The rate of angular momentum about the CoM, L_dot = sum_k (p_k - c) x f_k, is bilinear in
(c, f). It is not constrained to zero: the QP penalises (w_am) its first-order expansion about a fixed CoM
path c_bar and total force F_bar,

    L_dot ~ sum_k (p_k - c_bar) x f_k + F_bar x (c - c_bar)        (linear in the forces and the CoM)

The first solve takes c_bar = the CoM over the centroid of the loaded soles at the nominal height and
F_bar = m g e_z (static); each of the `am_iterations` re-solves (default 2) takes the previous solution.
What is neglected: the second-order term (c_bar - c) x (F - F_bar), reported as `am_linearization_error`
(metres of moment arm, i.e. divided by m g; about 1e-10 m after two re-solves on the scenarios of the tests);
the angular momentum L itself (not tracked, only its rate penalised; L is integrated from the true L_dot after
the solve and reported); the momentum of the swinging leg; and the whole-body kinematics beyond a crude bound
of the CoM height above each loaded sole (`max_com_height`). An optional trust-region term (w_trust, default
0) keeps c near c_bar.

Cost (each term summed over knots, times the knot spacing): CoM acceleration (w_acc), its rate (w_jerk), CoM
height against the nominal height above a smooth support height (w_height), the penalised L_dot (w_am), and
the corner forces (w_force, which spreads the load over the corners: each foot's centre of pressure is pulled
to its sole centre, away from the edges). Forces are scaled by m * gravity inside the QP.

Boundary conditions: at rest at the start (given CoM, zero velocity and acceleration) and at the end (zero
velocity and acceleration, CoM x-y over the midpoint of the final soles).

Solvers: "proxsuite" (proxsuite's sparse ProxQP, the default; a plan of ~15 s has ~4000 variables) or "daqp"
(dense, through `wbcbench.qp`, for short plans). After the solve the equalities and cone constraints are
re-checked on the solution; a failed or inaccurate solve raises `CentroidalPlanError`.

References for controllers: `CentroidalTrajectory` carries per tick the CoM, the contact wrenches, the ZMP of
the planned wrenches on the horizontal plane at the support height (force-weighted height of the loaded soles,
as the paper's metrics compute it from the ankle sensors), the ZMP the CoM motion implies with L_dot = 0, and
the DCM c + c_dot / omega with omega = sqrt(g / com_height) (paper Eq. 2). On horizontal coplanar contacts the
horizontal plane is the support surface; on tilted contacts each foot's own centre of pressure on its sole
plane is `ContactWrenchTrajectory.cop()`.
"""

from __future__ import annotations

import copyreg
import hashlib
import io
import os
import pickle
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

from ..errors import PlanningError
from ..types import GRAVITY
from .footsteps import Footstep, FootstepPlan
from .geometry import SoleRectangle, rotation_from_yaw, yaw_of
from .swing import SwingTrajectory, quintic_blend
from ..side import Side

__all__ = ["CentroidalPlanError", "CentroidalConfig", "LegReach", "CentroidalReport", "ContactWrenchTrajectory",
           "CentroidalTrajectory", "plan_centroidal"]


class CentroidalPlanError(ValueError):
    """The centroidal QP has no (accurate) solution: infeasible constraints or a failed solve."""


def _check_positive(name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and np.isfinite(value)
    ok = ok and (value >= 0.0 if allow_zero else value > 0.0)
    if not ok:
        raise PlanningError(f"CentroidalConfig.{name} must be {'>= 0' if allow_zero else 'positive'}, got {value!r}")


SOLVERS = ("proxsuite", "daqp")


@dataclass(frozen=True)
class LegReach:
    """Leg geometry for the centroidal plan's reach bound.

    The hip of side s is at c + Rz(yaw) hip_offset[s] (c the CoM, the pelvis upright, yaw the foot's), the ankle
    at p_sole + R_sole ankle_offset[s]; the bound keeps |hip - ankle| <= max_length. Being a ball, it is
    linearised per knot as an upper bound on c_z, with the horizontal hip-ankle distance taken from the CoM path
    of the previous solve (the same re-solves as the angular-momentum term).

    Attributes:
        hip_offset: per side, hip joint centre minus CoM in the robot's heading frame [m] (3,).
        ankle_offset: per side, ankle joint centre in the sole frame [m] (3,).
        max_length: largest hip-ankle distance allowed [m] (a fraction of thigh + shank).
        swing_max_length: largest hip-ankle distance of a swinging leg [m], at the swing's planned pose (the
            `swings` given to `plan_centroidal`); None: swinging legs are not bounded.

    `max_length` bounds the knots where a foot is on the ground (its lift-off and touch-down knots included).
    Bounding the first and last quarter of each swing at the lift-off / touch-down pose too was tried on the
    platforms: the planned CoM bobbed by 6 cm within each step (that pose is far more conservative than the rising
    foot) and IK fell. So a swinging foot may exceed `max_length`: with TALOS' 0.663 m bound, up to 0.681 m on the
    platforms and 0.691 m on the stairs (straight leg 0.705 m). Without `swing_max_length` the stairs' last step
    (onto the top tread next to the other foot: the swing rises 15 cm where the others rise 25) asked for 0.702 m
    0.24 s after lift-off, the CoM rising faster than the foot: the swing knee ran into its limit (0 rad) at
    3.4 rad/s and its stop put a 0.096 m ZMP x error on the stance foot. `swing_max_length` bounds each knot inside a
    swing at the swing's own planned pose, so the CoM rises with the foot.
    """

    hip_offset: Mapping[Side, np.ndarray]
    ankle_offset: Mapping[Side, np.ndarray]
    max_length: float
    swing_max_length: float | None = None

    def __post_init__(self) -> None:
        for name in ("hip_offset", "ankle_offset"):
            val = getattr(self, name)
            if set(val) != set(Side):
                raise PlanningError(f"LegReach.{name} needs both sides, got {sorted(map(str, val))}")
            fixed = {}
            for side, v in val.items():
                arr = np.asarray(v, dtype=float).ravel()
                if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                    raise PlanningError(f"LegReach.{name}[{side.value}] must be 3 finite numbers [m], got {v!r}")
                fixed[side] = arr
            object.__setattr__(self, name, MappingProxyType(fixed))
        _check_positive("leg_reach.max_length", self.max_length)
        if self.swing_max_length is not None:
            _check_positive("leg_reach.swing_max_length", self.swing_max_length)

    def ceiling(self, side: Side, R_sole: np.ndarray, p_sole: np.ndarray, p_xy_com: np.ndarray,
                max_length: float | None = None) -> float:
        """Highest CoM height [m] keeping that foot within reach (`max_length`, default the stance one), the CoM
        at p_xy_com horizontally."""
        length = self.max_length if max_length is None else max_length
        ankle = p_sole + R_sole @ self.ankle_offset[side]
        o = self.hip_offset[side]
        hip_xy = p_xy_com + (rotation_from_yaw(yaw_of(R_sole)) @ o)[:2]
        d2 = float(np.sum((hip_xy - ankle[:2]) ** 2))
        # beyond reach horizontally: no height helps; keep the bound finite (the hip at most at 30 % of the reach
        # above the ankle) so that the QP reports the plan as infeasible instead of silently ignoring it
        dz = np.sqrt(max(length**2 - d2, (0.3 * length) ** 2))
        return float(ankle[2] + dz - o[2])


@dataclass(frozen=True)
class CentroidalConfig:
    """Settings of the centroidal QP (SI units).

    Attributes:
        mass: robot mass [kg] (TALOS URDF: 90.27).
        com_height: nominal CoM height above the support [m] (TALOS half-sitting: about 0.87).
        gravity: [m/s^2].
        friction: Coulomb coefficient mu of the contacts (the pyramid uses mu / sqrt(2)).
        cop_margin: the force corners are the sole rectangle shrunk by this much on each side [m].
        max_com_height: upper bound of c_z above every loaded sole origin [m] (a crude leg-length bound);
            None: com_height + 0.08; inf: no bound.
        leg_reach: optional `LegReach` (the robot's hip and ankle geometry): bounds c_z so that each foot on
            the ground stays within reach of its hip with the pelvis upright. None: no such bound.
        knot_dt: largest knot spacing [s].
        dt: output tick period [s] (1 kHz).
        w_acc, w_jerk, w_height, w_am, w_force, w_trust: cost weights (see the module docstring), in the QP's
            scaled units (forces / (m g), metres, seconds).
        am_iterations: re-solves with the CoM path of the previous solution in the L_dot term (>= 0).
        solver: "proxsuite" (sparse) or "daqp" (dense).
        eps: stopping tolerance of proxsuite; also the accepted residual of the equalities (scaled units).
    """

    mass: float
    com_height: float = 0.87
    gravity: float = GRAVITY
    friction: float = 0.5
    cop_margin: float = 0.02
    max_com_height: float | None = None
    leg_reach: "LegReach | None" = None
    knot_dt: float = 0.1
    dt: float = 1e-3
    w_acc: float = 1e-2
    w_jerk: float = 1e-4
    w_height: float = 100.0
    w_am: float = 100.0
    w_force: float = 1.0
    w_trust: float = 0.0
    am_iterations: int = 2
    solver: str = "proxsuite"
    eps: float = 1e-8

    def __post_init__(self) -> None:
        for name in ("mass", "com_height", "gravity", "friction", "knot_dt", "dt", "eps"):
            _check_positive(name, getattr(self, name))
        for name in ("cop_margin", "w_acc", "w_jerk", "w_height", "w_am", "w_force", "w_trust"):
            _check_positive(name, getattr(self, name), allow_zero=True)
        if self.max_com_height is None:
            object.__setattr__(self, "max_com_height", self.com_height + 0.08)
        elif not (isinstance(self.max_com_height, (int, float, np.integer, np.floating))
                  and self.max_com_height > 0.0 and not np.isnan(self.max_com_height)):
            raise PlanningError(f"CentroidalConfig.max_com_height must be positive (inf: no bound), got "
                             f"{self.max_com_height!r}")
        if self.leg_reach is not None and not isinstance(self.leg_reach, LegReach):
            raise PlanningError(f"CentroidalConfig.leg_reach must be a LegReach or None, got {type(self.leg_reach).__name__}")
        if int(self.am_iterations) != self.am_iterations or self.am_iterations < 0:
            raise PlanningError(f"CentroidalConfig.am_iterations must be an integer >= 0, got {self.am_iterations!r}")
        if self.solver not in SOLVERS:
            raise PlanningError(f"CentroidalConfig.solver: unknown {self.solver!r}; allowed: {', '.join(SOLVERS)}")
        if self.knot_dt < self.dt:
            raise PlanningError("CentroidalConfig.knot_dt must be at least one tick (dt)")

    @property
    def omega(self) -> float:
        """sqrt(gravity / com_height) [1/s]."""
        return float(np.sqrt(self.gravity / self.com_height))


@dataclass(frozen=True)
class CentroidalReport:
    """How the QP went.

    Attributes:
        solver: backend name. solves: number of QP solves (1 + am_iterations).
        n_variables, n_eq, n_in: size of the QP. n_knots: knots.
        iterations: solver iterations of the last solve. solve_time: total wall time of the solves [s].
        max_equality_residual: largest residual of the dynamics/boundary equalities at the knots (scaled).
        max_cone_violation: largest violation of the friction-pyramid rows (>= 0 means violated) [N].
        am_linearization_error: max over knots of |(c_bar - c) x (F - F_bar)| / (m g) [m], the neglected
            second-order part of the L_dot term in the last solve.
    """

    solver: str
    solves: int
    n_variables: int
    n_eq: int
    n_in: int
    n_knots: int
    iterations: int
    solve_time: float
    max_equality_residual: float
    max_cone_violation: float
    am_linearization_error: float


def _freeze(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class ContactWrenchTrajectory:
    """One foot's planned contact, per tick (world frame).

    Attributes:
        side: the foot.
        in_contact: (n,) bool.
        corners: (n, 4, 3) world positions of the force corners [m] (the shrunk sole rectangle; last contact
            pose while in the air).
        normal: (n, 3) contact normal (the sole z axis).
        corner_forces: (n, 4, 3) forces on the foot at the corners [N], zero in the air.
        force: (n, 3) total force [N]. torque: (n, 3) moment about the sole origin [N m].
        p_world_sole: (n, 3) the sole origin the torque is taken about [m].
    """

    side: Side
    in_contact: np.ndarray
    corners: np.ndarray
    normal: np.ndarray
    corner_forces: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    p_world_sole: np.ndarray

    def __post_init__(self) -> None:
        for name in ("in_contact", "corners", "normal", "corner_forces", "force", "torque", "p_world_sole"):
            object.__setattr__(self, name, _freeze(getattr(self, name)))

    def cop(self, min_normal_force: float = 1e-6) -> np.ndarray:
        """Centre of pressure on the sole plane, (n, 3) [m]; NaN where the normal force is below the threshold."""
        fn = np.einsum("ni,ni->n", self.force, self.normal)
        moment = self.torque  # about the sole origin, which lies on the sole plane
        ok = fn > min_normal_force
        r = np.cross(self.normal, moment) / np.where(ok, fn, 1.0)[:, None]
        return np.where(ok[:, None], self.p_world_sole + r, np.nan)


@dataclass(frozen=True, eq=False)
class CentroidalTrajectory:
    """The planned centroidal motion, one row per tick (t = tick * dt), world frame.

    Attributes:
        dt: tick period [s]. mass [kg]. gravity [m/s^2]. friction: mu used. com_height: nominal [m].
        omega: sqrt(gravity / com_height) [1/s].
        p_world_com, v_world_com, a_world_com: (n, 3) [m], [m/s], [m/s^2].
        dL_world_com: (n, 3) rate of angular momentum about the CoM from the planned forces [N m].
        L_world_com: (n, 3) its integral from 0 (trapezoid) [kg m^2 / s].
        wrenches: Side -> ContactWrenchTrajectory.
        support_height: (n,) height of the horizontal ZMP plane: the mean height of the loaded sole origins
            weighted by their vertical force [m].
        p_world_zmp: (n, 3) ZMP of the planned contact wrenches on that plane [m].
        p_world_zmp_com: (n, 3) ZMP implied by the CoM motion if L_dot = 0:
            c_xy - (c_z - h) c_ddot_xy / (c_ddot_z + gravity) [m]; differs from p_world_zmp by L_dot.
        p_world_dcm: (n, 3) c + c_dot / omega [m].
        knot_ticks: (N + 1,) tick index of each knot.
        report: solver report.
    """

    dt: float
    mass: float
    gravity: float
    friction: float
    com_height: float
    omega: float
    p_world_com: np.ndarray
    v_world_com: np.ndarray
    a_world_com: np.ndarray
    dL_world_com: np.ndarray
    L_world_com: np.ndarray
    wrenches: Mapping[Side, ContactWrenchTrajectory]
    support_height: np.ndarray
    p_world_zmp: np.ndarray
    p_world_zmp_com: np.ndarray
    p_world_dcm: np.ndarray
    knot_ticks: np.ndarray
    report: CentroidalReport

    def __post_init__(self) -> None:
        for name in ("p_world_com", "v_world_com", "a_world_com", "dL_world_com", "L_world_com", "support_height",
                     "p_world_zmp", "p_world_zmp_com", "p_world_dcm", "knot_ticks"):
            object.__setattr__(self, name, _freeze(getattr(self, name)))
        object.__setattr__(self, "wrenches", MappingProxyType(dict(self.wrenches)))

    @property
    def n_ticks(self) -> int:
        return len(self.p_world_com)

    @property
    def t(self) -> np.ndarray:
        """Tick times, (n,) [s]."""
        return np.arange(self.n_ticks) * self.dt

    def total_force(self) -> np.ndarray:
        """Sum of the contact forces, (n, 3) [N]."""
        return sum(w.force for w in self.wrenches.values())


# ---- the contact schedule on the knot grid -------------------------------------------------------------------

def _tick(t: float, dt: float) -> int:
    return int(round(t / dt))


@dataclass(frozen=True, eq=False)
class _Contact:
    """One foot on the ground between two knots, at a fixed pose."""

    side: Side
    first: int   # first knot of the contact (its force is zero there unless it is knot 0)
    last: int    # last knot (zero force unless it is the last knot)
    R: np.ndarray
    p_sole: np.ndarray
    corners: np.ndarray  # (4, 3) world


def _schedule(plan: FootstepPlan, dt: float) -> tuple[int, dict[Side, np.ndarray], list[tuple[Side, int, int,
                                                                                                  Footstep]]]:
    """Number of ticks, in_contact per side, and the contacts (side, first tick, end tick, pose)."""
    n = _tick(plan.duration, dt) + 1
    contact = {s: np.ones(n, bool) for s in Side}
    spans: list[tuple[Side, int, int, Footstep]] = []
    start = {s: 0 for s in Side}
    pose = dict(plan.initial_feet)
    for i, step in enumerate(plan.steps):
        lo, td = _tick(plan.lift_off_time(i), dt), _tick(plan.touch_down_time(i), dt)
        if not 0 < lo < td < n - 1:
            raise PlanningError(f"step {i}: lift-off tick {lo} and touch-down tick {td} must satisfy 0 < lo < td < "
                             f"{n - 1} (durations shorter than a tick?)")
        contact[step.side][lo:td] = False
        spans.append((step.side, start[step.side], lo, pose[step.side]))
        start[step.side] = td
        pose[step.side] = step
    for s in Side:
        spans.append((s, start[s], n - 1, pose[s]))
    return n, contact, spans


def _knots(n: int, boundaries: list[int], knot_dt: float, dt: float) -> np.ndarray:
    ticks = [0]
    for a, b in zip(boundaries[:-1], boundaries[1:]):
        q = max(1, int(np.ceil((b - a) * dt / knot_dt - 1e-9)))
        ticks.extend(int(round(a + (b - a) * (k + 1) / q)) for k in range(q))
    return np.array(ticks)


def _support_reference(plan: FootstepPlan, n: int, dt: float) -> np.ndarray:
    """Smooth support height per tick [m]: the stance sole height at mid single support, the mean of the feet at
    both ends, quintic blends between these anchors."""
    feet0, feet1 = plan.initial_feet, plan.final_feet
    anchors = [(0, 0.5 * (feet0[Side.LEFT].p_world_sole[2] + feet0[Side.RIGHT].p_world_sole[2]))]
    for i in range(plan.n_steps):
        mid = 0.5 * (plan.lift_off_time(i) + plan.touch_down_time(i))
        anchors.append((_tick(mid, dt), float(plan.stance_foot(i).p_world_sole[2])))
    anchors.append((n - 1, 0.5 * (feet1[Side.LEFT].p_world_sole[2] + feet1[Side.RIGHT].p_world_sole[2])))
    z = np.empty(n)
    k = np.arange(n)
    for (ka, za), (kb, zb) in zip(anchors[:-1], anchors[1:]):
        seg = slice(ka, kb + 1)
        q, _, _ = quintic_blend((k[seg] - ka) / max(kb - ka, 1))
        z[seg] = za + (zb - za) * q
    return z


def _reach_caps(caps: list[list[float]], contacts: list["_Contact"], c_bar: np.ndarray,
                reach: LegReach, swing_knots: list[tuple[int, Side, np.ndarray, np.ndarray]] = ()
                ) -> list[list[float]]:
    """`caps` plus the leg-reach ceilings of each knot (see `LegReach`), the CoM xy taken from `c_bar`; the
    knots inside a swing (knot, side, sole position, sole rotation) with `reach.swing_max_length`."""
    out = [list(c) for c in caps]
    for ct in contacts:
        for j in range(ct.first, ct.last + 1):
            out[j].append(reach.ceiling(ct.side, ct.R, ct.p_sole, c_bar[j, :2]))
    for j, side, p, R in swing_knots:
        out[j].append(reach.ceiling(side, R, p, c_bar[j, :2], reach.swing_max_length))
    return out


# ---- the QP -----------------------------------------------------------------------------------------------

def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class _Layout:
    """Variable indices: per knot c (3), v (3); per (contact, knot) 12 corner-force components (local frame)."""

    def __init__(self, n_knots: int, contacts: list[_Contact]):
        self.n_knots = n_knots
        self.contacts = contacts
        self.c = np.arange(n_knots)[:, None] * 6 + np.arange(3)
        self.v = self.c + 3
        nxt = 6 * n_knots
        self.blocks: dict[int, list[tuple[int, int]]] = {j: [] for j in range(n_knots)}  # knot -> (contact, col0)
        for ci, ct in enumerate(contacts):
            lo = ct.first if ct.first == 0 else ct.first + 1
            hi = ct.last if ct.last == n_knots - 1 else ct.last - 1
            for j in range(lo, hi + 1):
                self.blocks[j].append((ci, nxt))
                nxt += 12
        self.n = nxt

    def force_rows(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Columns and coefficients of the scaled total force F_j = sum R f (3 rows, world)."""
        cols, coef = [], []
        for ci, col0 in self.blocks[j]:
            R = self.contacts[ci].R
            for k in range(4):
                cols.append(col0 + 3 * k + np.arange(3))
                coef.append(R)
        if not cols:
            return np.zeros((0,), int), np.zeros((3, 0))
        return np.concatenate(cols), np.hstack(coef)


class _Rows:
    """Accumulates sparse rows (coo) with right-hand sides."""

    def __init__(self, n: int):
        self.n = n
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.rhs: list[float] = []
        self.weights: list[float] = []

    def add(self, cols: np.ndarray, coefs: np.ndarray, rhs: float, weight: float = 1.0) -> None:
        i = len(self.rhs)
        cols = np.asarray(cols, int).ravel()
        self.r.append(np.full(len(cols), i))
        self.c.append(cols)
        self.v.append(np.asarray(coefs, float).ravel())
        self.rhs.append(float(rhs))
        self.weights.append(float(weight))

    def add_block(self, cols: np.ndarray, M: np.ndarray, rhs: np.ndarray, weight: float = 1.0) -> None:
        for row, b in zip(np.atleast_2d(M), np.atleast_1d(rhs)):
            self.add(cols, row, b, weight)

    def matrix(self) -> sp.csc_matrix:
        m = len(self.rhs)
        if m == 0:
            return sp.csc_matrix((0, self.n))
        return sp.csc_matrix((np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))),
                             shape=(m, self.n))

    @property
    def b(self) -> np.ndarray:
        return np.array(self.rhs)


def _build(lay: _Layout, h: np.ndarray, c_init: np.ndarray, c_final_xy: np.ndarray, z_ref: np.ndarray,
           c_bar: np.ndarray, F_bar: np.ndarray, caps: list[list[float]], cfg: CentroidalConfig, mu_lin: float
           ) -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix, np.ndarray, sp.csc_matrix, np.ndarray, np.ndarray]:
    """H, g, A, b, C, l, u in scaled units (forces / (m g))."""
    g0 = cfg.gravity
    N = lay.n_knots - 1
    ez = np.array([0.0, 0.0, 1.0])
    eq = _Rows(lay.n)
    I3 = np.eye(3)
    F = [lay.force_rows(j) for j in range(N + 1)]
    for j in range(N):
        hj = h[j]
        (cf0, Mf0), (cf1, Mf1) = F[j], F[j + 1]
        # v_{j+1} - v_j - h g (F_j + F_{j+1}) / 2 = -h g e_z
        cols = np.concatenate([lay.v[j + 1], lay.v[j], cf0, cf1])
        M = np.hstack([I3, -I3, -0.5 * hj * g0 * Mf0, -0.5 * hj * g0 * Mf1])
        eq.add_block(cols, M, -hj * g0 * ez)
        # c_{j+1} - c_j - h v_j - h^2 g (F_j / 3 + F_{j+1} / 6) = -h^2 g e_z / 2
        cols = np.concatenate([lay.c[j + 1], lay.c[j], lay.v[j], cf0, cf1])
        M = np.hstack([I3, -I3, -hj * I3, -hj * hj * g0 / 3.0 * Mf0, -hj * hj * g0 / 6.0 * Mf1])
        eq.add_block(cols, M, -0.5 * hj * hj * g0 * ez)
    eq.add_block(lay.c[0], I3, c_init)
    eq.add_block(lay.v[0], I3, np.zeros(3))
    eq.add_block(F[0][0], F[0][1], ez)
    eq.add_block(lay.v[N], I3, np.zeros(3))
    eq.add_block(F[N][0], F[N][1], ez)
    eq.add_block(lay.c[N][:2], I3[:2, :2], c_final_xy)

    ineq = _Rows(lay.n)
    lower: list[float] = []
    pyramid = np.array([[1.0, 0.0, -mu_lin], [-1.0, 0.0, -mu_lin], [0.0, 1.0, -mu_lin], [0.0, -1.0, -mu_lin]])
    for j in range(N + 1):
        for ci, col0 in lay.blocks[j]:
            for k in range(4):
                ineq.add_block(col0 + 3 * k + np.arange(3), pyramid, np.zeros(4))
                lower.extend([-np.inf] * 4)
        for z in caps[j]:   # CoM height ceilings (max_com_height, leg reach)
            ineq.add(lay.c[j][2:], [1.0], z)
            lower.append(-np.inf)

    cost = _Rows(lay.n)
    w_knot = np.empty(N + 1)
    w_knot[1:-1] = 0.5 * (h[:-1] + h[1:])
    w_knot[0], w_knot[-1] = 0.5 * h[0], 0.5 * h[-1]
    for j in range(N + 1):
        cf, Mf = F[j]
        wj = w_knot[j]
        if len(cf) and cfg.w_acc > 0.0:   # a_j = g (F_j - e_z)
            cost.add_block(cf, g0 * Mf, g0 * ez, cfg.w_acc * wj)
        cost.add(lay.c[j][2:], [1.0], z_ref[j], cfg.w_height * wj)
        if len(cf) and cfg.w_am > 0.0:
            # L_dot_j = sum (p_k - c_j) x f_k ~ sum (p_k - c_bar_j) x R f_k + F_bar_j x (c_j - c_bar_j)
            cols, coefs = [lay.c[j]], [_skew(F_bar[j])]
            for ci, col0 in lay.blocks[j]:
                ct = lay.contacts[ci]
                for k in range(4):
                    cols.append(col0 + 3 * k + np.arange(3))
                    coefs.append(_skew(ct.corners[k] - c_bar[j]) @ ct.R)
            cost.add_block(np.concatenate(cols), np.hstack(coefs), _skew(F_bar[j]) @ c_bar[j], cfg.w_am * wj)
        if cfg.w_trust > 0.0:
            cost.add_block(lay.c[j], np.eye(3), c_bar[j], cfg.w_trust * wj)
        if cfg.w_force > 0.0:
            for ci, col0 in lay.blocks[j]:
                for r in range(12):
                    cost.add([col0 + r], [1.0], 0.0, cfg.w_force * wj)
        if j < N and cfg.w_jerk > 0.0:    # (a_{j+1} - a_j) / h
            (cf0, Mf0), (cf1, Mf1) = F[j], F[j + 1]
            cols = np.concatenate([cf1, cf0])
            M = np.hstack([g0 * Mf1, -g0 * Mf0]) / h[j]
            if len(cols):
                cost.add_block(cols, M, np.zeros(3), cfg.w_jerk * h[j])
    J = cost.matrix()
    W = sp.diags(np.array(cost.weights))
    H = (2.0 * (J.T @ W @ J)).tocsc()
    gvec = -2.0 * (J.T @ (W @ cost.b))
    C = ineq.matrix()
    return H, np.asarray(gvec).ravel(), eq.matrix(), eq.b, C, np.array(lower), ineq.b


def _solve(H, g, A, b, C, l, u, cfg: CentroidalConfig) -> tuple[np.ndarray, int, str]:
    if cfg.solver == "proxsuite":
        from proxsuite import proxqp

        qp = proxqp.sparse.QP(H.shape[0], A.shape[0], C.shape[0])
        qp.settings.eps_abs = cfg.eps
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = 20_000
        qp.settings.verbose = False
        # proxsuite's automatic choice is its matrix-free backend here, 20x slower than the sparse Cholesky one
        qp.settings.sparse_backend = proxqp.SparseBackend.SparseCholesky
        qp.init(H, g, A, b, C, l, u)
        qp.solve()
        status = qp.results.info.status
        if status != proxqp.PROXQP_SOLVED:
            raise CentroidalPlanError(f"centroidal QP: proxsuite ended with {status.name} after "
                                      f"{qp.results.info.iter} iterations (the contact plan admits no dynamically "
                                      "consistent CoM motion within the friction cones and bounds?)")
        return np.array(qp.results.x), int(qp.results.info.iter), "proxsuite"
    from ..qp import QPProblem, make_solver

    n = H.shape[0]
    if n > 4000:
        raise CentroidalPlanError(f"centroidal QP: {n} variables is too large for the dense daqp backend; use "
                                  "solver='proxsuite' or a larger knot_dt")
    # a tiny regularisation keeps H positive definite (the CoM and its velocity have no cost of their own)
    problem = QPProblem(H.toarray() + 1e-9 * np.eye(n), g, A.toarray(), b, C.toarray(), l, u)
    result = make_solver("daqp").solve(problem)
    if not result.ok:
        raise CentroidalPlanError(f"centroidal QP: daqp ended with status {result.status.value} (flag "
                                  f"{result.raw_status}); the contact plan admits no dynamically consistent CoM "
                                  "motion within the friction cones and bounds?")
    return result.unwrap(), result.iterations, "daqp"


def _contacts_on_knots(spans: list[tuple[Side, int, int, Footstep]], knot_ticks: np.ndarray, sole: SoleRectangle,
                       margin: float) -> list[_Contact]:
    shrunk = SoleRectangle(sole.length - 2.0 * margin, sole.width - 2.0 * margin, sole.center_x, sole.center_y)
    index = {int(t): j for j, t in enumerate(knot_ticks)}
    out = []
    for side, t0, t1, foot in spans:
        corners = foot.p_world_sole + shrunk.corners_in_sole() @ foot.R_world_sole.T
        out.append(_Contact(side, index[t0], index[t1], foot.R_world_sole.copy(), foot.p_world_sole.copy(),
                            corners))
    return out


#: environment variable naming a directory where `plan_centroidal` keeps the plans it made, shared by processes
#: (set by `reproduce` for its workers, in a directory of its own that lives as long as the command: the three
#: controllers of a scene start from the same state and need the same plan)
PLAN_CACHE_ENV = "WBCBENCH_PLAN_CACHE"
_MEMO: dict[str, bytes] = {}
#: pickling as the standard library does, and the read-only mappings of the planning types as dicts
_DISPATCH = copyreg.dispatch_table.copy()
_DISPATCH[MappingProxyType] = lambda m: (_read_only_mapping, (dict(m),))


def _read_only_mapping(d: dict) -> Mapping:
    return MappingProxyType(d)


def _pickled(obj) -> bytes:
    buf = io.BytesIO()
    pickler = pickle.Pickler(buf, protocol=5)
    pickler.dispatch_table = _DISPATCH
    pickler.dump(obj)
    return buf.getvalue()


def plan_centroidal(plan: FootstepPlan, config: CentroidalConfig, p_world_com_init: np.ndarray | None = None,
                    swings: Sequence[SwingTrajectory] | None = None) -> CentroidalTrajectory:
    """Plan the CoM and contact forces for a footstep plan (see the module docstring).

    The same inputs give the same plan: a plan made earlier in this process (the last few), or by another
    process in the directory named by ``WBCBENCH_PLAN_CACHE`` if set, is returned (a copy) instead of being
    solved again.

    Args:
        plan: feet poses (possibly tilted) and timing; each foot is a contact while on the ground.
        config: the QP settings, with the robot mass.
        p_world_com_init: the CoM at t = 0 (3,) [m]; default: over the midpoint of the initial sole centres,
            com_height above them. The plan starts at rest there.
        swings: the planned swing of each step (`SwingTrajectory`, in the order of plan.steps), for the
            leg-reach bound of swinging legs (`LegReach.swing_max_length`); None: swinging legs unbounded.

    Returns:
        CentroidalTrajectory with n = round(plan.duration / dt) + 1 ticks.

    Raises:
        ValueError: bad inputs (a sole shrunk by cop_margin to nothing, timing shorter than a tick).
        CentroidalPlanError: the QP is infeasible or its solution inaccurate.
    """
    if not isinstance(plan, FootstepPlan):
        raise PlanningError(f"plan must be a FootstepPlan, got {type(plan).__name__}")
    try:
        key = hashlib.sha256(_pickled((plan, config, None if p_world_com_init is None else
                                       np.asarray(p_world_com_init, float), swings))).hexdigest()
    except (pickle.PicklingError, TypeError, AttributeError):  # an input of the user's that does not pickle
        key = None
    if key is not None:
        cached = _cached_plan(key)
        if cached is not None:
            return cached
    out = _plan_centroidal(plan, config, p_world_com_init, swings)
    if key is not None:
        _keep_plan(key, out)
    return out


def _cached_plan(key: str) -> CentroidalTrajectory | None:
    """A copy of the plan made for `key` in this process or found in the shared directory; None if none."""
    data = _MEMO.get(key)
    if data is None:
        folder = os.environ.get(PLAN_CACHE_ENV)
        if not folder:
            return None
        try:
            data = (Path(folder) / f"{key}.pickle").read_bytes()
        except OSError:
            return None
    try:
        out = pickle.loads(data)
    except (pickle.UnpicklingError, EOFError, AttributeError, TypeError):
        return None
    _remember(key, data)
    return out


def _remember(key: str, data: bytes) -> None:
    if key not in _MEMO and len(_MEMO) >= 8:
        _MEMO.clear()
    _MEMO[key] = data


def _keep_plan(key: str, plan: CentroidalTrajectory) -> None:
    try:
        data = _pickled(plan)
    except (pickle.PicklingError, TypeError, AttributeError):
        return
    _remember(key, data)
    folder = os.environ.get(PLAN_CACHE_ENV)
    if folder:  # written whole, then renamed: another process reads the old state or the new file
        path = Path(folder) / f"{key}.pickle"
        try:
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_bytes(data)
            os.replace(tmp, path)
        except OSError:  # a cache: a full disk only costs the next process the solve
            pass


def _plan_centroidal(plan: FootstepPlan, config: CentroidalConfig, p_world_com_init: np.ndarray | None,
                     swings: Sequence[SwingTrajectory] | None) -> CentroidalTrajectory:
    cfg = config
    sole = plan.sole
    if min(sole.length, sole.width) <= 2.0 * cfg.cop_margin:
        raise PlanningError(f"CentroidalConfig.cop_margin {cfg.cop_margin} m leaves nothing of the "
                         f"{sole.length} x {sole.width} m sole")
    dt = cfg.dt
    n, in_contact, spans = _schedule(plan, dt)
    boundaries = sorted({0, n - 1, *(t for _, t0, t1, _ in spans for t in (t0, t1))})
    knot_ticks = _knots(n, boundaries, cfg.knot_dt, dt)
    N = len(knot_ticks) - 1
    h = np.diff(knot_ticks) * dt
    contacts = _contacts_on_knots(spans, knot_ticks, sole, cfg.cop_margin)
    lay = _Layout(N + 1, contacts)

    centers0 = [sole.center_in_world(f.p_world_sole, f.R_world_sole) for f in plan.initial_feet.values()]
    centers1 = [sole.center_in_world(f.p_world_sole, f.R_world_sole) for f in plan.final_feet.values()]
    support = _support_reference(plan, n, dt)
    z_ref = support[knot_ticks] + cfg.com_height
    if p_world_com_init is None:
        c_init = np.append(np.mean(centers0, axis=0)[:2], z_ref[0])
    else:
        c_init = np.asarray(p_world_com_init, float).ravel()
        if c_init.shape != (3,) or not np.all(np.isfinite(c_init)):
            raise PlanningError(f"p_world_com_init must be 3 finite numbers [m], got {p_world_com_init!r}")
    c_final_xy = np.mean(centers1, axis=0)[:2]

    # soles loaded around each knot (for the height bound) and the reference CoM path for the L_dot term
    sole_z: list[list[float]] = [[] for _ in range(N + 1)]
    c_bar = np.zeros((N + 1, 3))
    for j in range(N + 1):
        active = [ct for ct in contacts if ct.first <= j <= ct.last]
        loaded = [ct for ct in active if (ct.first < j or j == 0) and (j < ct.last or j == N)]
        sole_z[j] = ([float(ct.p_sole[2]) + cfg.max_com_height for ct in loaded]
                     if np.isfinite(cfg.max_com_height) else [])
        c_bar[j, :2] = np.mean([ct.corners.mean(axis=0)[:2] for ct in (loaded or active)], axis=0)
    c_bar[:, 2] = z_ref
    c_bar[0] = c_init
    swing_knots: list[tuple[int, Side, np.ndarray, np.ndarray]] = []
    if swings is not None and cfg.leg_reach is not None and cfg.leg_reach.swing_max_length is not None:
        if len(swings) != plan.n_steps:
            raise PlanningError(f"swings: one per step ({plan.n_steps}), got {len(swings)}")
        for i, (step, sw) in enumerate(zip(plan.steps, swings)):
            lo, td = _tick(plan.lift_off_time(i), dt), _tick(plan.touch_down_time(i), dt)
            for j in np.flatnonzero((knot_ticks > lo) & (knot_ticks < td)):
                pose = sw.at(knot_ticks[j] * dt)
                swing_knots.append((int(j), step.side, pose.p_world_sole, pose.R_world_sole))
    F_bar = np.tile([0.0, 0.0, 1.0], (N + 1, 1))  # static support (scaled)

    mu_lin = cfg.friction / np.sqrt(2.0)
    t0 = time.perf_counter()
    solves = 0
    for it in range(cfg.am_iterations + 1):
        caps = sole_z if cfg.leg_reach is None else _reach_caps(sole_z, contacts, c_bar, cfg.leg_reach, swing_knots)
        H, g, A, b, C, l, u = _build(lay, h, c_init, c_final_xy, z_ref, c_bar, F_bar, caps, cfg, mu_lin)
        x, iters, solver = _solve(H, g, A, b, C, l, u, cfg)
        solves += 1
        c_sol = x[lay.c]
        c_bar_used, F_bar_used = c_bar, F_bar
        c_bar = c_sol.copy()
        F_bar = np.array([(Mf @ x[cf]) if len(cf) else np.zeros(3) for cf, Mf in
                          (lay.force_rows(j) for j in range(N + 1))])
    solve_time = time.perf_counter() - t0

    eq_res = float(np.abs(A @ x - b).max()) if A.shape[0] else 0.0
    if eq_res > max(1e3 * cfg.eps, 1e-6):
        raise CentroidalPlanError(f"centroidal QP: the solution violates the dynamics by {eq_res:.2e} (scaled); the "
                                  "solver did not converge accurately")
    mg = cfg.mass * cfg.gravity
    cone_viol = float(np.max(C @ x - u)) * mg if C.shape[0] else -np.inf
    if cone_viol > 1e-4 * mg:
        raise CentroidalPlanError(f"centroidal QP: the solution leaves a friction pyramid (or the CoM height bound) "
                                  f"by {cone_viol:.3e} N")

    # ---- per-knot values -> per tick --------------------------------------------------------------------
    v_sol = x[lay.v]
    Fk = np.array([(Mf @ x[cf]) if len(cf) else np.zeros(3) for cf, Mf in (lay.force_rows(j) for j in range(N + 1))])
    a_knot = cfg.gravity * (Fk - np.array([0.0, 0.0, 1.0]))
    # neglected second-order part of L_dot: (c_bar - c) x (F - F_bar), scaled (metres of moment arm)
    am_err = float(np.linalg.norm(np.cross(c_bar_used - c_sol, Fk - F_bar_used), axis=1).max())

    ticks = np.arange(n)
    j_of = np.clip(np.searchsorted(knot_ticks, ticks, side="right") - 1, 0, N - 1)
    s = (ticks - knot_ticks[j_of]) * dt
    hh = h[j_of]
    lam = (s / hh)[:, None]
    a0, a1 = a_knot[j_of], a_knot[j_of + 1]
    acc = (1.0 - lam) * a0 + lam * a1
    vel = v_sol[j_of] + a0 * s[:, None] + (a1 - a0) * (s**2 / (2.0 * hh))[:, None]
    com = c_sol[j_of] + v_sol[j_of] * s[:, None] + a0 * (s**2 / 2.0)[:, None] + (a1 - a0) * (s**3 / (6.0 * hh))[:, None]

    wrenches = {}
    dL = np.zeros((n, 3))
    for side in Side:
        corners = np.zeros((n, 4, 3))
        normal = np.zeros((n, 3))
        p_sole = np.zeros((n, 3))
        cforce = np.zeros((n, 4, 3))
        knot_force = {}  # (contact, knot) -> (4, 3) world forces [N]
        for ci, ct in enumerate(contacts):
            if ct.side is not side:
                continue
            for j in range(ct.first, ct.last + 1):
                knot_force[(ci, j)] = np.zeros((4, 3))
            for jj, col0 in ((jj, col0) for jj in range(N + 1) for (cc, col0) in lay.blocks[jj] if cc == ci):
                knot_force[(ci, jj)] = mg * (x[col0:col0 + 12].reshape(4, 3) @ ct.R.T)
            k0, k1 = knot_ticks[ct.first], knot_ticks[ct.last]
            seg = slice(k0, k1 + 1)
            corners[seg] = ct.corners
            normal[seg] = ct.R[:, 2]
            p_sole[seg] = ct.p_sole
            for j in range(ct.first, ct.last):
                ta, tb = knot_ticks[j], knot_ticks[j + 1]
                kk = np.arange(ta, tb + 1)
                w = ((kk - ta) / (tb - ta))[:, None, None]
                cforce[ta:tb + 1] = (1.0 - w) * knot_force[(ci, j)] + w * knot_force[(ci, j + 1)]
        # in the air: keep the last contact pose for the corners (forces are zero there)
        last = None
        for k in range(n):
            if np.any(normal[k]):
                last = k
            elif last is not None:
                corners[k], normal[k], p_sole[k] = corners[last], normal[last], p_sole[last]
        force = cforce.sum(axis=1)
        torque = np.cross(corners - p_sole[:, None, :], cforce).sum(axis=1)
        dL += np.cross(corners - com[:, None, :], cforce).sum(axis=1)
        wrenches[side] = ContactWrenchTrajectory(side, in_contact[side], corners, normal, cforce, force, torque,
                                                 p_sole)
    L = np.zeros((n, 3))
    L[1:] = np.cumsum(0.5 * (dL[1:] + dL[:-1]) * dt, axis=0)

    # ZMP on the horizontal plane at the force-weighted support height
    fz = np.stack([np.maximum(wrenches[s].force[:, 2], 0.0) for s in Side], axis=1)
    zs = np.stack([wrenches[s].p_world_sole[:, 2] for s in Side], axis=1)
    height = (fz * zs).sum(axis=1) / np.maximum(fz.sum(axis=1), 1e-12)
    o = np.column_stack([np.zeros(n), np.zeros(n), height])
    F_tot = sum(wrenches[s].force for s in Side)
    M_o = sum(wrenches[s].torque + np.cross(wrenches[s].p_world_sole - o, wrenches[s].force) for s in Side)
    zmp = np.column_stack([-M_o[:, 1] / F_tot[:, 2], M_o[:, 0] / F_tot[:, 2], height])
    zmp_com = np.column_stack([com[:, :2] - ((com[:, 2] - height) / (acc[:, 2] + cfg.gravity))[:, None] * acc[:, :2],
                               height])
    dcm = com + vel / cfg.omega
    report = CentroidalReport(solver, solves, lay.n, A.shape[0], C.shape[0], N + 1, iters, solve_time, eq_res,
                              cone_viol, am_err)
    return CentroidalTrajectory(dt, cfg.mass, cfg.gravity, cfg.friction, cfg.com_height, cfg.omega, com, vel, acc,
                                dL, L, wrenches, height, zmp, zmp_com, dcm, knot_ticks, report)
