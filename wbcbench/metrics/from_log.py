"""All benchmark metrics of a run, from its log (one row per control tick) and the robot model.

`compute_run_metrics(log, robot, dt=...)` returns a JSON-ready nested dict (no NaN: undefined values are
None) with what paper 000 reports (Tables 2-8) and a little more:

    distance_m                     D, horizontal start-to-end displacement of the base [m]
    zmp_error_m.{x,y}.{mean,std,peak,rms}   measured ZMP (ankle F/T) minus zmp_ref       (if zmp_ref logged)
    zmp_ft_vs_contact_m.{x,y}.{...}          F/T ZMP minus the ZMP of the ground-truth contact wrenches
    com_error_m.{x,y,z}.{...}      CoM minus com_ref, on the ticks where com_ref is defined
    feet_error_m.{left,right}.{x,y,z}.{...}  sole origin (forward kinematics) minus foot_ref_<side>, on the
                                   ticks where that reference is defined (a walk gives it in swing only)
    E_m, E_m_plus                  [J], Eq. 10 over the actuated joints
    C_et, C_mt                     E / (m g D) with m the model's mass
    C_et_paper_mass, C_mt_paper_mass   the same with m = 100 kg (m g = 981 N), see below
    E_el, E_cu, C_el, C_el_paper_mass  electrical energy drawn, its copper losses [J] and E_el / (m g D), only when
                                   a motor model is given (`motors`, a realism preset's `motors:` section)
    pgm.{double_support,single_support,flying_foot}   Eq. 11-12 on the scenario's contact schedule
    compute_time_us.{mean,median,p99,max}   controller time per tick
    n_ticks, duration_s, mass_kg

A metric whose inputs are not in the log is absent (never invented); a metric that is undefined on this
run (no travel for a cost of transport, no single support for the PGM) is None. `notes` lists why.

Choices, in one place:
- Measured ZMP: each ankle F/T reading (the wrench the leg exerts on the foot, sensor frame) becomes the
  ground's wrench on the foot with `wbcbench.estimation.contact_wrench_from_ft`, the foot below the sensor
  taken from the model (`Robot.foot_below_sensor`), the sensor pose from forward kinematics of the logged q
  of the same row. (MuJoCo's sensor data lag the state by one physics step; the stance foot that carries the
  ZMP does not move, so this is far below a millimetre.) The ZMP is that of the summed wrenches of the feet
  carrying at least 10 N (`zmp_from_wrenches`) on the horizontal plane z = zmp_ref.z where the scenario
  gives one, else z = the lower sole's height.
- Cost of transport: the published Table 6 values only reproduce with m g = 981 N, i.e. m = 100 kg (the real
  TALOS, "about 100 kg"), not the 90.27 kg model: C_et = E_m / (981 D) to the printed precision for the 20 cm
  (D = 1.2 m) and 60 cm (D = 3.6 m) walks, e.g. 1983.9 / (981 x 1.2) = 1.685 for 1.68. We report both; the
  paper comparison uses the `_paper_mass` pair. D below `MIN_COT_DISTANCE_M` gives None.
- PGM ankles: the last two joints on the kinematic chain from the root to each sole frame (TALOS: leg_*_5
  pitch and leg_*_6 roll), found from the model, not from names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..estimation import FootMass, Plane, Wrench, contact_wrench_from_ft, zmp_from_wrenches
from ..side import Side
from ..tasks.placements import ForwardKinematics
from .energy import (STANDARD_GRAVITY, cost_of_transport, electrical_cost_of_transport, electrical_energy,
                     horizontal_distance, mechanical_energy)
from .pgm import passivity_gait_measure
from .timing import timing_stats
from .tracking import tracking_error_stats

PAPER_MASS_KG = 100.0
"""Mass [kg] that reproduces the published costs of transport (m g = 981 N), see the module docstring."""

MIN_COT_DISTANCE_M = 0.05
"""Below this horizontal distance [m] a cost of transport is undefined (None): standing still has none."""

BASE_Q = ("x", "y", "z", "qx", "qy", "qz", "qw")
WRENCH = ("fx", "fy", "fz", "mx", "my", "mz")
XYZ = ("x", "y", "z")
FOOT_REF_CHANNELS = ("foot_ref", "feet_ref")
"""Names under which a log may hold the sole position references (`<name>_<side>.x/y/z`), first found wins."""


class FootKinematics(NamedTuple):
    """Per-tick foot poses from forward kinematics of the logged configuration.

    Attributes:
        valid: (N,) bool, ticks whose logged q is complete and finite (other rows of the arrays are NaN).
        R_world_sensor: per side (N, 3, 3) ankle F/T sensor orientation in world.
        p_world_sensor: per side (N, 3) sensor origin [m], world frame.
        p_world_sole: per side (N, 3) sole frame origin [m], world frame.
    """

    valid: np.ndarray
    R_world_sensor: dict[Side, np.ndarray]
    p_world_sensor: dict[Side, np.ndarray]
    p_world_sole: dict[Side, np.ndarray]


# ---------------------------------------------------------------------------------------------- helpers
def _n_ticks(log: dict[str, np.ndarray]) -> int:
    if "t" in log:
        return int(np.asarray(log["t"]).shape[0])
    return int(np.asarray(next(iter(log.values()))).shape[0]) if log else 0


def _columns(log: dict[str, np.ndarray], names: list[str]) -> np.ndarray | None:
    """Stack the named columns as (N, k) floats; None if any is absent."""
    if not names or any(n not in log for n in names):
        return None
    return np.column_stack([np.asarray(log[n], dtype=float) for n in names])


def _finite_rows(a: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(a), axis=1)


def json_ready(x):
    """`x` with numpy scalars/arrays turned into Python objects and NaN / inf into None (valid JSON)."""
    if isinstance(x, Mapping):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_ready(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x


def _stats(stats: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    return {axis: {k: s[k] for k in ("mean", "std", "peak", "rms")} for axis, s in stats.items()}


def _masked_tracking(ref: np.ndarray, meas: np.ndarray, axes: tuple[str, ...]) -> dict | None:
    """Per-axis error stats on the ticks where both are finite; None if there is no such tick."""
    keep = _finite_rows(ref) & _finite_rows(meas)
    if not keep.any():
        return None
    return _stats(tracking_error_stats(ref, meas, axes=axes, mask=keep))


# ---------------------------------------------------------------------------------------------- kinematics
def ankle_joints(robot) -> dict[Side, tuple[str, str]]:
    """The two joints nearest each sole: the last two joints on the chain from the root to the sole frame.

    Returns:
        {side: (name of the joint above, name of the joint carrying the sole)}, e.g. TALOS
        ("leg_left_5_joint", "leg_left_6_joint").
    """
    model = robot.model
    out = {}
    for side in Side:
        jid = model.frames[robot.sole_frame_id(side)].parentJoint
        chain = []
        while jid > 0:
            if model.nvs[jid] == 1:  # actuated 1-DoF joint (not the free flyer)
                chain.append(model.names[jid])
            jid = model.parents[jid]
        if len(chain) < 2:
            raise ValueError(f"the {side.value} sole frame has fewer than two actuated joints above it")
        out[side] = (chain[1], chain[0])
    return out


def configuration(log: dict[str, np.ndarray], robot) -> np.ndarray | None:
    """(N, nq) logged pinocchio configurations (columns q.x ... q.qw, q.<joint>); None if a column is absent."""
    return _columns(log, [f"q.{c}" for c in BASE_Q] + [f"q.{j}" for j in robot.joint_names])


def foot_kinematics(log: dict[str, np.ndarray], robot) -> FootKinematics | None:
    """Ankle sensor and sole poses at every tick from the logged q; None if q is not logged."""
    q = configuration(log, robot)
    if q is None:
        return None
    n = q.shape[0]
    valid = _finite_rows(q)
    quat_norm = np.linalg.norm(q[:, 3:7], axis=1)
    valid &= quat_norm > 1e-9
    model = robot.model
    data = model.createData()
    sensor_ids = {s: model.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
    sole_ids = {s: robot.sole_frame_id(s) for s in Side}
    R = {s: np.full((n, 3, 3), np.nan) for s in Side}
    p = {s: np.full((n, 3), np.nan) for s in Side}
    sole = {s: np.full((n, 3), np.nan) for s in Side}
    rows = np.flatnonzero(valid)
    fk = ForwardKinematics(model)
    if fk.supported:  # every tick in one compiled call (pinocchio's placements to rounding)
        Q = q[rows]
        Q[:, 3:7] /= quat_norm[rows, None]
        arrays = fk.frame_arrays([sensor_ids[Side.LEFT], sensor_ids[Side.RIGHT], sole_ids[Side.LEFT],
                                  sole_ids[Side.RIGHT]])
        Rs, ts = fk.frames_along(Q, arrays)
        for i, s in enumerate((Side.LEFT, Side.RIGHT)):
            R[s][rows] = Rs[:, i]
            p[s][rows] = ts[:, i]
            sole[s][rows] = ts[:, 2 + i]
        return FootKinematics(valid, R, p, sole)
    qk = np.empty(model.nq)
    for k in rows:
        qk[:] = q[k]
        qk[3:7] /= quat_norm[k]
        pin.forwardKinematics(model, data, qk)
        for s in Side:
            M = pin.updateFramePlacement(model, data, sensor_ids[s])
            R[s][k] = M.rotation
            p[s][k] = M.translation
            sole[s][k] = pin.updateFramePlacement(model, data, sole_ids[s]).translation
    return FootKinematics(valid, R, p, sole)


def ground_height(log: dict[str, np.ndarray], kin: FootKinematics) -> np.ndarray:
    """(N,) height [m] of the horizontal plane the ZMP is computed on: zmp_ref.z where finite, else the lower
    sole's height (NaN where neither is known)."""
    lower = np.fmin(kin.p_world_sole[Side.LEFT][:, 2], kin.p_world_sole[Side.RIGHT][:, 2])
    if "zmp_ref.z" in log:
        ref = np.asarray(log["zmp_ref.z"], dtype=float)
        return np.where(np.isfinite(ref), ref, lower)
    return lower


