"""The toe-off (a walk's `toe_off`, with a task set that takes the swing pitch): before its lift-off the leaving foot
rolls about its toe edge, a line contact in the inverse-dynamics QP, and its swing starts turned with the leg."""

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ConfigError
from wbcbench.planning.swing_pitch import SwingPitchConfig
from wbcbench.runner import run
from wbcbench.scenarios import load_scenario
from wbcbench.side import Side
from wbcbench.tasks import Contact6D

_QUICK = """name: walk-60cm-toe-off-quick
kind: walk
terrain: {type: flat}
params:
  steps: 1
  initial_double_support: 2.5
  final_double_support: 1.0
  preview_horizon: 1.6
  step_length: 0.60
  single_support: 0.9
  double_support: 0.115
  apex: 0.05
  com_height: 0.76
  toe_off: 0.05
  swing_pitch_max: 1.0
"""


def test_edge_contact_rows_hold_the_centre_of_pressure_on_the_edge(talos):
    c = Contact6D(talos.model, talos.profile.feet[Side.LEFT].frame, length=0.2, width=0.13, kp=30.0, mu=0.5)
    assert c.edge is None and c.edge_x("toe") == pytest.approx(0.1) and c.edge_x("heel") == pytest.approx(-0.1)
    f = 300.0
    at = lambda x: np.array([0.0, 0.0, f, 0.0, -x * f, 0.0])  # noqa: E731  (a normal force with its CoP at x)
    assert c.inside(at(0.0)) and c.inside(at(0.099))
    c.set_edge("toe")
    assert c.inside(at(0.099)) and not c.inside(at(0.0)) and not c.inside(at(-0.099))
    c.set_edge("heel")
    assert c.inside(at(-0.099)) and not c.inside(at(0.099))
    c.set_edge(None)
    assert c.inside(at(0.0))
    with pytest.raises(Exception, match="edge"):
        c.edge_x("side")


def test_swing_pitch_about_a_given_axis():
    """A toe-off's swing turns about the ankle pitch joint's axis: Rot(axis, delta) R, the rate about that axis;
    with the foot's own lateral axis it is the usual turn."""
    from wbcbench.controllers.task_references import with_swing_pitch
    from wbcbench.types import PoseReference

    R = pin.rpy.rpyToMatrix(0.05, -0.02, 0.3)
    foot = PoseReference.unchecked(np.zeros(3), R, np.zeros(6), np.zeros(6))
    d = np.array([0.4, 2.0, -5.0, 0.0])
    own = with_swing_pitch({Side.LEFT: foot}, {Side.LEFT: d})[Side.LEFT]
    same = with_swing_pitch({Side.LEFT: foot}, {Side.LEFT: d}, {Side.LEFT: R[:, 1]})[Side.LEFT]
    np.testing.assert_allclose(same.rotation, own.rotation, atol=1e-12)
    np.testing.assert_allclose(same.velocity, own.velocity, atol=1e-12)
    axis = np.array([0.0, np.cos(0.15), np.sin(0.15)])  # a shank leaning sideways
    tilted = with_swing_pitch({Side.LEFT: foot}, {Side.LEFT: d}, {Side.LEFT: axis})[Side.LEFT]
    np.testing.assert_allclose(tilted.rotation, pin.exp3(axis * 0.4) @ R, atol=1e-12)
    np.testing.assert_allclose(tilted.velocity[3:], axis * 2.0, atol=1e-12)
    np.testing.assert_allclose(tilted.acceleration[3:], axis * -5.0, atol=1e-12)
    # a moving foot: v_w += y rate, a_w += y acc + (omega x y) rate, the linear parts unchanged
    rng = np.random.default_rng(3)
    vel, acc = rng.normal(size=6), rng.normal(size=6)
    moving = PoseReference.unchecked(np.ones(3), R, vel, acc)
    for ax, y in ((None, R[:, 1]), (axis, axis)):
        out = with_swing_pitch({Side.LEFT: moving}, {Side.LEFT: d}, None if ax is None else {Side.LEFT: ax})
        got = out[Side.LEFT]
        np.testing.assert_allclose(got.velocity, np.r_[vel[:3], vel[3:] + y * 2.0], atol=1e-12)
        np.testing.assert_allclose(got.acceleration, np.r_[acc[:3], acc[3:] + y * -5.0 + np.cross(vel[3:], y) * 2.0],
                                   atol=1e-12)
        np.testing.assert_array_equal(got.position, np.ones(3))


