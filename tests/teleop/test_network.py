"""Network realism for the operator's stream (wbcbench/teleop/network.py, prediction.py): the impairment model
(exact latency, binomial loss, bursts, jitter, reordering, duplication, stalls), the same model on real loopback
sockets (the relay) and in simulated time (a recording through the live receiver), operator-pose prediction, and
garbage on a live stream rejected and logged while the robot holds. The latency / loss table itself is
benchmarks/teleop_network.py."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ConfigError
from wbcbench.scenarios.teleop_kind import TeleopScenario
from wbcbench.teleop import ReplaySender, UdpPoseReceiver, encode_datagram, open_recording
from wbcbench.teleop.network import (ImpairedLink, ImpairedRelay, ImpairedReplay, NetworkImpairment,
                                     parse_impairment)
from wbcbench.teleop.prediction import PosePredictor

DATA = b"x" * 100
PERIOD = 0.02  # 50 Hz


def _send(imp: NetworkImpairment, n: int) -> tuple[ImpairedLink, list]:
    """n datagrams at 50 Hz through a link: per datagram, its list of (arrival, bytes)."""
    link = ImpairedLink(imp)
    return link, [link.transmit(i * PERIOD, DATA) for i in range(n)]


# ------------------------------------------------------------------------------------------------ the model
def test_latency_is_exact_and_loss_is_binomial_and_independent_of_the_latency():
    n, p = 4000, 0.05
    _, exact = _send(NetworkImpairment(latency=0.05), n)
    assert all(len(a) == 1 and a[0][0] == pytest.approx(i * PERIOD + 0.05, abs=1e-12) and a[0][1] == DATA
               for i, a in enumerate(exact))
    link, out = _send(NetworkImpairment(loss=p, seed=3), n)
    lost = [i for i, a in enumerate(out) if not a]
    sigma = np.sqrt(n * p * (1 - p))
    assert abs(len(lost) - n * p) < 4 * sigma and link.stats.lost == len(lost)
    # the same seed loses the same datagrams at 100 ms (tables over latency compare like with like)
    _, late = _send(NetworkImpairment(latency=0.1, loss=p, seed=3), n)
    assert [i for i, a in enumerate(late) if not a] == lost
    _, other = _send(NetworkImpairment(loss=p, seed=4), n)
    assert [i for i, a in enumerate(other) if not a] != lost


def test_gilbert_bursts_keep_the_loss_rate_and_have_the_mean_length():
    n = 20000
    _, out = _send(NetworkImpairment(loss=0.1, burst=4.0, seed=1), n)
    lost = np.array([not a for a in out])
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], lost.astype(int), [0]]))))[::2]
    assert 0.08 < lost.mean() < 0.12
    assert 3.4 < runs.mean() < 4.6  # Bernoulli at 10 % would give 1.1
    _, indep = _send(NetworkImpairment(loss=0.1, seed=1), n)
    lost_i = np.array([not a for a in indep])
    runs_i = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], lost_i.astype(int), [0]]))))[::2]
    assert runs_i.mean() < 1.3


def test_jitter_reordering_duplication_and_corruption():
    n = 2000
    _, out = _send(NetworkImpairment(latency=0.03, jitter=0.01, seed=2), n)
    delay = np.array([a[0][0] - i * PERIOD for i, a in enumerate(out)])
    assert delay.min() >= 0.0 and delay.mean() == pytest.approx(0.03, abs=1e-3)
    assert delay.std() == pytest.approx(0.01, rel=0.1)
    link, out = _send(NetworkImpairment(latency=0.01, reorder=0.1, duplicate=0.1, corrupt=0.1, seed=2), n)
    arrivals = [t for a in out for t, _ in a]
    overtaken = sum(a[0][0] > out[i + 1][0][0] for i, a in enumerate(out[:-1]))
    assert overtaken == pytest.approx(0.1 * n, rel=0.2) and link.stats.reordered == pytest.approx(0.1 * n, rel=0.2)
    dups = [a for a in out if len(a) == 2]
    assert len(dups) == link.stats.duplicated == pytest.approx(0.1 * n, rel=0.2)
    assert all(b[0] > a[0] and b[1] == a[1] for a, b in dups)
    bad = sum(a[0][1] != DATA for a in out)
    assert bad == link.stats.corrupted == pytest.approx(0.1 * n, rel=0.2) and len(arrivals) == link.stats.delivered


def test_a_stalled_sender_sends_nothing_in_its_window():
    link, out = _send(NetworkImpairment(stalls=((1.0, 0.5),)), 200)
    silent = [i for i, a in enumerate(out) if not a]
    assert silent == list(range(50, 75)) and link.stats.stalled == 25 and link.stats.lost == 0


@pytest.mark.parametrize(("spec", "needle"), [
    ("latency=abc", "latency='abc' is not a duration"),
    ("laggy=5ms", "unknown key 'laggy'"),
    ("loss=120%", "0-100 %"),
    ("loss=100%", "below 100 %"),
    ("burst=0.5,loss=5%", "burst"),
    ("stall=2s", "DURATION@START"),
    ("jitter", "KEY=VALUE"),
    ("seed=-1", "seed"),
    ("latency=5ms,latency=6ms", "twice"),
])
def test_bad_specs_are_one_line_naming_the_option(spec, needle):
    with pytest.raises(ConfigError) as exc:
        parse_impairment(spec)
    assert "\n" not in str(exc.value) and "--net" in str(exc.value) and needle in str(exc.value)


def test_spec_round_trip():
    imp = parse_impairment("latency=50ms,jitter=0.005,loss=5%,burst=3,reorder=2%,duplicate=1%,corrupt=0.01,"
                           "stall=0.5s@3s,stall=100ms@5,seed=7")
    assert imp == NetworkImpairment(latency=0.05, jitter=0.005, loss=0.05, burst=3.0, reorder=0.02, duplicate=0.01,
                                    corrupt=0.01, stalls=((3.0, 0.5), (5.0, 0.1)), seed=7)
    assert parse_impairment(imp.describe()) == imp


# ------------------------------------------------------------------------ simulated time: the live receiver
def test_replay_through_the_link_delivers_what_a_receiver_would_hold():
    rec = open_recording("waving")
    imp = NetworkImpairment(latency=0.04, jitter=0.015, reorder=0.1, duplicate=0.1, loss=0.05, seed=5)
    replay = ImpairedReplay(rec, imp)
    last = -1.0
    for k in range(0, 3000, 5):  # 3 s at 5 ms
        t = k * 1e-3
        frame = replay.frame_at(t)
        if frame is None:
            assert t < 0.04 + 3 * 0.015
            continue
        assert frame.time >= last  # never goes back: late and duplicate frames are dropped
        assert frame.time <= t - 0.0 + 1e-9  # nothing arrives before it is sent
        last = frame.time
    st = replay.receiver.stats
    assert st.reordered > 5 and st.duplicates > 5 and st.lost > 0 and st.malformed == 0
    assert st.received + replay.in_flight == replay.link.stats.delivered
    # the same seed, the same run
    again = ImpairedReplay(rec, imp)
    again.frame_at(3.0)
    assert again.receiver.stats == st


# ------------------------------------------------------------------------------------ real sockets: relay
def test_the_relay_delays_duplicates_and_loses_real_datagrams():
    with UdpPoseReceiver(port=0) as receiver, ImpairedRelay(NetworkImpairment(latency=0.08, duplicate=1.0),
                                                            receiver.address) as relay:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            sent = time.monotonic()
            s.sendto(encode_datagram(0, 0.0, {15: ((0, 0, 0), (0, 0, 0, 1.0))}), ("127.0.0.1", relay.port))
            while receiver.stats.received < 2 and time.monotonic() - sent < 3.0:
                receiver.poll()
                time.sleep(0.001)
            delay = receiver.latest.arrival - sent
        assert 0.08 <= delay < 1.0  # never early (the upper bound is loose: a loaded machine)
        assert receiver.stats.received == 2 and receiver.stats.duplicates == 1
    with UdpPoseReceiver(port=0) as receiver, ImpairedRelay(NetworkImpairment(loss=0.5, seed=1),
                                                            receiver.address) as relay:
        with ReplaySender(open_recording("waving"), relay.port, speed=20.0) as sender:
            sender.run(0, 100)
        end = time.monotonic() + 3.0
        while ((relay.link.stats.offered < 100 or receiver.stats.received < relay.link.stats.delivered)
               and time.monotonic() < end):
            receiver.poll()
            time.sleep(0.002)
        assert receiver.stats.received == relay.link.stats.delivered == 100 - relay.link.stats.lost
        assert 30 < relay.link.stats.lost < 70


def test_the_relay_forwards_to_loopback_only():
    with pytest.raises(ConfigError, match="loopback"):
        ImpairedRelay(NetworkImpairment(), ("10.0.0.1", 9000))


# -------------------------------------------------------------------------------------------- prediction
def _linear(tau):
    return pin.SE3(pin.exp3(np.array([0.3, -0.2, 0.5]) * tau) @ pin.exp3(np.array([0.1, 0.2, 0.3])),
                   np.array([0.4, -0.1, 1.0]) + np.array([0.5, 0.2, -0.3]) * tau)


def test_constant_velocity_extrapolates_a_linear_motion_exactly_and_the_horizon_is_capped():
    pred = PosePredictor("velocity", max_horizon=0.15)
    for k in range(6):
        pred.push(0.02 * k, {"left_hand": _linear(0.02 * k)})
    newest = 0.1
    for age in (0.0, 0.03, 0.12):
        poses, rates, h = pred.predict(age)
        assert h == pytest.approx(age)
        M = poses["left_hand"]
        np.testing.assert_allclose(M.translation, _linear(newest + age).translation, atol=1e-12)
        np.testing.assert_allclose(M.rotation, _linear(newest + age).rotation, atol=1e-12)
        np.testing.assert_allclose(rates["left_hand"][:3], [0.5, 0.2, -0.3], atol=1e-12)
    poses, _, h = pred.predict(5.0)  # a stalled stream: extrapolated no further than the cap
    assert h == 0.15
    np.testing.assert_allclose(poses["left_hand"].translation, _linear(newest + 0.15).translation, atol=1e-12)
    none = PosePredictor("none")
    none.push(0.0, {"left_hand": _linear(0.0)})
    none.push(0.02, {"left_hand": _linear(0.02)})
    poses, rates, h = none.predict(0.1)
    assert h == 0.0 and poses["left_hand"].isApprox(_linear(0.02))
    np.testing.assert_allclose(rates["left_hand"][:3], [0.5, 0.2, -0.3], atol=1e-12)  # still a feed-forward


def test_spline_extrapolates_a_constant_acceleration_exactly_and_forgets_across_a_stall():
    def quad(tau):
        return pin.SE3(np.eye(3), np.array([0.1, 0.2, 0.3]) + np.array([0.5, 0.0, -0.2]) * tau
                       + np.array([-2.0, 1.0, 0.5]) * tau**2)

    pred = PosePredictor("spline", max_horizon=0.2)
    taus = [0.0, 0.02, 0.06, 0.08, 0.1]  # a frame lost: irregular spacing
    for tau in taus:
        pred.push(tau, {"h": quad(tau)})
    poses, _, h = pred.predict(0.08)
    np.testing.assert_allclose(poses["h"].translation, quad(0.18).translation, atol=1e-10)
    velocity = PosePredictor("velocity", max_horizon=0.2)
    for tau in taus:
        velocity.push(tau, {"h": quad(tau)})
    assert np.linalg.norm(velocity.predict(0.08)[0]["h"].translation - quad(0.18).translation) > 1e-3
    # after a 0.5 s stall the old frames are forgotten: no extrapolation from one fresh frame
    pred.push(0.6, {"h": quad(0.6)})
    poses, rates, h = pred.predict(0.1)
    assert poses["h"].isApprox(quad(0.6)) and not rates["h"].any()
    assert not pred.push(0.59, {"h": quad(0.59)})  # a late frame is ignored


def _source_run(talos, network, predict, start, t0, t1):
    """The teleop reference source alone (no simulation), reach_forward from recording time `start`, no
    engagement blend, over run times [t0, t1): per tick the hands' targets and undelayed references (positions),
    validity, horizon."""
    sc = TeleopScenario.from_source(talos, "reach_forward", duration=t1, network=network, predict=predict,
                                    start=start, engage_time=0.0)
    sc.setup(talos.q0, np.zeros(3))
    src = sc.reference_source
    out = {"target": [], "truth": [], "valid": [], "horizon": [], "t": []}
    for k in range(int(round(t1 / 1e-3))):
        t = k * 1e-3
        named = src.targets(t)
        if t < t0:
            continue
        out["t"].append(t)
        out["target"].append(np.concatenate([named["left_hand"].position, named["right_hand"].position]))
        out["truth"].append(np.concatenate([src.truth[0:3], src.truth[12:15]]))
        out["valid"].append(src.record_valid[-1])
        out["horizon"].append(src.stream_horizon)
    return sc, {k: np.array(v) for k, v in out.items()}


def test_prediction_reduces_the_target_error_against_the_undelayed_reference_at_50_ms(talos):
    """The right hand reaching forward (recording 1.0-2.5 s) through a 50 ms link: the target handed to the
    controller lags the operator; extrapolating the newest frame takes most of the lag out."""
    errs = {}
    for predict in ("none", "velocity", "spline"):
        _, r = _source_run(talos, "latency=50ms,seed=1", predict, 1.0, 0.2, 1.2)
        e = np.linalg.norm(r["target"][:, 3:] - r["truth"][:, 3:], axis=1)
        errs[predict] = (e.mean(), e.max())
        if predict != "none":
            assert 0.05 + 0.03 <= r["horizon"].max() <= 0.15  # the age (latency + up to a frame) + the filter lag
    assert errs["none"][0] > 0.01  # the lag is there: ~1 cm and more while the hand moves
    assert errs["velocity"][0] < 0.4 * errs["none"][0] and errs["spline"][0] < 0.4 * errs["none"][0]
    assert errs["velocity"][1] < 0.6 * errs["none"][1]


def test_a_stalled_sender_goes_stale_and_the_robot_holds_then_resumes(talos):
    """The operator's sender stalls 0.6 s from t = 0.4 s: after the receiver's 0.2 s timeout the source is
    invalid and the targets are held (the loss policy); fresh frames end it; the horizon stays within its cap."""
    sc, r = _source_run(talos, "latency=20ms,stall=0.6s@0.4s", "velocity", 1.5, 0.1, 1.3)
    t, valid = r["t"], r["valid"].astype(bool)
    invalid = t[~valid]
    assert invalid.min() == pytest.approx(0.38 + 0.02 + 0.2, abs=0.003)  # the last frame was sent at 0.38 s
    assert invalid.max() == pytest.approx(1.0 + 0.02, abs=0.003)  # the first fresh frame arrives
    held = r["target"][~valid]
    assert np.ptp(held, axis=0).max() < 1e-12
    assert sc.reference_source.loss_events == 1 and r["horizon"].max() <= 0.15


def test_a_live_streams_frame_age_without_a_shared_clock(talos):
    """A live receiver (own clock) fed a recording 50 ms late with up to 10 ms of jitter: the age the source gives
    a frame is its delay beyond the fastest delivery plus the time since it arrived plus `predict_latency`, i.e.
    the true age within the jitter of the fastest delivery."""
    from wbcbench.teleop.sender import recording_datagram

    rec = open_recording("reach_forward")
    now = [0.0]
    receiver = UdpPoseReceiver(None, clock=lambda: now[0])
    sc = TeleopScenario.from_source(talos, receiver, duration=1.0, realtime=False, predict="velocity",
                                    predict_latency=0.05, engage_time=0.0)
    sc.setup(talos.q0, np.zeros(3))
    src = sc.reference_source
    rng = np.random.default_rng(0)
    arrivals = [(rec.times[i] + 0.05 + 0.01 * rng.random(), i) for i in range(60)]
    ages = []
    for k in range(1000):
        t = now[0] = k * 1e-3
        while arrivals and arrivals[0][0] <= t:
            arrival, i = arrivals.pop(0)
            receiver.feed(recording_datagram(rec, i, i), arrival=arrival)
        src.targets(t)
        if receiver.latest is not None:
            ages.append(src.stream_age - (t - receiver.latest.timestamp))
    ages = np.array(ages)
    assert len(ages) > 900 and np.all(np.abs(ages) <= 0.01 + 1e-9)
    assert src.stream_horizon == pytest.approx(min(src.stream_age + 0.03, 0.15))


# ------------------------------------------------------------------------------- garbage on a live stream
def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_live_stream_of_garbage_is_rejected_and_logged_while_the_robot_holds(tmp_path):
    """A live stream through the relay, every datagram corrupted: each is rejected (malformed, counted per tick in
    the log's teleop_stream channel), the source never becomes valid, the hands' targets stay the robot's own."""
    from wbcbench.teleop.commands import run_session

    port = _free_port()
    stop = threading.Event()

    def operator():
        with ReplaySender(open_recording("waving"), port) as sender:
            i = 0
            while not stop.is_set() and i < 200:
                sender.send_raw(sender.datagram(i))
                i += 1
                time.sleep(0.01)

    thread = threading.Thread(target=operator, daemon=True)
    thread.start()
    try:
        res = run_session(f"udp://127.0.0.1:{port}", duration=0.6, stabilizer=False, out=tmp_path / "live",
                          network=parse_impairment("latency=10ms,corrupt=100%"))
    finally:
        stop.set()
        thread.join(2.0)
    s = res.summary
    assert not s["fell"]
    tele = s["metrics"]["teleop"]
    assert tele["network"]["path"] == "relay" and tele["network"]["link"]["corrupted"] >= 10
    assert tele["stream"]["accepted"] == 0 and tele["stream"]["malformed"] >= 10 and tele["stream"]["last_error"]
    assert tele["valid_ticks"] == 0
    log = res.log
    malformed = np.asarray(log["teleop_stream.malformed"])
    assert malformed[-1] >= 10 and np.all(np.diff(malformed) >= 0) and not np.asarray(log["teleop_stream.valid"]).any()
    for c in ("x", "y", "z"):
        assert np.ptp(np.asarray(log[f"target_right_hand.{c}"])) < 1e-9  # held: the robot's own pose


def test_cli_network_options_bad_values_are_one_line_exit_2(capsys):
    """Through the command line's entry point (the subprocess form of these checks is in test_session.py)."""
    from wbcbench.cli import main

    for argv, needle in ((["--net", "latency=fast"], "latency"), (["--net", "loss=5%,burst=x"], "burst"),
                         (["--predict-horizon", "-1"], "--predict-horizon"),
                         (["--predict-latency", "nan"], "--predict-latency")):
        assert main(["teleop", "--mocap", "waving", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err


def _live_switch(talos, scale: float, switch: int = 40, n: int = 75, drop: str | None = None):
    """A live receiver (own clock) fed the waving recording; from frame `switch` on, another skeleton: the same
    motion with every segment's position scaled by `scale` about the pelvis (a taller or shorter performer), or
    without segment `drop`. Per tick: the hands' targets, validity."""
    import dataclasses

    from wbcbench.teleop.sender import recording_datagram
    from wbcbench.teleop.segments import MVN_SEGMENT_IDS

    rec = open_recording("waving")
    pelvis = rec.positions[:, rec.segments.index("Pelvis")][:, None, :]
    other = dataclasses.replace(rec, positions=pelvis + scale * (rec.positions - pelvis))
    ids = dict(MVN_SEGMENT_IDS)
    now = [0.0]
    receiver = UdpPoseReceiver(None, clock=lambda: now[0])
    sc = TeleopScenario.from_source(talos, receiver, duration=1.5, realtime=False, engage_time=0.0)
    sc.setup(talos.q0, np.zeros(3))
    src = sc.reference_source
    out = {"t": [], "target": [], "valid": []}
    i = 0
    for k in range(1500):
        t = now[0] = k * 1e-3
        while i < n and rec.times[i] - rec.times[0] <= t:
            after = i >= switch
            seg_ids = {s: v for s, v in ids.items() if not (after and s == drop)}
            receiver.feed(recording_datagram(other if after and drop is None else rec, i, i, seg_ids), arrival=t)
            i += 1
        named = src.targets(t)
        out["t"].append(t)
        out["target"].append(np.concatenate([named["left_hand"].position, named["right_hand"].position]))
        out["valid"].append(src.record_valid[-1])
    return src, {k: np.array(v) for k, v in out.items()}, rec.times[switch] - rec.times[0]


def test_a_stream_that_switches_skeleton_is_held_and_says_why(talos):
    """Mid-run the stream's performer is 30 % taller: the watchdog trips on the first such frame, every tick after
    it is invalid, the hands' targets are held, and the reason names the bone and both lengths. The same stream
    without the switch, and one 5 % taller (within the tolerance), never trip."""
    src, r, t_switch = _live_switch(talos, 1.3)
    w = src.watchdog
    assert w is not None and w["frame_time"] == pytest.approx(t_switch + open_recording("waving").times[0])
    assert "switched skeleton" in w["reason"] and "bone" in w["reason"] and "+30 %" in w["reason"]
    after = r["t"] >= w["time"]
    assert r["valid"][(r["t"] > 0.1) & ~after].all() and not r["valid"][after].any()
    assert np.ptp(r["target"][after], axis=0).max() < 1e-12   # held
    for scale in (1.0, 1.05):
        src, r, _ = _live_switch(talos, scale)
        assert src.watchdog is None and r["valid"][r["t"] > 0.1].all()


def test_a_stream_that_loses_a_limb_segment_is_held(talos):
    src, r, _ = _live_switch(talos, 1.0, drop="LeftForeArm")
    assert src.watchdog is not None and "LeftForeArm is gone" in src.watchdog["reason"]
