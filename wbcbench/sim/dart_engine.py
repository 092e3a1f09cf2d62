"""DART (`dartpy`) as a second physics engine: the same robot file, terrain, actuation modes and sensors as the
MuJoCo `Simulator`, behind the same interface (see `wbcbench.sim.engines`).

The model, built from the URDF pinocchio reads (visuals and collision meshes removed, as for MuJoCo):
- a free root joint; DART's free joint has positions (rotation vector, translation) and velocities (angular,
  linear) in the world frame, the linear one of the base origin; converted to pinocchio's conventions (base
  frame, linear first) only in `_DartBridge`;
- one box per sole matching the profile's rectangle (bottom face on the sole plane), the terrain's floor and
  boxes as boxes of a fixed skeleton; no other collision geometry, no self-collision;
- contacts by DART's collision detector (`ode` by default: four points on a flat sole) and its boxed-LCP
  solver; Coulomb friction with the sole's and terrain's coefficient (DART uses the smaller of two shapes');
- the URDF's joint damping and Coulomb friction (DART's own joint friction constraint).

Differences from the MuJoCo model that cannot be removed (stated in every engine comparison):
- DART 6 has no joint armature: the pinocchio model's rotor inertia (0.1 kg m^2 on TALOS' actuated joints) is
  absent from the simulated robot. The controller keeps its nominal model, as it would on a robot whose rotor
  inertia it over-estimates. The bridge test compares DART's mass matrix with pinocchio's without armature.
- Position mode: the servo PD (kp (q_ref - q) + kd (v_ref - v), MuJoCo's position actuator) evaluated at the
  next step's state predicted from the skeleton's dynamics (stable PD, Tan et al. 2011: stable at the profile's
  gains without armature, as MuJoCo's implicit integration is) and clipped to the effort limit (MuJoCo's actuator
  force range); the same law as the spd mode. With rigid contacts and no armature, TALOS held at half-sitting by
  its servos alone (no balance controller) rocks from foot to foot (about 5 mm at the base); the stabilized
  controllers walk. Tried and not kept: DART's implicit joint springs, unclipped (the 10x-Menagerie ankle servos
  fought the rigid ground with 600 N m standing and up to 10 kN m walking; the position schemes' energies were
  20-70 times MuJoCo's; TSID position fell in every scene), clipped by moving the rest position (the saturated
  ankles tipped the robot over), or switched off for a saturated joint's step (chatter: the feet bounced).
- Contacts are rigid (an LCP with a small error-reduction and a penetration allowance), MuJoCo's soft.

Sensors, as in MuJoCo: the IMU (orientation, gyro in the IMU frame, accelerometer: the IMU point's acceleration
over the last step minus gravity, in its frame), the ankle F/T (the wrench the leg exerts on the foot, in the
sensor frame: DART's transmitted body wrench of the sensor's body, constraint impulses included).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys

import numpy as np
import pinocchio as pin

from ..errors import ConfigError, UnknownNameError
from ..robots import Robot, Side
from ..scene import Terrain
from ..types import ActuationMode, Command, Measurement
from .model import SimOptions
from .push import Push
from .simulator import FallStatus

try:  # dartpy is an optional extra (pip install 'wbcbench[dart]')
    import dartpy as dart
except ImportError:  # pragma: no cover - checked by the engine registry before use
    dart = None

__all__ = ["DartSimulator", "COLLISION_DETECTORS"]

#: DART collision detectors by name (`SimOptions.extra["dart_collision"]`)
COLLISION_DETECTORS = ("ode", "dart", "fcl", "bullet")


_STANDING = FallStatus(False)


def _urdf_text(robot: Robot) -> str:
    """The URDF without visuals and collision meshes, packages resolved (as the MuJoCo model is built)."""
    txt = robot.files.urdf.read_text()
    txt = re.sub(r"<visual\b.*?</visual>", "", txt, flags=re.S)
    txt = re.sub(r"<collision\b.*?</collision>", "", txt, flags=re.S)
    return txt.replace("package://", str(robot.files.package_root) + "/")


@contextlib.contextmanager
def _quiet_native_stderr():
    """DART's loader warns on the process' standard error for every massless URDF link (TALOS' camera frames):
    silenced while the model is built, since wbcbench states the massless links' treatment itself."""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, ValueError, OSError):  # no real file descriptor (e.g. captured): nothing to silence
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
            yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


def _links_without_inertial(urdf: str) -> list[str]:
    """The names of the URDF's links that have no <inertial> element."""
    out = []
    for m in re.finditer(r"<link\b[^>]*?\bname=\"([^\"]+)\"[^>]*?(/>|>(.*?)</link>)", urdf, flags=re.S):
        if m.group(2) == "/>" or "<inertial" not in (m.group(3) or ""):
            out.append(m.group(1))
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors (numpy's cross costs ten times more on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _isometry(R: np.ndarray, p: np.ndarray):
    T = dart.math.Isometry3()
    T.set_rotation(np.asarray(R, dtype=float))
    T.set_translation(np.asarray(p, dtype=float))
    return T


class _DartBridge:
    """Index maps and conversions between a DART skeleton and a Robot's pinocchio model (joints by name)."""

    def __init__(self, robot: Robot, skel):
        pm = robot.model
        self.nq, self.nv = pm.nq, pm.nv
        self.ndof = skel.getNumDofs()
        dofs = {skel.getDof(i).getName(): i for i in range(self.ndof)}
        pin_q, pin_v, dart_i = [], [], []
        for name in robot.joint_names:
            if name not in dofs:
                raise ConfigError(f"joint '{name}' of the pinocchio model is missing in the DART model",
                                  file=robot.profile.file)
            jid = pm.getJointId(name)
            pin_q.append(pm.idx_qs[jid])
            pin_v.append(pm.idx_vs[jid])
            dart_i.append(dofs[name])
        self.pin_q_idx, self.pin_v_idx = np.array(pin_q), np.array(pin_v)
        self.dart_idx = np.array(dart_i)

    def q_from_dart(self, pos: np.ndarray) -> np.ndarray:
        q = np.empty(self.nq)
        R = pin.exp3(pos[0:3])
        q[0:3] = pos[3:6]
        q[3:7] = pin.Quaternion(R).coeffs()
        q[self.pin_q_idx] = pos[self.dart_idx]
        return q

    def v_from_dart(self, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        v = np.empty(self.nv)
        R = pin.exp3(pos[0:3])
        v[0:3] = R.T @ vel[3:6]   # DART: (angular, linear) in the world frame; pinocchio: (linear, angular) local
        v[3:6] = R.T @ vel[0:3]
        v[self.pin_v_idx] = vel[self.dart_idx]
        return v

    def q_to_dart(self, q: np.ndarray) -> np.ndarray:
        pos = np.zeros(self.ndof)
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        pos[0:3] = pin.log3(R)
        pos[3:6] = q[0:3]
        pos[self.dart_idx] = q[self.pin_q_idx]
        return pos

    def v_to_dart(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        vel = np.zeros(self.ndof)
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        vel[0:3] = R @ v[3:6]
        vel[3:6] = R @ v[0:3]
        vel[self.dart_idx] = v[self.pin_v_idx]
        return vel


class DartSimulator:
    """A profiled robot in DART, with the interface of `wbcbench.sim.simulator.Simulator` that the run loop,
    sensing, faults and pushes use (`measure`, `apply`, `step`, `read_tick`, `true_q`, `set_pushes`, ...)."""

    engine = "dart"
    #: what a comparison with another engine must say beside its numbers (the engine-sensitivity report prints it)
    COMPARISON_NOTE = (
        "DART 6 has no joint armature: its TALOS lacks the 0.1 kg m^2 rotor inertia of every actuated joint (the "
        "controllers keep it in their model), and its contacts are rigid (MuJoCo's soft). Measured cause of the "
        "position-controlled schemes' larger errors and falls: in MuJoCo with the armature removed, IK and TSID "
        "position fall on sway and walk-20cm-quick while TSID torque walks as before. Tried for DART's position "
        "servo and not kept: its implicit joint springs unclipped, clipped by the rest position, switched off when "
        "saturated; DART's own, FCL and Bullet collision detectors (docs/results/engines.md).")

    def __init__(self, robot: Robot, terrain: Terrain | None = None, mode: ActuationMode | str = "torque",
                 options: SimOptions | None = None, pushes: tuple[Push, ...] = (), model_error=None):
        if dart is None:
            raise ConfigError("the 'dart' engine needs dartpy: pip install 'wbcbench[dart]'", key="--engine")
        if robot.files.is_mjcf:
            raise ConfigError(f"the 'dart' engine reads URDF models only and robot '{robot.name}' is MJCF "
                              f"({robot.files.path.name}); run it with --engine mujoco", file=robot.profile.file or None,
                              key="--engine")
        if model_error is not None:
            raise ConfigError("model error (mass, friction and payload changes) is applied to MuJoCo models only; "
                              "run it with --engine mujoco", key="model_error")
        self.robot = robot
        self.mode = ActuationMode(mode)
        self.options = options or SimOptions()
        if self.options.self_collision == "physical":  # "detect" counts on a kinematic MuJoCo copy: engine-free
            raise ConfigError("self_collision 'physical' (collision geometry in the simulated robot) needs the mujoco "
                              "engine; 'detect' works with any", key="self_collision")
        self.terrain = terrain or Terrain()
        self.model_error = {}
        self.dt = float(self.options.timestep)
        self._gravity = np.asarray(self.options.gravity, dtype=float)
        detector = str(self.options.extra.get("dart_collision", "ode"))
        if detector not in COLLISION_DETECTORS:
            raise ConfigError(f"unknown DART collision detector '{detector}'; allowed: "
                              f"{', '.join(COLLISION_DETECTORS)}", key="dart_collision")
        self.world = dart.simulation.World()
        self.world.setTimeStep(self.dt)
        self.world.setGravity(np.asarray(self.options.gravity, dtype=float))
        self.world.setCollisionDetector({"ode": dart.collision.OdeCollisionDetector,
                                         "dart": dart.collision.DARTCollisionDetector,
                                         "fcl": dart.collision.FCLCollisionDetector,
                                         "bullet": dart.collision.BulletCollisionDetector}[detector]())
        with _quiet_native_stderr():
            self.skel = self._load_robot()
        self.world.addSkeleton(self.skel)
        self.ground = self._build_terrain()
        if self.ground is not None:
            self.world.addSkeleton(self.ground)
        self.bridge = _DartBridge(robot, self.skel)
        self.kp, self.kd = robot.profile.position_gains.resolve(robot.joint_names, robot.profile.file)
        self.effort = np.asarray(robot.effort_limit, dtype=float)
        self._act = self.bridge.dart_idx
        self._urdf_damping = np.array([self.skel.getDof(int(i)).getDampingCoefficient() for i in self._act])
        self._sole_shapes = {}
        self._ft_body = {}
        self._ft_placement = {}
        self._add_feet()
        imu_body, imu_M = self._body_and_placement(robot.profile.imu_frame)
        self._imu_body, self._imu_M = imu_body, imu_M
        self._sole_bodies = {s: self._body_and_placement(robot.profile.feet[s].frame)[0] for s in Side}
        self._min_base_height = float(robot.profile.min_base_height)
        self._max_tilt = float(robot.profile.max_tilt)
        self._fault = {}  # joint index -> "cut" | "passive" | "locked"
        self._tau = np.zeros(robot.na)
        self.set_pushes(pushes)
        self.reset()

    # ------------------------------------------------------------------ model
    def _load_robot(self):
        loader = dart.utils.DartLoader()
        skel = loader.parseSkeletonString(_urdf_text(self.robot), dart.common.Uri(str(self.robot.files.urdf)))
        if skel is None:
            raise ConfigError("DART cannot read the robot's URDF", file=str(self.robot.files.urdf))
        if skel.getRootJoint().getType() != "FreeJoint":
            raise ConfigError("the DART model's root joint is not free", file=str(self.robot.files.urdf))
        skel.disableSelfCollisionCheck()
        for i in range(skel.getNumDofs()):
            skel.getDof(i).setSpringStiffness(0.0)
        # a URDF link without <inertial> is massless (URDF, pinocchio, MuJoCo); DART's loader gives it 1 kg
        for name in _links_without_inertial(self.robot.files.urdf.read_text()):
            body = skel.getBodyNode(name)
            if body is not None:
                body.setMass(0.0)
                body.setMomentOfInertia(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return skel

    def _body_and_placement(self, frame_name: str):
        """The DART body carrying a pinocchio frame, and the frame's placement in that body (pin.SE3)."""
        pm = self.robot.model
        if not pm.existFrame(frame_name):
            raise UnknownNameError("frame", frame_name, [f.name for f in pm.frames], key="frame")
        f = pm.frames[pm.getFrameId(frame_name)]
        body = self.skel.getBodyNode(frame_name)
        if body is not None:  # a link of the URDF (a body of its own in DART, fixed joints are not merged)
            return body, pin.SE3.Identity()
        joint_name = pm.names[f.parentJoint]
        child = self.skel.getJoint(joint_name).getChildBodyNode() if f.parentJoint > 0 else self.skel.getRootBodyNode()
        return child, f.placement

    def _add_feet(self) -> None:
        sole = self.robot.profile.sole
        for side in Side:
            foot = self.robot.profile.feet[side]
            body, M = self._body_and_placement(foot.frame)
            center = M.act(np.array([sole.center[0], sole.center[1], sole.thickness / 2]))
            shape = dart.dynamics.BoxShape(np.array([sole.length, sole.width, sole.thickness]))
            node = body.createShapeNode(shape)
            node.setRelativeTransform(_isometry(M.rotation, center))
            node.createCollisionAspect()
            node.createDynamicsAspect().setFrictionCoeff(self.options.sole_friction)
            node.createVisualAspect().setColor(np.array([0.2, 0.2, 0.8]))
            self._sole_shapes[side] = node
            self._ft_body[side], self._ft_placement[side] = self._body_and_placement(foot.ft_sensor_frame)
        self._sole_names = {node.getName(): k for k, node in enumerate(self._sole_shapes.values())}

    def _build_terrain(self):
        t = self.terrain
        if not t.floor and not t.boxes:
            return None
        ground = dart.dynamics.Skeleton("terrain")
        _, body = ground.createWeldJointAndBodyNodePair()
        boxes = []
        if t.floor:  # a 200 m x 200 m x 1 m box whose top face is z = 0
            boxes.append(((200.0, 200.0, 1.0), np.eye(3), np.array([0.0, 0.0, -0.5])))
        for b in t.boxes:
            boxes.append((tuple(b.size), pin.rpy.rpyToMatrix(*b.rpy), np.asarray(b.center, dtype=float)))
        for size, R, p in boxes:
            node = body.createShapeNode(dart.dynamics.BoxShape(np.asarray(size, dtype=float)))
            node.setRelativeTransform(_isometry(R, p))
            node.createCollisionAspect()
            node.createDynamicsAspect().setFrictionCoeff(t.friction)
            node.createVisualAspect().setColor(np.array([0.5, 0.5, 0.5]))
        return ground

    def set_pushes(self, pushes: tuple[Push, ...]) -> None:
        """The external pushes of the following steps (replacing any; each active over its own time window)."""
        bodies = []
        for p in pushes:
            name = self.robot.profile.base_frame if p.body == "base" else p.body
            body = self.skel.getBodyNode(name)
            if body is None:
                names = [b.getName() for b in self.skel.getBodyNodes()]
                raise UnknownNameError("body for push", p.body, names, key="pushes.body")
            bodies.append(body)
        self.pushes, self._push_bodies = tuple(pushes), bodies

    # ------------------------------------------------------------------ state
    @property
    def t(self) -> float:
        return self._tick * self.dt

    @property
    def tick(self) -> int:
        return self._tick

    def reset(self, q: np.ndarray | None = None, v: np.ndarray | None = None) -> None:
        """Put the robot at pinocchio configuration q (default: the profile's reference posture) and velocity v."""
        q = self.robot.q0 if q is None else q
        self.skel.setPositions(self.bridge.q_to_dart(q))
        self.skel.setVelocities(self.bridge.v_to_dart(q, np.zeros(self.robot.nv) if v is None else v))
        self.skel.resetAccelerations()
        self.world.setTime(0.0)
        self._tick = 0
        self._command = Command(tau=np.zeros(self.robot.na), q=q[7:].copy(), v=np.zeros(self.robot.na))
        self._tau = np.zeros(self.robot.na)
        self._imu_w, self._imu_vel = self._imu_world_velocity()  # the IMU's velocities now (world frame)
        self._imu_acc = -self._gravity
        self._configure_joints()

    def true_q(self) -> np.ndarray:
        return self.bridge.q_from_dart(self.skel.getPositions())

    def true_v(self) -> np.ndarray:
        return self.bridge.v_from_dart(self.skel.getPositions(), self.skel.getVelocities())

    # ------------------------------------------------------------------ sensing
    def _imu_world_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """The IMU frame's angular and linear velocity in the world frame."""
        body = self._imu_body
        off = self._imu_M.translation
        w = np.asarray(body.getAngularVelocity(dart.dynamics.Frame.World(), dart.dynamics.Frame.World()))
        lin = np.asarray(body.getLinearVelocity(off, dart.dynamics.Frame.World(), dart.dynamics.Frame.World()))
        return w, lin

    def _ft_reading(self, side: Side) -> np.ndarray:
        """The F/T sensor's (force, torque) in its frame: the wrench the leg exerts on the foot."""
        F = np.asarray(self._ft_body[side].getBodyForce())  # (torque, force) in the body frame at its origin
        M = self._ft_placement[side]
        force_b, torque_b = F[3:6], F[0:3]
        R, p = M.rotation, M.translation
        torque_s = R.T @ (torque_b - _cross(p, force_b))
        return np.concatenate([R.T @ force_b, torque_s])

    def read_state(self) -> np.ndarray:
        """The state and sensors now (pinocchio conventions): q, v, IMU quaternion (x, y, z, w), gyro,
        accelerometer, then force and torque of the left and right ankle F/T sensors."""
        nq, nv = self.robot.nq, self.robot.nv
        out = np.empty(nq + nv + 22)
        out[:nq] = self.true_q()
        out[nq:nq + nv] = self.true_v()
        k = nq + nv
        T = self._imu_body.getWorldTransform()
        R = np.asarray(T.rotation()) @ self._imu_M.rotation
        out[k:k + 4] = pin.Quaternion(R).coeffs()
        out[k + 4:k + 7] = R.T @ self._imu_w
        out[k + 7:k + 10] = R.T @ self._imu_acc
        for j, side in enumerate(Side):
            ft = self._ft_reading(side)
            out[k + 10 + 6 * j:k + 16 + 6 * j] = ft
        return out

    def measure(self) -> Measurement:
        return self.measurement(self.read_state())

    def measurement(self, state: np.ndarray) -> Measurement:
        nq, nv = self.robot.nq, self.robot.nv
        k = nq + nv
        return Measurement(self._tick * self.dt, state[:nq], state[nq:k], state[k:k + 4], state[k + 4:k + 7],
                           state[k + 7:k + 10], {Side.LEFT: state[k + 10:k + 13], Side.RIGHT: state[k + 16:k + 19]},
                           {Side.LEFT: state[k + 13:k + 16], Side.RIGHT: state[k + 19:k + 22]})

    def contact_wrench_array(self) -> np.ndarray:
        """Ground-truth contact wrench on each sole, (2, 6), left then right: the force the ground exerts on the
        sole (world frame) and its moment about the world origin."""
        out = np.zeros((2, 6))
        contacts = self.world.getLastCollisionResult().getContacts()
        if not contacts:
            return out
        names = self._sole_names
        side, sign, forces, points = [], [], [], []
        for c in contacts:
            n1 = c.collisionObject1.getShapeFrame().getName()
            k = names.get(n1)
            if k is not None:  # DART's contact force acts on the first object
                s = 1.0
            else:
                k = names.get(c.collisionObject2.getShapeFrame().getName())
                if k is None:
                    continue
                s = -1.0
            side.append(k)
            sign.append(s)
            forces.append(c.force)
            points.append(c.point)
        if side:
            f = np.asarray(forces) * np.asarray(sign)[:, None]
            p = np.asarray(points)
            m = np.column_stack([p[:, 1] * f[:, 2] - p[:, 2] * f[:, 1], p[:, 2] * f[:, 0] - p[:, 0] * f[:, 2],
                                 p[:, 0] * f[:, 1] - p[:, 1] * f[:, 0]])
            np.add.at(out, np.asarray(side), np.column_stack([f, m]))
        return out

    def contact_wrenches(self) -> dict[Side, np.ndarray]:
        out = self.contact_wrench_array()
        return {s: out[k].copy() for k, s in enumerate(Side)}

    # ------------------------------------------------------------------ faults
    def set_joint_fault(self, joint: str, kind: str | None) -> None:
        """A joint's actuator fails: `cut` gives no torque, `passive` only damps (the profile's kd), `locked`
        brakes the joint (heavy damping); None restores it. The controller is not told."""
        if joint not in self.robot.joint_names:
            raise UnknownNameError("joint", joint, self.robot.joint_names, key="faults.target")
        i = self.robot.joint_names.index(joint)
        if kind is None:
            self._fault.pop(i, None)
        else:
            self._fault[i] = kind
        self._configure_joints()

    def _configure_joints(self) -> None:
        """Each actuated joint's implicit damping: a failed joint's, or the URDF's alone."""
        for i, d in enumerate(self._act):
            dof = self.skel.getDof(int(d))
            kind = self._fault.get(i)
            damping = float(self._urdf_damping[i])
            if kind == "passive":
                damping += float(self.kd[i])
            elif kind == "locked":
                damping += 1e5
            dof.setDampingCoefficient(damping)

    def fall_status(self) -> FallStatus:
        pos = self.skel.getPositions()
        if not np.all(np.isfinite(pos)) or not np.all(np.isfinite(self.skel.getVelocities())):
            return FallStatus(True, "simulation diverged (non-finite state)")
        base_z = pos[5]
        lower = min(float(np.asarray(self._sole_bodies[s].getWorldTransform().translation())[2]) for s in Side)
        height = base_z - lower
        if height < self._min_base_height:
            return FallStatus(True, f"base {height:.3f} m above the lower foot (< {self._min_base_height})")
        R = pin.exp3(pos[0:3])
        tilt = math.acos(min(1.0, max(-1.0, float(R[2, 2]))))
        if tilt > self._max_tilt:
            return FallStatus(True, f"base tilted {tilt:.2f} rad (> {self._max_tilt})")
        return _STANDING

    def read_tick(self, row: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, FallStatus]:
        """The state and sensors (`read_state`'s array, returned), the fall status, and the ground truth written
        into a log row at ``dst`` (q, v, applied torque, the soles' contact wrenches, the F/T readings), as
        `Simulator.read_tick`."""
        state = self.read_state()
        nq, nv, na = self.robot.nq, self.robot.nv, self.robot.na
        q0, v0, t0, c0, f0 = (int(x) for x in dst)
        row[q0:q0 + nq] = state[:nq]
        row[v0:v0 + nv] = state[nq:nq + nv]
        row[t0:t0 + na] = self._tau
        row[c0:c0 + 12] = self.contact_wrench_array().reshape(-1)
        row[f0:f0 + 12] = state[nq + nv + 10:nq + nv + 22]
        return state, self.fall_status()

    # ------------------------------------------------------------------ acting
    def apply(self, command: Command) -> None:
        """Set the command used by the following physics steps (held until the next call)."""
        self._command = command

    def _joint_torque(self) -> np.ndarray:
        """The actuators' torque for the next physics step (pinocchio joint order), before any fault."""
        cmd = self._command
        na = self.robot.na
        if self.mode is ActuationMode.TORQUE:
            tau = np.zeros(na) if cmd.tau is None else np.asarray(cmd.tau, dtype=float)
            return np.clip(tau, -self.effort, self.effort)
        return self._spd_torque()  # the position servo and SPD (see the module docstring)

    def _spd_torque(self) -> np.ndarray:
        """Stable PD (Tan et al. 2011): the PD on the next step's state, with the next acceleration predicted from
        the skeleton's dynamics (mass matrix, Coriolis and gravity, the last step's constraint forces)."""
        cmd = self._command
        skel, act, dt = self.skel, self._act, self.dt
        q, dq = skel.getPositions(), skel.getVelocities()
        M = np.asarray(skel.getMassMatrix())
        h = np.asarray(skel.getCoriolisAndGravityForces()) - np.asarray(skel.getConstraintForces())
        n = len(q)
        Kp, Kd = np.zeros(n), np.zeros(n)
        Kp[act], Kd[act] = self.kp, self.kd
        q_ref, v_ref = np.zeros(n), np.zeros(n)
        q_ref[act] = cmd.q
        v_ref[act] = 0.0 if cmd.v is None else cmd.v
        err = np.zeros(n)
        err[act] = q[act] + dq[act] * dt - q_ref[act]
        tau_ff = np.zeros(n)
        if cmd.tau is not None:
            tau_ff[act] = cmd.tau
        rhs = -h - Kp * err - Kd * (dq - v_ref) + tau_ff
        rhs[act] -= self._urdf_damping * dq[act]
        ddq = np.linalg.solve(M + np.diag(Kd * dt), rhs)
        tau = (-Kp * err - Kd * (dq + ddq * dt - v_ref) + tau_ff)[act]
        return np.clip(tau, -self.effort, self.effort)

    def step(self, n: int = 1) -> None:
        """Advance n physics steps, applying pushes and the actuators' torque."""
        skel = self.skel
        for _ in range(n):
            tau = self._joint_torque()
            for i in self._fault:
                tau[i] = 0.0
            forces = np.zeros(skel.getNumDofs())
            forces[self._act] = tau
            skel.setForces(forces)
            if self.pushes:
                t = self.t
                for p, body in zip(self.pushes, self._push_bodies):
                    if p.active(t):
                        body.addExtForce(np.asarray(p.force, dtype=float), np.zeros(3), False, True)
            self.world.step()
            w, lin = self._imu_world_velocity()  # the accelerometer: the IMU point's velocity change over the step
            self._imu_acc = (lin - self._imu_vel) / self.dt - self._gravity
            self._imu_w, self._imu_vel = w, lin
            self._tau = tau
            self._tick += 1

    def applied_torque(self) -> np.ndarray:
        """Torque the actuators produced at the last step, (na,) in pinocchio joint order [N m]."""
        return np.array(self._tau, dtype=float)