def test_toe_off_bad_config_is_one_line_error(talos, tmp_path):
    from wbcbench.errors import PlanningError

    with pytest.raises(PlanningError, match="toe_off"):
        SwingPitchConfig(toe_off=-0.1)
    bad = tmp_path / "neg.yaml"
    bad.write_text(_QUICK.replace("toe_off: 0.05", "toe_off: -0.1"))
    with pytest.raises(ConfigError, match="toe_off"):
        load_scenario(str(bad), talos)
    both = tmp_path / "both.yaml"
    both.write_text(_QUICK + "  step_adjustment: {}\n")
    with pytest.raises(ConfigError, match="toe_off") as err:
        load_scenario(str(both), talos)
    assert "\n" not in str(err.value) and "both.yaml" in str(err.value)
    # switched on from outside the file (--step-adjustment): the walk plans no toe-off
    ok = tmp_path / "ok.yaml"
    ok.write_text(_QUICK)
    scen = load_scenario(str(ok), talos)
    scen.enable_step_adjustment()
    scen.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
    assert scen.swing_pitch.toe_off == 0.0 and not any(scen._tabulate(scen.walk).rolling)


def test_toe_off_rolls_the_loaded_foot_about_its_toe_without_slipping(talos, tmp_path):
    """tsid-torque on one 60 cm step with a toe-off: no fall; in each roll before a lift-off the QP puts the leaving
    foot's load on its toe edge, the simulated ground pushes there, and the foot turns heel up about its toe while
    the toe stays where it was."""
    path = tmp_path / "toe.yaml"
    path.write_text(_QUICK)
    res = run(str(path), "tsid-torque", talos, out=tmp_path / "run")
    assert not res.summary["fell"], res.summary["fall_reason"]
    log = res.log
    scen = load_scenario(str(path), talos)
    scen.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
    table = scen._tabulate(scen.walk)
    rolling = np.flatnonzero(table.rolling)
    rolls = np.split(rolling, np.flatnonzero(np.diff(rolling) > 1) + 1)
    # the first step's leaving foot, from standing, has none (the planned ZMP goes sideways onto the other foot and
    # never passes its toe: one tick, its lift-off); the final step's does
    assert len(rolls) == 2 and len(rolls[0]) == 1
    rolls = rolls[1:]
    model, data = talos.model, talos.model.createData()
    Q = np.column_stack([log[k] for k in log if k.startswith("q.")])
    loads = []
    for ticks in rolls:
        assert len(ticks) > 40  # 50 ms at most (from when the planned ZMP has passed the toe)
        side = next(s for s in Side if table.pitch[s][ticks[0], 3] != 0.0 and scen.walk.feet[s].in_contact[ticks[0]])
        assert not scen.walk.feet[side].in_contact[ticks[-1] + 1]  # the roll ends at the lift-off
        name, fid = side.value, talos.sole_frame_id(side)
        toe, heel, pitch = [], [], []
        for k in ticks:
            pin.framesForwardKinematics(model, data, Q[k])
            M = data.oMf[fid]
            toe.append(M.act(np.array([0.1, 0.0, 0.0])))
            heel.append(M.act(np.array([-0.1, 0.0, 0.0])))
            x = M.rotation[:, 0]
            pitch.append(np.arctan2(-x[2], np.hypot(x[0], x[1])))
        toe, heel, pitch = np.array(toe), np.array(heel), np.array(pitch)
        # the foot turns heel up about its toe, and the toe edge holds: no slip, no sinking, no lifting
        assert pitch[-1] - pitch[0] > 0.008
        assert heel[-1, 2] - heel[0, 2] > 0.0015
        assert np.abs(toe - toe[0]).max() < 0.001
        # the QP's wrench on the leaving foot (a log row holds the previous tick's solve: from the roll's second
        # row on): where it is loaded, its centre of pressure on the toe's strip (x in the sole frame)
        wq = np.column_stack([log[f"wrench_qp_{name}.{a}"] for a in ("fz", "my")])[ticks[1:]]
        loaded = wq[:, 0] > 20.0
        if loaded.any():
            np.testing.assert_array_less(0.094, -wq[loaded, 1] / wq[loaded, 0] + 1e-9)
        # the simulated ground (world wrench, ground at z = 0: CoP x = -my / fz), once the switch has reached it
        fz = np.asarray(log[f"contact_{name}.fz"])[ticks[4:]]
        my = np.asarray(log[f"contact_{name}.my"])[ticks[4:]]
        ground = fz > 20.0
        if ground.any():
            assert np.abs(-my[ground] / fz[ground] - toe[4:][ground, 0]).max() < 0.005
        loads.append(fz.max())
    # the roll starts loaded
    assert loads[0] > 200.0
