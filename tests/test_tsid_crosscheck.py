"""wbcbench's inverse-dynamics formulation against C++ TSID's numbers, built with public options only: the contacts'
classical drift and split pose error, TSID's wrench metric (`tsid_wrench_metric`), TSID's weights and gains.

The reference (tests/data/tsid_reference/talos_stand.json, the recorded numbers as text) is recorded by benchmarks/peers/tsid_record.py in the
peers' venv (TSID 1.7.1 with pinocchio 3.4): TALOS standing on both soles, CoM, waist orientation, angular momentum,
posture, joint position bounds, at four states (at rest, the CoM reference moved with a velocity and an
acceleration, joints and velocities perturbed, and that state with the contacts' references off the soles).
"""

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.id_formulation import InverseDynamicsFormulation
from wbcbench.controllers.taskset import ContactSpec, TsidWrenchMetric
from wbcbench.qp import QPStatus, make_solver
from wbcbench.tasks import AngularMomentumTask, CoMTask, Contact6D, FrameTask, PostureTask, tsid_wrench_metric

REF = Path(__file__).parent / "data" / "tsid_reference" / "talos_stand.json"


@pytest.fixture(scope="module")
def ref():
    raw = json.loads(REF.read_text())
    return {k: v if k in ("params", "tsid_version", "pinocchio_version") else np.asarray(v) for k, v in raw.items()}


def _formulation(talos, ref, drift="classical", metric=True, error="split"):
    """wbcbench's formulation of the recorded TSID problem (the record's parameters, the robot's model)."""
    P = ref["params"]
    m = talos.model
    corners = ref["corners"]
    length, width = np.ptp(corners[:, 0]), np.ptp(corners[:, 1])
    center = corners[:, :2].mean(axis=0)
    W = tsid_wrench_metric(corners, weight=P["force_regularization_weight"], axis_weights=P["force_axis_weights"],
                           corner_regularization=P["hessian_regularization"]) if metric else None
    # TSID's mu is its corner pyramids' slope; Contact6D's pyramid is mu / sqrt(2)
    contacts = {f: Contact6D(m, f, length=length, width=width, center=center, kp=P["contact_kp"],
                             kd=P["contact_kd"], mu=P["mu"] * np.sqrt(2.0), min_normal_force=P["min_normal_force"],
                             max_normal_force=P["max_normal_force"], drift=drift, wrench_metric=W, error=error)
                for f in P["frames"]}
    free = {f: FrameTask(m, f, kp=1.0, name=f"free_{f}") for f in P["frames"]}
    com = CoMTask(m, kp=P["com_kp"], kd=P["com_kd"], weight=P["com_weight"])
    waist = FrameTask(m, P["waist_frame"], kp=P["waist_kp"], kd=P["waist_kd"], weight=P["waist_weight"],
                      mask=(0, 0, 0, 1, 1, 1))
    posture = PostureTask(m, kp=P["posture_kp"], kd=P["posture_kd"], weight=P["posture_weight"])
    am = AngularMomentumTask(m, kd=P["am_kp"], weight=P["am_weight"])
    F = InverseDynamicsFormulation(
        m, [com, waist, posture, am], contacts, free, position_limits=(m.lowerPositionLimit[7:],
                                                                       m.upperPositionLimit[7:]),
        velocity_limit=m.velocityLimit[6:], effort_limit=m.effortLimit[6:],
        regularization_dv=P["hessian_regularization"], dt=P["dt"])
    return F, contacts, (com, waist, posture, am)


def _problem(F, contacts, tasks, ref, state):
    """The formulation's QP at a recorded state with the recorded references."""
    com, waist, posture, am = tasks
    q, v = ref[f"{state}/q"], ref[f"{state}/v"]
    F.update(q, v)
    for c, M in zip(contacts.values(), ref[f"{state}/contact_refs"]):
        c.set_reference(pin.SE3(M))
    com.set_reference(*ref[f"{state}/com_ref"])
    waist.set_reference(pin.SE3(ref[f"{state}/waist_ref"]))
    q_ref = q.copy()
    q_ref[7:] = ref[f"{state}/posture_ref"]
    posture.set_reference(q_ref)
    am.set_reference(np.zeros(3))
    return F.problem()


def _optimum(P):
    """The QP's optimum from its equality-constrained KKT system, checked to satisfy every inequality (then it is
    the optimum of the whole convex QP, the inequalities' multipliers zero): exact to rounding, where an iterative
    solver stops at its tolerances."""
    n, m = P.H.shape[0], P.A_eq.shape[0]
    K = np.block([[P.H, P.A_eq.T], [P.A_eq, np.zeros((m, m))]])
    x = np.linalg.solve(K, np.concatenate([-P.g, P.b_eq]))[:n]
    Cx = P.C @ x
    assert np.all(Cx <= P.u + 1e-9) and np.all(Cx >= P.l - 1e-9), "an inequality binds"
    assert np.all(x <= P.ub + 1e-9) and np.all(x >= P.lb - 1e-9), "a bound binds"
    return x