def _plane(height: np.ndarray) -> Plane:
    point = np.zeros((height.shape[0], 3))
    point[:, 2] = height
    return Plane(point, np.array([0.0, 0.0, 1.0]))


def ft_contact_wrenches(log: dict[str, np.ndarray], robot, kin: FootKinematics | None = None
                        ) -> dict[Side, Wrench] | None:
    """Ground wrench on each foot from its ankle F/T sensor (foot weight removed), world frame, moment about
    the sensor origin; rows NaN where q or the sensor reading is missing. None if F/T is not logged."""
    kin = kin if kin is not None else foot_kinematics(log, robot)
    if kin is None:
        return None
    out = {}
    n = kin.valid.shape[0]
    for s in Side:
        ft = _columns(log, [f"ft_{s.value}.{c}" for c in WRENCH])
        if ft is None:
            return None
        ok = kin.valid & _finite_rows(ft)
        force, moment, point = (np.full((n, 3), np.nan) for _ in range(3))
        if ok.any():
            mass, com = robot.foot_below_sensor(s)
            w = contact_wrench_from_ft(ft[ok, :3], ft[ok, 3:], kin.R_world_sensor[s][ok],
                                       kin.p_world_sensor[s][ok], FootMass(mass, com))
            force[ok], moment[ok], point[ok] = w.force, w.moment, w.point
        out[s] = Wrench(force, moment, point)
    return out


