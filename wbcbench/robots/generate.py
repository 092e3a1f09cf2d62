"""`wbcbench robot init`: a first robot profile generated from a humanoid's model.

What it finds, from the pinocchio model and its collision geometry at the joints' zero:

* the feet: the two links (one each side of the sagittal plane) whose collision geometry (or visual meshes, when
  those reach lower) reaches lowest, well below the base; their sole rectangle is the x-y extent of that geometry
  (its bounding boxes, world-aligned at the joints' zero), the sole frame is added at the centre of the
  rectangle's bottom face, level; the F/T frame is the foot's own joint (the ankle);
* base (the root link), torso (the last body joint both arms hang from), IMU (a frame named *imu*, else the base),
  head (a frame named *head*, else the torso), hands (the last joint every arm leaf of a side shares);
* a standing posture: least squares over the leg joints with the knees bent by `knee` [rad], soles flat and
  level, the CoM over the middle of the feet;
* gains from the masses: position kp = m g l / 0.01 rad (the load's weight times its lever, stiff enough for a
  1 cm-rad sag; legs carry the whole robot at 0.1 m), torque-PD kp = 1/15 of it; kd ratios as the shipped
  profiles';
* fall thresholds from the base height, stepping limits from the leg length, limits the model lacks;
* the self-collision repulsors and the self-collision check from the collision geometry (collision.py).

The result is a commented YAML profile; `missing` lists what could not be found (and the key to fill).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from .collision import self_collision_keys, self_collision_yaml
from .robot import (MENAGERIE_PREFIX, MJCF_SUFFIXES, _model_files, build_geometry, build_pinocchio_model,
                    menagerie_model)

G = 9.81


@dataclass
class Generated:
    text: str
    missing: list[str] = field(default_factory=list)


def _loader_for(source: str) -> str:
    """The profile's `loader` for a SOURCE: a URDF or MJCF path (absolute), `fourier:<name>`,
    `menagerie:<robot>[/<entry>]`, or an example-robot-data name; a bare fourier model name is tried after
    example-robot-data's."""
    if source.endswith(".urdf") or source.lower().endswith(MJCF_SUFFIXES):
        p = Path(source).expanduser()
        if not p.is_file():
            raise ConfigError(f"model file '{p}' does not exist", file=str(p), key="SOURCE")
        return str(p.resolve())
    if source.startswith(MENAGERIE_PREFIX):
        menagerie_model(source, "", "SOURCE")  # (the package, the name and the download: errors as SOURCE's)
        return source
    if source.startswith("fourier:"):
        return source
    from example_robot_data.robots_loader import ROBOTS

    if source in ROBOTS:
        return source
    try:
        from fourier_robot_descriptions.fourier import PACKAGE_PATH

        if (PACKAGE_PATH / f"{source}.urdf").exists():
            return f"fourier:{source}"
    except ImportError:
        pass
    raise ConfigError(f"'{source}' is neither a URDF or MJCF file (.urdf, .xml, .mjcf), an example-robot-data model, "
                      "a fourier model nor menagerie:<robot>", key="SOURCE")


def _geom_points(geom: pin.GeometryObject) -> np.ndarray:
    """Corners of the geometry's local bounding box, in its parent joint's frame."""
    g = geom.geometry
    g.computeLocalAABB()
    lo, hi = np.array(g.aabb_local.min_), np.array(g.aabb_local.max_)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return np.array([geom.placement.act(c) for c in corners])


