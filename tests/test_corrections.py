"""Plan corrections as stages (wbcbench/controllers/corrections.py): a task set's `corrections:` list runs in its
order, each stage seeing what the ones before it made; the old sections map onto the same stages; stages that need
an integrated model are left out in torque mode; and the configuration errors name file and key."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from wbcbench.controllers.corrections import (Correction, CorrectionSpec, available_corrections, correction_class,
                                              register_correction)
from wbcbench.controllers.ik import IKController
from wbcbench.controllers.inverse_dynamics import TSIDPosition, TSIDTorque
from wbcbench.controllers.plan_corrections import PlanCorrections
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError, UnknownNameError
from wbcbench.estimation.base_feedback import BaseFeedbackConfig
from wbcbench.sim.model import ActuationMode
from wbcbench.sim.simulator import Simulator
from wbcbench.types import PointReference, References

CALLS: list = []


@register_correction
class _Raise(Correction):
    """Test stage: the CoM reference raised by `dz` [m]; records (its name's dz, the raise it was handed)."""

    type = "test_raise"

    @classmethod
    def parse(cls, sec):
        return sec.float("dz")

    def apply(self, ctx):
        refs = ctx.refs
        CALLS.append((self.config, round(float(refs.com.position[2] - ctx.plan.com.position[2]), 12)))
        com = PointReference(refs.com.position + [0.0, 0.0, self.config], refs.com.velocity, refs.com.acceleration)
        return replace(refs, com=com)


def _write(tmp_path: Path, base: str, talos, corrections=None, drop=(), **extra) -> Path:
    """The shipped task set `base` of TALOS with the sections `drop` removed and `corrections` (a list) added."""
    data = yaml.safe_load(Path(taskset_path(talos, base)).read_text())
    for k in drop:
        data.pop(k, None)
    if corrections is not None:
        data["corrections"] = corrections
    data.update(extra)
    p = tmp_path / f"{base}-{len(list(tmp_path.iterdir()))}.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


_SECTIONS = ("stabilizer", "base_feedback", "touchdown_search", "plan_lead", "lift_off_wait", "swing_tilt")


def _stand_refs(ctrl, t: float) -> References:
    import pinocchio as pin

    com = pin.centerOfMass(ctrl.model, ctrl.model.createData(), ctrl.robot.q0)
    return References(t=t, com=PointReference(com), zmp=np.array([com[0], com[1], 0.0]))


@pytest.mark.parametrize("order", ["raise-first", "raise-last"])
def test_the_list_runs_in_its_order_each_stage_on_what_the_previous_made(talos, tmp_path, order):
    entries = [{"type": "test_raise", "name": "first", "dz": 0.001}, {"type": "base_feedback", "time_constant": 0.3},
               {"type": "test_raise", "name": "second", "dz": 0.002}]
    if order == "raise-last":
        entries = entries[::-1]
    spec = load_taskset(_write(tmp_path, "ik", talos, entries, drop=_SECTIONS), talos, max_level=8)
    assert [c.name for c in spec.correction_specs()] == [e.get("name", e["type"]) for e in entries]
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3, spec)
    assert ctrl.corrections.names == tuple(e.get("name", e["type"]) for e in entries)
    assert ctrl.stabilizer is None and ctrl.corrections.base_feedback is not None
    meas = Simulator(talos, mode="position").measure()
    ctrl.reset(meas, _stand_refs(ctrl, 0.0))
    CALLS.clear()
    for k in range(3):
        ctrl.step(meas, _stand_refs(ctrl, 1e-3 * (k + 1)))
    # the base feedback's drift is zero on the first ticks (the model is the robot): it passes the raise on exactly
    first, second = ((0.001, 0.0), (0.002, 0.001)) if order == "raise-first" else ((0.002, 0.0), (0.001, 0.002))
    assert CALLS == [first, second] * 3


