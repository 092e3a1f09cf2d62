"""The one place where MuJoCo and pinocchio states are converted.

MuJoCo free joint: qpos = (x, y, z, qw, qx, qy, qz), qvel = (linear velocity in WORLD, angular in LOCAL).
Pinocchio free flyer: q = (x, y, z, qx, qy, qz, qw), v = (linear in LOCAL, angular in LOCAL).
Joints are matched by name, never by index.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from ..robots import Robot


class StateBridge:
    """Index maps and conversions between a MuJoCo model and a Robot's pinocchio model."""

    def __init__(self, robot: Robot, mj_model: mujoco.MjModel, root_joint: str = "root"):
        self.robot = robot
        pm = robot.model
        self.nq, self.nv = pm.nq, pm.nv
        root = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_JOINT, root_joint)
        if root < 0 or mj_model.jnt_type[root] != mujoco.mjtJoint.mjJNT_FREE:
            raise ConfigError(f"MuJoCo model has no free joint named '{root_joint}'")
        self.root_qadr = int(mj_model.jnt_qposadr[root])
        self.root_vadr = int(mj_model.jnt_dofadr[root])
        pin_q, mj_q, pin_v, mj_v, act = [], [], [], [], []
        for name in robot.joint_names:
            jid = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                raise ConfigError(f"joint '{name}' of the pinocchio model is missing in the MuJoCo model")
            pid = pm.getJointId(name)
            pin_q.append(pm.idx_qs[pid])
            pin_v.append(pm.idx_vs[pid])
            mj_q.append(mj_model.jnt_qposadr[jid])
            mj_v.append(mj_model.jnt_dofadr[jid])
            aid = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
            act.append(aid)
        self.pin_q_idx = np.array(pin_q)
        self.mj_q_idx = np.array(mj_q)
        self.pin_v_idx = np.array(pin_v)
        self.mj_v_idx = np.array(mj_v)
        self.actuator_idx = np.array(act)  # -1 where a joint has no actuator
        # joint index in robot.joint_names order -> pinocchio v index (6 + i for 1-DoF chains)
        self.joint_v_idx = self.pin_v_idx

    # --- MuJoCo -> pinocchio
    def q_from_mj(self, qpos: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        q = np.empty(self.nq) if out is None else out
        a = self.root_qadr
        q[0:3] = qpos[a:a + 3]
        q[3:6] = qpos[a + 4:a + 7]
        q[6] = qpos[a + 3]
        q[self.pin_q_idx] = qpos[self.mj_q_idx]
        return q

    def v_from_mj(self, qpos: np.ndarray, qvel: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        v = np.empty(self.nv) if out is None else out
        a, b = self.root_qadr, self.root_vadr
        R = _rot_wxyz(qpos[a + 3:a + 7])
        v[0:3] = R.T @ qvel[b:b + 3]
        v[3:6] = qvel[b + 3:b + 6]
        v[self.pin_v_idx] = qvel[self.mj_v_idx]
        return v

    # --- pinocchio -> MuJoCo
    def q_to_mj(self, q: np.ndarray, qpos: np.ndarray) -> None:
        a = self.root_qadr
        qpos[a:a + 3] = q[0:3]
        qpos[a + 3] = q[6]
        qpos[a + 4:a + 7] = q[3:6]
        qpos[self.mj_q_idx] = q[self.pin_q_idx]

    def v_to_mj(self, q: np.ndarray, v: np.ndarray, qvel: np.ndarray) -> None:
        b = self.root_vadr
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        qvel[b:b + 3] = R @ v[0:3]
        qvel[b + 3:b + 6] = v[3:6]
        qvel[self.mj_v_idx] = v[self.pin_v_idx]

    def joint_q_from_mj(self, qpos: np.ndarray) -> np.ndarray:
        """Actuated joint positions in robot.joint_names order."""
        return qpos[self.mj_q_idx]

    def joint_v_from_mj(self, qvel: np.ndarray) -> np.ndarray:
        return qvel[self.mj_v_idx]


def _rot_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = quat_wxyz.tolist()  # Python floats: the same IEEE arithmetic as numpy scalars, faster
    n = w * w + x * x + y * y + z * z
    s = 2.0 / n
    return np.array([
        [1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
        [s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)],
        [s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)],
    ])
