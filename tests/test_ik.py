"""The hierarchical IK controller: sway and a short walk in closed loop, strict priorities on the robot,
graceful degradation when a level is out of reach, bad task files."""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.ik import IKController
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.runner import run
from wbcbench.side import Side
from wbcbench.sim.model import ActuationMode
from wbcbench.sim.simulator import Simulator
from wbcbench.types import PointReference, References


def test_ik_sway_within_1cm(talos, tmp_path):
    res = run("sway", "ik", talos, duration=10.0, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["com_rms_error_m"] < 0.01
    assert res.log["com.y"].max() - res.log["com.y"].min() > 0.08


def _ik(talos):
    sim = Simulator(talos, mode="position")
    # no stabilizer: these tests give no ZMP plan (the DCM stabilizer needs one, see test_stabilizer_protocol.py)
    spec = replace(load_taskset(taskset_path(talos, "ik"), talos, max_level=8), stabilizer=None)
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3, spec)
    meas = sim.measure()
    ctrl.reset(meas, References(t=0.0))
    return sim, ctrl, meas


def test_out_of_reach_com_degrades_gracefully_and_feet_keep_priority(talos):
    """A CoM 60 cm above its reach: the feet (level 0) stay exactly where they are, the CoM-height level is
    reported unmet, and the command is finite and within the joint limits."""
    sim, ctrl, meas = _ik(talos)
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, ctrl.q_int)
    feet0 = {s: d.oMf[talos.sole_frame_id(s)].copy() for s in Side}
    com0 = pin.centerOfMass(talos.model, d, ctrl.q_int)
    refs = References(t=0.0, com=PointReference(com0 + [0.0, 0.0, 0.6]))
    for _ in range(200):
        cmd = ctrl.step(meas, refs)
        assert np.all(np.isfinite(cmd.q))
        lo, hi = talos.position_limits
        assert np.all(cmd.q >= lo - 1e-9) and np.all(cmd.q <= hi + 1e-9)
    assert ctrl.unmet_levels == 1 and ctrl.status()["unmet_level_ticks"] > 0
    pin.framesForwardKinematics(talos.model, d, ctrl.q_int)
    for s in Side:
        # the feet rows are met to 1e-11 every tick; what is left is the second-order error of integrating
        # joint velocities saturated at their limits over 200 ticks
        assert np.allclose(d.oMf[talos.sole_frame_id(s)].translation, feet0[s].translation, atol=1e-4)
    # the CoM went up as far as it could
    assert pin.centerOfMass(talos.model, d, ctrl.q_int)[2] > com0[2] + 0.05


def test_lower_level_does_not_disturb_a_higher_one(talos):
    """Posture (level IV) pulls against a CoM x-y target (level II): the feet and CoM rows keep exactly the
    residual they have without the lower levels (strict priority on the real robot problem)."""
    sim, ctrl, meas = _ik(talos)
    d = talos.model.createData()
    com0 = pin.centerOfMass(talos.model, d, ctrl.q_int)
    refs = References(t=0.0, com=PointReference(com0 + [0.02, 0.03, 0.0]))
    seen = {}
    solve = ctrl.solver.solve

    def spy(levels, lower, upper):
        seen["levels"], seen["bounds"] = levels, (lower.copy(), upper.copy())
        return solve(levels, lower, upper)

    ctrl.solver.solve = spy
    ctrl.step(meas, refs)
    levels, (lo, hi) = seen["levels"], seen["bounds"]
    full = solve(levels, lo, hi)
    upto_com = solve(levels[:3], lo, hi)  # feet, CoM height, CoM x-y
    for k in range(3):
        assert full.levels[k].residual == pytest.approx(upto_com.levels[k].residual, abs=1e-8)
    assert full.levels[0].residual < 1e-8  # the feet are held exactly
    assert full.levels[-1].residual > 1e-3  # and the posture really conflicts


@pytest.mark.parametrize("old,new,needles", [
    ("frame: base,", "frame: torso_9_link,", ["tasks[2].frame", "torso_9_link"]),
    ("name: com_xy,", "name: com_z,", ["tasks[1].name", "twice"]),
    ("kp: 100.0, level: 4}", "kp: 100.0, level: 9}", ["tasks[3].level", "between 1 and 8"]),
    ("kp: 100.0, level: 4}", "kp: 100.0, priority: 4}", ["tasks[3].priority", "level"]),
    ("kp: 100.0, level: 1}", "kp: 100.0, level: 0}", ["tasks[0].level", ">= 1"]),
])
def test_bad_ik_task_files(talos, tmp_path, old, new, needles):
    text = taskset_path(talos, "ik").read_text()
    assert old in text
    p = tmp_path / "ik.yaml"
    p.write_text(text.replace(old, new))
    with pytest.raises(ConfigError) as err:
        load_taskset(p, talos, max_level=8)
    for n in needles + [str(p)]:
        assert n in str(err.value), str(err.value)


def test_ik_rejects_a_hard_task(talos, tmp_path):
    """`hard` makes an equality constraint of the inverse-dynamics QP; a hierarchy orders tasks by level."""
    text = taskset_path(talos, "ik").read_text().replace("kp: 100.0, level: 1}", "kp: 100.0, level: 1, hard: true}")
    p = tmp_path / "ik.yaml"
    p.write_text(text)
    spec = load_taskset(p, talos, max_level=8)
    with pytest.raises(ConfigError, match="com_z.*level"):
        IKController(talos, ActuationMode.POSITION, 1e-3, spec)


@pytest.mark.parametrize("option", ["drift: classical", "wrench_metric: {form: tsid}"])
def test_ik_rejects_the_contacts_dynamics_options(talos, tmp_path, option):
    """The contacts' drift and wrench metric are the inverse-dynamics QP's; the kinematic hierarchy refuses them."""
    text = taskset_path(talos, "ik").read_text().replace("contacts: {kp: 1000.0}",
                                                         f"contacts: {{kp: 1000.0, {option}}}")
    p = tmp_path / "ik.yaml"
    p.write_text(text)
    spec = load_taskset(p, talos, max_level=8)
    with pytest.raises(ConfigError, match=f"contacts.{option.split(':')[0]}.*inverse-dynamics") as err:
        IKController(talos, ActuationMode.POSITION, 1e-3, spec)
    assert str(p) in str(err.value)


def test_ik_contacts_take_the_pose_error_option(talos, tmp_path):
    """`contacts.error: split` (the pose error of the contact rows, the kinematic hierarchy's too) reaches the IK's
    contacts."""
    text = taskset_path(talos, "ik").read_text().replace("contacts: {kp: 1000.0}", "contacts: {kp: 1000.0, error: split}")
    p = tmp_path / "ik.yaml"
    p.write_text(text)
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3, load_taskset(p, talos, max_level=8))
    assert all(c.error_convention == "split" for c in ctrl.formulation.contacts.values())
