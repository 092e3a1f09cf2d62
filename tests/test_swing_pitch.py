"""The swing that pitches with the leg (`wbcbench.planning.swing_pitch`, task-set key `swing_foot.pitch_with_leg`):
the plan's pitch offset leaves and lands the foot at its planned orientation, keeps the sole clear of the ground,
lowers the predicted swing-ankle acceleration, and tsid-torque, taking it, walks with less swing-ankle torque."""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.inverse_dynamics import TSIDTorque
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.planning.swing_pitch import SwingPitchConfig, swing_pitch_offsets
from wbcbench.runner import run
from wbcbench.scenarios import load_scenario
from wbcbench.side import Side
from wbcbench.sim.model import ActuationMode


def _walk(talos, name, toe_off=None):
    scen = load_scenario(name, talos)
    if toe_off is not None:  # the swing's own pitch (walk-60cm's toe-off: tests/test_toe_off.py)
        scen.toe_off = toe_off
    q0 = talos.q0
    scen.setup(q0, pin.centerOfMass(talos.model, talos.model.createData(), q0))
    return scen


def _swings(foot, n):
    air = ~np.asarray(foot.in_contact[:n], dtype=bool)
    e = np.flatnonzero(np.diff(np.concatenate([[0], air.astype(np.int8), [0]])))
    return [(a - 1, b) for a, b in zip(e[::2], e[1::2])]  # last tick on the ground, first tick back on it


@pytest.mark.parametrize("name", ["walk-20cm-quick", "walk-60cm-quick"])
def test_planned_swing_pitch_is_level_at_both_ends_bounded_and_relieves_the_ankle(talos, name):
    scen = _walk(talos, name, toe_off=0.0)
    w, cfg, legs = scen.walk, scen.swing_pitch, scen.legs
    assert cfg.max_pitch > 0.0
    lever = talos.profile.sole.length / 2
    n_swings = 0
    for side in Side:
        f = w.feet[side]
        for lo, td in _swings(f, w.n_ticks):
            sl = slice(lo, td + 1)
            t = np.arange(lo, td + 1) * w.dt
            yaw = np.zeros(len(t))
            d, acc = swing_pitch_offsets(t, w.p_world_com[sl], yaw, f.p_world_sole[sl], f.R_world_sole[sl], side,
                                         legs, cfg)
            # level and at rest at lift-off and touch-down, and until the sole is `clearance` up
            assert np.all(d[0] == 0.0) and np.all(d[-1] == 0.0)
            z = f.p_world_sole[sl, 2] - min(f.p_world_sole[lo, 2], f.p_world_sole[td, 2])
            low = z <= cfg.clearance
            assert low[:5].all() and low[-5:].all()
            assert np.abs(d[low]).max() < 1e-6  # the window's last tick: the polynomials to rounding
            # bounded, and the sole's lower end (toe or heel) stays `clearance` above the ground
            assert np.abs(d[:, 0]).max() <= cfg.max_pitch + 1e-6
            tilted = np.abs(d[:, 0]) > 1e-9
            assert np.all(z[tilted] - lever * np.abs(np.sin(d[tilted, 0])) >= cfg.clearance - 1e-4)
            # the foot does pitch, and the predicted ankle acceleration falls (the first swing, from standing, the
            # least: 8 % on the 60 cm walk; the others 17-50 %)
            assert np.abs(d[:, 0]).max() > 0.03
            rms = np.sqrt(np.mean(acc**2))
            assert np.sqrt(np.mean((acc + d[:, 2]) ** 2)) < 0.95 * rms
            # it reaches the references of the swinging foot only
            k = (lo + td) // 2
            refs = scen.references(k * w.dt)
            assert set(refs.swing_pitch) == set(refs.feet) == {side}
            np.testing.assert_allclose(refs.swing_pitch[side], d[k - lo], atol=1e-9)
            n_swings += 1
    assert n_swings >= 3
    assert scen.references(0.0).swing_pitch == {}  # both feet on the ground: none


def test_swing_pitch_config_rejects_bad_values():
    from wbcbench.errors import PlanningError

    with pytest.raises(PlanningError, match="max_pitch"):
        SwingPitchConfig(max_pitch=-0.1)
    with pytest.raises(PlanningError, match="clearance"):
        SwingPitchConfig(clearance=float("nan"))


