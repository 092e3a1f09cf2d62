"""Records C++ TSID's solutions of the standing problem of `tsid_stand.py` (TALOS, both soles as 6D contacts, CoM,
waist orientation, angular momentum, posture, joint position bounds) at a few states, as test data for
tests/test_tsid_crosscheck.py (TSID's wheels need pinocchio 3.4, wbcbench pinocchio 4: the test reads
the recorded numbers).

Two steps, from the repository root:

    .venv/bin/python benchmarks/peers/tsid_record.py --prepare DIR     # wbcbench's TALOS: URDF, q0, armature, sole
    PEERS/tsid/bin/python benchmarks/peers/tsid_record.py DIR --out tests/data/tsid_reference/talos_stand.json

(PEERS from benchmarks/peers/setup.sh). The model is wbcbench's (the URDF with its armature, which enters the mass
matrix in both). States: `stand` (half-sitting at rest, references where the robot is), `com_moved` (the CoM
reference 1-2 cm away with a velocity and an acceleration), `perturbed` (joint positions and all velocities
perturbed, the references those of half-sitting but the contacts', set where the soles are), `contacts_off` (the
perturbed state with the contacts' references 1-2.6 cm and 1.6-3 degrees off the soles). Recorded per state:
q, v, the references, and TSID's joint accelerations dv, torques tau, corner forces (12 per contact) and contact
wrenches (its force generator matrix times them, at the sole frame).
"""

import argparse
import json
import re
from importlib import metadata
from pathlib import Path

import numpy as np

#: The problem's parameters (stored with the outputs; the test builds wbcbench's formulation from them)
PARAMS = {
    "mu": 0.5,  # TSID's corner pyramid coefficient
    "min_normal_force": 0.0, "max_normal_force": 2000.0,
    "contact_kp": 30.0, "contact_kd": 2.0 * np.sqrt(30.0),
    "force_regularization_weight": 1e-5, "force_axis_weights": [1.0, 1.0, 1e-3, 2.0, 2.0, 2.0],
    "hessian_regularization": 1e-8,  # TSID 1.7's DEFAULT_HESSIAN_REGULARIZATION, on every QP variable
    "com_kp": 20.0, "com_kd": 2.0 * np.sqrt(20.0), "com_weight": 1e3,
    "waist_frame": "base_link", "waist_kp": 100.0, "waist_kd": 20.0, "waist_weight": 1.0,
    "posture_kp": 10.0, "posture_kd": 2.0 * np.sqrt(10.0), "posture_weight": 0.1,
    "am_kp": 10.0, "am_weight": 2e-2,
    "dt": 1e-3,
    "frames": ["left_sole_link", "right_sole_link"],
}


def prepare(out: Path) -> None:
    """wbcbench's TALOS for the peers' venv: its URDF without visuals and collisions, q0, armature and sole."""
    from wbcbench.robots import load_robot

    robot = load_robot("talos")
    out.mkdir(parents=True, exist_ok=True)
    txt = re.sub(r"<(visual|collision)\b.*?</\1>", "", robot.files.urdf.read_text(), flags=re.S)
    (out / "talos.urdf").write_text(txt)
    sole = robot.profile.sole
    np.savez(out / "talos.npz", q0=robot.q0, armature=robot.model.armature,
             sole=np.array([sole.length, sole.width, *sole.center]))