def generate_profile(source: str, name: str | None = None, knee: float = 0.6) -> Generated:
    loader = _loader_for(source)
    files = _model_files(loader, "")
    src = str(files.path)
    model = build_pinocchio_model(files)
    if model.nq < 8 or any(model.nqs[j] != 1 for j in range(2, model.njoints)):
        raise ConfigError("only robots with 1-DoF joints below a free base are supported", file=src)
    try:
        geom = build_geometry(model, files, pin.GeometryType.COLLISION)
    except (ValueError, RuntimeError) as exc:  # a mesh the package does not ship
        raise ConfigError(f"cannot read the collision geometry: {exc}", file=src, key="collision")
    data = model.createData()
    q = pin.neutral(model)
    q[7:] = np.clip(0.0, model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
    pin.framesForwardKinematics(model, data, q)
    missing: list[str] = []
    name = name or Path(loader.split(":")[-1]).stem
    jname = list(model.names)

    # ---- feet: the lowest geometry each side (collision geometry, else the visual meshes)
    feet, low = _find_feet(model, data, geom)
    try:  # the visual meshes: for models whose collision geometry misses the legs
        visual = build_geometry(model, files, pin.GeometryType.VISUAL)
        vfeet, vlow = _find_feet(model, data, visual)
    except (ValueError, RuntimeError):
        vfeet, vlow = {}, {}

    def lowest(ft, lw):
        return max(lw[j][:, 2].min() for j in ft.values()) if len(ft) == 2 else np.inf

    if len(vfeet) == 2 and lowest(vfeet, vlow) < lowest(feet, low) - 0.02:
        feet, low = vfeet, vlow
        missing.append("sole (from the visual meshes: the model has no collision geometry at the feet)")
    if len(feet) == 2:  # legs: the feet well below the base (an upper body's grippers are not feet)
        z_feet = min(low[j][:, 2].min() for j in feet.values())
        z_top = max(pts[:, 2].max() for pts in low.values())
        if data.oMi[1].translation[2] - z_feet < 0.25 * (z_top - z_feet):
            feet = {}
    if len(feet) != 2:
        raise ConfigError("no feet found: no geometry reaching lowest on each side of the robot; write the "
                          "profile's feet and sole by hand", file=src, key="feet")
    foot_body, sole_in_joint, sole_in_body = {}, {}, {}
    sizes = []
    for side, j in feet.items():
        bodies = [k for k, f in enumerate(model.frames) if f.type == pin.FrameType.BODY and f.parentJoint == j]
        fid = bodies[-1] if bodies else model.getFrameId(jname[j])
        foot_body[side] = model.frames[fid].name
        lo, hi = low[j].min(axis=0), low[j].max(axis=0)  # world-aligned box of the foot's geometry
        sole_w = pin.SE3(np.eye(3), np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]))
        sole_in_joint[side] = data.oMi[j].actInv(sole_w)
        sole_in_body[side] = data.oMf[fid].actInv(sole_w)
        sizes.append((hi[0] - lo[0], hi[1] - lo[1]))
    length, width = float(min(s[0] for s in sizes)), float(min(s[1] for s in sizes))

    # ---- chains
    def chain(j):
        return list(model.supports[j])[2:]  # without universe and root

    leaves = [j for j in range(2, model.njoints) if not any(model.parents[k] == j for k in range(2, model.njoints))]
    leg_joints = set(chain(feet["left"])) | set(chain(feet["right"]))
    hands, hand_joint = {}, {}
    for side, sign in (("left", 1), ("right", -1)):
        arm_leaves = [j for j in leaves if j not in leg_joints and sign * data.oMi[j].translation[1] > 0.05]
        if not arm_leaves:
            missing.append(f"hands.{side}")
            continue
        common = set(model.supports[arm_leaves[0]])
        for j in arm_leaves[1:]:
            common &= set(model.supports[j])
        hj = max(common)
        hand_joint[side] = hj
        bodies = [f for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == hj]
        hands[side] = bodies[-1].name if bodies else jname[hj]
    base = next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == 1)
    torso = base
    if len(hand_joint) == 2:
        common = set(model.supports[hand_joint["left"]]) & set(model.supports[hand_joint["right"]])
        tj = max(common)
        if tj > 1:
            torso = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == tj][-1]
    imu = next((f.name for f in model.frames if "imu" in f.name.lower()), None)
    if imu is None:
        imu = base
        missing.append("imu_frame (the base frame used)")
    heads = [f.name for f in model.frames if "head" in f.name.lower() and f.type == pin.FrameType.BODY]
    head = heads[-1] if heads else torso
    if not heads:
        missing.append("head_frame (the torso used)")

    # ---- the knees: per leg, the joint with a lateral axis nearest the middle height of hip and ankle
    knees = {}
    for side, j in feet.items():
        ch = chain(j)
        zt, za = data.oMi[ch[0]].translation[2], data.oMi[j].translation[2]
        best = None
        for k in ch:
            axis = data.oMi[k].rotation @ _axis(model, k)
            if abs(axis[1]) < 0.9:
                continue
            d = abs(data.oMi[k].translation[2] - (zt + za) / 2)
            if best is None or d < best[0]:
                best = (d, k)
        if best is None:
            raise ConfigError("no knee found (no pitch joint in the leg)", file=src,
                              key="reference_posture")
        knees[side] = best[1]

    # ---- standing posture: least squares on the leg joints
    from scipy.optimize import least_squares

    leg_idx = sorted(model.idx_qs[k] for k in leg_joints)
    knee_q = {}
    for side, k in knees.items():
        qi = model.idx_qs[k]
        lo_k, hi_k = model.lowerPositionLimit[qi], model.upperPositionLimit[qi]
        # the sign that moves the ankle backward (the knee bending forward, as a human's)
        qq = q.copy()
        qq[qi] = 0.3
        pin.forwardKinematics(model, data, qq)
        x_plus = data.oMi[feet[side]].translation[0]
        pin.forwardKinematics(model, data, q)
        sign = 1.0 if x_plus < data.oMi[feet[side]].translation[0] else -1.0
        knee_q[qi] = float(np.clip(sign * knee, lo_k, hi_k))
    free = [i for i in leg_idx if i not in knee_q]
    y_feet = {s: data.oMi[j].translation[1] for s, j in feet.items()}

    def full(x):
        qq = q.copy()
        qq[free] = x
        for i, v in knee_q.items():
            qq[i] = v
        return qq

    def residual(x):
        qq = full(x)
        pin.forwardKinematics(model, data, qq)
        com = pin.centerOfMass(model, data, qq)
        r = []
        pos = {}
        for s, j in feet.items():
            M = data.oMi[j]
            S = M * sole_in_joint[s]
            r.extend(10 * pin.log3(S.rotation))
            pos[s] = S.translation
            r.append(10 * (M.translation[1] - y_feet[s]))
        r.append(10 * (pos["left"][2] - pos["right"][2]))
        r.append(10 * (pos["left"][0] - pos["right"][0]))
        mid = (pos["left"] + pos["right"]) / 2
        r.extend(10 * (com[:2] - mid[:2]))
        r.extend(0.01 * np.asarray(x))
        return np.array(r)

    lb, ub = model.lowerPositionLimit[free], model.upperPositionLimit[free]
    sol = least_squares(residual, np.clip(q[free], lb, ub), bounds=(lb, ub))
    if np.linalg.norm(residual(sol.x)[:-len(free)]) > 1e-2:
        missing.append("reference_posture (no flat-footed posture with the CoM over the feet found; check it)")
    q_ref = full(sol.x)
    pin.framesForwardKinematics(model, data, q_ref)
    pin.centerOfMass(model, data, q_ref)
    sole_z = min((data.oMi[j] * sole_in_joint[s]).translation[2] for s, j in feet.items())
    base_h = float(data.oMi[1].translation[2] - sole_z)
    top = max(data.oMi[j].translation[2] for j in range(1, model.njoints)) - sole_z
    pin.forwardKinematics(model, data, q)
    leg = float(data.oMi[chain(feet["left"])[0]].translation[2] - data.oMi[feet["left"]].translation[2])

    # ---- gains from the masses
    mass = float(pin.computeTotalMass(model))
    pin.forwardKinematics(model, data, q_ref)
    pin.centerOfMass(model, data, q_ref, True)  # subtree masses and CoMs
    kp = {}
    for j in range(2, model.njoints):
        if j in leg_joints:
            load = mass * G * 0.1
        else:
            sub = data.mass[j]
            lever = np.linalg.norm(data.com[j] - data.oMi[j].translation) if sub > 0 else 0.0
            load = min(sub * G * max(lever, 0.05), mass * G * 0.1)  # no stiffer than the legs
        kp[jname[j]] = float(max(5.0, round(load / 0.01, -1 if load / 0.01 > 100 else 0)))

    # ---- limits the model lacks
    eff_missing = [jname[j] for j in range(2, model.njoints) if not 0 < model.effortLimit[model.idx_vs[j]] < np.inf]
    vel_missing = [jname[j] for j in range(2, model.njoints)
                   if not 0 < model.velocityLimit[model.idx_vs[j]] < np.inf]  # (an MJCF gives none: inf)
    masses = [model.inertias[j].mass for j in range(1, model.njoints)]
    massless = min(masses) <= 0 and not files.is_mjcf  # (an MJCF's bounds: its own <inertial>s)

    # ---- write
    L = []
    w = L.append
    w(f"# Robot profile generated by `wbcbench robot init {source}` ({mass:.1f} kg, {model.nv - 6} joints,")
    w(f"# {top:.2f} m from the soles to the highest joint at the standing posture). Check and tune it; see")
    w("# wbcbench/robots/generate.py for how each value was found.")
    w(f"name: {name}")
    w(f"description: {name} (generated profile)")
    w(f"loader: {loader}")
    w(f"reference_posture:                  # least squares: knees bent {knee} rad, soles flat and level, CoM over"
      " the feet")
    for i in range(7, model.nq):
        if abs(q_ref[i]) > 1e-6:
            j = next(k for k in range(2, model.njoints) if model.idx_qs[k] == i)
            w(f"  {jname[j]}: {q_ref[i]:.4f}")
    w(f"base_frame: {base}                 # the root link")
    w(f"torso_frame: {torso}               # the last body both arms hang from")
    w(f"imu_frame: {imu}")
    w(f"head_frame: {head}")
    w("feet:                              # the sole frame: centre of the bottom of the foot's collision geometry")
    for s in ("left", "right"):
        o = sole_in_body[s].translation
        rpy = pin.rpy.matrixToRpy(sole_in_body[s].rotation)
        w(f"  {s}:")
        w(f"    frame: {s}_sole_generated")
        w(f"    parent_frame: {foot_body[s]}")
        w(f"    offset: [{o[0]:.4f}, {o[1]:.4f}, {o[2]:.4f}]")
        if np.abs(rpy).max() > 1e-9:
            w(f"    rpy: [{rpy[0]:.6f}, {rpy[1]:.6f}, {rpy[2]:.6f}]   # level at the joints' zero")
        w(f"    ft_sensor_frame: {jname[feet[s]]}   # the ankle joint")
    w("sole:                              # the x-y extent of the foot's collision geometry [m]")
    w(f"  length: {length:.4f}")
    w(f"  width: {width:.4f}")
    w("  center: [0.0, 0.0]")
    w("  thickness: 0.01")
    w("hands:")
    for s in ("left", "right"):
        w(f"  {s}: {hands.get(s, base)}")
    w("limits:")
    if not np.any(model.armature[6:] > 0):
        w("  armature: 0.01                    # [kg m^2] reflected rotor inertia (the model gives none)")
    if massless:
        w("  min_body_mass: 1.0e-3             # [kg] the model has massless links")
        w("  min_body_inertia: 1.0e-7          # [kg m^2]")
    for key, names, val, unit in (("effort_overrides", eff_missing, None, "N m"),
                                  ("velocity_overrides", vel_missing, 10.0, "rad/s")):
        if names:
            w(f"  {key}:                 # [{unit}] joints the model gives none")
            for n in names:
                v = val if val is not None else max(2.0, round(kp[n] * 0.1, 1))
                w(f"    {n}: {v}")
    w("# Position mode (ik, tsid-position): kp = m g l / 0.01 rad (legs: the whole robot at 0.1 m; others: the")
    w("# subtree's weight at its CoM lever, at least 0.05 m), kd = 0.01 kp.")
    w("position_gains:")
    w("  kp:")
    for n, v in kp.items():
        w(f"    {n}: {v}")
    w("  kd_ratio: 0.01")
    w("# Torque-PD (tsid-torque's joint feedback): 1/15 of the position gains, kd = 0.05 kp.")
    w("torque_pd_gains:")
    w("  kp:")
    for n, v in kp.items():
        w(f"    {n}: {max(1.0, round(v / 15, 1))}")
    w("  kd_ratio: 0.05")
    w(f"# Footstep limits from the leg length ({leg:.3f} m, hip to ankle at the joints' zero).")
    w("stepping:")
    w(f"  max_forward: {min(1.0, 0.33 * leg):.3f}")
    w(f"  max_backward: {min(1.0, 0.2 * leg):.3f}")
    w(f"  max_lateral: {min(1.0, 0.13 * leg):.3f}")
    w("  max_turn: 0.35")
    w("  min_clearance: 0.02")
    w(f"# Fallen: the base below half its standing height ({base_h:.3f} m) or tilted more than 0.7 rad.")
    w("fall:")
    w(f"  min_base_height: {0.5 * base_h:.3f}")
    w("  max_tilt: 0.7")
    keys = self_collision_keys(model, geom, hands, torso, q_ref) if len(hands) == 2 else None
    if keys is not None:
        L.extend(self_collision_yaml(keys))
    else:
        missing.append("repulsors, collision_check (no hands, or no collision geometry on an arm)")
    return Generated("\n".join(L) + "\n", missing)