def test_sections_and_list_give_the_same_stages_and_the_same_commands(talos, tmp_path):
    """TSID position's shipped sections (touch-down search, base feedback, stabilizer) written as the list in the
    sections' order: the same stage specs, and bit-identical commands."""
    legacy = load_taskset(taskset_path(talos, "tsid-position"), talos)
    raw = yaml.safe_load(Path(taskset_path(talos, "tsid-position")).read_text())
    stab = dict(raw["stabilizer"])
    entries = [{"type": "touchdown_search", **raw["touchdown_search"]}, {"type": "base_feedback",
               **raw["base_feedback"]}, {"type": "stabilizer", "law": stab.pop("type"), **stab}]
    listed = load_taskset(_write(tmp_path, "tsid-position", talos, entries, drop=_SECTIONS), talos)
    assert [c.type for c in legacy.correction_specs()] == ["touchdown_search", "base_feedback", "stabilizer"]
    assert listed.correction_specs() == legacy.correction_specs()
    assert listed.stabilizer is None and listed.base_feedback is None  # the list form leaves the sections empty
    sim = Simulator(talos, mode="position")
    meas = sim.measure()
    cmds = []
    for spec in (legacy, listed):
        ctrl = TSIDPosition(talos, ActuationMode.POSITION, 1e-3, spec)
        ctrl.reset(meas, _stand_refs(ctrl, 0.0))
        cmds.append([ctrl.step(meas, _stand_refs(ctrl, 1e-3 * (k + 1))).q for k in range(5)])
        assert [type(s).__name__ for s in ctrl.corrections.stages] == ["TouchdownSearch", "BaseFeedbackStage",
                                                                      "StabilizerStage"]
    np.testing.assert_array_equal(np.array(cmds[0]), np.array(cmds[1]))


def test_stages_needing_an_integrated_model_are_left_out_in_torque_mode(talos, tmp_path):
    entries = [{"type": "plan_lead", "time": 0.02}, {"type": "test_raise", "dz": 0.001},
               {"type": "swing_tilt"}, {"type": "stabilizer", "law": "dcm", "kp_adm": 0.0, "kp_dcm": 2.0,
                                                       "ki_dcm": 0.0, "kz_dcm": 0.0}]
    spec = load_taskset(_write(tmp_path, "tsid-torque", talos, entries, drop=_SECTIONS), talos)
    torque = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3, spec)
    assert torque.corrections.names == ("test_raise", "stabilizer")
    position = TSIDPosition(talos, ActuationMode.POSITION, 1e-3, spec)
    assert position.corrections.names == ("plan_lead", "test_raise", "swing_tilt", "stabilizer")
    assert "stabilizer" in position.log_channels() and position.stabilizer.type == "dcm"
    assert set(position.status()) >= {"swing_tilt_max_rad", "qp_relaxed_ticks"}


def test_a_given_stabilizer_replaces_the_listed_one_in_place(talos, tmp_path):
    from wbcbench.stabilizers.base import make_stabilizer, parse_stabilizer
    from wbcbench.config import Section

    entries = [{"type": "stabilizer", "law": "dcm", "kp_adm": 1.0, "kp_dcm": 2.0, "ki_dcm": 0.0, "kz_dcm": 0.0},
               {"type": "test_raise", "dz": 0.001}]
    spec = load_taskset(_write(tmp_path, "tsid-position", talos, entries, drop=_SECTIONS), talos)
    mine = make_stabilizer(parse_stabilizer(Section({"type": "dcm", "kp_adm": 3.0, "kp_dcm": 1.0, "ki_dcm": 0.0,
                                                     "kz_dcm": 0.0}, None)), talos, 1e-3)
    pc = PlanCorrections(talos, 1e-3, spec, mine)
    assert pc.names == ("stabilizer", "test_raise") and pc.stabilizer is mine
    assert PlanCorrections(talos, 1e-3, spec.without_stabilizer()).names == ("test_raise",)
    assert PlanCorrections(talos, 1e-3, spec.without_stabilizer(), mine).names == ("test_raise", "stabilizer")


