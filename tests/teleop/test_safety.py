"""The command filter between the operator and the controller (wbcbench/teleop/safety.py): every case it handles,
the stream watchdog's resume, and that the shipped recordings pass through untouched."""

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.scenarios.teleop_kind import TeleopScenario
from wbcbench.side import Side
from wbcbench.teleop.safety import CommandFilter, SafetyConfig

DT = 1e-3


@pytest.fixture(scope="module")
def start(talos):
    """The robot's own effector poses at its reference posture (the filter's first outputs)."""
    model = talos.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, talos.q0)
    frames = {"left_hand": talos.profile.hands[Side.LEFT], "right_hand": talos.profile.hands[Side.RIGHT],
              "head": talos.profile.head_frame}
    return {k: pin.SE3(data.oMf[model.getFrameId(f)]) for k, f in frames.items()}


def _feed(flt, poses_at, n, t0=0.0):
    """Run the filter over n ticks of `poses_at(k) -> {effector: SE3}` (zero feed-forward); the outputs."""
    out = []
    for k in range(n):
        raw = {e: (M, np.zeros(6), np.zeros(6)) for e, M in poses_at(k).items()}
        out.append(flt(t0 + k * DT, raw))
    return out


def _moved(M, dp):
    return pin.SE3(M.rotation, M.translation + np.asarray(dp, float))


def test_garbage_is_held_and_counted(talos, start):
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    bad_rotation = pin.SE3(2.0 * np.eye(3), start["left_hand"].translation)
    nan = pin.SE3(start["left_hand"].rotation, np.array([np.nan, 0.0, 0.0]))

    def poses(k):
        M = {10: nan, 11: bad_rotation}.get(k, start["left_hand"])
        return {"left_hand": M}

    out = _feed(flt, poses, 20)
    for k in (10, 11):
        M, v, a = out[k]["left_hand"]
        assert np.array_equal(M.translation, start["left_hand"].translation) and not v.any() and not a.any()
    assert flt.counts["non_finite"] == {"left_hand": 2}
    assert flt.summary()["events"][0]["t"] == pytest.approx(10 * DT)


def test_a_teleport_is_rejoined_smoothly(talos, start):
    """0.4 m in one tick (a stream resuming elsewhere): the output leaves with zero velocity, never moves faster
    than the limit, and arrives on the reference by the end of the re-join (min-jerk over 0.8 s at 0.5 m/s)."""
    cfg = SafetyConfig()
    flt = CommandFilter(talos, talos.q0, cfg, DT)
    far = _moved(start["right_hand"], [0.4, 0.0, 0.0])
    out = _feed(flt, lambda k: {"right_hand": start["right_hand"] if k < 5 else far}, 1200)
    p = np.array([o["right_hand"][0].translation for o in out])
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert flt.counts["jump"] == {"right_hand": 1}
    assert step[4] < 1e-5  # the first tick of the re-join barely moves (min-jerk starts at rest)
    assert step.max() <= cfg.max_speed * DT + 1e-12
    assert step.max() == pytest.approx(1.875 * 0.4 / 0.8 * DT, rel=0.01)  # min-jerk peak speed 1.875 d / T
    np.testing.assert_allclose(p[5 + 800], far.translation, atol=1e-9)
    # the feed-forward velocity is the blend's own
    v = np.array([o["right_hand"][1][:3] for o in out])
    np.testing.assert_allclose(v[6:800], np.diff(p, axis=0)[6:800] / DT, atol=0.01)


def test_speed_and_acceleration_are_clipped(talos, start):
    cfg = SafetyConfig(max_speed=1.0, max_acceleration=5.0)
    flt = CommandFilter(talos, talos.q0, cfg, DT)
    fast = lambda k: {"left_hand": _moved(start["left_hand"], [0.004 * k, 0.0, 0.0])}  # 4 m/s
    out = _feed(flt, fast, 50)
    p = np.array([o["left_hand"][0].translation for o in out])
    np.testing.assert_allclose(np.diff(p[:, 0]), 1.0 * DT, rtol=1e-9)  # held at 1 m/s
    assert flt.counts["speed"]["left_hand"] == 49
    M = _moved(start["left_hand"], [0.2, 0.0, 0.0])  # the stream goes on (no jump)
    res = flt(50 * DT, {"left_hand": (M, np.array([3.0, 0, 0, 0, 0, 0]), np.array([0.0, 40.0, 0, 0, 0, 0]))})
    _, v, a = res["left_hand"]
    assert np.linalg.norm(v[:3]) == pytest.approx(1.0) and np.linalg.norm(a[:3]) == pytest.approx(5.0)
    assert flt.counts["acceleration"] == {"left_hand": 1}


