"""C++ TSID (through its Python bindings) on the peers' standing problem: TALOS, both soles as 6D contacts, the CoM
following a lateral sine (2 cm, 0.5 Hz), waist orientation, angular momentum to zero, posture to half-sitting,
joint position bounds (the weights and gains of wbcbench's tsid-torque task set); the solution integrated at
1 kHz (TSID's own demos' loop). Run in the peers' virtual environment (benchmarks/peers/setup.sh); prints one
JSON line: the median and p99 microseconds of a control step (problem data + solve + torques).

    PEERS/tsid/bin/python benchmarks/peers/tsid_stand.py URDF Q0.npy [--ticks 3000]
"""

import argparse
import json
import time
from importlib import metadata

import numpy as np
import pinocchio as pin

try:
    import tsid
    tsid.RobotWrapper
except AttributeError:  # tsid 1.7.1's wheel puts its __init__ one level too deep: the extension module directly
    from tsid import tsid_pywrap as tsid

p = argparse.ArgumentParser()
p.add_argument("urdf")
p.add_argument("q0")
p.add_argument("--ticks", type=int, default=3000)
args = p.parse_args()

dt = 1e-3
robot = tsid.RobotWrapper(args.urdf, [], pin.JointModelFreeFlyer(), False)
model = robot.model()
q = np.load(args.q0)
v = np.zeros(model.nv)
form = tsid.InverseDynamicsFormulationAccForce("tsid", robot, False)
form.computeProblemData(0.0, q, v)
data = form.data()

lx, ly = 0.10, 0.065  # the sole rectangle's half sizes (0.20 x 0.13 m)
corners = np.array([[lx, -lx, -lx, lx], [ly, ly, -ly, -ly], [0.0] * 4])
contacts = []
for side in ("left", "right"):
    frame = f"{side}_sole_link"
    c = tsid.Contact6d(f"contact_{side}", robot, frame, corners, np.array([0.0, 0.0, 1.0]), 0.5, 0.0, 2000.0)
    c.setKp(30.0 * np.ones(6))
    c.setKd(2.0 * np.sqrt(30.0) * np.ones(6))
    c.setReference(robot.framePosition(data, model.getFrameId(frame)))
    form.addRigidContact(c, 1e-5)
    contacts.append(c)

com_task = tsid.TaskComEquality("com", robot)
com_task.setKp(20.0 * np.ones(3))
com_task.setKd(2.0 * np.sqrt(20.0) * np.ones(3))
form.addMotionTask(com_task, 1e3, 1, 0.0)
waist = tsid.TaskSE3Equality("waist", robot, "base_link")
waist.setKp(100.0 * np.ones(6))
waist.setKd(20.0 * np.ones(6))
waist.setMask(np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))
form.addMotionTask(waist, 1.0, 1, 0.0)
posture = tsid.TaskJointPosture("posture", robot)
posture.setKp(10.0 * np.ones(model.nv - 6))
posture.setKd(2.0 * np.sqrt(10.0) * np.ones(model.nv - 6))
form.addMotionTask(posture, 0.1, 1, 0.0)

am = tsid.TaskAMEquality("angular_momentum", robot)
am.setKp(10.0 * np.ones(3))
am.setKd(2.0 * np.sqrt(10.0) * np.ones(3))
form.addMotionTask(am, 2e-2, 1, 0.0)
bounds = tsid.TaskJointPosVelAccBounds("joint_bounds", robot, dt)
bounds.setPositionBounds(model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
form.addMotionTask(bounds, 1.0, 0, 0.0)

com0 = robot.com(data).copy()
com_traj = tsid.TrajectoryEuclidianConstant("com", com0)
waist_traj = tsid.TrajectorySE3Constant("waist", robot.framePosition(data, model.getFrameId("base_link")))
posture_traj = tsid.TrajectoryEuclidianConstant("posture", q[7:].copy())
am_traj = tsid.TrajectoryEuclidianConstant("am", np.zeros(3))
solver = tsid.SolverHQuadProgFast("qp")
solver.resize(form.nVar, form.nEq, form.nIn)

w = 2 * np.pi * 0.5
times = np.empty(args.ticks)
for k in range(args.ticks):
    t = k * dt
    sample = com_traj.computeNext()
    sample.value(com0 + np.array([0.0, 0.02 * np.sin(w * t), 0.0]))
    sample.derivative(np.array([0.0, 0.02 * w * np.cos(w * t), 0.0]))
    sample.second_derivative(np.array([0.0, -0.02 * w * w * np.sin(w * t), 0.0]))
    t0 = time.perf_counter()
    com_task.setReference(sample)
    waist.setReference(waist_traj.computeNext())
    posture.setReference(posture_traj.computeNext())
    am.setReference(am_traj.computeNext())
    hqp = form.computeProblemData(t, q, v)
    sol = solver.solve(hqp)
    tau = form.getActuatorForces(sol)
    dv = form.getAccelerations(sol)
    times[k] = (time.perf_counter() - t0) * 1e6
    if sol.status != 0:
        raise SystemExit(f"TSID's QP failed at tick {k} (status {sol.status})")
    v_mean = v + 0.5 * dt * dv
    v = v + dt * dv
    q = pin.integrate(model, q, dt * v_mean)
warm = times[args.ticks // 10:]
print(json.dumps({"peer": "tsid", "version": metadata.version("tsid"), "median_us": float(np.median(warm)),
                  "p99_us": float(np.percentile(warm, 99)),
                  "com_error_m": float(np.linalg.norm(robot.com(form.data()) - sample.value()))}))