def _zmp_of(wrenches: dict[Side, Wrench], height: np.ndarray) -> np.ndarray:
    n = height.shape[0]
    ok = np.isfinite(height)
    for w in wrenches.values():
        ok &= _finite_rows(w.force) & _finite_rows(w.moment) & _finite_rows(np.broadcast_to(w.point, (n, 3)))
    zmp = np.full((n, 3), np.nan)
    if ok.any():
        parts = [Wrench(w.force[ok], w.moment[ok], np.broadcast_to(w.point, (n, 3))[ok]) for w in wrenches.values()]
        zmp[ok] = zmp_from_wrenches(parts, _plane(height[ok]))
    return zmp


def measured_zmp(log: dict[str, np.ndarray], robot, kin: FootKinematics | None = None) -> np.ndarray | None:
    """(N, 3) ZMP [m] from the two ankle F/T sensors (see the module docstring); NaN where no foot is loaded.
    None if q or the F/T readings are not logged."""
    kin = kin if kin is not None else foot_kinematics(log, robot)
    if kin is None:
        return None
    wrenches = ft_contact_wrenches(log, robot, kin)
    if wrenches is None:
        return None
    return _zmp_of(wrenches, ground_height(log, kin))


def contact_zmp(log: dict[str, np.ndarray], robot, kin: FootKinematics | None = None) -> np.ndarray | None:
    """(N, 3) ZMP [m] of the ground-truth contact wrenches (`contact_<side>.*`, moment about the world
    origin) on the same plane as `measured_zmp`; None if they are not logged."""
    kin = kin if kin is not None else foot_kinematics(log, robot)
    if kin is None:
        return None
    wrenches = {}
    for s in Side:
        cw = _columns(log, [f"contact_{s.value}.{c}" for c in WRENCH])
        if cw is None:
            return None
        wrenches[s] = Wrench(cw[:, :3], cw[:, 3:], np.zeros((cw.shape[0], 3)))
    return _zmp_of(wrenches, ground_height(log, kin))


