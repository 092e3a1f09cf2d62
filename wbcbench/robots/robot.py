"""The Robot: a pinocchio model built from a URDF or an MJCF model, plus its profile.

One `Robot` is shared by planners, controllers, estimators and metrics; the simulator builds its MuJoCo
model from the same file (`Robot.files.path`) so the two never disagree about masses or frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import ConfigError, UnknownNameError
from .profile import RobotProfile, Side, load_profile


@dataclass(frozen=True)
class ModelFiles:
    """The files a profile's `loader` names: the model (`path`, in `format` "urdf" or "mjcf"), an SRDF, the directory
    `package://` resolves to, and whether the SRDF carries rotor parameters."""

    path: Path
    srdf: Path | None
    package_root: Path  # directory that `package://example-robot-data/` resolves to (its parent)
    has_rotor_parameters: bool
    format: str = "urdf"

    @property
    def urdf(self) -> Path:
        """The URDF (for code that reads URDF only; an MJCF model raises the one-line error that says so)."""
        if self.format != "urdf":
            raise ConfigError("this needs a URDF model; the robot's is MJCF", file=str(self.path), key="loader")
        return self.path

    @property
    def is_mjcf(self) -> bool:
        return self.format == "mjcf"


MJCF_SUFFIXES = (".xml", ".mjcf")
"""Model files in MuJoCo's format (MJCF): read by pinocchio (`buildModelFromMJCF`) and MuJoCo (`MjSpec.from_file`)."""
MENAGERIE_PREFIX = "menagerie:"
"""A `loader` / SOURCE `menagerie:<robot>[/<entry>]`: a MuJoCo Menagerie model through the `mujoco-menagerie` package's
download cache (the robot's default model unless an entry is named)."""


def _model_path(name: str, profile_file: str) -> Path:
    path = Path(name).expanduser()
    if not path.is_absolute() and profile_file:
        path = Path(profile_file).parent / path
    return path


def _model_files(loader_name: str, profile_file: str) -> ModelFiles:
    """The model files a profile's `loader` names: an example-robot-data loader name, `fourier:<model>` (a URDF of
    the `fourier-robot-descriptions` package), `menagerie:<robot>[/<entry>]`, a URDF path or an MJCF path (.xml,
    .mjcf; relative paths from the profile's directory)."""
    if loader_name.lower().endswith(MJCF_SUFFIXES):
        return _mjcf_files(_model_path(loader_name, profile_file), profile_file or "", "loader")
    if loader_name.startswith(MENAGERIE_PREFIX):
        return _mjcf_files(menagerie_model(loader_name, profile_file, "loader"), profile_file or "", "loader")
    if loader_name.startswith("fourier:") or loader_name.endswith(".urdf"):
        return _urdf_files(loader_name, profile_file)
    from example_robot_data.robots_loader import ROBOTS
    from example_robot_data.utils import getModelPath

    if loader_name not in ROBOTS:
        raise UnknownNameError("example-robot-data loader", loader_name, ROBOTS, file=profile_file, key="loader")
    cls = ROBOTS[loader_name]
    if not cls.urdf_filename:
        raise ConfigError(f"loader '{loader_name}' has no URDF (SDF models are not supported)",
                          file=profile_file, key="loader")
    rel = Path(cls.path) / cls.urdf_subpath / cls.urdf_filename
    root = Path(getModelPath(str(rel)))
    srdf = root / cls.path / cls.srdf_subpath / cls.srdf_filename if cls.srdf_filename else None
    # URDF meshes are "package://example-robot-data/robots/...": the package root is two levels above robots/
    return ModelFiles(path=(root / rel).resolve(), srdf=srdf.resolve() if srdf else None,
                      package_root=root.resolve().parent.parent,
                      has_rotor_parameters=bool(getattr(cls, "has_rotor_parameters", False)))


def _mjcf_files(path: Path, file: str, key: str) -> ModelFiles:
    if not path.is_file():
        raise ConfigError(f"model file '{path}' does not exist", file=file or str(path), key=key)
    return ModelFiles(path=path.resolve(), srdf=None, package_root=path.resolve().parent,
                      has_rotor_parameters=False, format="mjcf")


