"""The electrical energy of the motors (wbcbench.metrics.energy.electrical_energy, a realism preset's `motors:`):
hand-computed on a synthetic log, physically bounded on a short run, absent without a preset, and bad motor
parameters are one line naming the file and key (exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from wbcbench.metrics.energy import electrical_energy, motor_current

# two joints, three ticks of 10 ms
TAU = np.array([[10.0, -5.0], [20.0, 0.0], [-4.0, 2.0]])
OMEGA = np.array([[1.0, 2.0], [-1.0, 0.5], [2.0, -3.0]])
MOTORS = dict(torque_constant=[0.1, 0.05], gear_ratio=[100.0, 50.0], resistance=[0.4, 1.0])


def test_currents_and_energy_by_hand():
    """i = tau / (N k_t): joint 0 tau / 10, joint 1 tau / 2.5. dq copper loss 1.5 R i^2: joint 0 0.6 i^2 =
    [0.6, 2.4, 0.096] W, joint 1 1.5 i^2 = [6, 0, 0.96] W, so E_cu = 0.01 x 10.056 J. Net work 0.01 x (10 - 20 - 8
    - 10 + 0 - 6) = -0.34 J. With regeneration E_el = work + E_cu; without, only the positive per-joint electrical
    powers count: joint 0 at the first tick, 10 + 0.6 W, i.e. 0.106 J."""
    np.testing.assert_allclose(motor_current(TAU, [0.1, 0.05], [100.0, 50.0]),
                               [[1.0, -2.0], [2.0, 0.0], [-0.4, 0.8]])
    regen = electrical_energy(TAU, OMEGA, 0.01, **MOTORS, regeneration=True)
    assert regen.e_cu == pytest.approx(0.10056)
    assert regen.work == pytest.approx(-0.34)
    assert regen.e_el == pytest.approx(regen.work + regen.e_cu) and regen.e_el == pytest.approx(-0.23944)
    none = electrical_energy(TAU, OMEGA, 0.01, **MOTORS)
    assert none.e_el == pytest.approx(0.106) and none.e_cu == pytest.approx(regen.e_cu)
    dc = electrical_energy(TAU, OMEGA, 0.01, **MOTORS, convention="dc", regeneration=True)
    assert dc.e_cu == pytest.approx(0.01 * (0.4 + 1.6 + 0.064 + 4.0 + 0.0 + 0.64))
    # all powers positive: both choices give the mechanical work plus the copper losses
    pos = electrical_energy(np.abs(TAU), np.abs(OMEGA), 0.01, **MOTORS)
    assert pos.e_el == pytest.approx(0.01 * (10 + 10 + 20 + 0 + 8 + 6) + pos.e_cu)
    with pytest.raises(ValueError, match="resistance"):
        electrical_energy(TAU, OMEGA, 0.01, torque_constant=[0.1, 0.05], gear_ratio=[100.0, 50.0],
                          resistance=[0.4, -1.0])


def test_short_run_draws_at_least_the_positive_work(tmp_path):
    """0.2 s of standing on the realistic TALOS (torque mode): the summary has E_el and its copper losses; without
    regeneration E_el >= E_m+ (copper losses only add); a report recomputing the metrics from the run directory
    (config.json's motor model) finds the same E_el; the ideal run has no electrical metrics and the same E_m it
    always had (no preset: nothing added)."""
    from wbcbench.report.runs import run_metrics
    from wbcbench.runner import run

    res = run("stand", "tsid-torque", duration=0.2, out=tmp_path / "real", realism="talos-real")
    m = res.summary["metrics"]
    assert not res.summary["fell"]
    assert m["E_cu"] > 0 and m["E_m_plus"] > 0
    assert m["E_el"] > m["E_m_plus"]
    assert m["E_el"] <= m["E_m"] + m["E_cu"] + 1e-9   # at most every joint's |work| plus its losses
    config = json.loads((tmp_path / "real" / "config.json").read_text())
    assert config["realism"]["motors"]["joints"]["leg_left_4_joint"] == {"torque_constant": 0.065,
                                                                         "gear_ratio": 144.0, "resistance": 0.15}
    again = run_metrics(tmp_path / "real", res.summary, config)
    assert again["E_el"] == pytest.approx(m["E_el"], rel=1e-12) and again["E_cu"] == pytest.approx(m["E_cu"])
    ideal = run("stand", "tsid-torque", duration=0.2, out=tmp_path / "ideal")
    assert not any(k in ideal.summary["metrics"] for k in ("E_el", "E_cu", "C_el", "C_el_paper_mass"))


@pytest.mark.parametrize("motors, needles", [
    ('  joints: {"*": {torque_constant: 0.1, gear_ratio: 100, resistance: -0.1}}\n',
     ("motors.joints.*.resistance", ">= 0")),
    ('  joints: {"*": {torque_constant: 0.0, gear_ratio: 100, resistance: 0.1}}\n',
     ("motors.joints.*.torque_constant", "> 0")),
    ('  joints: {"leg_*": {torque_constant: 0.1, gear_ratio: 100, resistance: 0.1}}\n',
     ("motors.joints", "no torque_constant for joint torso_1_joint")),
    ('  convention: ac\n  joints: {"*": {torque_constant: 0.1, gear_ratio: 100, resistance: 0.1}}\n',
     ("motors.convention", "dq, dc")),
])
def test_bad_motor_parameters_one_line_exit_2(tmp_path, motors, needles):
    f = tmp_path / "motors.yaml"
    f.write_text("motors:\n" + motors)
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "tsid-torque", "-d", "0.01",
                          "-q", "--realism", str(f), "--out", str(tmp_path / "run")], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    err = out.stderr.strip()
    assert len(err.splitlines()) == 1 and "motors.yaml" in err, err
    for n in needles:
        assert n in err, err
    assert not (tmp_path / "run" / "log.parquet").exists()


def test_table6_shows_e_el_beside_e_m_only_when_the_runs_have_it():
    from wbcbench.report.render import _energy_table
    from wbcbench.report.runs import OK, RunOutcome
    from wbcbench.report.tables import table_results

    energy = {"E_m": 500.0, "E_m_plus": 300.0, "C_et": 0.4, "C_mt": 0.2, "C_et_paper_mass": 0.42,
              "C_mt_paper_mass": 0.25}
    plain = RunOutcome("paper", "tsid-torque", "walk-20cm", OK, metrics=dict(energy))
    real = RunOutcome("paper", "tsid-torque", "walk-20cm", OK,
                      metrics={**energy, "E_el": 612.5, "E_cu": 150.0, "C_el_paper_mass": 0.52})
    ideal = _energy_table({"tables": {"table6": table_results("table6", {("tsid-torque", "walk-20cm"): plain})}})
    assert not any("E_el" in h for h in ideal.header)
    assert all(len(r) == len(ideal.header) for r in ideal.rows)
    t = _energy_table({"tables": {"table6": table_results("table6", {("tsid-torque", "walk-20cm"): real})}})
    assert t.header[-2:] == ["E_el ours [J]", "C_el ours [J/kg/m]"]
    assert all(len(r) == len(t.header) for r in t.rows)
    [row] = [r for r in t.rows if r[-2] != "-"]   # the one run that has it; the other cells are missing
    assert "20" in row[1] and row[-2].startswith("612") and row[-1].startswith("0.5") and "E_el" in t.notes[-1]