def _foot_reference(log: dict[str, np.ndarray], side: Side) -> np.ndarray | None:
    """(N, 3) sole position reference: the runner's `foot_ref_<side>.*` (or `feet_ref_<side>.*`)."""
    for name in FOOT_REF_CHANNELS:
        ref = _columns(log, [f"{name}_{side.value}.{a}" for a in XYZ])
        if ref is not None:
            return ref
    return None


# ---------------------------------------------------------------------------------------------- metrics
def _electrical(motors: Mapping, joints: list[str], tau: np.ndarray, omega: np.ndarray, dt: float, mass: float,
                distance: float | None) -> dict:
    """E_el, E_cu, C_el and C_el_paper_mass over `joints` (a joint without motor data: ValueError)."""
    per = motors["joints"]
    missing = [j for j in joints if j not in per]
    if missing:
        raise ValueError(f"the motor model has no joint {missing[0]}")
    vals = {k: [per[j][k] for j in joints] for k in ("torque_constant", "gear_ratio", "resistance")}
    e = electrical_energy(tau, omega, dt, **vals, convention=motors.get("convention", "dq"),
                          regeneration=bool(motors.get("regeneration", False)))
    out = {"E_el": e.e_el, "E_cu": e.e_cu}
    for key, m in (("", mass), ("_paper_mass", PAPER_MASS_KG)):
        out[f"C_el{key}"] = (electrical_cost_of_transport(e, m, distance, gravity=STANDARD_GRAVITY)
                             if distance is not None and distance >= MIN_COT_DISTANCE_M else None)
    return out


