"""An operator who walks, turns, jumps or sits down while the robot stands: the operator's translation and yaw are
taken out of the recording ("feet fixed"), so that the hands and head are retargeted as if the operator's pelvis
stayed where it was in the first frame (the calibration frame, which is left unchanged); what the upper body does
relative to the pelvis (reaching, bowing, turning the head) is kept.

Per frame k, in the suit's world with up vector u (the recording's detected up axis): c_k is the pelvis position,
theta_k the rotation about u that takes the first frame's heading (the horizontal vector from the right to the left
hip) to frame k's. Every segment position p and orientation R becomes

    p' = R_u(-theta_k) (p - c_k) + c_0,        R' = R_u(-theta_k) R

``mode="auto"`` does this only when the operator moves (the pelvis travels more than ``travel_threshold``
horizontally or vertically, or turns more than ``yaw_threshold``), leaving an operator who stands on the spot bit
for bit untouched.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from .. import _rotations as rot
from ..io.recording import MocapRecording

__all__ = ["LOCOMOTION_MODES", "OperatorMotion", "fix_feet"]

#: `locomotion` values: take the operator's walk out always, when the operator moves, or never
LOCOMOTION_MODES = ("feet_fixed", "auto", "off")


@dataclass(frozen=True)
class OperatorMotion:
    """How far the operator moved in the recording and whether it was taken out.

    Attributes:
        travel_m: the pelvis's largest distance from its first-frame position [m].
        yaw_deg: the largest heading change from the first frame [deg].
        applied: whether the translation and yaw were taken out.
        mode: the `locomotion` mode asked for.
    """

    travel_m: float
    yaw_deg: float
    applied: bool
    mode: str

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _hold_nan(x: np.ndarray) -> np.ndarray:
    """Rows with a NaN replaced by the previous finite row (the first finite one at the start)."""
    x = np.array(x, dtype=float)
    ok = np.isfinite(x).all(axis=1)
    if not ok.any():
        return x
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(ok))
    idx[:first] = first
    return x[idx]


def fix_feet(recording: MocapRecording, names: dict, up: str, mode: str = "auto", *,
             travel_threshold: float = 0.25, yaw_threshold: float = 20.0) -> tuple[MocapRecording, OperatorMotion]:
    """The recording with the operator's horizontal translation and yaw taken out (module docstring).

    Args:
        recording: positions in metres.
        names: canonical segment -> the recording's segment (needs Pelvis, LeftUpperLeg, RightUpperLeg).
        up: the signed up axis of the recording's world ("+y", "-z" ...).
        mode: one of :data:`LOCOMOTION_MODES`.

    Raises:
        ConfigError: an unknown mode.
    """
    if mode not in LOCOMOTION_MODES:
        raise ConfigError(f"locomotion '{mode}': use {', '.join(LOCOMOTION_MODES)}", key="locomotion")
    need = ("Pelvis", "LeftUpperLeg", "RightUpperLeg")
    if any(names.get(k) not in recording.segments for k in need) or len(up) != 2:
        return recording, OperatorMotion(float("nan"), float("nan"), False, mode)
    u = np.eye(3)["xyz".index(up[1])] * (1.0 if up[0] == "+" else -1.0)
    pelvis = _hold_nan(recording.position(names["Pelvis"]))
    left = _hold_nan(recording.position(names["LeftUpperLeg"]) - recording.position(names["RightUpperLeg"]))
    c = pelvis
    h = left - np.outer(left @ u, u)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta = np.arctan2(np.cross(h[0], h) @ u, h @ h[0])
    travel = float(np.nanmax(np.linalg.norm(c - c[0], axis=1)))
    yaw = float(np.degrees(np.nanmax(np.abs(theta))))
    moved = travel > travel_threshold or yaw > yaw_threshold
    applied = mode == "feet_fixed" or (mode == "auto" and moved)
    motion = OperatorMotion(travel, yaw, applied, mode)
    if not applied:
        return recording, motion
    # R_u(-theta) per frame (Rodrigues about u)
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s, co = np.sin(-theta)[:, None, None], np.cos(-theta)[:, None, None]
    R = np.eye(3)[None] + s * K[None] + (1.0 - co) * (K @ K)[None]  # (N, 3, 3)
    P = np.asarray(recording.positions, dtype=float)
    P2 = np.einsum("nij,nsj->nsi", R, P - c[:, None, :]) + c[0][None, None, :]
    Q = np.asarray(recording.orientations, dtype=float)
    finite = np.isfinite(Q).all(axis=2)
    Rq = rot.to_matrix(np.where(finite[..., None], Q, [0.0, 0.0, 0.0, 1.0]))
    Q2 = rot.from_matrix(np.einsum("nij,nsjk->nsik", R, Rq))
    Q2[~finite] = np.nan
    return dataclasses.replace(recording, positions=P2, orientations=Q2), motion
