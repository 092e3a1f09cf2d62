"""The MuJoCo simulator: a Robot in a Terrain, one actuation mode, sensors, pushes and fall detection."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import ConfigError, UnknownNameError
from ..robots import Robot, Side
from ..types import Command, Measurement
from .bridge import StateBridge
from .contact_kernel import ContactRecords, sole_wrenches
from .friction_kernel import joint_friction_step, torque_loop_and_friction_step
from .state_kernel import STATE_SENSORS, fall_numbers, read_state, read_tick, state_layout, state_size, tick_aux
from .model import ActuationMode, SimOptions, build_mujoco_model, sole_geom_name
from .push import Push
from .spd_kernel import spd_torque
from .torque_loop_kernel import torque_loop_step
from ..scene import Terrain


@dataclass(frozen=True)
class FallStatus:
    fell: bool
    reason: str = ""


_STANDING = FallStatus(False)
_LEFT, _RIGHT = Side.LEFT, Side.RIGHT
_TORQUE = ActuationMode.TORQUE
_NO_RECORDS = (np.zeros((0, 1)), np.zeros((0, 1), dtype=np.int32))  # read_tick's contact records before the first


_NONE = np.zeros(0)


def _f64(x) -> np.ndarray:
    """A command's array as float64 (None: empty, i.e. zero for `spd_torque`)."""
    return _NONE if x is None else np.asarray(x, dtype=np.float64)


class TorqueLoop:
    """The low-level torque loop of a realism preset (torque mode): the command through a pure delay of whole
    physics steps and a first-order lag (exact discretization of the bandwidth), minus the torque sensor's noise
    (the loop makes the sensor's reading follow the reference), clipped to the torque limit. The noise is drawn
    `NOISE_BLOCK` physics steps at a time (the same numbers, in the same order, as one draw per step)."""

    NOISE_BLOCK = 256

    def __init__(self, spec, dt: float, limit: np.ndarray):
        self.delay = int(round(spec.delay / dt))
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * spec.bandwidth * dt) if spec.bandwidth > 0 else 1.0
        self.noise = float(spec.sensor_noise)
        self.seed = int(spec.seed)
        self.limit = np.ascontiguousarray(limit, dtype=np.float64)
        self._all = np.arange(len(self.limit), dtype=np.int64)
        self.reset()

    def reset(self) -> None:
        n = len(self.limit)
        self.rng = np.random.default_rng(self.seed)
        self.buf = np.zeros((self.delay + 1, n))
        self.k = 0
        self.out = np.zeros(n)
        self.target = np.zeros(n)
        self._noise = np.zeros((0, n))
        self._row = 0

    def _next_noise(self) -> np.ndarray:
        """The torque sensor's noise of the next physics step (empty without noise)."""
        if self.noise <= 0:
            return _NONE
        if self._row == len(self._noise):
            self._noise = self.rng.normal(0.0, self.noise, (self.NOISE_BLOCK, len(self.limit)))
            self._row = 0
        self._row += 1
        return self._noise[self._row - 1]

    def write(self, dst: np.ndarray, idx: np.ndarray) -> None:
        """The torque delivered during the next physics step into ``dst[idx]`` (MuJoCo's ctrl, the actuators)."""
        self.k = torque_loop_step(self.buf, self.k, self.target, self.out, self.alpha, self._next_noise(), self.limit,
                                  dst, idx)

    def write_with_friction(self, dst: np.ndarray, idx: np.ndarray, fr: "JointFriction", model, data) -> None:
        """`write`, then `fr.write(model, data)`, in one compiled call."""
        v = fr.views(model, data)
        self.k = torque_loop_and_friction_step(self.buf, self.k, self.target, self.out, self.alpha, self._next_noise(),
                                               self.limit, dst, idx, v[1], fr.dof, fr.coulomb, fr.damping, fr.stick,
                                               fr.state, fr.vprev, fr.base, v[2], v[3])

    def next(self) -> np.ndarray:
        """The torque delivered during the next physics step."""
        tau = np.empty(len(self.limit))
        self.write(tau, self._all)
        return tau