def test_a_logging_stage_gets_its_channel(talos, tmp_path):
    @register_correction
    class _Logged(_Raise):
        type = "test_logged"
        LOG_LABELS = ("dz",)

        def reset(self, ctx=None):
            self.log = np.array([self.config])

    spec = load_taskset(_write(tmp_path, "ik", talos, [{"type": "test_logged", "name": "mine", "dz": 0.003},
                                                        {"type": "base_feedback"}], drop=_SECTIONS), talos,
                        max_level=8)
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3, spec)
    assert ctrl.log_channels() == {"ik_unmet_level": [], "correction_mine": ["dz"]}
    meas = Simulator(talos, mode="position").measure()
    ctrl.reset(meas, _stand_refs(ctrl, 0.0))
    ctrl.step(meas, _stand_refs(ctrl, 1e-3))
    assert ctrl.log_values()[1][0] == 0.003


def test_built_in_types_are_a_lazy_table(talos):
    assert set(available_corrections()) >= {"plan_lead", "lift_off_wait", "touchdown_search", "base_feedback",
                                            "swing_tilt", "stabilizer", "test_raise"}
    assert correction_class("plan_lead").__name__ == "PlanLead"
    with pytest.raises(UnknownNameError, match="did you mean 'plan_lead'"):
        correction_class("plan_led")


@pytest.mark.parametrize("entries, extra, key, match", [
    ([{"type": "plan_lead", "time": 0.02}], {"base_feedback": {"time_constant": 0.3}}, "corrections",
     "given twice"),
    ([{"type": "plan_leed", "time": 0.02}], {}, "corrections[0].type", "known: base_feedback, hip_compensation, lift_off_wait"),
    ([{"type": "plan_lead", "time": 0.02, "tme": 1.0}], {}, "corrections[0].tme", "unknown key"),
    ([{"type": "plan_lead"}], {}, "corrections[0].time", None),
    ([{"type": "plan_lead", "time": -1.0}], {}, "corrections[0].time", None),
    ([{"type": "lift_off_wait", "max_load": 1.5}], {}, "corrections[0].max_load", "in \\(0, 1\\)"),
    ([{"type": "stabilizer", "law": "dcn"}], {}, "corrections[0].law", "unknown stabilizer type 'dcn'"),
    ([{"type": "stabilizer", "kp_adm": 1.0, "kp_dcm": 1.0, "ki_dcm": 0.0, "kz_dcm": 0.0},
      {"type": "stabilizer", "law": "force"}], {}, "corrections[1].type", "at most one stabilizer"),
    ([{"type": "test_raise", "dz": 0.1}, {"type": "test_raise", "dz": 0.2}], {}, "corrections[1].name",
     "names entry 0 too"),
    (["plan_lead"], {}, "corrections[0]", "must be a mapping"),
    ([{"time": 0.02}], {}, "corrections[0].type", None),
])
def test_config_errors_name_file_and_key(talos, tmp_path, entries, extra, key, match):
    path = _write(tmp_path, "tsid-position", talos, entries, drop=_SECTIONS, **extra)
    with pytest.raises(ConfigError, match=match) as err:
        load_taskset(path, talos)
    assert err.value.file == str(path) and err.value.key == key, str(err.value)
    assert "\n" not in str(err.value)


def test_a_spec_cannot_hold_both_forms(talos, tmp_path):
    spec = load_taskset(_write(tmp_path, "ik", talos, [{"type": "base_feedback"}], drop=_SECTIONS), talos,
                        max_level=8)
    assert spec.correction_specs() == (CorrectionSpec("base_feedback", BaseFeedbackConfig()),)
    with pytest.raises(ConfigError, match="not both"):
        replace(spec, base_feedback=BaseFeedbackConfig())