def _find_feet(model: pin.Model, data: pin.Data, geom: pin.GeometryModel) -> tuple[dict, dict]:
    """Per side (y > 0: left), the joint whose geometry reaches lowest; and every joint's geometry points (world,
    at the configuration in `data`)."""
    low: dict[int, np.ndarray] = {}
    for g in geom.geometryObjects:
        j = g.parentJoint
        world = np.array([data.oMi[j].act(p) for p in _geom_points(g)])
        low[j] = np.vstack([low[j], world]) if j in low else world
    feet = {}
    for side, sign in (("left", 1), ("right", -1)):
        cands = [(pts[:, 2].min(), j) for j, pts in low.items() if j > 1 and sign * data.oMi[j].translation[1] > 0.02]
        if cands:
            feet[side] = min(cands)[1]
    return feet, low


def _axis(model: pin.Model, j: int) -> np.ndarray:
    jm = model.joints[j]
    sn = jm.shortname()
    for c, a in (("X", [1, 0, 0]), ("Y", [0, 1, 0]), ("Z", [0, 0, 1])):
        if sn.endswith(c) and "Unaligned" not in sn:
            return np.array(a, float)
    if hasattr(jm, "extract"):
        ext = jm.extract()
        if hasattr(ext, "axis"):
            return np.asarray(ext.axis, float)
    return np.zeros(3)


def run_command(args) -> int:
    """`wbcbench robot init SOURCE --out PROFILE.yaml`."""
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        raise ConfigError(f"'{out}' exists; pass --overwrite to replace it", key="--out")
    gen = generate_profile(args.source, name=args.name, knee=args.knee)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(gen.text)
    from .profile import load_profile
    from .robot import Robot

    Robot(load_profile(out))  # the profile loads and builds the model
    print(f"wrote {out}")
    print("not found: " + "; ".join(gen.missing) + " (fill these keys)" if gen.missing
          else "found everything: feet, soles, F/T, IMU, hands, posture, gains, limits")
    return 0