def compute_run_metrics(log: dict[str, np.ndarray], robot, *, dt: float,
                        distance_planned_m: float | None = None, motors: Mapping | None = None) -> dict:
    """Every metric of paper 000 computable from one run log (see the module docstring for keys and units).

    Args:
        log: {column: (N,) array}, as `wbcbench.recorder.read_log` returns.
        robot: the `Robot` the run used (model for kinematics, masses, ankle joints).
        dt: control period [s] (one log row per tick).
        distance_planned_m: the scenario's planned travel [m], reported as is when given.
        motors: the motor model for the electrical energy, as a realism preset describes it in config.json
            ({"convention", "regeneration", "joints": {joint: {"torque_constant", "gear_ratio", "resistance"}}});
            None: no electrical metrics.

    Returns:
        JSON-ready nested dict; absent keys = inputs not logged; None = undefined on this run.
    """
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite control period > 0 [s], got {dt!r}")
    n = _n_ticks(log)
    out: dict = {"n_ticks": n, "duration_s": n * float(dt), "mass_kg": robot.mass}
    notes: list[str] = []
    if n == 0:
        out["notes"] = ["empty log"]
        return json_ready(out)

    # ---- distance travelled by the base (horizontal)
    distance = None
    base = _columns(log, ["q.x", "q.y"])
    if base is not None:
        rows = base[_finite_rows(base)]
        if rows.shape[0]:
            distance = horizontal_distance(rows)
            out["distance_m"] = distance
    if distance_planned_m is not None:
        out["distance_planned_m"] = float(distance_planned_m)

    # ---- ZMP from the ankle F/T sensors, CoM and feet tracking
    kin = foot_kinematics(log, robot)
    if kin is not None:
        zmp = measured_zmp(log, robot, kin)
        ref = _columns(log, ["zmp_ref.x", "zmp_ref.y"])
        if zmp is not None and ref is not None:
            err = _masked_tracking(ref, zmp[:, :2], ("x", "y"))
            if err is None:
                notes.append("zmp_error_m: no tick with both a ZMP reference and a loaded foot")
            else:
                out["zmp_error_m"] = err
        truth = contact_zmp(log, robot, kin)
        if zmp is not None and truth is not None:
            diff = _masked_tracking(truth[:, :2], zmp[:, :2], ("x", "y"))
            if diff is not None:
                out["zmp_ft_vs_contact_m"] = diff
        feet = {}
        for s in Side:
            fref = _foot_reference(log, s)
            if fref is not None:
                e = _masked_tracking(fref, kin.p_world_sole[s], XYZ)
                if e is not None:
                    feet[s.value] = e
        if feet:
            out["feet_error_m"] = feet
    com, com_ref = _columns(log, [f"com.{a}" for a in XYZ]), _columns(log, [f"com_ref.{a}" for a in XYZ])
    if com is not None and com_ref is not None:
        e = _masked_tracking(com_ref, com, XYZ)
        if e is not None:
            out["com_error_m"] = e

    # ---- energy and cost of transport
    joints = [j for j in robot.joint_names if f"tau.{j}" in log and f"v.{j}" in log]
    tau = _columns(log, [f"tau.{j}" for j in joints])
    omega = _columns(log, [f"v.{j}" for j in joints])
    if tau is not None and omega is not None:
        keep = _finite_rows(tau) & _finite_rows(omega)
        if keep.any():
            energy = mechanical_energy(tau[keep], omega[keep], float(dt))
            out["E_m"], out["E_m_plus"] = energy.e_m, energy.e_m_plus
            for key, mass in (("", robot.mass), ("_paper_mass", PAPER_MASS_KG)):
                if distance is not None and distance >= MIN_COT_DISTANCE_M:
                    cot = cost_of_transport(energy, mass, distance, gravity=STANDARD_GRAVITY)
                    out[f"C_et{key}"], out[f"C_mt{key}"] = cot.c_et, cot.c_mt
                else:
                    out[f"C_et{key}"] = out[f"C_mt{key}"] = None
            if distance is None or distance < MIN_COT_DISTANCE_M:
                notes.append(f"C_et/C_mt: base travelled less than {MIN_COT_DISTANCE_M} m")
            if motors is not None:
                out.update(_electrical(motors, joints, tau[keep], omega[keep], float(dt), robot.mass, distance))

    # ---- passivity gait measure on the scenario's contact schedule
    contacts = _columns(log, ["in_contact_ref_left", "in_contact_ref_right"])
    if tau is not None and contacts is not None:
        ankles = ankle_joints(robot)
        index = {j: i for i, j in enumerate(joints)}
        if all(j in index for a in ankles.values() for j in a):
            keep = _finite_rows(tau) & _finite_rows(contacts)
            if keep.any():
                pgm = passivity_gait_measure(
                    tau[keep], contacts[keep, 0] > 0.5, contacts[keep, 1] > 0.5,
                    left_ankle=[index[j] for j in ankles[Side.LEFT]],
                    right_ankle=[index[j] for j in ankles[Side.RIGHT]], dt=float(dt))
                out["pgm"] = pgm._asdict()
        else:
            notes.append("pgm: ankle joint torques not logged")

    # ---- controller compute time
    if "controller_time_us" in log:
        us = np.asarray(log["controller_time_us"], dtype=float)
        us = us[np.isfinite(us) & (us >= 0)]
        if us.size:
            ts = timing_stats(us * 1e-6)
            out["compute_time_us"] = {"mean": ts.mean, "median": ts.median, "p99": ts.p99, "max": ts.max}

    if notes:
        out["notes"] = notes
    return json_ready(out)
