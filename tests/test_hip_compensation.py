"""Hip flexibility compensation (`hip_compensation`): the swing foot's reference turned against the hips' estimated
deflection; the estimates (fixed, filtered joint torque, model) against the simulator's hidden hip springs."""

import math
import subprocess
import sys

import numpy as np
import pytest

from wbcbench.config import Section
from wbcbench.controllers.corrections import CorrectionContext
from wbcbench.controllers.hip_compensation import HipCompensation
from wbcbench.controllers.taskset import load_taskset
from wbcbench.errors import ConfigError
from wbcbench.planning.geometry import so3_log
from wbcbench.side import Side
from wbcbench.types import Measurement, PoseReference, References

L, R = Side.LEFT, Side.RIGHT
DT = 0.001


def _stage(talos, **settings):
    return HipCompensation.build(HipCompensation.parse(Section(settings, "ts.yaml", "corrections[0]")), talos, DT)


def _meas(q, tau=None):
    return Measurement(t=0.0, q=q, v=np.zeros(len(q) - 1), imu_quat=np.array([0, 0, 0, 1.0]), gyro=np.zeros(3),
                       accelerometer=np.zeros(3), ft_force={s: np.zeros(3) for s in Side},
                       ft_torque={s: np.zeros(3) for s in Side}, tau=tau)


FOOT = PoseReference([0.1, 0.1, 0.03], np.eye(3))


def _apply(stage, refs, q, tau=None):
    return stage.apply(CorrectionContext.of(refs, _meas(q, tau), q))


def _hip_only_ik(tmp_path, compensation: str):
    """A realism preset with the hip flexibility alone (talos-actuation without drives and torque loop) and an IK
    task set with base feedback, the given hip compensation and the DCM stabilizer: (preset, task set) paths."""
    preset = tmp_path / "hip-only.yaml"
    preset.write_text("extends: talos-actuation\nactuators: null\ntorque_loop: null\n")
    ts = tmp_path / "ik-hip.yaml"
    ts.write_text(f"""solver: daqp
contacts: {{kp: 1000.0}}
swing_foot: {{weight: 1.0, kp: 1000.0}}
tasks:
  - {{name: com_z, type: com, mask: [0, 0, 1], weight: 1.0, kp: 100.0, level: 1}}
  - {{name: com_xy, type: com, mask: [1, 1, 0], weight: 1.0, kp: 100.0, level: 2}}
  - {{name: waist, type: frame, frame: base, mask: [0, 0, 0, 1, 1, 1], weight: 1.0, kp: 300.0, level: 3}}
  - {{name: posture, type: posture, weight: 1.0, kp: 100.0, level: 4}}
corrections:
  - {{type: base_feedback, time_constant: 0.3, liftoff_blend: 0.3}}
  - {compensation}
  - {{type: stabilizer, law: dcm, kp_adm: 15.0, kp_dcm: 8.0, ki_dcm: 1.0, kz_dcm: 1.0}}
""")
    return preset, ts


def test_fixed_mode_turns_the_swing_foot_about_the_stance_hip_in_single_support_only(talos):
    stage = _stage(talos, mode="fixed")
    q = talos.q0
    single = References(t=0.0, contacts=frozenset({R}), feet={L: FOOT})
    out = _apply(stage, single, q).feet[L]
    # the turn: 0.021 rad about the stance (right) hip roll axis, through that joint, against the swing side's sag
    data = talos.model.createData()
    import pinocchio as pin

    pin.forwardKinematics(talos.model, data, q)
    M = data.oMi[talos.model.getJointId("leg_right_2_joint")]
    w = so3_log(out.rotation)
    assert np.linalg.norm(w) == pytest.approx(20.0 / 973.0, rel=1e-9)
    axis = w / np.linalg.norm(w)
    assert abs(abs(axis @ M.rotation[:, 0]) - 1.0) < 1e-9        # TALOS' hip roll axis: the joint's x
    c = M.translation
    np.testing.assert_allclose(out.position - c, out.rotation @ (FOOT.position - c), atol=1e-12)
    assert out.position[2] > FOOT.position[2]                    # the swing foot is lifted against its sag
    # double support: nothing changes (the same references)
    double = References(t=0.0, contacts=frozenset(Side), feet={})
    assert _apply(stage, double, q) is double
    # the other side swinging: the mirrored turn, about the left hip
    out_r = _apply(stage, References(t=0.0, contacts=frozenset({L}), feet={R: FOOT}), q).feet[R]
    assert out_r.position[2] > FOOT.position[2]
    assert np.linalg.norm(so3_log(out_r.rotation)) == pytest.approx(20.0 / 973.0, rel=1e-9)


