"""pink (differential IK on pinocchio, with daqp) on the peers' standing problem (see tsid_stand.py): the soles as
frame tasks of high weight, the CoM following a lateral sine of 2 cm at 0.5 Hz, base orientation, posture to
half-sitting, the model's configuration limits; the velocity integrated at 1 kHz. Run in the peers' virtual
environment; prints one JSON line.

    PEERS/placo/bin/python benchmarks/peers/pink_stand.py URDF Q0.npy [--ticks 3000]
"""

import argparse
import json
import time
from importlib import metadata

import numpy as np
import pinocchio as pin
import pink
from pink.tasks import ComTask, FrameTask, PostureTask

p = argparse.ArgumentParser()
p.add_argument("urdf")
p.add_argument("q0")
p.add_argument("--ticks", type=int, default=3000)
args = p.parse_args()

dt = 1e-3
model = pin.buildModelFromUrdf(args.urdf, pin.JointModelFreeFlyer())
q = np.load(args.q0)
# half-sitting has the grippers exactly on a limit: widened as wbcbench widens them
model.lowerPositionLimit[7:] = np.minimum(model.lowerPositionLimit[7:], q[7:] - 1e-3)
model.upperPositionLimit[7:] = np.maximum(model.upperPositionLimit[7:], q[7:] + 1e-3)
data = model.createData()
config = pink.Configuration(model, data, q)
feet = []
for side in ("left", "right"):
    task = FrameTask(f"{side}_sole_link", position_cost=1e3, orientation_cost=1e3)
    task.set_target_from_configuration(config)
    feet.append(task)
com = ComTask(cost=1e2)
com0 = pin.centerOfMass(model, data, q).copy()
base = FrameTask("base_link", position_cost=0.0, orientation_cost=1.0)
base.set_target_from_configuration(config)
posture = PostureTask(cost=1e-2)
posture.set_target(q)
tasks = [*feet, com, base, posture]

w = 2 * np.pi * 0.5
times = np.empty(args.ticks)
for k in range(args.ticks):
    t = k * dt
    target = com0 + np.array([0.0, 0.02 * np.sin(w * t), 0.0])
    t0 = time.perf_counter()
    com.set_target(target)
    velocity = pink.solve_ik(config, tasks, dt, solver="daqp")
    config.integrate_inplace(velocity, dt)
    times[k] = (time.perf_counter() - t0) * 1e6
warm = times[args.ticks // 10:]
print(json.dumps({"peer": "pink", "version": metadata.version("pin-pink"), "median_us": float(np.median(warm)),
                  "p99_us": float(np.percentile(warm, 99)),
                  "com_error_m": float(np.linalg.norm(pin.centerOfMass(model, data, config.q) - target))}))
