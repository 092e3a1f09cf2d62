"""Shared fixtures for the teleoperation tests."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.teleop import HumanModel, MocapRecording
from wbcbench.teleop.segments import MVN_PARENTS


@pytest.fixture(scope="session")
def human() -> HumanModel:
    return HumanModel()


def make_recording(n: int = 40, rate: float = 50.0, seed: int = 0, source: str = "") -> MocapRecording:
    """A small recording with random smooth poses for four MVN segments, and three joint channels (one MVNX joint)."""
    rng = np.random.default_rng(seed)
    segments = ("Pelvis", "T8", "LeftHand", "RightHand")
    t = np.arange(n) / rate
    positions = rng.normal(size=(1, 4, 3)) + 0.1 * np.sin(t)[:, None, None] * rng.normal(size=(1, 4, 3))
    quats = rng.normal(size=(n, 4, 4))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    quats[quats[..., 3] < 0] *= -1
    angles = np.stack([np.sin(t), np.cos(t), 0.5 * t], axis=1)
    return MocapRecording(
        source=source, frame_rate=rate, times=t, segments=segments,
        parents=tuple(segments.index(MVN_PARENTS[s]) if MVN_PARENTS[s] in segments else -1 for s in segments),
        positions=positions, orientations=quats, joint_names=("jA:x", "jA:y", "jA:z"), joint_angles=angles,
    )


def assert_one_line_error(excinfo, *fragments: str) -> None:
    """The error is one line and contains every fragment (file name, line number, element...)."""
    message = str(excinfo.value)
    assert "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
