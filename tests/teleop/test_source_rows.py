"""The reference source's common tick (a recording's stacked rows screened by the command filter in one compiled
call, wbcbench/teleop/source.py `_row_targets`) against the general path it short-cuts: the same references, bit
for bit, and the same bookkeeping, through the cases that leave it (filter interventions, invalid frames, the
recording's end, signal-loss policies, times off the tick grid)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.scenarios.teleop_kind import TeleopScenario
from wbcbench.teleop import open_recording

DT = 1e-3


def _pair(robot, mocap, **params):
    """The same scenario twice, set up; the second one without the common tick (every tick the general path)."""
    out = []
    for rows in (True, False):
        sc = TeleopScenario.from_source(robot, mocap, **params)
        q = robot.q0
        sc.setup(q, pin.centerOfMass(robot.model, robot.model.createData(), q))
        if not rows:
            sc.reference_source._rows = None
        out.append(sc)
    return out


def _compare(fast, slow, times) -> int:
    """References of both at each time, identical; returns how many ticks the common tick served."""
    src = fast.reference_source
    served = [0]
    rows = src._row_targets

    def spy(t):
        out = rows(t)
        served[0] += out is not None
        return out

    src._row_targets = spy
    for t in times:
        a, b = fast.references(t).targets, slow.references(t).targets
        assert list(a) == list(b), t
        for name in a:
            for f in ("position", "rotation", "velocity", "acceleration"):
                assert np.array_equal(getattr(a[name], f), getattr(b[name], f)), (t, name, f)
        np.testing.assert_array_equal(src.command_filter.flags, slow.reference_source.command_filter.flags)
    return served[0]


def _same_state(fast, slow) -> None:
    a, b = fast.reference_source, slow.reference_source
    assert a.record_t == b.record_t and a.record_valid == b.record_valid
    for e in a.record_pose:
        np.testing.assert_array_equal(a.record_pose[e], b.record_pose[e])
    assert a.clamped_ticks == b.clamped_ticks and a.loss_events == b.loss_events
    assert a.loss_durations == b.loss_durations
    assert a.command_filter.summary() == b.command_filter.summary()


def test_the_common_tick_is_the_general_path(talos):
    fast, slow = _pair(talos, "reach_forward", duration=4.0)
    times = [k * DT for k in range(4001)]
    served = _compare(fast, slow, [0.0, *times])  # the runner asks for t = 0 twice (reset, first tick)
    _same_state(fast, slow)
    # every tick but the first two (no previous output for the filter's limits yet) is served by the rows
    assert served == len(times) - 1
    assert fast.reference_source.command_filter.summary()["total"] == 0


def test_interventions_invalid_frames_and_the_end_of_the_recording(talos):
    """Speed limits low enough that the filter intervenes now and then (ticks go back and forth between the two
    paths), the right hand missing for half a second (invalid frames), the recording's end (invalid ticks),
    replayed twice as fast, with the return to the reference posture and times off the tick grid."""
    rec = open_recording("reach_forward")
    seg = rec.segments.index("RightHand")
    start = float(rec.times[-1]) - 7.0
    gap = (rec.times >= start + 2.0) & (rec.times <= start + 2.6)  # replayed at t = 1.0-1.3 s
    pos = np.array(rec.positions, dtype=float)
    pos[gap, seg] = np.nan
    holed = replace(rec, positions=pos)
    for params in ({"on_loss": "hold", "safety": {"max_speed": 0.5, "max_angular_speed": 2.0}},
                   {"on_loss": "reference", "return_time": 0.5, "engage_time": 0.7,
                    "safety": {"max_acceleration": 5.0, "jump_distance": 0.01}}):
        fast, slow = _pair(talos, holed, duration=4.0, speed=2.0, start=start, **params)
        times = [k * DT for k in range(4200)]
        times[500:510] = [t + 0.25 * DT for t in times[500:510]]  # off the grid: the general path
        served = _compare(fast, slow, times)
        _same_state(fast, slow)
        assert 0 < served < len(times) - 100
        src = fast.reference_source
        counts = src.command_filter.summary()["counts"]
        assert counts["jump"] and (counts["speed"] or counts["acceleration"]) and src.loss_events == 2
        assert not all(src.record_valid) and any(src.record_valid)


@pytest.mark.parametrize("enabled", [True, False])
def test_without_the_filter_and_without_engagement(talos, enabled):
    fast, slow = _pair(talos, "waving", duration=1.5, engage_time=0.0, safety={"enabled": enabled})
    served = _compare(fast, slow, [k * DT for k in range(1500)])
    _same_state(fast, slow)
    assert served == 1500 if not enabled else served == 1499



def test_body_spheres_following_the_measured_posture(talos):
    """The measured torso leans forward (torso_2_joint +0.5 rad over 2 s, the spheres following every 5 ms) onto
    crossing_arms' crossed forearms: the references the moving chest pushes out are the same on both paths."""
    fast, slow = _pair(talos, "crossing_arms", duration=4.0)
    model = talos.model
    q0, q1 = talos.q0, talos.q0.copy()
    q1[model.joints[model.getJointId("torso_2_joint")].idx_q] += 0.5
    rows = fast.reference_source._row_targets
    served = [0]

    def spy(t):
        out = rows(t)
        served[0] += out is not None
        return out

    fast.reference_source._row_targets = spy
    for k in range(4000):
        t = k * DT
        s = min(t / 2.0, 1.0)
        q = q0 + s * (q1 - q0)
        for sc in (fast, slow):
            sc.reference_source.follow(t, q)
        a, b = fast.references(t).targets, slow.references(t).targets
        for name in a:
            for f in ("position", "rotation", "velocity", "acceleration"):
                assert np.array_equal(getattr(a[name], f), getattr(b[name], f)), (t, name, f)
    _same_state(fast, slow)
    counts = fast.reference_source.command_filter.summary()["counts"]
    assert counts["body"] and 0 < served[0] < 4000