def test_references_inside_the_body_are_pushed_out(talos, start):
    """A hand reference at the pelvis is moved radially to r_rep + margin from the nearest static sphere; the
    paper's absolute anchor keeps it (the repulsors' study), and so does `body: false`."""
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    offset, centres, radii = flt._body["left_hand"]
    pelvis = centres[np.argmax(radii)]  # the largest static sphere: the pelvis (0.15 m)
    M = pin.SE3(start["left_hand"].rotation, pelvis - start["left_hand"].rotation @ offset + [0.02, 0.0, 0.0])
    out = flt(0.0, {"left_hand": (M, np.zeros(6), np.zeros(6))})["left_hand"][0]
    x = out.act(offset)
    gaps = np.linalg.norm(x - centres, axis=1) - (radii + 0.03)
    assert gaps.min() >= -1e-9 and gaps.min() < 1e-6  # on the surface of the sphere it was in, in no other
    assert flt.counts["body"] == {"left_hand": 1}
    kept = CommandFilter(talos, talos.q0, SafetyConfig(body=False), DT)(0.0, {"left_hand": (M, np.zeros(6),
                                                                                           np.zeros(6))})
    np.testing.assert_array_equal(kept["left_hand"][0].translation, M.translation)
    sc = TeleopScenario.from_source(talos, "arms_down", duration=1.0, anchor="absolute")
    assert sc.safety.body is False


def test_a_stalled_stream_holds_then_resumes_smoothly(talos, start):
    """The watchdog: a stream that stops is held (the source's loss policy); the operator has moved meanwhile, and
    the first fresh pose is re-joined, not jumped to."""
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    held = start["left_hand"]
    moved = _moved(held, [0.0, 0.25, 0.1])
    out = _feed(flt, lambda k: {"left_hand": held if k < 300 else moved}, 1000)
    p = np.array([o["left_hand"][0].translation for o in out])
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert flt.counts["jump"] == {"left_hand": 1} and step.max() < 0.0012  # 1.2 m/s at the most
    np.testing.assert_allclose(p[-1], moved.translation, atol=1e-9)


def test_the_shipped_recordings_pass_through_untouched_at_twice_their_speed(talos):
    """No jump, speed, acceleration or garbage intervention on any shipped recording at x2; the body projection
    moves a reference at most 1 cm (crossing_arms' right hand near the chest)."""
    from wbcbench.teleop import list_recordings

    for rec in list_recordings():
        sc = TeleopScenario.from_source(talos, rec.name, duration=rec.duration / 2, speed=2.0)
        sc.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
        raw_source = TeleopScenario.from_source(talos, rec.name, duration=rec.duration / 2, speed=2.0,
                                                safety={"enabled": False})
        raw_source.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
        worst = 0.0
        for k in range(0, int(round(sc.spec.duration / DT))):
            got, raw = sc.references(k * DT).targets, raw_source.references(k * DT).targets
            for name in ("left_hand", "right_hand", "head"):
                worst = max(worst, float(np.linalg.norm(got[name].position - raw[name].position)))
        counts = sc.reference_source.command_filter.counts
        assert not any(counts[kind] for kind in ("non_finite", "jump", "speed", "acceleration")), (rec.name, counts)
        assert worst < 0.01, (rec.name, worst)


def test_a_glitching_recording_reaches_the_robot_filtered(talos, tmp_path):
    """One frame of reach_forward with the right hand 0.5 m off (a marker swap): unfiltered, the hand reference
    moves at tens of m/s; through the filter no target step exceeds the speed limit, the interventions are in the
    log channel and the summary, and the robot stands."""
    import dataclasses

    from wbcbench.teleop import open_recording
    from wbcbench.teleop.commands import run_session

    rec = open_recording("reach_forward")
    positions = np.array(rec.positions)
    hand = rec.segments.index("RightHand")
    positions[100, hand] += [0.5, 0.0, 0.0]  # t = 2 s
    glitch = dataclasses.replace(rec, positions=positions)
    raw = TeleopScenario.from_source(talos, glitch, duration=3.0, safety={"enabled": False})
    raw.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
    p = np.array([raw.references(k * DT).targets["right_hand"].position for k in range(3000)])
    assert np.linalg.norm(np.diff(p, axis=0), axis=1).max() > 10.0 * DT  # > 10 m/s: the glitch is real

    res = run_session(glitch, duration=3.0, out=tmp_path / "g")
    log, s = res.log, res.summary
    assert not s["fell"]
    target = np.column_stack([log[f"target_right_hand.{c}"] for c in "xyz"])
    assert np.linalg.norm(np.diff(target, axis=0), axis=1).max() <= SafetyConfig().max_speed * DT + 1e-9
    flt = s["metrics"]["teleop"]["filter"]
    assert flt["counts"]["speed"]["right_hand"] > 0 and flt["events"][0]["effector"] == "right_hand"
    t = log["t"]
    flagged = t[log["teleop_filter.speed"] > 0]
    assert flagged.min() > 1.9 and flagged.max() < 2.2  # around the glitch only