def menagerie_model(source: str, file: str, key: str) -> Path:
    """The MJCF file of `menagerie:<robot>[/<entry>]` (the robot's default model, without a scene, unless an entry
    is named) in the `mujoco-menagerie` package's cache, downloaded on first use (or from the Menagerie checkout
    MENAGERIE_ROOT names); one-line errors when the package or the network is absent, or a name unknown."""
    name, _, entry = source[len(MENAGERIE_PREFIX):].partition("/")
    where = {"file": file or None, "key": key}
    try:
        import mujoco_menagerie as mm
    except ImportError:
        raise ConfigError(f"'{source}' needs the mujoco-menagerie package (pip install mujoco-menagerie) and, on "
                          "first use, the network to download the model", **where) from None
    if name not in mm.names():
        raise UnknownNameError("Menagerie robot", name, mm.names(), **where)
    robot = mm.get(name)
    if entry and entry not in robot.entry_names:
        raise UnknownNameError(f"entry of Menagerie robot '{name}'", entry, robot.entry_names, **where)
    try:
        return Path(robot.xml(entry or robot.default_model))  # downloads the model on first use
    except Exception as exc:  # no network, a failed download or checksum, a missing checkout: one line
        raise ConfigError(f"'{source}' could not be fetched (Menagerie models are downloaded on first use: is the "
                          f"network reachable? MENAGERIE_ROOT may name a local checkout): {type(exc).__name__}: "
                          f"{exc}", **where) from None


def build_pinocchio_model(files: ModelFiles, file: str = "") -> pin.Model:
    """The pinocchio model of the files, with a free-flyer root: the URDF's root link gets one; an MJCF must have
    a free joint on its root body (pinocchio reads it as the free flyer). `file`: the profile, for errors."""
    if not files.is_mjcf:
        return pin.buildModelFromUrdf(str(files.path), pin.JointModelFreeFlyer())
    try:
        model = pin.buildModelFromMJCF(str(files.path))
    except (ValueError, RuntimeError) as exc:
        raise ConfigError(f"pinocchio cannot read the MJCF model '{files.path}': {exc}", file=file or str(files.path),
                          key="loader") from None
    if model.njoints < 2 or model.joints[1].shortname() != "JointModelFreeFlyer":
        raise ConfigError(f"MJCF model '{files.path}' has no free joint on its root body; add "
                          "<freejoint/> to the robot's root body (the floating base)", file=file or str(files.path),
                          key="loader")
    _mjcf_actuator_effort_limits(model, files.path)
    return model


def _mjcf_actuator_effort_limits(model: pin.Model, path: Path) -> None:
    """Effort limits [N m] of the joints whose MJCF gives no `actuatorfrcrange` (pinocchio: inf) from the file's
    actuators on them: the actuator's force range, else a motor's control range times its gear and gain."""
    missing = [j for j in range(2, model.njoints) if not np.isfinite(model.effortLimit[model.idx_vs[j]])]
    if not missing:
        return
    import mujoco  # (the MJCF's actuators, their defaults applied, as MuJoCo reads them)

    spec = mujoco.MjSpec.from_file(str(path))
    limit = {}
    for a in spec.actuators:
        if a.trntype != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        lo, hi = a.forcerange
        if a.forcelimited != mujoco.mjtLimited.mjLIMITED_FALSE and hi > lo:
            tau = max(abs(lo), abs(hi))
        elif (a.ctrllimited != mujoco.mjtLimited.mjLIMITED_FALSE and a.ctrlrange[1] > a.ctrlrange[0]
              and a.biastype == mujoco.mjtBias.mjBIAS_NONE):
            tau = max(abs(a.ctrlrange[0]), abs(a.ctrlrange[1])) * abs(a.gear[0] * a.gainprm[0])
        else:
            continue
        limit[a.target] = max(limit.get(a.target, 0.0), float(tau))
    eff = model.effortLimit.copy()
    for j in missing:
        if model.names[j] in limit:
            eff[model.idx_vs[j]] = limit[model.names[j]]
    model.effortLimit = eff


def build_geometry(model: pin.Model, files: ModelFiles, kind: pin.GeometryType) -> pin.GeometryModel:
    """The model's collision or visual geometry (URDF <collision>/<visual>; MJCF geoms)."""
    if files.is_mjcf:
        return pin.buildGeomFromMJCF(model, str(files.path), kind)
    return pin.buildGeomFromUrdf(model, str(files.path), kind, package_dirs=[str(files.package_root)])