class JointFriction:
    """The realism preset's Coulomb friction with stiction (`wbcbench/sim/friction_kernel.py`) on the joints whose
    preset sets `coulomb` > 0: their break-away torque (MuJoCo's `frictionloss`, taken out of MuJoCo's constraint
    solver: set to 0 in `model`), their own damping and the stick damping; each physics step the kernel writes the
    joints' damping and friction force into the model and data."""

    def __init__(self, model, dofs: np.ndarray, stick: float):
        self.dof = np.ascontiguousarray(dofs, dtype=np.int64)
        self.coulomb = np.array(model.dof_frictionloss[self.dof], dtype=np.float64)
        self.damping = np.array(model.dof_damping[self.dof], dtype=np.float64)
        self.stick = float(stick)
        model.dof_frictionloss[self.dof] = 0.0
        self.state = np.zeros(len(self.dof), dtype=np.int64)
        self.vprev = np.zeros(len(self.dof))
        self.base = np.zeros(len(self.dof))  # the command's own generalized force on these joints (position mode)
        self._views = (None,)

    def reset(self) -> None:
        self.state[:] = 0
        self.vprev[:] = 0.0
        self.base[:] = 0.0

    def views(self, model, data) -> tuple:
        """(data, qvel, dof_damping, qfrc_applied): MuJoCo's arrays viewed once per data (each access makes a view)."""
        v = self._views
        if v[0] is not data:
            v = self._views = (data, data.qvel, model.dof_damping, data.qfrc_applied)
        return v

    def write(self, model, data) -> None:
        """The friction of the next physics step."""
        v = self.views(model, data)
        joint_friction_step(v[1], self.dof, self.coulomb, self.damping, self.stick, self.state, self.vprev, self.base,
                            v[2], v[3])