@pytest.mark.parametrize("safety,needle", [({"max_speed": -1.0}, "max_speed"), ({"jump_distanse": 0.1}, "jump_distanse"),
                                           ({"body": "yes"}, "body")])
def test_bad_safety_params_name_the_key(talos, safety, needle):
    from wbcbench.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        TeleopScenario.from_source(talos, "arms_down", duration=1.0, safety=safety)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_interleaved_interventions_are_one_event_each(talos, start):
    """A clamp of one kind that lasts (counted every tick) is one event from its first to its last tick, even
    when another kind on the same effector comes and goes between its ticks."""
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    flt._count(0.0, "left_hand", "speed")
    for k in range(1, 30):
        flt._count(k * DT, "left_hand", "speed")
        if k % 2:
            flt._count(k * DT, "left_hand", "acceleration")
    flt._count(0.5, "left_hand", "speed")  # later: a new event
    events = [(e["kind"], e["t"], e["t_last"]) for e in flt.summary()["events"]]
    assert events == [("speed", 0.0, pytest.approx(29 * DT)), ("acceleration", DT, pytest.approx(29 * DT)),
                      ("speed", 0.5, 0.5)]
    assert flt.counts["speed"]["left_hand"] == 31 and flt.counts["acceleration"]["left_hand"] == 15


def _crouched(robot, knee: float = 1.6) -> np.ndarray:
    """The reference posture with the knees bent by `knee` [rad] (hips and ankles by half of it each way, the base
    lowered so that the soles stay where they were, roughly)."""
    q = robot.q0.copy()
    model = robot.model
    for side in ("left", "right"):
        for joint, bend in ((3, -0.5), (4, 1.0), (5, -0.5)):
            q[model.joints[model.getJointId(f"leg_{side}_{joint}_joint")].idx_q] += bend * knee
    q[2] -= 0.6 * (1.0 - np.cos(0.5 * knee)) * 2.0
    return q


def test_the_body_spheres_follow_a_crouch(talos, start):
    """Given the measured configuration, the spheres move with the legs and the pelvis (where a filter made at that
    posture puts them); a hand reference at a crouched sphere's centre, which the standing spheres let through, is
    then pushed out, on the general path and on the compiled row path alike."""
    q = _crouched(talos)
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    standing = {e: c.copy() for e, (_, c, _) in flt._body.items()}
    offset, centres, radii = flt._body["left_hand"]
    at_crouch = CommandFilter(talos, q, SafetyConfig(), DT)._body
    crouched = at_crouch["left_hand"][1]
    pelvis = np.argmax(radii)  # the largest sphere: the pelvis (0.15 m)
    assert standing["left_hand"][pelvis][2] - crouched[pelvis][2] > 0.1  # the crouch lowers it by more than 10 cm
    # the crouched sphere farthest out of the standing ones (a knee, moved forwards and down)
    clear = [np.min(np.linalg.norm(c - standing["left_hand"], axis=1) - (radii + 0.03)) for c in crouched]
    x = crouched[int(np.argmax(clear))]
    assert max(clear) > 0.0
    M = pin.SE3(start["left_hand"].rotation, x - start["left_hand"].rotation @ offset)
    ref = {"left_hand": (M, np.zeros(6), np.zeros(6))}
    assert flt(0.0, ref)["left_hand"][0] is M and not flt.counts["body"]  # outside the standing spheres
    flt.follow(0.0, q)
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, q)
    spec = talos.profile.repulsors[Side.LEFT]
    points = np.array([data.oMf[talos.model.getFrameId(p.frame)].act(np.asarray(p.offset, float)) for p in spec.points])
    for e, (_, c, _) in flt._body.items():
        np.testing.assert_allclose(c, at_crouch[e][1], atol=1e-12)
    # each a repulsion point of the profile at the crouch, by pinocchio's frame kinematics
    assert all(np.linalg.norm(points - x, axis=1).min() < 1e-9 for x in flt._body["left_hand"][1])
    # a posture reached at once (a real one moves the spheres by millimetres a period): the output leaves the body
    # as the speed and re-join limits allow, and stays on the surface
    out = _feed(flt, lambda k: {"left_hand": M}, 500, t0=DT)
    gaps = np.linalg.norm(out[-1]["left_hand"][0].act(offset) - centres, axis=1) - (radii + 0.03)
    assert gaps.min() >= -1e-9 and gaps.min() < 1e-6 and flt.counts["body"] == {"left_hand": 500}
    # the same on the row path: the stacked spheres moved too, the reference is no longer passed untouched
    rows = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    rows.bind_rows(("left_hand",))
    P, R = M.translation[None, None].copy(), M.rotation[None, None].copy()
    V = A = np.zeros((1, 1, 6))
    rows(0.0, ref)
    assert rows.pass_rows(DT, 0, P, R, V, A)
    rows.follow(2 * DT, q)
    assert not rows.pass_rows(3 * DT, 0, P, R, V, A)
    assert rows(3 * DT, ref)["left_hand"][0] is not M and rows.counts["body"] == {"left_hand": 1}