def _urdf_files(loader_name: str, profile_file: str) -> ModelFiles:
    if loader_name.startswith("fourier:"):
        try:
            from fourier_robot_descriptions.fourier import PACKAGE_PATH
        except ImportError:
            raise ConfigError("fourier models need the fourier-robot-descriptions package (pip install "
                              "fourier-robot-descriptions)", file=profile_file, key="loader") from None
        name = loader_name.split(":", 1)[1]
        urdf = PACKAGE_PATH / f"{name}.urdf"
        if not urdf.exists():
            raise UnknownNameError("fourier model", name, sorted(p.stem for p in PACKAGE_PATH.glob("*.urdf")),
                                   file=profile_file, key="loader")
        # their meshes are "../meshes/<model>/...", relative to the URDF's folder (GR2, Qinglong: only found there)
        return ModelFiles(path=urdf.resolve(), srdf=None, package_root=PACKAGE_PATH.resolve(),
                          has_rotor_parameters=False)
    urdf = Path(loader_name).expanduser()
    if not urdf.is_absolute() and profile_file:
        urdf = Path(profile_file).parent / urdf
    if not urdf.is_file():
        raise ConfigError(f"model file '{urdf}' does not exist", file=profile_file, key="loader")
    return ModelFiles(path=urdf.resolve(), srdf=None, package_root=urdf.resolve().parent,
                      has_rotor_parameters=False)


