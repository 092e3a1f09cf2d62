"""Task library shared by the inverse-dynamics (acceleration + wrench) and IK (velocity) formulations.

Per tick::

    update_kinematics(model, data, q, v)            # or update_kinematics_velocity_level(model, data, q)
    com.set_reference(p_com, v_com, a_com)           # references from the planner / stabilizer
    A, b = acceleration_rows(com, model, data)       # or velocity_rows(...) for IK
    C, u = contact.force_rows()                      # C w <= u on each contact wrench

    stack = TaskStack([com, waist, posture], model.nv)   # once; then per tick, all rows in one go:
    A, b = stack.acceleration_rows(model, data)      # same rows as stacking acceleration_rows(...)

Conventions: task errors are ``reference (-) current``; frame tasks live in LOCAL_WORLD_ALIGNED (world axes,
origin on the frame), contacts in the LOCAL contact frame (z = normal); wrenches are ``[f; tau]`` exerted by
the environment on the robot, in the contact frame at its origin. Units SI.
"""

from wbcbench.tasks.angular_momentum_task import AngularMomentumTask
from wbcbench.tasks.com_task import CoMTask
from wbcbench.tasks.contact_6d import Contact6D, tsid_wrench_metric
from wbcbench.tasks.exceptions import ReferenceNotSetError, TaskConfigError, UnknownNameError
from wbcbench.tasks.formulation import acceleration_rows, velocity_rows
from wbcbench.tasks.frame_task import FrameTask
from wbcbench.tasks.kinematics import update_kinematics, update_kinematics_velocity_level
from wbcbench.tasks.posture_task import PostureTask
from wbcbench.tasks.registry import TaskSpec, register_task, task_class, task_types
from wbcbench.tasks.rows import Inequality, Rows
from wbcbench.tasks.self_collision import RepulsionPoint, SelfCollisionTask
from wbcbench.tasks.stack import TaskStack
from wbcbench.tasks.task import Task

__all__ = [
    "AngularMomentumTask",
    "CoMTask",
    "Contact6D",
    "FrameTask",
    "Inequality",
    "PostureTask",
    "ReferenceNotSetError",
    "RepulsionPoint",
    "Rows",
    "SelfCollisionTask",
    "Task",
    "TaskConfigError",
    "TaskSpec",
    "TaskStack",
    "UnknownNameError",
    "acceleration_rows",
    "register_task",
    "task_class",
    "task_types",
    "tsid_wrench_metric",
    "update_kinematics",
    "update_kinematics_velocity_level",
    "velocity_rows",
]