def test_torque_mode_lags_as_configured(talos):
    cutoff, k = 5.0, 973.0
    stage = _stage(talos, mode="torque", cutoff=cutoff, stiffness=k)
    ids = [talos.model.joints[talos.model.getJointId(n)].idx_v - 6 for n in ("leg_left_2_joint", "leg_right_2_joint")]
    refs = References(t=0.0, contacts=frozenset(Side), feet={})
    tau = np.zeros(talos.na)
    _apply(stage, refs, talos.q0, tau)
    tau = tau.copy()
    tau[ids[0]], tau[ids[1]] = 50.0, -20.0          # a step in the hips' joint torques
    tc = 1.0 / (2.0 * math.pi * cutoff)
    n = int(round(tc / DT))
    for _ in range(n):
        _apply(stage, refs, talos.q0, tau)
    # one time constant after the step: 1 - 1/e of the static deflection -tau / k
    np.testing.assert_allclose(stage.log, np.array([-50.0, 20.0]) / k * (1.0 - math.exp(-1.0)), rtol=0.01)
    for _ in range(6 * n):
        _apply(stage, refs, talos.q0, tau)
    np.testing.assert_allclose(stage.log, np.array([-50.0, 20.0]) / k, rtol=0.01)


def test_model_estimate_matches_the_hidden_hip_deflection(tmp_path):
    """IK on walk-20cm-quick with the hip flexibility alone (973 N m/rad), the model estimate fed forward, up to
    the middle of the first single support. In double support the static balance is what the hidden springs
    deflect (the measured difference 0.2 mrad); in single support the springs swing about it (their lightly
    damped mode with the body, about 1 Hz) and the feet land early, so the bound is on the means over the first
    0.5 s of single support (measured differences 0.025 and 0.021 rad)."""
    from wbcbench.runner import run

    preset, ts = _hip_only_ik(tmp_path, "{type: hip_compensation, mode: model}")
    res = run("walk-20cm-quick", "ik", taskset=ts, realism=str(preset), duration=3.0, out=tmp_path / "run")
    log = res.log
    t = log["t"]
    both = (log["in_contact_ref_left"] == 1) & (log["in_contact_ref_right"] == 1)
    single = (log["in_contact_ref_left"] == 1) & (log["in_contact_ref_right"] == 0)
    t_lift = t[single][0]
    assert not res.summary["fell"]
    for s in ("left", "right"):
        est = log[f"correction_hip_compensation.delta_{s}"]
        hidden = log[f"hidden_deflection.leg_{s}_2_joint:hip_flex"]
        settled = both & (t > 0.5) & (t < t_lift)
        assert np.abs(est - hidden)[settled].max() < 1e-3
        first = single & (t < t_lift + 0.5)
        assert abs(est[first].mean() - hidden[first].mean()) < 0.035
    # the stance (left) hip's estimate has the sign and size of a hip holding the upper body
    assert -0.08 < log["correction_hip_compensation.delta_left"][single].mean() < -0.03