class Simulator:
    """TALOS (or any profiled robot) in MuJoCo.

    The control loop calls `measure()` (what a real robot gives: encoders, base estimate, IMU, ankle F/T),
    `apply(command)` and `step()`. Ground truth (`true_q`, `true_v`, `contact_wrenches`) is for metrics.
    """

    def __init__(self, robot: Robot, terrain: Terrain | None = None, mode: ActuationMode | str = "torque",
                 options: SimOptions | None = None, pushes: tuple[Push, ...] = (), model_error=None):
        self.robot = robot
        self.mode = ActuationMode(mode)
        self.options = options or SimOptions()
        self.terrain = terrain or Terrain()
        self.model = build_mujoco_model(robot, self.terrain, self.mode, self.options)
        # the simulated robot may differ from the controller's model (masses, payloads, friction, ground)
        self.model_error = {}
        if model_error is not None:
            from .model_error import apply_model_error

            ground = [g for g in range(self.model.ngeom) if self.model.geom_bodyid[g] == 0]
            self.model_error = apply_model_error(self.model, model_error, ground)
        self.data = mujoco.MjData(self.model)
        self.bridge = StateBridge(robot, self.model)
        self.dt = float(self.model.opt.timestep)
        self.kp, self.kd = robot.profile.position_gains.resolve(robot.joint_names, robot.profile.file)
        self.effort = robot.effort_limit
        realism = self.options.realism
        self._torque_loop = None
        self._friction = None
        if realism is not None:  # the hidden actuator chains (wbcbench/sim/realism)
            if self.mode is ActuationMode.SPD:
                raise ConfigError("a realism preset needs torque or position mode (the SPD law assumes the "
                                  "nominal joints)", file=realism.file, key="--mode")
            self.effort = np.minimum(self.effort, np.asarray(realism.torque_limit, dtype=float))
            if self.mode is _TORQUE and realism.torque_loop is not None:
                self._torque_loop = TorqueLoop(realism.torque_loop, float(self.model.opt.timestep), self.effort)
            if realism.stiction_impedance is None:  # the stick-slip kernel (else MuJoCo's frictionloss constraint)
                m = self.model
                dofs = [int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)])
                        for j, c in zip(robot.joint_names, realism.coulomb) if c > 0]
                if dofs:
                    self._friction = JointFriction(m, np.array(dofs), realism.stiction_damping)
        self._kd_over_kp = self.kd / self.kp  # position mode: the servo's velocity reference enters as kd/kp v
        self.set_pushes(pushes)
        self._sole_geoms = {s: mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s))
                            for s in Side}
        self._sensor_adr = {name: int(self.model.sensor_adr[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SENSOR,
                                                                              name)])
                            for name in STATE_SENSORS}
        # read_state's arguments besides MuJoCo's arrays, and the layout of what it fills
        b = self.bridge
        self._state_layout = state_layout(b.root_qadr, b.root_vadr, robot.nq, b.mj_q_idx, b.pin_q_idx, b.mj_v_idx,
                                          b.pin_v_idx, [self._sensor_adr[n] for n in STATE_SENSORS])
        self._state_size = state_size(robot.nq, robot.nv)
        k = robot.nq + robot.nv
        self._measurement_slices = (slice(0, robot.nq), slice(robot.nq, k), slice(k, k + 4), slice(k + 4, k + 7),
                                    slice(k + 7, k + 10), slice(k + 10, k + 13), slice(k + 13, k + 16),
                                    slice(k + 16, k + 19), slice(k + 19, k + 22))
        # the joints' actuators, as a slice when they are consecutive (the usual case; indexing with one is faster)
        act = b.actuator_idx
        self._act = (slice(int(act[0]), int(act[0]) + len(act))
                     if len(act) and act[0] >= 0 and np.array_equal(act, np.arange(act[0], act[0] + len(act))) else act)
        self._act_idx = np.ascontiguousarray(act, dtype=np.int64)
        self._command = Command(tau=np.zeros(robot.na))
        self._tick = 0
        self._spd_M = np.zeros((self.model.nv, self.model.nv))
        self._dof_parent = np.asarray(self.model.dof_parentid, dtype=np.int64)
        self._kp64, self._kd64, self._effort64 = (np.ascontiguousarray(x, dtype=np.float64)
                                                  for x in (self.kp, self.kd, self.effort))
        self._sole_ids = np.array(list(self._sole_geoms.values()), dtype=np.int32)
        self._sole_wrench = np.zeros((len(self._sole_ids), 6))
        self._contacts: ContactRecords | None = None  # located from the first contact
        self._min_base_height = float(robot.profile.min_base_height)
        self._max_tilt = float(robot.profile.max_tilt)
        self._cos_max_tilt = math.cos(self._max_tilt) + 1e-12  # at or above: certainly within the tilt limit
        self._soles2 = (int(self._sole_ids[0]), int(self._sole_ids[1]))
        self._pyramidal = int(self.model.opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
        self._tick_aux = tick_aux(self._soles2, np.zeros(6, np.int64), self.bridge.actuator_idx)
        self.reset()

    def set_pushes(self, pushes: tuple[Push, ...]) -> None:
        """The external pushes of the following steps (replacing any; each active over its own time window)."""
        bodies = []
        for p in pushes:
            body = self.robot.profile.base_frame if p.body == "base" else p.body
            bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body)
            if bid < 0:
                names = [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, self.model.nbody)]
                raise UnknownNameError("body for push", p.body, names, key="pushes.body")
            bodies.append(bid)
        if not pushes and getattr(self, "pushes", ()):
            self.data.xfrc_applied[:] = 0.0  # the last push's force must not stay applied
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
        mujoco.mj_resetData(self.model, self.data)
        q = self.robot.q0 if q is None else q
        self.bridge.q_to_mj(q, self.data.qpos)
        self.bridge.v_to_mj(q, np.zeros(self.robot.nv) if v is None else v, self.data.qvel)
        self._tick = 0
        self._command = Command(tau=np.zeros(self.robot.na), q=q[7:].copy(), v=np.zeros(self.robot.na))
        if self._torque_loop is not None:
            self._torque_loop.reset()
        if self._friction is not None:
            self._friction.reset()
        mujoco.mj_forward(self.model, self.data)

    def true_q(self) -> np.ndarray:
        return self.bridge.q_from_mj(self.data.qpos)

    def true_v(self) -> np.ndarray:
        return self.bridge.v_from_mj(self.data.qpos, self.data.qvel)

    # ------------------------------------------------------------------ sensing
    def measure(self) -> Measurement:
        """Sensors as a real robot has them. The base estimate is ground truth (no noise, no delay) here; the
        sensor layer (wbcbench.sensing) degrades it."""
        return self.measurement(self.read_state())

    def read_state(self) -> np.ndarray:
        """The state and sensors now, in one new array (pinocchio conventions): q, v, IMU quaternion (x, y, z, w),
        gyro, accelerometer, then force and torque of the left and right ankle F/T sensors (`measurement` views
        it)."""
        d = self.data
        buf = np.empty(self._state_size)
        read_state(d.qpos, d.qvel, d.sensordata, self._state_layout, buf)
        return buf

    def measurement(self, state: np.ndarray) -> Measurement:
        """The `Measurement` whose arrays are views of `state` (from `read_state`, not to be reused), with the joint
        torque sensors' reading (`Measurement.tau`: the actuators' output torque now)."""
        q, v, imu, gyro, acc, fl, tl, fr, tr = self._measurement_slices
        return Measurement(self._tick * self.dt, state[q], state[v], state[imu], state[gyro], state[acc],
                           {_LEFT: state[fl], _RIGHT: state[fr]}, {_LEFT: state[tl], _RIGHT: state[tr]},
                           self.data.actuator_force[self._act].copy())

    def contact_wrenches(self) -> dict[Side, np.ndarray]:
        """Ground-truth contact wrench on each sole, world frame, (force (3), moment about the world origin (3))."""
        out = self.contact_wrench_array()
        return {s: out[k].copy() for k, s in enumerate(self._sole_geoms)}

    def contact_wrench_array(self) -> np.ndarray:
        """`contact_wrenches` as one (2, 6) array, left then right (the simulator's own buffer: overwritten by
        the next call)."""
        d = self.data
        n = d.ncon
        out = self._sole_wrench
        if n == 0:
            out[:] = 0.0
            return out
        rec = self._contacts
        if rec is None or rec.data is not d:
            rec = self._locate_contacts()
        sole_wrenches(n, d.efc_force, rec.floats, rec.ints, rec.offsets, self._sole_ids, self._pyramidal, out)
        return out

    def set_joint_fault(self, joint: str, kind: str | None) -> None:
        """A joint's actuator fails (inria_wbc's CUT / LOCKED / PASSIVE): `cut` gives no torque, `passive` only
        damps (the profile's kd), `locked` brakes the joint where it is (heavy joint damping, no actuator torque);
        None restores it. The controller is not told."""
        m = self.model
        a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, joint)
        if a < 0:
            raise UnknownNameError("joint", joint, self.robot.joint_names, key="faults.target")
        dof = int(m.jnt_dofadr[m.actuator_trnid[a, 0]])
        saved = self.__dict__.setdefault("_joint_saved", {})
        if joint not in saved:
            saved[joint] = (m.actuator_gainprm[a].copy(), m.actuator_biasprm[a].copy(), int(m.actuator_biastype[a]),
                            self._joint_damping(dof))
        gain, bias, btype, damping = saved[joint]
        m.actuator_gainprm[a], m.actuator_biasprm[a], m.actuator_biastype[a] = gain, bias, btype
        self._set_joint_damping(dof, damping)
        if kind is None:
            return
        m.actuator_gainprm[a] = 0.0
        m.actuator_biasprm[a] = 0.0
        if kind == "passive":
            m.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
            m.actuator_biasprm[a, 2] = -float(self.kd[self.robot.joint_names.index(joint)])
        elif kind == "locked":
            self._set_joint_damping(dof, 1e5)

    def _friction_index(self, dof: int) -> int | None:
        """The friction kernel's index of MuJoCo degree of freedom `dof` (None: the kernel does not manage it; it
        writes its joints' MuJoCo damping every step, from its own copy of their damping)."""
        fr = self._friction
        k = np.flatnonzero(fr.dof == dof) if fr is not None else ()
        return int(k[0]) if len(k) else None

    def _joint_damping(self, dof: int) -> float:
        """A degree of freedom's own joint damping [N m s/rad] (without the friction kernel's stick damping)."""
        k = self._friction_index(dof)
        return float(self.model.dof_damping[dof] if k is None else self._friction.damping[k])

    def _set_joint_damping(self, dof: int, value: float) -> None:
        self.model.dof_damping[dof] = value
        k = self._friction_index(dof)
        if k is not None:
            self._friction.damping[k] = value

    def fall_status(self) -> FallStatus:
        """Fallen if the state is not finite, the base is too low above the lower foot or too tilted."""
        d = self.data
        return self._fall(*fall_numbers(d.qpos, d.qvel, d.geom_xpos, self.bridge.root_qadr, *self._soles2))

    def _fall(self, finite: bool, height: float, cos_tilt: float) -> FallStatus:
        if not finite:  # a NaN or inf anywhere
            return FallStatus(True, "simulation diverged (non-finite state)")
        if height < self._min_base_height:
            return FallStatus(True, f"base {height:.3f} m above the lower foot (< {self._min_base_height})")
        if cos_tilt >= self._cos_max_tilt:
            return _STANDING
        tilt = math.acos(min(1.0, max(-1.0, cos_tilt)))
        if tilt > self._max_tilt:
            return FallStatus(True, f"base tilted {tilt:.2f} rad (> {self._max_tilt})")
        return _STANDING

    def read_tick(self, row: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, FallStatus]:
        """What the run loop reads after a step, in one compiled call: the state and sensors (`read_state`'s
        array, returned), the fall status, and the ground truth written into a log row: q, v, the applied
        torque, the soles' contact wrenches (left, right: `contact_wrench_array`) and the ankles' F/T readings
        (left, right: force then torque) in consecutive columns starting at ``dst`` (int64: q, v, tau, wrenches,
        F/T)."""
        d = self.data
        views = self._data_views()
        n = d.ncon
        rec = self._contacts
        if n and (rec is None or rec.data is not d):
            rec = self._locate_contacts()
        floats, ints = (rec.floats, rec.ints) if rec is not None else _NO_RECORDS
        state = np.empty(self._state_size)
        finite, height, cos_tilt = read_tick(views[1], views[2], views[3], views[4], views[5], d.efc_force, n, floats,
                                             ints, self._pyramidal, self._state_layout, self._tick_aux, state,
                                             self._sole_wrench, row, dst)
        if finite and height >= self._min_base_height and cos_tilt >= self._cos_max_tilt:
            return state, _STANDING
        return state, self._fall(finite, height, cos_tilt)

    _views = (None,)

    def _data_views(self) -> tuple:
        """`_make_views`' tuple for the current MjData (made again if the simulator's data was replaced)."""
        views = self._views
        return views if views[0] is self.data else self._make_views()

    def _make_views(self) -> tuple:
        """MuJoCo's fixed-size arrays of the data the per-tick calls use, viewed once per MjData (each attribute
        access makes a new view): the data, qpos, qvel, sensordata, actuator_force, geom_xpos, ctrl, and the SPD
        law's qfrc_bias, qfrc_passive, qfrc_constraint, qfrc_applied."""
        d = self.data
        self._views = (d, d.qpos, d.qvel, d.sensordata, d.actuator_force, d.geom_xpos, d.ctrl, d.qfrc_bias,
                       d.qfrc_passive, d.qfrc_constraint, d.qfrc_applied)
        return self._views

    def _locate_contacts(self) -> ContactRecords:
        rec = self._contacts = ContactRecords(self.data)
        self._tick_aux = tick_aux(self._soles2, rec.offsets, self.bridge.actuator_idx)
        return rec

    # ------------------------------------------------------------------ acting
    def apply(self, command: Command) -> None:
        """Set the command used by the following physics steps (held until the next call)."""
        self._command = command
        ctrl = self._data_views()[6]
        act = self._act
        if self.mode is _TORQUE:
            if self._torque_loop is not None:  # the loop sets ctrl at each physics step
                self._torque_loop.target[:] = command.tau if command.tau is not None else 0.0
                return
            ctrl[act] = command.tau if command.tau is not None else 0.0
        elif self.mode is ActuationMode.POSITION:
            v = command.v if command.v is not None else 0.0
            ctrl[act] = command.q + self._kd_over_kp * v
            self.data.qfrc_applied[:] = 0.0
            if command.tau is not None:
                self.data.qfrc_applied[self.bridge.mj_v_idx] = command.tau
            if self._friction is not None:  # the friction kernel adds its force to the command's
                self._friction.base[:] = self.data.qfrc_applied[self._friction.dof]

    def _spd_torque(self) -> np.ndarray:
        """Stable PD (Tan et al. 2011) with the next acceleration predicted from the full dynamics."""
        m, d, b = self.model, self.data, self.bridge
        views = self._data_views()
        cmd = self._command
        mujoco.mj_fullM(m, d, self._spd_M)
        out = np.empty(self.robot.na)
        spd_torque(self._spd_M, self._dof_parent, views[1], views[2], b.mj_q_idx, b.mj_v_idx, _f64(cmd.q), _f64(cmd.v),
                   _f64(cmd.tau), self._kp64, self._kd64, self.dt, *views[7:], self._effort64, out)
        return out

    def step(self, n: int = 1) -> None:
        """Advance n physics steps, applying pushes and (in SPD mode) recomputing the SPD torque each step."""
        for _ in range(n):
            if self.pushes:
                xf = self.data.xfrc_applied
                xf[:] = 0.0
                t = self.t
                for p, bid in zip(self.pushes, self._push_bodies):
                    if p.active(t):
                        xf[bid, :3] += p.force
            if self.mode is ActuationMode.SPD:
                self.data.ctrl[self._act] = self._spd_torque()
            elif self._torque_loop is not None and self._friction is not None:  # (one compiled call for both)
                self._torque_loop.write_with_friction(self._data_views()[6], self._act_idx, self._friction,
                                                      self.model, self.data)
            else:
                if self._torque_loop is not None:
                    self._torque_loop.write(self._data_views()[6], self._act_idx)
                if self._friction is not None:
                    self._friction.write(self.model, self.data)
            mujoco.mj_step(self.model, self.data)
            self._tick += 1

    def applied_torque(self) -> np.ndarray:
        """Torque the actuators produced at the last step, (na,) in pinocchio joint order [N m]."""
        return self.data.actuator_force[self._act].copy()
