"""The Stabilizer protocol: any registered stabilizer is selected from a task set's YAML, sees only the
measurement, the references and the controller's ModelFeedback, and acts through the references; a scenario that
lacks what a stabilizer needs fails at reset with one line."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import yaml

from wbcbench.config import Section
from wbcbench.controllers.inverse_dynamics import TSIDTorque
from wbcbench.controllers.taskset import taskset_path
from wbcbench.runner import run
from wbcbench.stabilizers.base import MissingReferenceError, Stabilizer, available_stabilizers, register_stabilizer
from wbcbench.types import ActuationMode, ModelFeedback, PointReference, References


@register_stabilizer
class ShiftCoM(Stabilizer):
    """Moves the CoM reference sideways by `offset` [m] (a test stabilizer)."""

    type = "test-shift-com"
    requires = ("com",)
    LOG_LABELS = ("offset",)
    seen: list = []

    @classmethod
    def parse(cls, sec: Section) -> float:
        value = sec.float("offset")
        sec.finish()
        return value

    def __init__(self, robot, spec: float, dt: float):
        self.offset = spec
        self.log = np.full(1, np.nan)

    def reset(self, meas, refs, feedback):
        ShiftCoM.seen.append(("reset", type(feedback)))

    def correct(self, meas, refs, feedback):
        ShiftCoM.seen.append(("correct", type(feedback), frozenset(feedback.active), feedback.q.shape))
        self.log[0] = self.offset
        com = refs.com
        return replace(refs, com=PointReference(com.position + [0.0, self.offset, 0.0], com.velocity,
                                                com.acceleration))


def test_a_registered_stabilizer_is_taken_from_the_task_set_yaml(talos, tmp_path):
    data = yaml.safe_load(taskset_path(talos, "tsid-torque").read_text())
    data["stabilizer"] = {"type": "test-shift-com", "offset": 0.02}
    p = tmp_path / "tsid-torque-shift.yaml"
    p.write_text(yaml.safe_dump(data))
    ShiftCoM.seen.clear()
    res = run("stand", "tsid-torque", duration=1.0, out=tmp_path / "run", taskset=p)
    assert not res.summary["fell"]
    assert ("reset", ModelFeedback) in ShiftCoM.seen
    kinds = {e[0] for e in ShiftCoM.seen}
    assert kinds == {"reset", "correct"}
    assert all(e[1] is ModelFeedback and e[3] == (talos.nq,) for e in ShiftCoM.seen if e[0] == "correct")
    # the CoM followed the shifted reference (the scenario's reference is logged, the shift is not)
    dy = res.log["com.y"][-1] - res.log["com_ref.y"][-1]
    assert dy == pytest.approx(0.02, abs=0.004)
    np.testing.assert_array_equal(res.log["stabilizer.offset"], 0.02)
    assert "test-shift-com" in available_stabilizers()


def test_dcm_stabilizer_needs_a_zmp_plan(talos):
    from wbcbench.controllers.ik import IKController
    from wbcbench.sim.simulator import Simulator

    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3)
    assert ctrl.stabilizer is not None and ctrl.stabilizer.type == "dcm"
    meas = Simulator(talos, mode="position").measure()
    with pytest.raises(MissingReferenceError, match="'dcm' stabilizer needs.*'com' and 'zmp'"):
        ctrl.reset(meas, References(t=0.0))
    with pytest.raises(MissingReferenceError, match="needs.*'zmp'"):
        ctrl.reset(meas, References(t=0.0, com=PointReference(np.zeros(3))))


def test_a_stabilizer_object_replaces_the_task_sets(talos):
    stab = ShiftCoM(talos, 0.01, 1e-3)
    ctrl = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3, stabilizer=stab)
    assert ctrl.stabilizer is stab and "stabilizer" in ctrl.log_channels()


def test_cli_scenario_without_what_the_stabilizer_needs(tmp_path):
    """A teleoperation scenario plans no ZMP: the IK's DCM stabilizer refuses it at reset, one line, exit 2."""
    scen = tmp_path / "replay.yaml"
    scen.write_text("name: replay\nkind: teleop\nduration: 0.05\nterrain: {type: flat}\n"
                    "params: {mocap: reach_forward, realtime: false}\n")
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", str(scen), "-c", "ik",
                          "--out", str(tmp_path / "r"), "--quiet"], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "'zmp'" in lines[0] and "stabilizer" in lines[0] and str(scen) in lines[0], out.stderr
    assert "Traceback" not in out.stderr


def test_cli_unknown_task_type_and_stabilizer_type(talos, tmp_path):
    data = yaml.safe_load(taskset_path(talos, "tsid-torque").read_text())
    data["tasks"][0]["type"] = "comm"
    p = tmp_path / "bad-task.yaml"
    p.write_text(yaml.safe_dump(data))
    q = tmp_path / "bad-stab.yaml"
    data = yaml.safe_load(taskset_path(talos, "tsid-position").read_text())
    data["stabilizer"]["type"] = "dcn"
    q.write_text(yaml.safe_dump(data))
    for path, needle in ((p, "unknown task type 'comm'"), (q, "unknown stabilizer type 'dcn'")):
        ctrl = "tsid-torque" if path is p else "tsid-position"
        out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", ctrl, "--taskset",
                              str(path), "--duration", "0.01", "--quiet", "--out", str(tmp_path / "r")],
                             capture_output=True, text=True)
        assert out.returncode == 2, out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and str(path) in lines[0], out.stderr


def test_the_fast_reference_constructors_set_every_field():
    """`References.planned` and `corrected` (slot by slot, for the per-tick paths) give what the constructor and
    `dataclasses.replace` give, for every field References has; `PointReference.unchecked` likewise."""
    from dataclasses import fields

    from wbcbench.robots import Side
    from wbcbench.types import PoseReference

    com = PointReference(np.array([0.1, 0.0, 0.9]))
    zmp = np.array([0.05, 0.0, 0.0])
    feet = {Side.LEFT: PoseReference(np.array([0.2, 0.1, 0.05]))}
    made = References.planned(0.5, frozenset({Side.RIGHT}), com, zmp, feet)
    full = References(t=0.5, contacts=frozenset({Side.RIGHT}), com=com, zmp=zmp, feet=feet)
    names = [f.name for f in fields(References)]
    for n in names:
        assert getattr(made, n) is getattr(full, n) or getattr(made, n) == getattr(full, n), n
    assert made.targets is not References.planned(0.5, frozenset(), None, None, {}).targets  # fresh dicts
    new_com = PointReference(np.array([0.0, 0.1, 0.8]))
    fixed = full.corrected(new_com, {"hand": 1}, {Side.RIGHT: np.ones(6)}, {Side.RIGHT: "pose"})
    expect = replace(full, com=new_com, targets={"hand": 1}, wrench_targets=fixed.wrench_targets,
                     contact_poses={Side.RIGHT: "pose"})
    for n in names:
        assert getattr(fixed, n) is getattr(expect, n) or getattr(fixed, n) == getattr(expect, n), n
    p = PointReference.unchecked(com.position, com.velocity, com.acceleration)
    assert p == com