def _split(F, x):
    tau, _ = F.torques(x)
    return x[:F.nv], tau, x[F.nv:].reshape(-1, 6)


def _rel(a, b):
    """The largest difference relative to the reference's largest entry."""
    return float(np.abs(a - b).max() / np.abs(b).max())


STATES = ["stand", "com_moved", "perturbed", "contacts_off"]


@pytest.mark.parametrize("state", STATES)
def test_formulation_matches_tsid(talos, ref, state):
    """The optimum of wbcbench's QP is TSID's: dv, tau and the contact wrenches to 1e-10 of each one's largest
    entry (measured: 1e-11 and below). TSID's corner forces enter through their least-norm regularisation; no
    friction row or bound binds in either problem (TSID's corner forces inside their pyramids)."""
    F, contacts, tasks = _formulation(talos, ref)
    dv, tau, w = _split(F, _optimum(_problem(F, contacts, tasks, ref, state)))
    assert _rel(dv, ref[f"{state}/dv"]) < 1e-10
    assert _rel(tau, ref[f"{state}/tau"]) < 1e-10
    assert _rel(w, ref[f"{state}/wrenches"]) < 1e-10
    mu = ref["params"]["mu"]
    f = ref[f"{state}/corner_forces"].reshape(-1, 4, 3)
    assert np.all(np.abs(f[..., :2]).max(axis=-1) < mu * f[..., 2])


@pytest.mark.parametrize("state", STATES)
def test_daqp_solution_near_tsid(talos, ref, state):
    """daqp's solution of the same QP (the controllers' solver) is TSID's to its tolerances: 1e-6 of each
    quantity's largest entry (measured up to 3.4e-7, on the tiny accelerations of the robot at rest; the
    wrenches' normal forces weigh 2.5e-9 per N^2 in this metric, which leaves them loosely determined)."""
    F, contacts, tasks = _formulation(talos, ref)
    res = make_solver("daqp").solve(_problem(F, contacts, tasks, ref, state))
    assert res.status is QPStatus.OPTIMAL
    dv, tau, w = _split(F, res.x)
    for name, ours in (("dv", dv), ("tau", tau), ("wrenches", w)):
        assert _rel(ours, ref[f"{state}/{name}"]) < 1e-6, name


def test_recorded_model_is_wbcbench_talos(talos, ref):
    """The record's robot is wbcbench's: the same half-sitting posture (its posture reference) and sole."""
    assert np.array_equal(ref["stand/q"][7:], talos.q0[7:])
    sole = talos.profile.sole
    corners = ref["corners"]
    assert np.isclose(np.ptp(corners[:, 0]), sole.length) and np.isclose(np.ptp(corners[:, 1]), sole.width)


def test_each_option_is_needed(talos, ref):
    """Without the classical drift (a moving state), without TSID's metric or without the split pose error (the
    contacts off their references), the optimum is not TSID's: the cross-check sees the three options."""
    F, contacts, tasks = _formulation(talos, ref, drift="spatial")
    dv, _, _ = _split(F, _optimum(_problem(F, contacts, tasks, ref, "perturbed")))
    assert _rel(dv, ref["perturbed/dv"]) > 1e-4
    F, contacts, tasks = _formulation(talos, ref, metric=False)
    _, _, w = _split(F, _optimum(_problem(F, contacts, tasks, ref, "com_moved")))
    assert _rel(w, ref["com_moved/wrenches"]) > 1e-4
    F, contacts, tasks = _formulation(talos, ref, error="log6")
    dv, _, _ = _split(F, _optimum(_problem(F, contacts, tasks, ref, "contacts_off")))
    assert _rel(dv, ref["contacts_off/dv"]) > 1e-3
    # the two errors agree where the contacts are on their references
    dv, _, _ = _split(F, _optimum(_problem(F, contacts, tasks, ref, "perturbed")))
    assert _rel(dv, ref["perturbed/dv"]) < 1e-10


def test_taskset_tsid_metric_is_the_helper(talos):
    """The task set's named form `{form: tsid}` gives `tsid_wrench_metric` on the sole's corners."""
    sole = talos.profile.sole
    spec = ContactSpec(kp=30.0, kd=11.0, wrench_metric=TsidWrenchMetric())
    W = spec.wrench_metric_matrix(sole.length, sole.width, sole.center)
    c = Contact6D(talos.model, "left_sole_link", length=sole.length, width=sole.width, kp=1.0)
    assert np.array_equal(W, tsid_wrench_metric(c.corners, weight=1e-5))