def test_hip_joint_target_shifts_the_hip_command_and_configuration_in_single_support(talos):
    """`target: hip_joint`: the references are untouched; in single support a position scheme's command of each
    fed-forward hip is lowered by its delta and a torque-mode configuration raised by it (a copy: the measured q
    is not changed); in double support nothing changes."""
    from wbcbench.types import Command

    stage = _stage(talos, mode="torque", target="hip_joint", hips=["stance"])
    ids = {s: talos.model.joints[talos.model.getJointId(f"leg_{s.value}_2_joint")].idx_v - 6 for s in Side}
    tau = np.zeros(talos.na)
    tau[ids[L]], tau[ids[R]] = 40.0, -30.0
    q = talos.q0.copy()
    single = References(t=0.0, contacts=frozenset({R}), feet={L: FOOT})
    ctx = CorrectionContext.of(single, _meas(q, tau), q)
    assert stage.apply(ctx) is single
    delta_r = -(-30.0) / 973.0  # the stance (right) hip's estimate, -tau / k (the filter starts at its first value)
    cmd = Command(q=talos.q0[7:].copy(), v=np.zeros(talos.na))
    out = stage.command(ctx, cmd)
    expected = cmd.q.copy()
    expected[ids[R]] -= delta_r
    np.testing.assert_allclose(out.q, expected, rtol=0, atol=1e-15)
    assert out.v is cmd.v
    qc = stage.configuration(ctx, q)
    assert qc is not q and np.array_equal(q, talos.q0)
    assert qc[7 + ids[R]] == pytest.approx(q[7 + ids[R]] + delta_r, abs=1e-15)
    assert np.array_equal(np.delete(qc, 7 + ids[R]), np.delete(q, 7 + ids[R]))
    double = References(t=0.0, contacts=frozenset(Side), feet={})
    ctx = CorrectionContext.of(double, _meas(q, tau), q)
    stage.apply(ctx)
    assert stage.command(ctx, cmd) is cmd and stage.configuration(ctx, q) is q


def test_hip_joint_target_keeps_the_pelvis_upright_and_walks(tmp_path):
    """IK on walk-20cm-quick with the hip flexibility alone: uncompensated the pelvis rolls about 0.14 rad on the
    stance hip and the robot falls in its second step (4.2 s); with the model estimate fed into the hip joints'
    command it stays within 0.08 rad (measured 0.06) and makes its touch-downs. Up to 4.5 s (past the
    uncompensated fall)."""
    from wbcbench.runner import run

    preset, ts = _hip_only_ik(tmp_path, "{type: hip_compensation, mode: model, target: hip_joint}")
    res = run("walk-20cm-quick", "ik", taskset=ts, realism=str(preset), duration=4.5, out=tmp_path / "run")
    log = res.log
    assert not res.summary["fell"]
    qx, qy, qz, qw = (np.asarray(log[f"q.{c}"]) for c in ("qx", "qy", "qz", "qw"))
    roll = np.arctan2(2 * (qw * qx + qy * qz), 1 - 2 * (qx * qx + qy * qy))
    assert np.abs(roll).max() < 0.08
    assert res.summary["metrics"]["landing"]["touchdowns"] >= 2
    assert 0.03 < res.summary["controller_status"]["hip_compensation_max_rad"] < 0.1


@pytest.mark.parametrize("entry, key, needle", [
    ("{type: hip_compensation, mode: guess}", "corrections[0].mode", "fixed"),
    ("{type: hip_compensation, mode: torque, cutoff: -1}", "corrections[0].cutoff", ""),
    ("{type: hip_compensation, mode: model, hips: [both]}", "corrections[0].hips", "stance, swing"),
    ("{type: hip_compensation, mode: model, joints: [leg_left_2_joint]}", "corrections[0].joints", "left and"),
    ("{type: hip_compensation, mode: model, joints: [leg_left_2_joint, hip_nope]}", "corrections[0].joints",
     "hip_nope"),
    ("{type: hip_compensation, mode: fixed, stifness: 900}", "corrections[0].stifness", ""),
    ("{type: hip_compensation, mode: model, target: pelvis}", "corrections[0].target", "hip_joint"),
])
def test_bad_settings_are_one_line_naming_file_and_key(talos, tmp_path, entry, key, needle):
    f = tmp_path / "bad.yaml"
    f.write_text("contacts: {kp: 1000.0}\nswing_foot: {weight: 1.0, kp: 1000.0}\ntasks: []\n"
                 f"corrections:\n  - {entry}\n")
    with pytest.raises(ConfigError) as e:
        spec = load_taskset(f, talos)
        from wbcbench.controllers.plan_corrections import PlanCorrections

        PlanCorrections(talos, DT, spec)
    msg = str(e.value)
    assert str(f) in msg and key in msg and needle in msg and "\n" not in msg


def test_cli_bad_setting_exits_2_with_one_line(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("contacts: {kp: 1000.0}\nswing_foot: {weight: 1.0, kp: 1000.0}\ntasks: []\n"
                 "corrections:\n  - {type: hip_compensation, mode: guess}\n")
    p = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "ik", "-d", "0.01", "-t", str(f),
                        "--out", str(tmp_path / "run")], capture_output=True, text=True)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and str(f) in lines[0] and "corrections[0].mode" in lines[0], p.stderr
