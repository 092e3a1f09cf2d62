"""Synthetic operator recordings generated from the human model.

Each motion is a joint-angle trajectory of the :class:`~wbcbench.teleop.HumanModel` (smooth keyframes plus
oscillations), performed by one of three operators of different sizes, feet planted (the free-flyer is set at every
frame so that the feet frame stays put, which also makes the squat of ``bimanual_lift`` keep the soles on the
floor). Every recording starts and ends with the operator standing still, arms along the body (1 s or more): the
calibration posture of :class:`~wbcbench.teleop.Retargeter`.

Recordings are written as BVH (centimetres, :meth:`HumanModel.bvh_skeleton`), in a y-up suit world where each
operator stands at his own position and heading (the retargeting must find it). :func:`generate_recordings`
rewrites them; :func:`~wbcbench.teleop.list_recordings` lists them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..io.bvh import write_bvh
from .model import LINKS, HumanModel

__all__ = ["Operator", "SyntheticMotion", "OPERATORS", "MOTIONS", "generate_recordings", "motion_configurations"]

FloatArray = npt.NDArray[np.float64]
Angles = dict[str, FloatArray]


@dataclass(frozen=True)
class Operator:
    """A synthetic operator: segment-length factors on the default 1.80 m model, and where he stands.

    Attributes:
        name: short name.
        scale: factor on every segment length.
        arm_scale: extra factor on the upper-arm and forearm lengths.
        position: (x, y) of his feet frame in the suit world, horizontal plane [m].
        heading: his heading about the suit's vertical axis [rad].
    """

    name: str
    scale: float
    arm_scale: float = 1.0
    position: tuple[float, float] = (0.0, 0.0)
    heading: float = 0.0

    def lengths(self) -> dict[str, float]:
        """Segment lengths [m] for :class:`HumanModel`."""
        defaults = HumanModel.default_lengths()
        out = {}
        for link in LINKS:
            factor = self.scale * (self.arm_scale if "arm" in link.name else 1.0)
            out[link.name] = defaults[link.name] * factor
        return out


#: The three operators of the recordings: A default size (1.80 m), B smaller (about 1.67 m), C taller with long arms.
OPERATORS: Mapping[str, Operator] = {
    "A": Operator("A", 1.0, 1.0, (0.4, -0.3), 0.35),
    "B": Operator("B", 0.93, 1.0, (-1.2, 0.8), -1.1),
    "C": Operator("C", 1.04, 1.08, (2.0, 1.5), 2.6),
}


@dataclass(frozen=True)
class SyntheticMotion:
    """One synthetic recording.

    Attributes:
        name: registry name (file ``<name>.bvh``).
        description: one line.
        operator: key of :data:`OPERATORS`.
        duration: [s].
        rate: frame rate [Hz].
        angles: t (N,) -> model joint name -> angle (N,) [deg].
    """

    name: str
    description: str
    operator: str
    duration: float
    rate: float
    angles: Callable[[FloatArray], Angles] = field(repr=False)


# ------------------------------------------------------------------------------------------------- helpers
def _smooth(t: FloatArray, t0: float, t1: float) -> FloatArray:
    """0 before t0, 1 after t1, quintic smoothstep between (zero velocity and acceleration at both ends)."""
    s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _keyframes(t: FloatArray, frames: Sequence[tuple[float, Mapping[str, float]]]) -> Angles:
    """Joint angles [deg] through keyframes ``(time, {joint: angle})``, smoothstep between consecutive ones.
    A joint missing from a keyframe is 0 there."""
    joints = sorted({j for _, pose in frames for j in pose})
    out = {j: np.full_like(t, frames[0][1].get(j, 0.0)) for j in joints}
    for (ta, pa), (tb, pb) in zip(frames[:-1], frames[1:], strict=True):
        s = _smooth(t, ta, tb)
        for j in joints:
            out[j] += s * (pb.get(j, 0.0) - pa.get(j, 0.0))
    return out


def _add(*parts: Angles) -> Angles:
    out: Angles = {}
    for part in parts:
        for j, v in part.items():
            out[j] = out.get(j, 0.0) + v
    return out


def _both(pose: Mapping[str, float]) -> dict[str, float]:
    """A pose given for the right side (``right_*``) applied to both sides (anatomical signs are mirrored)."""
    out = dict(pose)
    out.update({"left_" + k[len("right_"):]: v for k, v in pose.items() if k.startswith("right_")})
    return out


def _left(pose: Mapping[str, float]) -> dict[str, float]:
    return {"left_" + k[len("right_"):]: v for k, v in pose.items()}


# -------------------------------------------------------------------------------------------------- motions
_REACH_F = {"right_shoulder_Z": 85.0, "right_elbow_Z": 10.0, "right_shoulder_X": 5.0}
_REACH_S = {"right_shoulder_X": 85.0, "right_elbow_Z": 10.0, "right_shoulder_Z": 5.0}


def _reach_forward(t: FloatArray) -> Angles:
    return _keyframes(t, [
        (1.0, {}), (2.5, _REACH_F), (3.5, _REACH_F), (5.0, {}),
        (5.5, {}), (7.0, _left(_REACH_F)), (8.0, _left(_REACH_F)), (9.0, _both(_REACH_F)),
        (10.0, _both(_REACH_F)), (11.5, {}),
    ])  # fmt: skip


def _reach_sideways(t: FloatArray) -> Angles:
    return _keyframes(t, [
        (1.0, {}), (2.5, _REACH_S), (3.5, _REACH_S), (5.0, {}),
        (5.5, {}), (7.0, _left(_REACH_S)), (8.0, _left(_REACH_S)), (9.0, _both(_REACH_S)),
        (10.0, _both(_REACH_S)), (11.5, {}),
    ])  # fmt: skip


def _waving(t: FloatArray) -> Angles:
    up = {"right_shoulder_X": 80.0, "right_shoulder_Z": 15.0, "right_elbow_Z": 95.0, "right_shoulder_Y": -75.0}
    base = _keyframes(t, [(1.0, {}), (2.5, up), (9.5, up), (11.0, {})])
    envelope = _smooth(t, 2.5, 3.0) * (1.0 - _smooth(t, 9.0, 9.5))
    wave = {"right_shoulder_Y": 18.0 * envelope * np.sin(2 * np.pi * 1.2 * (t - 2.5)),
            "right_elbow_Z": -10.0 * envelope * np.sin(2 * np.pi * 1.2 * (t - 2.5))}
    return _add(base, wave)


def _crossing_arms(t: FloatArray) -> Angles:
    crossed = {
        "right_shoulder_Z": 40.0, "right_shoulder_X": -5.0, "right_shoulder_Y": 75.0, "right_elbow_Z": 105.0,
        "left_shoulder_Z": 52.0, "left_shoulder_X": -5.0, "left_shoulder_Y": 70.0, "left_elbow_Z": 100.0,
    }
    return _keyframes(t, [(1.0, {}), (3.0, crossed), (9.0, crossed), (11.0, {})])


def _arms_down(t: FloatArray) -> Angles:
    settle = _smooth(t, 0.5, 2.0) * (1.0 - _smooth(t, 10.5, 11.5))
    return {
        "right_shoulder_X": settle * (-4.0 + 3.0 * np.sin(2 * np.pi * 0.2 * t)),
        "left_shoulder_X": settle * (-4.0 + 3.0 * np.sin(2 * np.pi * 0.2 * t + 1.0)),
        "right_shoulder_Z": settle * 6.0 * np.sin(2 * np.pi * 0.15 * t),
        "left_shoulder_Z": settle * 6.0 * np.sin(2 * np.pi * 0.15 * t + 2.0),
        "right_elbow_Z": settle * 8.0, "left_elbow_Z": settle * 8.0,
        "middle_lumbar_X": settle * 3.0 * np.sin(2 * np.pi * 0.1 * t),
    }


def _head_turning(t: FloatArray) -> Angles:
    yaw_env = _smooth(t, 1.0, 1.5) * (1.0 - _smooth(t, 7.0, 7.5))
    nod_env = _smooth(t, 7.5, 8.0) * (1.0 - _smooth(t, 10.5, 11.0))
    return {
        "middle_cervical_Y": 60.0 * yaw_env * np.sin(2 * np.pi * (t - 1.0) / 3.0),
        "middle_cervical_Z": 20.0 * nod_env * np.sin(2 * np.pi * (t - 7.5) / 1.5),
        "middle_cervical_X": 8.0 * nod_env * np.sin(2 * np.pi * (t - 7.5) / 3.0),
    }


def _bimanual_lift(t: FloatArray) -> Angles:
    squat = {"right_hip_Z": 45.0, "right_knee_Z": 80.0, "right_ankle_Z": 35.0, "middle_lumbar_Z": 25.0}
    reach = {"right_shoulder_Z": 40.0, "right_elbow_Z": 20.0, "right_shoulder_X": -6.0}
    lift = {"right_shoulder_Z": 35.0, "right_elbow_Z": 105.0, "right_shoulder_X": -6.0, "right_shoulder_Y": 15.0}
    bottom = _both({**squat, **reach})
    return _keyframes(t, [
        (1.0, {}), (3.5, bottom), (5.0, bottom), (8.0, _both(lift)), (9.5, _both(lift)), (11.0, {}),
    ])  # fmt: skip


def _slow_circle(t: FloatArray) -> Angles:
    start = {"right_shoulder_Z": 55.0, "right_shoulder_X": 45.0, "right_elbow_Z": 25.0}
    base = _keyframes(t, [(1.0, {}), (3.0, start), (13.0, start), (15.0, {})])
    phase = 2 * np.pi * np.clip(t - 3.0, 0.0, 10.0) / 5.0  # two circles in 10 s
    return _add(base, {
        "right_shoulder_Z": 25.0 * np.sin(phase),
        "right_shoulder_X": 20.0 * (np.cos(phase) - 1.0),
    })


def _push_pull(t: FloatArray) -> Angles:
    """Both hands pushed forward to arm's length (shoulders 100 deg, elbows 10 deg) and pulled back to the chest
    (shoulders 0, elbows 110 deg) at 0.7 Hz for 8 s, the trunk leaning up to 20 deg into each push: a vigorous
    push-pull (sawing, pushing a cart), hands at up to 1.0 m/s. Replayed twice as fast it is the paper's
    Figure 2 experiment (tests/teleop/test_session.py)."""
    base = _both({"right_shoulder_Z": 50.0, "right_elbow_Z": 60.0})
    hold = _keyframes(t, [(1.0, {}), (2.5, base), (10.5, base), (12.0, {})])
    envelope = _smooth(t, 2.5, 3.0) * (1.0 - _smooth(t, 10.0, 10.5))
    s = np.sin(2 * np.pi * 0.7 * (t - 2.5))
    return _add(hold, {"right_shoulder_Z": 50.0 * envelope * s, "left_shoulder_Z": 50.0 * envelope * s,
                       "right_elbow_Z": -50.0 * envelope * s, "left_elbow_Z": -50.0 * envelope * s,
                       "middle_lumbar_Z": 20.0 * envelope * (s + 1) / 2})


#: The recordings, by name (the first eight are paper Table II's, benchmarks/teleop_table2.py).
MOTIONS: Mapping[str, SyntheticMotion] = {
    m.name: m
    for m in (
        SyntheticMotion("reach_forward", "right, left, then both arms reach forward at shoulder height", "A",
                        12.0, 50.0, _reach_forward),
        SyntheticMotion("reach_sideways", "right, left, then both arms raised sideways to shoulder height", "B",
                        12.0, 50.0, _reach_sideways),
        SyntheticMotion("waving", "right arm raised, forearm up, waving at 1.2 Hz", "C", 12.0, 50.0, _waving),
        SyntheticMotion("crossing_arms", "both forearms crossed in front of the chest, held 6 s", "A", 12.0, 50.0,
                        _crossing_arms),
        SyntheticMotion("arms_down", "arms hanging along the body, swaying: the hands would enter TALOS' hips",
                        "B", 12.0, 50.0, _arms_down),
        SyntheticMotion("head_turning", "head yaws +-60 deg, then nods +-20 deg", "C", 12.0, 50.0, _head_turning),
        SyntheticMotion("bimanual_lift", "squat, both hands low in front, stand up lifting them to the chest", "A",
                        12.0, 50.0, _bimanual_lift),
        SyntheticMotion("slow_circle", "right hand draws two slow circles (5 s each) in front of the body", "B",
                        16.0, 50.0, _slow_circle),
        SyntheticMotion("push_pull", "both hands pushed forward and pulled back to the chest at 0.7 Hz, leaning "
                        "into each push", "A", 13.0, 50.0, _push_pull),
    )
}


def motion_configurations(motion: SyntheticMotion) -> tuple[HumanModel, FloatArray, FloatArray]:
    """``(human model of the operator, times (N,), configurations (N, nq))`` of a motion, in the model world
    (z-up), the operator's feet frame at his position and heading."""
    operator = OPERATORS[motion.operator]
    human = HumanModel(operator.lengths())
    times = np.arange(int(round(motion.duration * motion.rate)) + 1) / motion.rate
    angles = motion.angles(times)
    T_feet = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, operator.heading),
                     np.array([operator.position[0], operator.position[1], 0.0]))
    qs = np.empty((len(times), human.model.nq))
    for i in range(len(times)):
        q = human.configuration_from_angles({j: np.radians(v[i]) for j, v in angles.items()})
        qs[i] = human.place_feet(q, T_feet)
    return human, times, qs


def generate_recordings(out_dir: str | Path, names: Sequence[str] | None = None) -> list[Path]:
    """Write the synthetic recordings (all, or ``names``) as ``<out_dir>/<name>.bvh``; returns the paths.

    Deterministic: the same files every time.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names if names is not None else list(MOTIONS):
        motion = MOTIONS[name]
        human, _, qs = motion_configurations(motion)
        path = write_bvh(out / f"{name}.bvh", human.bvh_skeleton(0.01), human.bvh_motion(qs, 0.01),
                         1.0 / motion.rate, decimals=2)
        paths.append(path)
    return paths
