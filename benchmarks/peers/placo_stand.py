"""PlaCo's solvers on the peers' standing problem (see tsid_stand.py): `dynamics` (DynamicsSolver: both soles as
fixed 6D contacts, CoM task following a lateral sine of 2 cm at 0.5 Hz, base orientation, joints to half-sitting,
integrated by PlaCo at 1 kHz) or `kinematics` (KinematicsSolver, weighted: soles as hard frame tasks, the same
CoM, orientation and posture tasks). Run in the peers' virtual environment; prints one JSON line.

    PEERS/placo/bin/python benchmarks/peers/placo_stand.py dynamics|kinematics URDF Q0.npy [--ticks 3000]
"""

import argparse
import json
import time
from importlib import metadata

import numpy as np
import placo

p = argparse.ArgumentParser()
p.add_argument("solver", choices=("dynamics", "kinematics"))
p.add_argument("urdf")
p.add_argument("q0")
p.add_argument("--ticks", type=int, default=3000)
args = p.parse_args()

dt = 1e-3
robot = placo.RobotWrapper(args.urdf, placo.Flags.ignore_collisions)
q0 = np.load(args.q0)
robot.state.q = q0.copy()
robot.update_kinematics()
com0 = robot.com_world().copy()
R_base = robot.get_T_world_frame("base_link")[:3, :3].copy()
joints = {name: float(q0[7 + i]) for i, name in enumerate(robot.joint_names())}

if args.solver == "dynamics":
    solver = placo.DynamicsSolver(robot)
    solver.dt = dt
    for side in ("left", "right"):
        frame = f"{side}_sole_link"
        task = solver.add_frame_task(frame, robot.get_T_world_frame(frame))
        task.configure(frame, "hard", 1.0, 1.0)
        contact = solver.add_fixed_contact(task)
        contact.length, contact.width, contact.mu = 0.20, 0.13, 0.5
    com = solver.add_com_task(com0)
    com.configure("com", "soft", 1e3)
    com.kp = 20.0
    orient = solver.add_orientation_task("base_link", R_base)
    orient.configure("base", "soft", 1.0)
    orient.kp = 100.0
    posture = solver.add_joints_task()
    posture.set_joints(joints)
    posture.configure("posture", "soft", 0.1)
    posture.kp = 10.0
    solver.enable_joint_limits(True)
    solver.enable_torque_limits(True)
else:
    solver = placo.KinematicsSolver(robot)
    solver.dt = dt
    for side in ("left", "right"):
        frame = f"{side}_sole_link"
        task = solver.add_frame_task(frame, robot.get_T_world_frame(frame))
        task.configure(frame, "hard", 1.0, 1.0)
    com = solver.add_com_task(com0)
    com.configure("com", "soft", 1e3)
    orient = solver.add_orientation_task("base_link", R_base)
    orient.configure("base", "soft", 1.0)
    posture = solver.add_joints_task()
    posture.set_joints(joints)
    posture.configure("posture", "soft", 0.1)
    solver.enable_joint_limits(True)

w = 2 * np.pi * 0.5
times = np.empty(args.ticks)
for k in range(args.ticks):
    t = k * dt
    target = com0 + np.array([0.0, 0.02 * np.sin(w * t), 0.0])
    t0 = time.perf_counter()
    com.target_world = target
    if args.solver == "dynamics":
        com.dtarget_world = np.array([0.0, 0.02 * w * np.cos(w * t), 0.0])
        com.ddtarget_world = np.array([0.0, -0.02 * w * w * np.sin(w * t), 0.0])
        result = solver.solve(True)
        if not result.success:
            raise SystemExit(f"PlaCo's dynamics QP failed at tick {k}")
    else:
        robot.update_kinematics()
        solver.solve(True)
    times[k] = (time.perf_counter() - t0) * 1e6
    if args.solver == "dynamics":
        robot.update_kinematics()
warm = times[args.ticks // 10:]
robot.update_kinematics()
print(json.dumps({"peer": f"placo-{args.solver}", "version": metadata.version("placo"),
                  "median_us": float(np.median(warm)), "p99_us": float(np.percentile(warm, 99)),
                  "com_error_m": float(np.linalg.norm(robot.com_world() - target))}))
