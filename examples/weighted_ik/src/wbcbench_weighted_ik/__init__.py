"""A weighted velocity IK from wbcbench's task library, shipped as a plugin (entry point wbcbench.controllers)."""
import numpy as np
import pinocchio as pin

from wbcbench import Command, Controller
from wbcbench.controllers.task_references import TaskReferences
from wbcbench.side import Side
from wbcbench.tasks import CoMTask, FrameTask, PostureTask, TaskStack, update_kinematics_velocity_level
from wbcbench.types import ActuationMode


class WeightedIK(Controller):
    """min sum_i w_i ||J_i v - (v_i* + Kp e_i)||^2 + 1e-6 ||v||^2: feet, CoM, waist, posture; integrated once."""

    name = "weighted-ik"
    modes = (ActuationMode.POSITION, ActuationMode.SPD)
    default_mode = ActuationMode.POSITION

    def reset(self, meas, refs):
        m, p = self.robot.model, self.robot.profile
        self.data, self.q = m.createData(), meas.q.copy()
        feet = {s: FrameTask(m, p.feet[s].frame, name=f"foot_{s.value}", weight=1e3, kp=100.0) for s in Side}
        tasks = [*feet.values(), CoMTask(m, name="com", weight=10.0, kp=50.0),
                 FrameTask(m, p.base_frame, name="waist", weight=1.0, kp=50.0, mask=[0, 0, 0, 1, 1, 1]),
                 PostureTask(m, name="posture", weight=1e-2, kp=10.0, joints=self.robot.joint_names)]
        update_kinematics_velocity_level(m, self.data, self.q)
        for t in tasks:
            t.reset_reference(m, self.data, self.robot.q0)
        self.stack, self.references = TaskStack(tasks, m.nv), TaskReferences(tasks, feet)

    def step(self, meas, refs):
        m = self.robot.model
        update_kinematics_velocity_level(m, self.data, self.q)
        self.references.apply(refs)
        A, b = self.stack.velocity_rows(m, self.data)
        w = self.stack.sqrt_weights[:, None]
        v = np.linalg.solve((w * A).T @ (w * A) + 1e-6 * np.eye(m.nv), (w * A).T @ (w[:, 0] * b))
        self.q = pin.integrate(m, self.q, v * self.dt)
        return Command(q=self.q[7:].copy(), v=v[6:].copy())