def record(src: Path, out: Path) -> None:
    import pinocchio as pin

    try:
        import tsid
        tsid.RobotWrapper
    except AttributeError:  # tsid 1.7.1's wheel puts its __init__ one level too deep
        from tsid import tsid_pywrap as tsid

    P = PARAMS
    z = np.load(src / "talos.npz")
    model = pin.buildModelFromUrdf(str(src / "talos.urdf"), pin.JointModelFreeFlyer())
    model.armature = z["armature"]
    length, width, cx, cy = z["sole"]
    # TSID's contact points (3, 4) in the sole frame: the sole rectangle's corners
    corners = np.array([[cx + sx * length / 2, cy + sy * width / 2, 0.0] for sx in (1, -1) for sy in (1, -1)]).T
    q0 = z["q0"]
    rng = np.random.default_rng(29)
    dq = np.zeros(model.nv)
    dq[6:] = rng.uniform(-0.03, 0.03, model.nv - 6)
    v_pert = np.concatenate([rng.uniform(-0.05, 0.05, 6), rng.uniform(-0.2, 0.2, model.nv - 6)])
    states = {"stand": (q0, np.zeros(model.nv), np.zeros(3), np.zeros(3), np.zeros(3)),
              "com_moved": (q0, np.zeros(model.nv), np.array([0.01, -0.02, -0.01]), np.array([0.0, 0.05, 0.02]),
                            np.array([0.1, -0.3, 0.0])),
              "perturbed": (pin.integrate(model, q0, dq), v_pert, np.zeros(3), np.zeros(3), np.zeros(3))}
    # the perturbed state with each contact's reference off its sole (in the sole's frame: a translation [m] and a
    # rotation vector [rad], about 1-2.6 cm and 1.6-3 degrees): where TSID's contact error differs from log6's
    offsets = {"contacts_off": [(np.array([0.008, -0.026, 0.004]), np.array([0.03, -0.04, 0.02])),
                                (np.array([-0.012, 0.01, -0.003]), np.array([-0.02, 0.01, 0.015]))]}
    states["contacts_off"] = states["perturbed"]
    data = {"tsid_version": metadata.version("tsid"), "pinocchio_version": pin.__version__,
            "params": P, "corners": corners.T, "states": list(states)}
    for name, (q, v, dcom, vcom, acom) in states.items():
        robot = tsid.RobotWrapper(model, tsid.RootJointType.FLOATING_BASE_SYSTEM, False)
        form = tsid.InverseDynamicsFormulationAccForce("tsid", robot, False)
        # the references: the soles where they are (TSID's contact error, [R^T (p_ref - p); log3(R^T R_ref)], is
        # not log6's, Contact6D's: they differ at second order off the reference), the others those of
        # half-sitting at rest (the CoM's moved by dcom)
        form.computeProblemData(0.0, q, v)
        soles = [robot.framePosition(form.data(), model.getFrameId(f)).copy() for f in P["frames"]]
        if name in offsets:
            soles = [M * pin.SE3(pin.exp3(w), p) for M, (p, w) in zip(soles, offsets[name])]
        form.computeProblemData(0.0, q0, np.zeros(model.nv))
        d0 = form.data()
        contact_refs, contacts = [], []
        for frame, ref in zip(P["frames"], soles):
            c = tsid.Contact6d(f"contact_{frame}", robot, frame, corners, np.array([0.0, 0.0, 1.0]), P["mu"],
                               P["min_normal_force"], P["max_normal_force"])
            c.setKp(P["contact_kp"] * np.ones(6))
            c.setKd(P["contact_kd"] * np.ones(6))
            c.setRegularizationTaskWeightVector(np.array(P["force_axis_weights"]))
            c.setReference(ref)
            contact_refs.append(ref.homogeneous.copy())
            form.addRigidContact(c, P["force_regularization_weight"])
            contacts.append(c)
        com_ref = robot.com(d0).copy() + dcom
        com = tsid.TaskComEquality("com", robot)
        com.setKp(P["com_kp"] * np.ones(3))
        com.setKd(P["com_kd"] * np.ones(3))
        form.addMotionTask(com, P["com_weight"], 1, 0.0)
        waist = tsid.TaskSE3Equality("waist", robot, P["waist_frame"])
        waist.setKp(P["waist_kp"] * np.ones(6))
        waist.setKd(P["waist_kd"] * np.ones(6))
        waist.setMask(np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))
        form.addMotionTask(waist, P["waist_weight"], 1, 0.0)
        posture = tsid.TaskJointPosture("posture", robot)
        posture.setKp(P["posture_kp"] * np.ones(model.nv - 6))
        posture.setKd(P["posture_kd"] * np.ones(model.nv - 6))
        form.addMotionTask(posture, P["posture_weight"], 1, 0.0)
        am = tsid.TaskAMEquality("angular_momentum", robot)
        am.setKp(P["am_kp"] * np.ones(3))
        am.setKd(2.0 * np.sqrt(P["am_kp"]) * np.ones(3))  # unused by the task (no momentum integral)
        form.addMotionTask(am, P["am_weight"], 1, 0.0)
        bounds = tsid.TaskJointPosVelAccBounds("joint_bounds", robot, P["dt"])
        bounds.setPositionBounds(model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        form.addMotionTask(bounds, 1.0, 0, 0.0)

        waist_ref = robot.framePosition(d0, model.getFrameId(P["waist_frame"]))
        com_sample = tsid.TrajectorySample(3)
        com_sample.value(com_ref)
        com_sample.derivative(vcom)
        com_sample.second_derivative(acom)
        com.setReference(com_sample)
        waist.setReference(tsid.TrajectorySE3Constant("waist", waist_ref).computeNext())
        posture.setReference(tsid.TrajectoryEuclidianConstant("posture", q0[7:].copy()).computeNext())
        am.setReference(tsid.TrajectoryEuclidianConstant("am", np.zeros(3)).computeNext())
        solver = tsid.SolverHQuadProgFast("qp")
        solver.resize(form.nVar, form.nEq, form.nIn)
        hqp = form.computeProblemData(0.0, q, v)
        sol = solver.solve(hqp)
        if sol.status != 0:
            raise SystemExit(f"TSID's QP failed in state {name} (status {sol.status})")
        corner_forces = np.array([form.getContactForce(c.name, sol) for c in contacts])
        wrenches = np.array([c.getForceGeneratorMatrix @ f for c, f in zip(contacts, corner_forces)])
        data.update({f"{name}/q": q, f"{name}/v": v, f"{name}/com_ref": np.array([com_ref, vcom, acom]),
                     f"{name}/contact_refs": np.array(contact_refs), f"{name}/waist_ref": waist_ref.homogeneous,
                     f"{name}/posture_ref": q0[7:], f"{name}/dv": form.getAccelerations(sol),
                     f"{name}/tau": form.getActuatorForces(sol), f"{name}/corner_forces": corner_forces,
                     f"{name}/wrenches": wrenches})
    out.parent.mkdir(parents=True, exist_ok=True)
    # text, so that the test data can be read and reviewed: every array as nested lists (floats round-trip exactly)
    out.write_text(json.dumps({k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in data.items()},
                              indent=1) + "\n")
    print(f"{out}: TSID {data['tsid_version']}, states {', '.join(states)}")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dir", help="the directory --prepare writes (URDF, q0, armature, sole) and the recording reads")
    p.add_argument("--prepare", action="store_true", help="write DIR from wbcbench (run in wbcbench's venv)")
    p.add_argument("--out", type=Path, default=Path("tests/data/tsid_reference/talos_stand.json"))
    a = p.parse_args()
    prepare(Path(a.dir)) if a.prepare else record(Path(a.dir), a.out)