def test_tsid_torque_swing_pitch_lowers_the_flying_ankle_torque(talos, tmp_path):
    """walk-60cm-quick with the shipped task set (pitch_with_leg on) and with it off: both walk without a fall,
    and with it the ankle of the foot in the air holds less torque (its rotor accelerates less)."""
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    assert spec.swing_pitch_with_leg
    off = replace(spec, swing_pitch_with_leg=False)
    rms, pgm = {}, {}
    for name, ts in (("on", spec), ("off", off)):
        res = run("walk-60cm-quick", TSIDTorque(talos, ActuationMode.TORQUE, 1e-3, ts), talos, out=tmp_path / name)
        assert not res.summary["fell"], res.summary["fall_reason"]
        log = res.log
        left, right = log["in_contact_ref_left"] > 0.5, log["in_contact_ref_right"] > 0.5
        sq = np.concatenate([log["tau.leg_left_5_joint"][right & ~left] ** 2,
                             log["tau.leg_right_5_joint"][left & ~right] ** 2])
        rms[name] = float(np.sqrt(sq.mean()))
        pgm[name] = res.summary["metrics"]["pgm"]["flying_foot"]
    assert rms["on"] < 0.9 * rms["off"], rms
    assert pgm["on"] > pgm["off"], pgm


def test_a_replan_brings_the_swing_pitch_under_way_back_to_level(talos):
    """A walk replacing another mid-swing (step adjustment) takes the swinging foot's pitch from its state at the
    re-plan tick (no jump in the reference) back to level and at rest by the touch-down; no other swing pitches."""
    from wbcbench.planning.swing_pitch import plan_swing_pitch

    scen = _walk(talos, "walk-60cm-quick", toe_off=0.0)
    w, legs, cfg = scen.walk, scen.legs, scen.swing_pitch
    fresh = plan_swing_pitch(w, legs, cfg)
    side = Side.LEFT
    lo, td = _swings(w.feet[side], w.n_ticks)[0]
    k = lo + 2 * (td - lo) // 5
    assert np.abs(fresh[side][k]).max() > 0.01  # under way
    new = plan_swing_pitch(w, legs, cfg, previous=(k, fresh))
    np.testing.assert_array_equal(new[side][lo:k], fresh[side][lo:k])
    np.testing.assert_allclose(new[side][k], fresh[side][k], atol=1e-9)
    assert np.abs(np.diff(new[side][k - 1:td + 1, 0])).max() < 0.005  # rad per tick
    assert np.abs(new[side][td]).max() < 1e-9
    assert np.abs(new[side][lo:td + 1, 0]).max() <= 1.05 * cfg.max_pitch
    other = np.ones(w.n_ticks, dtype=bool)
    other[lo:td + 1] = False
    assert not new[side][other].any() and not new[Side.RIGHT].any()
    assert fresh[Side.RIGHT].any()  # the right foot's swings, fresh, do pitch


def test_a_run_plans_the_swing_pitch_only_for_a_controller_that_takes_it(talos, tmp_path):
    """The walk plans the pitch (about 20 ms a walk, again at each re-plan) for tsid-torque, whose task set takes it,
    not for IK, whose does not; the same scenario object follows each run's controller."""
    scen = load_scenario("walk-20cm-quick", talos)
    run(scen, "ik", talos, out=tmp_path / "ik", duration=0.05)
    assert scen.legs is None and scen.references(3.0).swing_pitch == {}
    run(scen, "tsid-torque", talos, out=tmp_path / "torque", duration=0.05)
    assert scen.legs is not None and scen.references(3.0).swing_pitch
    assert _walk(talos, "walk-20cm-quick").legs is not None  # outside a run: offered


def test_ik_takes_the_swing_pitch_when_its_task_set_asks(talos, tmp_path):
    """The offer reaches any controller through its task set: IK with `swing_foot.pitch_with_leg` gives its swing
    task the planned rotation turned by the plan's offset (toe down mid-swing) and walks the quick 20 cm walk
    without a fall; with the shipped set (off) the swing task keeps the planned (level) rotation."""
    from wbcbench.controllers.ik import IKController

    spec = load_taskset(taskset_path(talos, "ik"), talos, max_level=8)
    assert not spec.swing_pitch_with_leg
    scen = _walk(talos, "walk-20cm-quick")
    w = scen.walk
    lo, td = _swings(w.feet[Side.LEFT], w.n_ticks)[0]
    t = (lo + (td - lo) // 2) * w.dt
    refs = scen.references(t)
    delta = float(refs.swing_pitch[Side.LEFT][0])
    assert delta > 0.05  # toe down mid-swing
    planned = refs.feet[Side.LEFT].rotation
    for on in (True, False):
        ctrl = IKController(talos, ActuationMode.POSITION, 1e-3, replace(spec, swing_pitch_with_leg=on))
        ctrl.references.apply(refs)
        R = ctrl.references.free_tasks[Side.LEFT]._R_ref
        turned = pin.log3(planned.T @ R)  # in the planned foot's frame
        np.testing.assert_allclose(turned, [0.0, delta if on else 0.0, 0.0], atol=1e-12)
    res = run("walk-20cm-quick", IKController(talos, ActuationMode.POSITION, 1e-3,
                                              replace(spec, swing_pitch_with_leg=True)), talos, out=tmp_path)
    assert not res.summary["fell"], res.summary["fall_reason"]
