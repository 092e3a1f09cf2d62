"""The MuJoCo simulator: a Robot in a Terrain, one actuation mode, sensors, pushes and fall detection."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import UnknownNameError
from ..robots import Robot, Side
from ..types import Command, Measurement
from .bridge import StateBridge
from .model import ActuationMode, SimOptions, build_mujoco_model, sole_geom_name
from .push import Push
from ..scene import Terrain


@dataclass(frozen=True)
class FallStatus:
    fell: bool
    reason: str = ""


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
        self.pushes = tuple(pushes)
        self._push_bodies = []
        for p in self.pushes:
            body = robot.profile.base_frame if p.body == "base" else p.body
            bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body)
            if bid < 0:
                names = [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, self.model.nbody)]
                raise UnknownNameError("body for push", p.body, names, key="pushes.body")
            self._push_bodies.append(bid)
        self._sole_geoms = {s: mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s))
                            for s in Side}
        self._sensor_adr = {name: int(self.model.sensor_adr[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SENSOR,
                                                                              name)])
                            for name in ["force_left", "torque_left", "force_right", "torque_right", "gyro",
                                         "accelerometer", "imu_quat"]}
        self._command = Command(tau=np.zeros(robot.na))
        self._tick = 0
        self._spd_M = np.zeros((self.model.nv, self.model.nv))
        self._cf = np.zeros(6)
        self.reset()

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
        mujoco.mj_forward(self.model, self.data)

    def true_q(self) -> np.ndarray:
        return self.bridge.q_from_mj(self.data.qpos)

    def true_v(self) -> np.ndarray:
        return self.bridge.v_from_mj(self.data.qpos, self.data.qvel)

    # ------------------------------------------------------------------ sensing
    def _sensor(self, name: str, n: int) -> np.ndarray:
        a = self._sensor_adr[name]
        return self.data.sensordata[a:a + n].copy()

    def measure(self) -> Measurement:
        """Sensors as a real robot has them. The base estimate is ground truth (no noise, no delay) for now."""
        quat = self._sensor("imu_quat", 4)  # w, x, y, z
        return Measurement(
            t=self.t, q=self.true_q(), v=self.true_v(),
            imu_quat=np.array([quat[1], quat[2], quat[3], quat[0]]),
            gyro=self._sensor("gyro", 3), accelerometer=self._sensor("accelerometer", 3),
            ft_force={s: self._sensor(f"force_{s.value}", 3) for s in Side},
            ft_torque={s: self._sensor(f"torque_{s.value}", 3) for s in Side},
        )

    def contact_wrenches(self) -> dict[Side, np.ndarray]:
        """Ground-truth contact wrench on each sole, world frame, (force (3), moment about the world origin (3))."""
        d = self.data
        out = {s: np.zeros(6) for s in Side}
        n = d.ncon
        if n == 0:
            return out
        con = d.contact
        g1, g2 = con.geom1[:n], con.geom2[:n]
        frames = con.frame[:n].reshape(n, 3, 3)
        pos = con.pos[:n]
        cf = self._cf
        local = np.empty((n, 3))
        for i in range(n):
            mujoco.mj_contactForce(self.model, d, i, cf)
            local[i] = cf[:3]
        # contact frame rows: normal first; force of geom1 on geom2
        world = np.einsum("nij,ni->nj", frames, local)
        for s, gid in self._sole_geoms.items():
            sign = np.where(g1 == gid, -1.0, np.where(g2 == gid, 1.0, 0.0))
            if not sign.any():
                continue
            f = world * sign[:, None]
            w = out[s]
            w[:3] = f.sum(axis=0)
            w[3] = (pos[:, 1] * f[:, 2] - pos[:, 2] * f[:, 1]).sum()
            w[4] = (pos[:, 2] * f[:, 0] - pos[:, 0] * f[:, 2]).sum()
            w[5] = (pos[:, 0] * f[:, 1] - pos[:, 1] * f[:, 0]).sum()
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
                            float(m.dof_damping[dof]))
        gain, bias, btype, damping = saved[joint]
        m.actuator_gainprm[a], m.actuator_biasprm[a], m.actuator_biastype[a] = gain, bias, btype
        m.dof_damping[dof] = damping
        if kind is None:
            return
        m.actuator_gainprm[a] = 0.0
        m.actuator_biasprm[a] = 0.0
        if kind == "passive":
            m.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
            m.actuator_biasprm[a, 2] = -float(self.kd[self.robot.joint_names.index(joint)])
        elif kind == "locked":
            m.dof_damping[dof] = 1e5

    def fall_status(self) -> FallStatus:
        """Fallen if the state is not finite, the base is too low above the lower foot or too tilted."""
        q = self.data.qpos
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(self.data.qvel))):
            return FallStatus(True, "simulation diverged (non-finite state)")
        a = self.bridge.root_qadr
        base_z = q[a + 2]
        feet_z = min(self.data.geom_xpos[g][2] for g in self._sole_geoms.values())
        height = base_z - feet_z
        if height < self.robot.profile.min_base_height:
            return FallStatus(True, f"base {height:.3f} m above the lower foot (< {self.robot.profile.min_base_height})")
        w, x, y, z = q[a + 3:a + 7]
        cos_tilt = 1 - 2 * (x * x + y * y)
        tilt = float(np.arccos(np.clip(cos_tilt / (w * w + x * x + y * y + z * z), -1, 1)))
        if tilt > self.robot.profile.max_tilt:
            return FallStatus(True, f"base tilted {tilt:.2f} rad (> {self.robot.profile.max_tilt})")
        return FallStatus(False)

    # ------------------------------------------------------------------ acting
    def apply(self, command: Command) -> None:
        """Set the command used by the following physics steps (held until the next call)."""
        self._command = command
        na = self.robot.na
        ctrl = self.data.ctrl
        act = self.bridge.actuator_idx
        if self.mode is ActuationMode.TORQUE:
            ctrl[act] = command.tau if command.tau is not None else np.zeros(na)
        elif self.mode is ActuationMode.POSITION:
            v = command.v if command.v is not None else 0.0
            ctrl[act] = command.q + self.kd / self.kp * v
            self.data.qfrc_applied[:] = 0.0
            if command.tau is not None:
                self.data.qfrc_applied[self.bridge.mj_v_idx] = command.tau

    def _spd_torque(self) -> np.ndarray:
        """Stable PD (Tan et al. 2011) with the next acceleration predicted from the full dynamics."""
        m, d, b = self.model, self.data, self.bridge
        cmd = self._command
        q = d.qpos[b.mj_q_idx]
        v = d.qvel[b.mj_v_idx]
        v_ref = cmd.v if cmd.v is not None else 0.0
        p_term = self.kp * (cmd.q - q - self.dt * v) + self.kd * (v_ref - v)
        mujoco.mj_fullM(m, d, self._spd_M)
        A = self._spd_M.copy()
        A[b.mj_v_idx, b.mj_v_idx] += self.dt * self.kd
        rhs = -d.qfrc_bias + d.qfrc_passive + d.qfrc_constraint + d.qfrc_applied
        rhs[b.mj_v_idx] += p_term + (cmd.tau if cmd.tau is not None else 0.0)
        acc = np.linalg.solve(A, rhs)
        tau = p_term - self.kd * self.dt * acc[b.mj_v_idx]
        if cmd.tau is not None:
            tau = tau + cmd.tau
        return np.clip(tau, -self.effort, self.effort)

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
                self.data.ctrl[self.bridge.actuator_idx] = self._spd_torque()
            mujoco.mj_step(self.model, self.data)
            self._tick += 1

    def applied_torque(self) -> np.ndarray:
        """Torque the actuators produced at the last step, (na,) in pinocchio joint order [N m]."""
        return self.data.actuator_force[self.bridge.actuator_idx].copy()
