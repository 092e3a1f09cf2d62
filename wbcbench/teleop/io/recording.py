"""One container for recorded motion capture, whatever the file format."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ...errors import ConfigError, UnknownNameError
from .. import _rotations as rot

__all__ = ["MocapRecording", "PoseFrame"]

FloatArray = npt.NDArray[np.float64]


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class PoseFrame(NamedTuple):
    """The operator at one instant, in the recording's (or stream's) world frame.

    Attributes:
        time: time of the sample [s] (recording time, or the sender's timestamp for a live stream).
        positions: segment name -> world position of the segment origin (3,) [m].
        orientations: segment name -> world orientation, unit quaternion (x, y, z, w).
        joint_angles: channel name -> angle [rad] (empty when the source has none).
        valid: False when the sample is held outside the recording or from a stale stream.
    """

    time: float
    positions: Mapping[str, FloatArray]
    orientations: Mapping[str, FloatArray]
    joint_angles: Mapping[str, float]
    valid: bool


@dataclass(frozen=True, eq=False)
class MocapRecording:
    """Recorded motion capture: per-segment world poses and/or joint angles over time.

    Every reader (:func:`~wbcbench.teleop.read_bvh`, :func:`~wbcbench.teleop.read_mvnx`,
    :func:`~wbcbench.teleop.read_pose_csv`) returns one. Arrays are read-only.

    Attributes:
        source: the file it was read from ("" when built in memory).
        frame_rate: nominal frame rate [Hz].
        times: (N,) strictly increasing timestamps [s].
        segments: (S,) segment names, as in the file (see :mod:`wbcbench.teleop.io.segments` for the canonical ones).
        parents: (S,) index of each segment's parent in ``segments``, -1 for a root or when unknown.
        positions: (N, S, 3) world positions of the segment origins [m], in the recording's world frame (its
            axes are whatever the suit or the exporter used: BVH is usually y-up, Xsens z-up).
        orientations: (N, S, 4) world orientations of the segments, unit quaternions (x, y, z, w).
        joint_names: (J,) joint-angle channel names: ``"<joint>:<X|Y|Z>rotation"`` for BVH,
            ``"<joint>:<x|y|z>"`` for MVNX.
        joint_angles: (N, J) joint angles [rad] (J may be 0).
        up_axis: the recording's vertical axis, "x", "y" or "z" (informative: the alignment does not use it).
        length_unit_note: how a BVH file's length unit was chosen (detected or given), "" for other formats.
        conventions: what :func:`~wbcbench.teleop.io.conventions.detect_conventions` found in the data (length
            unit and its confidence, up and forward axes, rotation orders, rest pose, naming family), as plain
            values; empty when the recording was not read through :func:`~wbcbench.teleop.load_recording`.

    Raises:
        ConfigError: inconsistent shapes, non-increasing or non-finite times, non-unit quaternions (the message
            names ``source``).
    """

    source: str
    frame_rate: float
    times: FloatArray
    segments: tuple[str, ...]
    positions: FloatArray
    orientations: FloatArray
    parents: tuple[int, ...] = ()
    joint_names: tuple[str, ...] = ()
    joint_angles: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    up_axis: str = "z"
    length_unit_note: str = ""
    conventions: Mapping = field(default_factory=dict)

    def __post_init__(self) -> None:
        err = self._error
        times = np.array(self.times, dtype=float).reshape(-1)
        n, s = len(times), len(self.segments)
        if n == 0:
            raise err("has no frame")
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0.0):
            raise err("timestamps must be finite and strictly increasing")
        if not (np.isfinite(self.frame_rate) and self.frame_rate > 0.0):
            raise err(f"frame rate must be > 0, got {self.frame_rate!r}")
        if len(set(self.segments)) != s:
            raise err("segment names must be unique")
        positions = np.array(self.positions, dtype=float)
        orientations = np.array(self.orientations, dtype=float)
        if positions.shape != (n, s, 3):
            raise err(f"positions have shape {positions.shape}, expected {(n, s, 3)}")
        if orientations.shape != (n, s, 4):
            raise err(f"orientations have shape {orientations.shape}, expected {(n, s, 4)}")
        if s:
            norms = np.linalg.norm(orientations, axis=-1)
            ok = np.isnan(norms) | (np.abs(norms - 1.0) < 1e-3)
            if not np.all(ok):
                raise err("orientations must be unit quaternions (x, y, z, w)")
        parents = tuple(int(p) for p in self.parents) if self.parents else (-1,) * s
        if len(parents) != s or any(p < -1 or p >= s for p in parents):
            raise err("parents must give one index in [-1, S) per segment")
        joint_angles = np.array(self.joint_angles, dtype=float)
        if len(self.joint_names) == 0:
            joint_angles = np.zeros((n, 0))
        if joint_angles.shape != (n, len(self.joint_names)):
            raise err(f"joint angles have shape {joint_angles.shape}, expected {(n, len(self.joint_names))}")
        if self.up_axis not in ("x", "y", "z"):
            raise err(f"up_axis must be x, y or z, got {self.up_axis!r}")
        object.__setattr__(self, "times", _frozen(times))
        object.__setattr__(self, "segments", tuple(self.segments))
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "positions", _frozen(positions))
        object.__setattr__(self, "orientations", _frozen(orientations))
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "joint_angles", _frozen(joint_angles))
        object.__setattr__(self, "_index", MappingProxyType({name: i for i, name in enumerate(self.segments)}))

    def _error(self, message: str) -> ConfigError:
        return ConfigError(message, file=self.source or "<recording>")

    # ------------------------------------------------------------------------------------------- shape
    @property
    def n_frames(self) -> int:
        """Number of frames N."""
        return len(self.times)

    @property
    def duration(self) -> float:
        """Last minus first timestamp [s]."""
        return float(self.times[-1] - self.times[0])

    @property
    def has_joint_angles(self) -> bool:
        """True when the recording carries joint-angle channels."""
        return len(self.joint_names) > 0

    def segment_index(self, name: str) -> int:
        """Index of segment ``name``; :class:`~wbcbench.errors.UnknownNameError` listing the segments otherwise."""
        try:
            return self._index[name]  # type: ignore[attr-defined]
        except KeyError:
            raise UnknownNameError("segment", name, self.segments, file=self.source or None) from None

    def has_segment(self, name: str) -> bool:
        """True when the recording has a segment called ``name``."""
        return name in self._index  # type: ignore[attr-defined]

    def position(self, name: str) -> FloatArray:
        """World positions (N, 3) [m] of segment ``name`` (read-only view)."""
        return self.positions[:, self.segment_index(name)]

    # -------------------------------------------------------------------------------------- sampling
    def frame(self, index: int) -> PoseFrame:
        """Frame ``index`` as a :class:`PoseFrame` (always valid)."""
        index = int(index)
        if not -self.n_frames <= index < self.n_frames:
            raise IndexError(f"frame {index} out of range [0, {self.n_frames})")
        return self._pose_frame(
            float(self.times[index]), self.positions[index], self.orientations[index], self.joint_angles[index], True
        )

    def frame_at(self, t: float) -> PoseFrame:
        """The operator at time ``t`` [s]: positions and joint angles interpolated linearly, orientations by
        slerp. Outside ``[times[0], times[-1]]`` the first or last frame is held and ``valid`` is False."""
        times = self.times
        valid = bool(times[0] <= t <= times[-1])
        tc = float(np.clip(t, times[0], times[-1]))
        i = int(np.searchsorted(times, tc, side="right")) - 1
        i = min(max(i, 0), len(times) - 1)
        if i == len(times) - 1:
            return self._pose_frame(float(t), self.positions[i], self.orientations[i], self.joint_angles[i], valid)
        alpha = (tc - times[i]) / (times[i + 1] - times[i])
        p = (1.0 - alpha) * self.positions[i] + alpha * self.positions[i + 1]
        q0, q1 = self.orientations[i], self.orientations[i + 1]
        finite = np.all(np.isfinite(q0), axis=-1) & np.all(np.isfinite(q1), axis=-1)
        q = np.full_like(q0, np.nan)
        if np.any(finite):
            q[finite] = rot.slerp(q0[finite], q1[finite], alpha)
        a = (1.0 - alpha) * self.joint_angles[i] + alpha * self.joint_angles[i + 1]
        return self._pose_frame(float(t), p, q, a, valid)

    def _pose_frame(
        self, t: float, p: FloatArray, q: FloatArray, a: FloatArray, valid: bool
    ) -> PoseFrame:
        positions = {name: p[k].copy() for k, name in enumerate(self.segments)}
        orientations = {name: q[k].copy() for k, name in enumerate(self.segments)}
        angles = {name: float(a[k]) for k, name in enumerate(self.joint_names)}
        return PoseFrame(t, positions, orientations, angles, valid)

    def with_source(self, source: str) -> "MocapRecording":
        """The same recording naming another source file."""
        return MocapRecording(
            source=source, frame_rate=self.frame_rate, times=self.times, segments=self.segments,
            positions=self.positions, orientations=self.orientations, parents=self.parents,
            joint_names=self.joint_names, joint_angles=self.joint_angles, up_axis=self.up_axis,
            length_unit_note=self.length_unit_note, conventions=self.conventions,
        )

    def __repr__(self) -> str:
        return (
            f"MocapRecording(source={self.source!r}, frames={self.n_frames}, frame_rate={self.frame_rate:g}, "
            f"segments={len(self.segments)}, joint_channels={len(self.joint_names)})"
        )


def parents_from_names(segments: Sequence[str], parent_names: Mapping[str, str | None]) -> tuple[int, ...]:
    """Parent indices for ``segments`` from a name -> parent-name table (-1 when absent)."""
    index = {name: i for i, name in enumerate(segments)}
    return tuple(index.get(parent_names.get(name) or "", -1) for name in segments)
