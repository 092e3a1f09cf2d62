"""Event-based lift-off: a leaving foot still loaded at its planned lift-off stays in contact (bounded), then its
swing catches up with the plan's clock."""

import numpy as np
import pytest

from wbcbench.controllers.liftoff import LiftOffWait, LiftOffWaitConfig
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.side import Side
from wbcbench.types import Measurement, PoseReference, References

L, R = Side.LEFT, Side.RIGHT
T0 = 1.0      # the left foot's planned lift-off
DT = 0.001


def _meas(t, load_left, load_right=500.0):
    """A measurement whose ankle sensors read these normal loads [N] (sensor z force = -load)."""
    return Measurement(t=t, q=np.zeros(7), v=np.zeros(6), imu_quat=np.array([0, 0, 0, 1.0]), gyro=np.zeros(3),
                       accelerometer=np.zeros(3), ft_force={L: np.array([0, 0, -load_left]),
                                                            R: np.array([0, 0, -load_right])})


def _plan(t):
    """Double support until T0, then the left foot swings up at 0.1 m/s^2 (z = 0.05 (t - T0)^2)."""
    if t < T0:
        return References(t=t, contacts=frozenset(Side), lift_off={L: T0, R: 3.0})
    s = t - T0
    foot = PoseReference([0.1 * s, 0.1, 0.05 * s * s], np.eye(3), [0.1, 0, 0.1 * s, 0, 0, 0], [0, 0, 0.1, 0, 0, 0])
    return References(t=t, contacts=frozenset({R}), feet={L: foot}, lift_off={R: 3.0})


def _run(wait, loads, t_end):
    """Apply `wait` tick by tick from T0 - 0.01 to t_end with the left foot's load loads(t); the last output and
    the outputs by time."""
    outs = {}
    for k in range(int(round((T0 - 0.01) / DT)), int(round(t_end / DT)) + 1):
        t = round(k * DT, 6)
        outs[t] = wait.correct(_meas(t, loads(t)), _plan(t))
    return outs[t], outs


def test_a_loaded_foot_stays_in_contact_until_unloaded():
    wait = LiftOffWait(LiftOffWaitConfig(max_load=0.2, max_wait=0.1, catch_up=0.5))
    loads = lambda t: 400.0 if t < T0 + 0.0395 else 50.0     # unloaded 40 ms after the planned lift-off
    out, outs = _run(wait, loads, T0 + 0.06)
    held = outs[T0 + 0.02]
    assert held.contacts == frozenset(Side) and L not in held.feet
    assert held.lift_off[L] == pytest.approx(T0)              # a controller unloading its leaving contacts keeps it so
    released = min(t for t, o in outs.items() if o.contacts == {R})
    assert released == pytest.approx(T0 + 0.04)
    assert wait.n_waits == 1 and wait.total_wait == pytest.approx(0.04)
    # the swing starts from the plan's lift-off: 20 ms after the release it is where the plan was 20 ms after T0, and
    # ahead of that since the clock catches up
    foot = out.feet[L]
    assert 0.1 * 0.02 <= foot.position[0] < 0.1 * 0.06
    assert foot.velocity[0] > 0.1                              # the warp speeds the swing up


def test_the_swing_is_back_on_the_plan_after_catch_up():
    wait = LiftOffWait(LiftOffWaitConfig(max_load=0.2, max_wait=0.1, catch_up=0.5))
    out, _ = _run(wait, lambda t: 400.0, T0 + 0.1 + 0.5 + 0.002)
    plan = _plan(T0 + 0.602)
    assert wait.total_wait == pytest.approx(0.1)              # never unloaded: the wait ends at max_wait
    np.testing.assert_allclose(out.feet[L].position, plan.feet[L].position, atol=1e-12)
    # mid catch-up the warped clock is behind the plan's and its rate above 1
    wait = LiftOffWait(LiftOffWaitConfig(max_load=0.2, max_wait=0.1, catch_up=0.5))
    out, _ = _run(wait, lambda t: 400.0, T0 + 0.35)
    z, vz = out.feet[L].position[2], out.feet[L].velocity[2]
    tau = T0 + 0.35 - 0.1 * 0.5                                # the quintic blend at u = 0.5 is 0.5
    assert z == pytest.approx(0.05 * (tau - T0) ** 2, rel=1e-3)
    assert vz == pytest.approx(0.1 * (tau - T0) * (1 + 0.1 * 1.875 / 0.5), rel=1e-3)


def test_an_unloaded_foot_leaves_on_time():
    wait = LiftOffWait(LiftOffWaitConfig())
    refs = _plan(T0)
    for t in (T0 - 0.002, T0 - 0.001):
        wait.correct(_meas(t, 300.0), _plan(t))
    assert wait.correct(_meas(T0, 100.0), refs) is refs         # 100 N of 600 N: below 20 %
    assert wait.n_waits == 0


def test_taskset_key_and_its_errors(talos, tmp_path):
    assert load_taskset(taskset_path(talos, "tsid-position"), talos).lift_off_wait is None
    text = taskset_path(talos, "tsid-position").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text + "lift_off_wait: {max_load: 0.25, max_wait: 0.15, catch_up: 0.4}\n")
    assert load_taskset(bad, talos).lift_off_wait == LiftOffWaitConfig(max_load=0.25, max_wait=0.15, catch_up=0.4)
    for entry, needle in (("{max_load: 1.5}", "max_load"), ("{max_wait: -0.1}", "max_wait"),
                          ("{max_wiat: 0.1}", "max_wiat")):
        bad.write_text(text + f"lift_off_wait: {entry}\n")
        with pytest.raises(ConfigError, match=needle) as err:
            load_taskset(bad, talos)
        assert "bad.yaml" in str(err.value) and "\n" not in str(err.value)


def test_tsid_position_waits_for_the_leaving_foot_on_the_stairs(talos, tmp_path):
    """TALOS' TSID position stairs set: at the planned lift-offs the real leaving foot still carries a third to a
    half of the load, so the model keeps that contact (unloaded) for up to 50 ms; the robot climbs."""
    from wbcbench.runner import run

    res = run("stairs-quick", "tsid-position", talos, out=tmp_path)
    s, log = res.summary, res.log
    assert not s["fell"], s["fall_reason"]
    assert s["controller_status"]["lift_off_waits"] >= 2
    planned, model = log["in_contact_ref_right"] > 0.5, log["contact_active.right"] > 0.5
    load = {side: np.maximum(-log[f"ft_{side}.fz"], 0.0) for side in ("left", "right")}
    share = load["right"] / (load["left"] + load["right"])
    k = np.flatnonzero(planned[:-1] & ~planned[1:])[0] + 1       # the right foot's first planned lift-off
    assert share[k] > 0.2
    held = np.flatnonzero(~model[k:])[0]                           # the model's contact goes this many ticks later
    assert 30 <= held <= 52
    assert share[k + held - 2] > 0.2 or held >= 50                 # held while loaded, at most 50 ms
    # x mean 0.0121 m; without the wait 0.0128 (the plan lead alone), with neither 0.0139
    assert s["metrics"]["zmp_error_m"]["x"]["mean"] < 0.0125
