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
  swing_pitch_max: 0.7
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
    scen = load_scenario(str(both), talos)
    with pytest.raises(ConfigError, match="toe_off") as err:
        scen.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
    assert "\n" not in str(err.value)


def test_toe_off_rolls_the_loaded_foot_about_its_toe_without_slipping(talos, tmp_path):
    """tsid-torque on one 60 cm step with a toe-off: no fall; in the roll before the lift-off the QP puts the leaving
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
    assert len(rolling) > 40  # a roll of 50 ms (from when the planned ZMP has passed the toe)
    side = next(s for s in Side if scen.walk.feet[s].in_contact[rolling[0]] and
                not scen.walk.feet[s].in_contact[rolling[-1] + 1])
    name = side.value
    model, data = talos.model, talos.model.createData()
    fid = talos.sole_frame_id(side)
    qcols = [k for k in log if k.startswith("q.")]
    Q = np.column_stack([log[k] for k in qcols])
    n = len(log["t"])
    ticks = rolling[rolling < n]
    toe, heel, pitch = [], [], []
    for k in ticks:
        q = Q[k].copy()
        pin.framesForwardKinematics(model, data, q)
        M = data.oMf[fid]
        toe.append(M.act(np.array([0.1, 0.0, 0.0])))
        heel.append(M.act(np.array([-0.1, 0.0, 0.0])))
        x = M.rotation[:, 0]
        pitch.append(np.arctan2(-x[2], np.hypot(x[0], x[1])))
    toe, heel, pitch = np.array(toe), np.array(heel), np.array(pitch)
    # the foot turns heel up about its toe, and the toe edge holds (nor sinks, nor lifts). Known defect: at the
    # roll's first ticks the sole still carries some 880 N, and the switch to the edge moves the toe back by
    # about 5.5 mm within 8 ms (README, "toe-off"); after that it holds to a millimetre
    assert pitch[-1] - pitch[0] > 0.008
    assert heel[-1, 2] - heel[0, 2] > 0.0015
    assert np.abs(toe[8:] - toe[8]).max() < 0.001
    assert np.abs(toe[:, 2]).max() < 0.002
    # the QP's wrench on the leaving foot: its normal force on the toe edge (CoP x in the sole frame)
    # (a log row holds the wrench of the previous tick's solve: from the roll's second row on)
    wq = np.column_stack([log[f"wrench_qp_{name}.{a}"] for a in ("fz", "my")])[ticks[1:]]
    loaded = wq[:, 0] > 20.0
    assert loaded.sum() > 10
    np.testing.assert_array_less(0.094, -wq[loaded, 1] / wq[loaded, 0] + 1e-9)
    # the simulated ground: the foot is loaded and its centre of pressure (world x, ground at z = 0) is at the toe
    # (from the roll's fifth tick: the switch's transient above)
    fz = np.asarray(log[f"contact_{name}.fz"])[ticks[4:]]
    my = np.asarray(log[f"contact_{name}.my"])[ticks[4:]]
    ground = fz > 20.0
    assert ground.sum() > 10
    cop_x = -my[ground] / fz[ground]
    assert np.abs(cop_x - toe[4:][ground, 0]).max() < 0.005