def test_the_body_spheres_follow_at_their_period(talos):
    """`follow` moves the spheres when `body_period` has passed since it last did, and not in between; a filter
    with the body check off has nothing to move."""
    q = _crouched(talos)
    flt = CommandFilter(talos, talos.q0, SafetyConfig(body_period=0.005), DT)
    c = flt._body["left_hand"][1]
    before = c.copy()
    flt.follow(0.0, talos.q0)
    flt.follow(0.004, q)
    np.testing.assert_array_equal(c, before)
    flt.follow(0.005, q)
    assert np.abs(c - before).max() > 0.1
    CommandFilter(talos, talos.q0, SafetyConfig(body=False), DT).follow(0.0, q)


def test_the_hands_turn_at_most_at_the_wrists_speed(talos, start):
    """With `hand_angular_speed: wrist`, TALOS' hands turn at up to what the wrist (arm_*_5/6/7_joint: 1.95, 1.76,
    1.76 rad/s) does, the norm of those limits: a hand reference turning at 6 rad/s is output turning at that speed
    (its feed-forward clipped too), the head's at 6 rad/s is not held (`max_angular_speed` 10). A number sets the
    hands' limit; by default there is none besides `max_angular_speed`; anything else is a one-line error."""
    from wbcbench.errors import ConfigError
    from wbcbench.teleop.safety import wrist_speed

    w = wrist_speed(talos)
    assert w == pytest.approx(np.linalg.norm([1.95, 1.76, 1.76]))
    flt = CommandFilter(talos, talos.q0, SafetyConfig(hand_angular_speed="wrist"), DT)
    assert flt.angular_speed == {"left_hand": w, "right_hand": w, "head": 10.0}
    spin = np.array([0.0, 0.0, 6.0])
    vel = np.concatenate([np.zeros(3), spin])

    def turned(M, k):
        return pin.SE3(pin.exp3(spin * k * DT) @ M.rotation, M.translation)

    outs = []
    for k in range(200):
        raw = {e: (turned(start[e], k), vel, np.zeros(6)) for e in ("left_hand", "head")}
        outs.append(flt(k * DT, raw))
    for e, speed in (("left_hand", w), ("head", 6.0)):
        R = [o[e][0].rotation for o in outs]
        rates = [np.linalg.norm(pin.log3(a.T @ b)) / DT for a, b in zip(R[1:], R[2:])]
        assert max(rates) == pytest.approx(speed, rel=1e-6), e
        assert np.linalg.norm(outs[-1][e][1][3:]) == pytest.approx(speed), e
    assert "head" not in flt.counts["speed"] and flt.counts["speed"]["left_hand"] > 0
    assert CommandFilter(talos, talos.q0, SafetyConfig(hand_angular_speed=5.0), DT).angular_speed["left_hand"] == 5.0
    assert CommandFilter(talos, talos.q0, SafetyConfig(), DT).angular_speed["left_hand"] == 10.0
    sc = TeleopScenario.from_source(talos, "arms_down", duration=1.0, safety={"hand_angular_speed": "wrist"})
    assert sc.safety.hand_angular_speed == "wrist"
    with pytest.raises(ConfigError, match="hand_angular_speed") as err:
        TeleopScenario.from_source(talos, "arms_down", duration=1.0, safety={"hand_angular_speed": "elbow"})
    assert "wrist" in str(err.value) and "\n" not in str(err.value)