def _urdf_link_inertias(urdf: Path) -> dict[str, pin.Inertia]:
    """Each URDF link's inertia in its link frame (zero for a link without <inertial>)."""
    import xml.etree.ElementTree as ET

    out = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        el = link.find("inertial")
        if el is None:
            out[link.get("name")] = pin.Inertia.Zero()
            continue
        origin = el.find("origin")
        xyz = np.array((origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split(), float)
        rpy = np.array((origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split(), float)
        mass = float(el.find("mass").get("value")) if el.find("mass") is not None else 0.0
        ie = el.find("inertia")
        g = (lambda k: float(ie.get(k, 0.0))) if ie is not None else (lambda k: 0.0)
        I = np.array([[g("ixx"), g("ixy"), g("ixz")], [g("ixy"), g("iyy"), g("iyz")], [g("ixz"), g("iyz"), g("izz")]])
        R = pin.rpy.rpyToMatrix(*rpy)
        out[link.get("name")] = pin.Inertia(mass, xyz, R @ I @ R.T)
    return out


class Robot:
    """A floating-base robot: pinocchio model (free flyer at the root), profile and derived quantities.

    Conventions: q = [p_world_base (3), quat_world_base (x, y, z, w), joints]; v = [v_base (3, LOCAL),
    w_base (3, LOCAL), joint velocities]. Joint order is pinocchio's (URDF tree order).
    """

    def __init__(self, profile: RobotProfile):
        self.profile = profile
        self.files = _model_files(profile.loader, profile.file)
        model = build_pinocchio_model(self.files, profile.file)
        if self.files.srdf is not None and self.files.has_rotor_parameters:
            pin.loadRotorParameters(model, str(self.files.srdf), False)
            model.armature = np.multiply(model.rotorInertia, np.square(model.rotorGearRatio))
        if profile.armature is not None:
            arm = model.armature.copy()
            arm[6:] = profile.armature
            model.armature = arm
        self._apply_limits(model)
        if profile.min_body_mass > 0 or profile.min_body_inertia > 0:
            if self.files.is_mjcf:
                raise ConfigError("min_body_mass / min_body_inertia apply to URDF models; give the MJCF's bodies "
                                  "their <inertial>", file=profile.file, key="limits.min_body_mass")
            self._bound_inertias(model)
        self.model = model
        self._add_sole_frames()
        self.data = self.model.createData()
        self.q0 = self._reference_configuration()

    # ------------------------------------------------------------------ construction helpers
    def _bound_inertias(self, model: pin.Model) -> None:
        """Massless links get the profile's minimum mass and inertia, link by link as MuJoCo's boundmass /
        boundinertia do before fusing fixed links into their moving body (a massless fixed link adds the bound
        mass at its origin)."""
        m_min, i_min = self.profile.min_body_mass, self.profile.min_body_inertia
        links = _urdf_link_inertias(self.files.urdf)
        body = {f.name: f for f in model.frames if f.type == pin.FrameType.BODY}

        def bounded(Y: pin.Inertia) -> pin.Inertia:
            w, V = np.linalg.eigh(Y.inertia)
            if Y.mass >= m_min and w.min() >= i_min:
                return Y
            return pin.Inertia(max(Y.mass, m_min), Y.lever, V @ np.diag(np.maximum(w, i_min)) @ V.T)

        for j in range(1, model.njoints):
            total, changed = pin.Inertia.Zero(), False
            for name, f in body.items():
                if f.parentJoint != j or name not in links:
                    continue
                Y = bounded(links[name])
                changed |= Y is not links[name]
                total += f.placement.act(Y)
            if changed:
                model.inertias[j] = total

    def _apply_limits(self, model: pin.Model) -> None:
        lo, hi = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
        lo[:7], hi[:7] = -np.inf, np.inf
        for jname, (a, b) in self.profile.position_limit_overrides.items():
            if not model.existJointName(jname):
                raise UnknownNameError("joint", jname, list(model.names)[2:], file=self.profile.file,
                                       key="limits.position_overrides")
            jid = model.getJointId(jname)
            lo[model.idx_qs[jid]], hi[model.idx_qs[jid]] = a, b
        model.lowerPositionLimit, model.upperPositionLimit = lo, hi
        # effort and velocity limits by joint-name prefix (the longest matching prefix wins)
        for key, attr in (("effort_overrides", "effortLimit"), ("velocity_overrides", "velocityLimit")):
            table = getattr(self.profile, key)
            if not table:
                continue
            lim = getattr(model, attr).copy()
            for jid in range(2, model.njoints):
                name = model.names[jid]
                best = max((p for p in table if name.startswith(p)), key=len, default=None)
                if best is not None:
                    lim[model.idx_vs[jid]:model.idx_vs[jid] + model.nvs[jid]] = table[best]
            setattr(model, attr, lim)
        slow = [model.names[j] for j in range(2, model.njoints)
                if not np.isfinite(model.velocityLimit[model.idx_vs[j]])]
        if slow:  # (an MJCF states no velocity limits)
            raise ConfigError(f"joints without a velocity limit in the model: {', '.join(slow[:6])}"
                              f"{', ...' if len(slow) > 6 else ''}; give them one (joint-name prefix -> rad/s)",
                              file=self.profile.file, key="limits.velocity_overrides")
        bad = [model.names[j] for j in range(2, model.njoints) if not 0 < model.effortLimit[model.idx_vs[j]] < np.inf]
        if bad:
            raise ConfigError(f"joints without an effort limit in the model: {', '.join(bad[:6])}"
                              f"{', ...' if len(bad) > 6 else ''}; give them one (joint-name prefix -> N m)",
                              file=self.profile.file, key="limits.effort_overrides")

    def _frame_id(self, name: str, key: str) -> int:
        if not self.model.existFrame(name):
            raise UnknownNameError("frame", name, [f.name for f in self.model.frames], file=self.profile.file,
                                   key=key)
        return self.model.getFrameId(name)

    def _add_sole_frames(self) -> None:
        for side, foot in self.profile.feet.items():
            if foot.parent_frame is None:
                self._frame_id(foot.frame, f"feet.{side.value}.frame")
                continue
            pid = self._frame_id(foot.parent_frame, f"feet.{side.value}.parent_frame")
            parent = self.model.frames[pid]
            placement = parent.placement * pin.SE3(pin.rpy.rpyToMatrix(*map(float, foot.rpy)),
                                                   np.asarray(foot.offset))
            self.model.addFrame(pin.Frame(foot.frame, parent.parentJoint, pid, placement, pin.FrameType.OP_FRAME))
        for side in Side:
            self._frame_id(self.profile.feet[side].ft_sensor_frame, f"feet.{side.value}.ft_sensor_frame")
            self._frame_id(self.profile.hands[side], f"hands.{side.value}")
        for key in ("base_frame", "torso_frame", "imu_frame", "head_frame"):
            self._frame_id(getattr(self.profile, key), key)
        for side, rep in self.profile.repulsors.items():
            self._frame_id(rep.frame, f"repulsors.{side.value}.frame")
            for i, point in enumerate(rep.points):
                self._frame_id(point.frame, f"repulsors.{side.value}.points[{i}].frame")
        bodies = [f.name for f in self.model.frames if f.type == pin.FrameType.BODY]
        for side, check in self.profile.collision_check.items():
            for key in ("effector", "bodies"):
                for link in getattr(check, key):
                    if link not in bodies:
                        raise UnknownNameError("link", link, bodies, file=self.profile.file,
                                               key=f"collision_check.{side.value}.{key}")

    def _reference_configuration(self) -> np.ndarray:
        model = self.model
        posture = self.profile.reference_posture
        if isinstance(posture, str):
            if self.files.srdf is None:
                raise ConfigError(f"'{posture}' names an SRDF state but the robot has no SRDF; give a mapping "
                                  "joint -> angle", file=self.profile.file, key="reference_posture")
            pin.loadReferenceConfigurations(model, str(self.files.srdf), False)
            names = [entry.key() for entry in model.referenceConfigurations]
            if posture not in names:
                raise UnknownNameError("SRDF state", posture, names, file=self.profile.file,
                                       key="reference_posture")
            q = np.array(model.referenceConfigurations[posture], dtype=float)
        else:
            q = pin.neutral(model)
            for jname, val in posture.items():
                if not model.existJointName(jname):
                    raise UnknownNameError("joint", jname, self.joint_names, file=self.profile.file,
                                           key="reference_posture")
                q[model.idx_qs[model.getJointId(jname)]] = val
        q[:3] = 0.0
        q[3:7] = [0, 0, 0, 1]
        q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        # Put the base at the height where the highest sole corner touches z = 0 (every corner at or below it), the
        # feet centred about x = y = 0. A posture with tilted soles (TALOS' half_sitting turns both ankle rolls by
        # -1.7 mrad, one sole edge 0.22 mm below the other) then starts with both edges of each sole on the ground:
        # with the sole origins at z = 0 each sole rested on one edge for the first 4 ms, the ZMP 6 cm to the side.
        pin.framesForwardKinematics(model, self.data, q)
        soles = np.array([self.data.oMf[self.sole_frame_id(s)].translation for s in Side])
        q[0] = -soles[:, 0].mean()
        q[1] = -soles[:, 1].mean()
        q[2] = -max(self.sole_rest_height(self.data, s) for s in Side)
        return q

    # ------------------------------------------------------------------ accessors
    @property
    def name(self) -> str:
        return self.profile.name

    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    @property
    def na(self) -> int:
        """Number of actuated joints (nv - 6)."""
        return self.model.nv - 6

    @cached_property
    def joint_names(self) -> list[str]:
        """Actuated joint names in pinocchio order (all 1-DoF joints after the free flyer)."""
        names = list(self.model.names)[2:]
        for jid in range(2, self.model.njoints):
            if self.model.nvs[jid] != 1 or self.model.nqs[jid] != 1:
                raise ConfigError(f"joint '{self.model.names[jid]}' is not a 1-DoF revolute/prismatic joint; "
                                  "only those are supported", file=self.profile.file)
        return names

    @cached_property
    def mass(self) -> float:
        return float(pin.computeTotalMass(self.model))

    def sole_frame_id(self, side: Side) -> int:
        return self.model.getFrameId(self.profile.feet[side].frame)

    def sole_rest_height(self, data: pin.Data, side: Side) -> float:
        """z [m] of the highest corner of a side's sole rectangle, in `data`'s frame placements: the ground a
        sole tilted by its posture rests on (its other corners at or below it)."""
        M = data.oMf[self.sole_frame_id(side)]
        return max(float(M.act(c)[2]) for c in self.profile.sole.corners)

    def frame_id(self, name: str) -> int:
        return self._frame_id(name, "frame")

    @cached_property
    def effort_limit(self) -> np.ndarray:
        return np.array(self.model.effortLimit[6:], dtype=float)

    @cached_property
    def velocity_limit(self) -> np.ndarray:
        return np.array(self.model.velocityLimit[6:], dtype=float)

    @cached_property
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array(self.model.lowerPositionLimit[7:]), np.array(self.model.upperPositionLimit[7:]))

    def foot_below_sensor(self, side: Side) -> tuple[float, np.ndarray]:
        """Mass [kg] and CoM (in the F/T sensor frame) [m] of everything below the ankle F/T sensor.

        Computed from the model: the inertias of the sensor's joint subtree, so the ZMP estimator can remove
        the foot's own weight from the sensor reading.
        """
        fid = self.model.getFrameId(self.profile.feet[side].ft_sensor_frame)
        frame = self.model.frames[fid]
        jid = frame.parentJoint
        total = pin.Inertia.Zero()
        pin.forwardKinematics(self.model, self.data, self.q0)
        oMj = self.data.oMi[jid]
        for k in range(jid, self.model.njoints):
            if jid in self.model.supports[k]:
                total += (oMj.inverse() * self.data.oMi[k]).act(self.model.inertias[k])
        in_sensor = frame.placement.actInv(total) if frame.type != pin.FrameType.JOINT else total
        return float(in_sensor.mass), np.array(in_sensor.lever)

    def arm_joint_ids(self) -> set[int]:
        """The arms' own joints (pinocchio joint ids): those that carry one gripper (the protected frame of a side's
        `repulsors` in the profile) and not the other; empty unless the profile gives both sides."""
        m = self.model
        chains = [set(m.supports[m.frames[m.getFrameId(spec.frame)].parentJoint])
                  for spec in self.profile.repulsors.values()]
        return chains[0] ^ chains[1] if len(chains) == 2 else set()

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.nq}, nv={self.nv}, mass={self.mass:.2f} kg)"


def load_robot(name_or_path: str) -> Robot:
    """Build a Robot from a profile name (see `available_robots()`) or a profile YAML path."""
    return Robot(load_profile(name_or_path))
