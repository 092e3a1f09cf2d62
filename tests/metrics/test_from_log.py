"""compute_run_metrics: known answers on synthetic logs, and the F/T ZMP on a real short run."""

import json
import math

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.metrics import (PAPER_MASS_KG, STANDARD_GRAVITY, ankle_joints, compute_run_metrics, contact_zmp,
                              measured_zmp)
from wbcbench.recorder import read_log
from wbcbench.robots import Side

DT = 1e-3


def _strict_json(d: dict) -> dict:
    """Round trip through JSON refusing NaN / inf."""
    def no_constants(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(json.dumps(d, allow_nan=False), parse_constant=no_constants)


def synthetic_log(robot, n: int = 1000) -> dict[str, np.ndarray]:
    """A log with torques, velocities, a contact schedule, timing, base x-y and a CoM reference, no F/T."""
    log = {"t": np.arange(1, n + 1) * DT}
    for j in robot.joint_names:
        log[f"tau.{j}"] = np.zeros(n)
        log[f"v.{j}"] = np.zeros(n)
    # constant power: +6 W in one knee, -2 W in the other (|.| 2 W, no positive part)
    log["tau.leg_left_4_joint"][:] = 2.0
    log["v.leg_left_4_joint"][:] = 3.0
    log["tau.leg_right_4_joint"][:] = -1.0
    log["v.leg_right_4_joint"][:] = 2.0
    # ankles carry no torque at all; other joints do
    log["tau.torso_1_joint"][:] = np.linspace(1.0, 5.0, n)
    # schedule: double support, left support, double, right support
    left = np.ones(n)
    right = np.ones(n)
    right[200:500] = 0.0
    left[600:900] = 0.0
    log["in_contact_ref_left"], log["in_contact_ref_right"] = left, right
    log["controller_time_us"] = np.full(n, 300.0)
    log["controller_time_us"][10] = 1200.0
    log["q.x"] = np.linspace(0.0, 1.0, n)  # 1 m forward
    log["q.y"] = np.zeros(n)
    for a, off in zip("xyz", (0.01, -0.02, 0.0), strict=True):
        log[f"com.{a}"] = np.full(n, 0.5)
        ref = np.full(n, 0.5 - off)
        ref[:100] = np.nan  # the scenario gives no reference there
        log[f"com_ref.{a}"] = ref
    return log


def test_ankle_joints_are_the_two_joints_above_each_sole(talos):
    assert ankle_joints(talos) == {Side.LEFT: ("leg_left_5_joint", "leg_left_6_joint"),
                                   Side.RIGHT: ("leg_right_5_joint", "leg_right_6_joint")}


def test_synthetic_log_known_answers(talos):
    n = 1000
    m = _strict_json(compute_run_metrics(synthetic_log(talos, n), talos, dt=DT))
    T = n * DT
    assert m["n_ticks"] == n and m["duration_s"] == pytest.approx(T)
    assert m["E_m"] == pytest.approx((6.0 + 2.0) * T, rel=1e-12)
    assert m["E_m_plus"] == pytest.approx(6.0 * T, rel=1e-12)
    assert m["distance_m"] == pytest.approx(1.0)
    assert m["C_et"] == pytest.approx(m["E_m"] / (talos.mass * STANDARD_GRAVITY * 1.0))
    assert m["C_mt_paper_mass"] == pytest.approx(m["E_m_plus"] / 981.0)
    assert PAPER_MASS_KG * STANDARD_GRAVITY == pytest.approx(981.0)
    # zero ankle torque: every stage is perfectly passive
    assert m["pgm"] == {"double_support": 1.0, "single_support": 1.0, "flying_foot": 1.0}
    ct = m["compute_time_us"]
    assert ct["max"] == 1200.0 and ct["median"] == 300.0 and ct["mean"] == pytest.approx(300.9)
    # CoM error only on the ticks with a reference: constant offsets per axis
    for axis, off in zip("xyz", (0.01, -0.02, 0.0), strict=True):
        e = m["com_error_m"][axis]
        assert e["mean"] == pytest.approx(abs(off)) and e["peak"] == pytest.approx(abs(off))
        assert e["std"] == pytest.approx(0.0, abs=1e-15)
    # inputs not logged: metrics absent, not invented
    for key in ("zmp_error_m", "zmp_ft_vs_contact_m", "feet_error_m"):
        assert key not in m


def test_undefined_metrics_are_null_not_nan(talos):
    log = synthetic_log(talos)
    log["in_contact_ref_left"][:] = 1.0
    log["in_contact_ref_right"][:] = 1.0  # double support only: no single-support stage
    log["q.x"][:] = 0.0  # no travel: no cost of transport
    m = _strict_json(compute_run_metrics(log, talos, dt=DT))
    assert m["pgm"]["single_support"] is None and m["pgm"]["flying_foot"] is None
    assert m["pgm"]["double_support"] == 1.0
    assert m["C_et"] is None and m["C_mt_paper_mass"] is None
    assert any("C_et" in note for note in m["notes"])


def test_nan_rows_are_skipped(talos):
    log = synthetic_log(talos, 1000)
    for j in talos.joint_names:
        log[f"tau.{j}"][-10:] = np.nan  # e.g. the ticks after a crash
    m = _strict_json(compute_run_metrics(log, talos, dt=DT))
    assert m["E_m"] == pytest.approx(8.0 * 990 * DT)


def test_bad_dt_is_refused(talos):
    with pytest.raises(ValueError, match="dt"):
        compute_run_metrics(synthetic_log(talos), talos, dt=0.0)


# ------------------------------------------------------------------------------------------ real run
@pytest.fixture(scope="module")
def stand_log(tmp_path_factory):
    from wbcbench.runner import run

    out = tmp_path_factory.mktemp("stand")
    run("stand", "joint-pd", duration=0.5, out=out)
    return read_log(out / "log.parquet")


def test_real_run_metrics_are_finite(stand_log, talos):
    m = _strict_json(compute_run_metrics(stand_log, talos, dt=DT))
    for key in ("E_m", "E_m_plus", "distance_m"):
        assert math.isfinite(m[key])
    assert 0.0 < m["pgm"]["double_support"] <= 1.0
    assert m["compute_time_us"]["mean"] > 0
    assert m["C_et"] is None  # standing: no travel
    assert "zmp_ft_vs_contact_m" in m


def test_ft_zmp_between_the_feet_and_equal_to_contact_zmp(stand_log, talos):
    zmp = measured_zmp(stand_log, talos)
    truth = contact_zmp(stand_log, talos)
    assert np.isfinite(zmp).all() and np.isfinite(truth).all()
    data = talos.model.createData()
    q = np.array([stand_log[f"q.{c}"][-1] for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
                 + [stand_log[f"q.{j}"][-1] for j in talos.joint_names])
    pin.framesForwardKinematics(talos.model, data, q)
    left, right = (data.oMf[talos.sole_frame_id(s)].translation for s in Side)
    half = talos.profile.sole.length / 2
    assert np.all(zmp[:, 1] < left[1]) and np.all(zmp[:, 1] > right[1])
    assert np.all(np.abs(zmp[:, 0] - (left[0] + right[0]) / 2) < half)
    # The F/T estimate neglects the foot's own acceleration: exact once the feet settle (the first ticks
    # are the touch-down of the robot placed on the floor).
    settled = stand_log["t"] > 0.05
    assert np.abs(zmp - truth)[settled, :2].max() < 0.005
    assert np.abs(zmp - truth)[:, :2].mean() < 0.001


def test_reference_channels_give_tracking_errors(stand_log, talos):
    """zmp_ref = the contact ZMP and foot_ref = FK sole + 1 cm: errors known from other quantities."""
    log = dict(stand_log)
    truth = contact_zmp(log, talos)
    for j, a in enumerate("xyz"):
        log[f"zmp_ref.{a}"] = truth[:, j]
    base = compute_run_metrics(log, talos, dt=DT)
    assert base["zmp_error_m"]["y"]["peak"] == pytest.approx(base["zmp_ft_vs_contact_m"]["y"]["peak"])
    data = talos.model.createData()
    q = np.array([log[f"q.{c}"][0] for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
                 + [log[f"q.{j}"][0] for j in talos.joint_names])
    pin.framesForwardKinematics(talos.model, data, q)
    n = log["t"].shape[0]
    ref = data.oMf[talos.sole_frame_id(Side.LEFT)].translation
    for j, a in enumerate("xyz"):
        col = np.full(n, np.nan)
        col[:1] = ref[j] + (0.01 if a == "x" else 0.0)  # defined on the first tick only, like a swing phase
        log[f"foot_ref_left.{a}"] = col
    feet = compute_run_metrics(log, talos, dt=DT)["feet_error_m"]
    assert list(feet) == ["left"]
    assert feet["left"]["x"]["mean"] == pytest.approx(0.01, abs=1e-12)
    assert feet["left"]["z"]["peak"] == pytest.approx(0.0, abs=1e-12)


def test_foot_kinematics_compiled_equals_pinocchio(talos, monkeypatch):
    """The feet's sensor and sole placements of every logged tick, computed in one compiled call, are pinocchio's
    (the per-tick loop kept for models the compiled kinematics lacks) to rounding; a NaN row and an unnormalised
    quaternion are handled alike."""
    from wbcbench.metrics import from_log

    m = talos.model
    rng = np.random.default_rng(1)
    qs = np.array([pin.randomConfiguration(m, -np.ones(m.nq), np.ones(m.nq)) for _ in range(40)])
    qs[:, 3:7] *= rng.uniform(0.5, 2.0, size=(40, 1))  # not unit: the kinematics normalises
    qs[7, 9] = np.nan
    names = [f"q.{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")] + [f"q.{j}" for j in talos.joint_names]
    log = {name: qs[:, i] for i, name in enumerate(names)}
    fast = from_log.foot_kinematics(log, talos)
    monkeypatch.setattr(from_log.ForwardKinematics, "__init__",
                        lambda self, model: setattr(self, "supported", False))
    slow = from_log.foot_kinematics(log, talos)
    assert not fast.valid[7] and fast.valid.sum() == 39
    np.testing.assert_array_equal(fast.valid, slow.valid)
    for s in Side:
        for a, b in ((fast.R_world_sensor[s], slow.R_world_sensor[s]), (fast.p_world_sensor[s], slow.p_world_sensor[s]),
                     (fast.p_world_sole[s], slow.p_world_sole[s])):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
            assert np.isnan(a[7]).all()
