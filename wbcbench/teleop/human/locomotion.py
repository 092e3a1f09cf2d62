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
for bit untouched. ``mode="stepping"`` takes the walk out of the upper body's references as ``feet_fixed`` does
(they are then carried by the robot's own walk) and the operator's steps are read from the feet
(`detect_steps`), for the robot to take them (wbcbench/teleop/session/stepping.py).

Step detection (`detect_steps`), per foot segment (the ankle), in the suit's world: the foot's height above its
own standing height (the 5th percentile of its height over the recording) and its horizontal speed (central
differences, averaged over `smoothing` s). The foot is *down* from the first frame on while low and slow; it
lifts off when it rises more than ``height_off`` above its standing height or moves faster than ``speed_off``,
and is down again once both are back under ``height_on`` and ``speed_on`` (hysteresis: ``*_on`` < ``*_off``)
for at least ``min_stance`` s. Each stance after a lift-off whose ankle lies more than ``min_move`` from the
previous stance's (or is turned more than ``min_turn`` about the vertical) is a step: its touch-down time, the
median ankle position and foot heading change over the stance's first ``settle`` s.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from .. import _rotations as rot
from ..io.conventions import up_vector
from ..io.recording import MocapRecording

__all__ = ["LOCOMOTION_MODES", "OperatorMotion", "OperatorStep", "StepDetection", "detect_steps", "fix_feet"]

#: `locomotion` values: take the operator's walk out always, when the operator moves, or never; or take it out of
#: the upper body and have the robot step where the operator steps
LOCOMOTION_MODES = ("feet_fixed", "auto", "off", "stepping")


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
    u = up_vector(up)
    pelvis = _hold_nan(recording.position(names["Pelvis"]))
    left = _hold_nan(recording.position(names["LeftUpperLeg"]) - recording.position(names["RightUpperLeg"]))
    c = pelvis
    h = left - np.outer(left @ u, u)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta = np.arctan2(np.cross(h[0], h) @ u, h @ h[0])
    travel = float(np.nanmax(np.linalg.norm(c - c[0], axis=1)))
    yaw = float(np.degrees(np.nanmax(np.abs(theta))))
    moved = travel > travel_threshold or yaw > yaw_threshold
    applied = mode in ("feet_fixed", "stepping") or (mode == "auto" and moved)
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


@dataclass(frozen=True)
class OperatorStep:
    """One step of the operator (`detect_steps`).

    Attributes:
        side: "left" or "right".
        lift_off, touch_down: source times [s] the foot left the ground and was down again.
        p_suit: (3,) the ankle (foot segment origin) in its new stance, in the suit's world [m].
        p_suit_before: (3,) the ankle in the stance before [m].
        yaw: the foot's heading change about the up axis from the first frame [rad].
    """

    side: str
    lift_off: float
    touch_down: float
    p_suit: np.ndarray
    p_suit_before: np.ndarray
    yaw: float


@dataclass(frozen=True)
class StepDetection:
    """Thresholds of `detect_steps` (module docstring): heights [m] above the standing height, horizontal speeds
    [m/s], durations [s], min_move [m], min_turn [rad]."""

    height_on: float = 0.03
    height_off: float = 0.05
    speed_on: float = 0.3
    speed_off: float = 0.6
    min_stance: float = 0.08
    settle: float = 0.15
    smoothing: float = 0.05
    min_move: float = 0.03
    min_turn: float = 0.10


def _foot_yaw(quats: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(N,) heading change about u of each orientation from the first finite one [rad] (the rotation R_k R_0^T
    turning some horizontal axis: the one of R_0's axes most horizontal)."""
    finite = np.isfinite(quats).all(axis=1)
    R = rot.to_matrix(np.where(finite[:, None], quats, [0.0, 0.0, 0.0, 1.0]))
    first = int(np.argmax(finite)) if finite.any() else 0
    axes = R[first].T  # rows: the segment's axes in the world
    a = axes[int(np.argmin(np.abs(axes @ u)))]  # the most horizontal one, followed over time
    d = np.einsum("nij,j->ni", R @ R[first].T, a)
    d -= np.outer(d @ u, u)
    a_h = a - (a @ u) * u
    yaw = np.arctan2(np.cross(a_h, d) @ u, d @ a_h)
    yaw = np.unwrap(yaw)
    yaw[~finite] = np.nan
    return yaw


def detect_steps(recording: MocapRecording, names: dict, up: str,
                 config: StepDetection | None = None) -> list[OperatorStep]:
    """The operator's steps in a recording (module docstring), in order of touch-down.

    Args:
        recording: positions in metres.
        names: canonical segment -> the recording's segment (needs LeftFoot and RightFoot).
        up: the signed up axis of the recording's world ("+y", "-z" ...).

    Raises:
        ConfigError: a foot segment is missing.
    """
    cfg = config or StepDetection()
    missing = [k for k in ("LeftFoot", "RightFoot") if names.get(k) not in recording.segments]
    if missing or len(up) != 2:
        raise ConfigError(f"locomotion 'stepping' needs the foot segments {missing or ['LeftFoot', 'RightFoot']} "
                          "and a known up axis", file=getattr(recording, "source", None) or None, key="locomotion")
    u = up_vector(up)
    t = np.asarray(recording.times, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    w = max(1, int(round(cfg.smoothing / dt)))
    steps = []
    for side, seg in (("left", names["LeftFoot"]), ("right", names["RightFoot"])):
        p = _hold_nan(recording.position(seg))
        h = p @ u
        h = h - np.percentile(h, 5.0)
        hor = p - np.outer(p @ u, u)
        v = np.linalg.norm(np.gradient(hor, t, axis=0), axis=1) if len(t) > 1 else np.zeros(len(t))
        v = np.convolve(v, np.ones(w) / w, mode="same")
        yaw = _foot_yaw(np.asarray(recording.orientations[:, recording.segment_index(seg)], dtype=float), u)
        down = np.zeros(len(t), dtype=bool)
        state = bool(h[0] < cfg.height_off and v[0] < cfg.speed_off)
        for k in range(len(t)):
            if state and (h[k] > cfg.height_off or v[k] > cfg.speed_off):
                state = False
            elif not state and h[k] < cfg.height_on and v[k] < cfg.speed_on:
                state = True
            down[k] = state
        # stance phases [a, b): down, at least min_stance long (or reaching the recording's end)
        edges = np.flatnonzero(np.diff(np.r_[0, down.astype(int), 0]))
        phases = [(a, b) for a, b in zip(edges[::2], edges[1::2])
                  if t[b - 1] - t[a] >= cfg.min_stance or (b == len(t) and a > 0)]
        prev = None
        for a, b in phases:
            n = max(1, int(round(cfg.settle / dt)))
            stance = slice(a, min(b, a + n))
            here = np.median(p[stance], axis=0)
            heading = float(np.nanmedian(yaw[stance]))
            if prev is not None and a > prev[2]:
                move = np.linalg.norm((here - prev[0]) - ((here - prev[0]) @ u) * u)
                if move > cfg.min_move or abs(heading - prev[1]) > cfg.min_turn:
                    steps.append(OperatorStep(side, float(t[prev[2]]), float(t[a]), here, prev[0], heading))
                    prev = (here, heading, b)
                    continue
            if prev is None or a > prev[2]:
                prev = (here, heading, b) if prev is None else (prev[0], prev[1], b)
    steps.sort(key=lambda s: s.touch_down)
    return steps