def test_a_reference_passing_through_the_body_is_led_round_it(talos, start):
    """A hand reference swept through the pelvis from one side to the other at 2 m/s: pushed out radially it flips
    sides at the centre, a jump the filter re-joins along a straight line; the output stays out of the spheres all
    the way (the re-join and the speed clamp pushed out again)."""
    flt = CommandFilter(talos, talos.q0, SafetyConfig(), DT)
    offset, centres, radii = flt._body["left_hand"]
    pelvis = centres[np.argmax(radii)]
    Rh = start["left_hand"].rotation
    outs = []
    for k in range(600):
        x = pelvis + np.array([0.0, 0.4 - 2.0 * k * DT, 0.0])  # the protected point from 0.4 m left to 0.8 m right
        raw = {"left_hand": (pin.SE3(Rh, x - Rh @ offset), np.array([0.0, -2.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(6))}
        outs.append(flt(k * DT, raw)["left_hand"][0])
    depth = max(float((radii + 0.03 - np.linalg.norm(M.act(offset) - centres, axis=1)).max()) for M in outs)
    assert depth < 1e-9 and flt.counts["jump"] and flt.counts["body"]


def test_in_a_run_the_body_spheres_crouch_with_the_robot(talos, tmp_path):
    """An operator squats (hips 45, knees 80 deg, arms hanging; a fixture of our own, written as BVH) and TALOS
    crouches with him (the base 10 cm and more lower): the filter's spheres were moved with the measured posture
    (the runner hands the scenario each tick's measurement), to within the 5 ms of motion since their last update,
    no reference handed to the controller is inside them, and the robot stands."""
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.runner import run
    from wbcbench.teleop import load_recording, write_bvh
    from wbcbench.teleop.synthetic import SyntheticMotion, _both, _keyframes, motion_configurations
    from wbcbench.types import ActuationMode

    squat = _both({"right_hip_Z": 45.0, "right_knee_Z": 80.0, "right_ankle_Z": 35.0})
    frames = [(0.3, {}), (1.8, squat), (2.5, squat)]
    motion = SyntheticMotion("squat", "a squat, arms hanging", "A", 2.5, 50.0, lambda t: _keyframes(t, frames))
    human, _, qs = motion_configurations(motion)
    path = write_bvh(tmp_path / "squat.bvh", human.bvh_skeleton(0.01), human.bvh_motion(qs, 0.01), 1 / 50.0)
    scen = TeleopScenario.from_source(talos, load_recording(path), duration=2.5, name="squat")
    ctrl = TSIDTeleop(talos, ActuationMode.SPD, scen.spec.control_dt)
    res = run(scen, ctrl, robot=talos, out=tmp_path / "run")
    log = res.log
    assert not res.summary["fell"]
    assert log["q.z"][0] - log["q.z"].min() > 0.10
    names = ["x", "y", "z", "qx", "qy", "qz", "qw"] + talos.joint_names
    q_end = np.array([log[f"q.{c}"][-1] for c in names])
    flt = scen.reference_source.command_filter
    now = CommandFilter(talos, q_end, SafetyConfig(), DT)._body
    standing = CommandFilter(talos, talos.q0, SafetyConfig(), DT)._body
    for e, (offset, centres, radii) in flt._body.items():
        assert np.abs(centres - now[e][1]).max() < 0.005, e  # moved with the robot (< 1 m/s for 5 ms)
        assert np.abs(centres - standing[e][1]).max() > 0.10, e
    Q = np.column_stack([log[f"q.{c}"] for c in names])
    for k in range(0, len(Q), 25):
        at = CommandFilter(talos, Q[k], SafetyConfig(), DT)._body
        for e, (offset, centres, radii) in at.items():
            R = np.array([log[f"target_{e}.r{i}{j}"][k] for i in range(3) for j in range(3)]).reshape(3, 3)
            x = np.array([log[f"target_{e}.{c}"][k] for c in "xyz"]) + R @ offset
            assert (np.linalg.norm(x - centres, axis=1) - radii).min() > 0.0, (k, e)
