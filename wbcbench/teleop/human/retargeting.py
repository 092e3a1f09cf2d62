"""Retargeting (paper 004, Section V): operator segment poses -> hand and head references for the robot.

Calibration, once, on one frame of the operator (default: the first frame of a recording, the first live frame of a
stream), which should show the operator standing, arms along the body (the robot's reference posture):

1. pose the operator's human model (:class:`~wbcbench.teleop.HumanModel`, scaled to the operator) from the
   frame's joint angles when the source has channels the model knows ("joint_angles"); otherwise fit the model to
   the segment positions ("fit");
2. move the model rigidly so that its feet overlay the robot's feet in the robot's reference posture: the
   :func:`~wbcbench.teleop.human.model.feet_frame` of the model's soles (ankles lowered by the ankle height)
   coincides with the feet frame of the robot's sole frames (:func:`robot_feet_frame`: midpoint of the soles,
   heading from the right sole to the left one, z the world vertical). An operator caught mid-stride (the feet's
   direction more than 45 deg from the hips') takes the hips' heading (``stride_heading``, on by default): the
   feet's then points along the walk, the operator would be calibrated turned by that angle (17 of 37
   real-capture clips, 20 to 89 deg) and a walk would map sideways;
3. estimate the rigid transform ``T_world_suit`` from the suit's world frame to the robot's world with Umeyama's
   method on the 15 keypoints (segment origins) of the frame and of the placed model. If the posture from the
   joint angles leaves an RMS residual above ``fit_threshold`` (angles in another convention, sensor drift), the
   model is refined by fitting it to the aligned positions and steps 2-3 are redone ("joint_angles+fit");
4. record, per effector, the rotation offset ``R_off = (R_world_suit R_suit_segment)^T R_world_effector(q_ref)``
   so that at the calibration instant each reference orientation equals the robot's own in its reference posture.

Then at time ``t``, for each effector (left_hand <- LeftHand, right_hand <- RightHand, head <- Head; the hand
segments' origins are the wrists, as in the paper)::

    p_world   = T_world_suit p_suit(t)
    p_ref     = c + k (p_world - c)                 c: origin of the robot's feet frame (on the ground)
    R_ref     = R_world_suit R_suit(t) R_off
    p_ref     <- clamp(p_ref) to the effector's ReachShell (flagged in ``clamped``)

with ``k`` the robot/human proportion: ``"shoulders"`` (default) is the robot's shoulder height (mean height of the
hands' chain roots, TALOS ``arm_*_1_joint``, in the reference posture) over the operator model's standing
shoulder height, both above the feet frame; ``"head"`` uses the head frame and the head segment; a number is used
as given (1.0 is the paper's plain overlay). Scaling about the feet keeps the operator's feet on the robot's and
maps the operator's shoulder height to the robot's.

``valid`` is False when the source has no data yet, when ``t`` lies outside the recording (the first or last frame
is held) or the stream is stale (the last frame is held), or when an effector segment is missing in the frame.

The skeleton watchdog (`watch_skeleton`, on for live streams): the calibration frame's bone lengths (`BONES`: the
distances between the origins of rigidly linked segments, upper arm, forearm, thigh, shank) are the operator's;
a later frame whose segments lost one of them, or whose bone differs from the calibration's by more than the
tolerance (relative), means the stream switched skeleton (another performer, another suit or exporter, a
re-calibrated system). The retargeting cannot map that skeleton with this calibration, so every sample from then
on is invalid (the source's loss policy holds the robot) and `watchdog` says why, once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ...errors import ConfigError, WbcError
from ...side import Side
from .. import _rotations as rot
from .model import HumanModel, feet_frame
from ..io.recording import MocapRecording, PoseFrame
from ..io.segments import KEYPOINTS, canonical_name
from .umeyama import SimilarityTransform, umeyama
from .workspace import ReachShell, chain_joints, reach_shell

__all__ = [
    "EFFECTORS",
    "EFFECTOR_SEGMENTS",
    "PoseSource",
    "Calibration",
    "TeleopSample",
    "Retargeter",
    "effector_chains",
    "robot_workspaces",
    "robot_feet_frame",
]

FloatArray = npt.NDArray[np.float64]

#: Reference names produced by the retargeting.
EFFECTORS: tuple[str, ...] = ("left_hand", "right_hand", "head")
#: Effector -> operator segment.
EFFECTOR_SEGMENTS: Mapping[str, str] = MappingProxyType(
    {"left_hand": "LeftHand", "right_hand": "RightHand", "head": "Head"}
)
#: The bones the skeleton watchdog measures: pairs of canonical segments whose origins are rigidly linked.
BONES: tuple[tuple[str, str], ...] = (
    ("LeftUpperArm", "LeftForeArm"), ("LeftForeArm", "LeftHand"), ("RightUpperArm", "RightForeArm"),
    ("RightForeArm", "RightHand"), ("LeftUpperLeg", "LeftLowerLeg"), ("LeftLowerLeg", "LeftFoot"),
    ("RightUpperLeg", "RightLowerLeg"), ("RightLowerLeg", "RightFoot"))
# Torso-ish keypoints for the first rough alignment before a fit (nearly rigid while standing).
_TRUNK = ("Pelvis", "T8", "Head", "LeftUpperArm", "RightUpperArm", "LeftUpperLeg", "RightUpperLeg")


class PoseSource(Protocol):
    """Anything that gives the operator at time ``t``: a :class:`~wbcbench.teleop.MocapRecording` or a
    :class:`~wbcbench.teleop.UdpPoseReceiver`."""

    def frame_at(self, t: float) -> PoseFrame | None: ...


@dataclass(frozen=True)
class Calibration:
    """What the calibration found.

    Attributes:
        time: source time of the calibration frame [s].
        method: "joint_angles", "joint_angles+fit" or "fit" (how the human model was posed).
        T_world_suit: rigid transform from the suit's world frame to the robot's world.
        rms: Umeyama residual over the keypoints [m].
        q_human: the human model configuration, feet on the robot's feet (nq of the human model).
        proportion: robot/human scale ``k``.
        center: (3,) scaling centre ``c``, the robot's feet frame origin [m].
        rotation_offsets: effector -> ``R_off`` (3, 3).
    """

    time: float
    method: str
    T_world_suit: SimilarityTransform
    rms: float
    q_human: FloatArray
    proportion: float
    center: FloatArray
    rotation_offsets: Mapping[str, FloatArray]


class TeleopSample(NamedTuple):
    """References at one instant.

    Attributes:
        time: the time asked for [s].
        references: effector name -> ``T_world_ref`` (pin.SE3).
        valid: see the module docstring.
        clamped: effector name -> True when its position was clamped to the reachable workspace.
    """

    time: float
    references: dict[str, pin.SE3]
    valid: bool
    clamped: dict[str, bool]


def robot_feet_frame(robot: Any, q: FloatArray | None = None) -> pin.SE3:
    """Feet frame of the robot's sole frames (profile ``feet``) at ``q`` (default the reference posture), with
    the world vertical as z: the robot stands on a horizontal floor (TALOS' half-sitting soles are tilted by
    1.7 mrad in the model, an artefact of the reference configuration, not a slope to copy)."""
    model, data = robot.model, robot.model.createData()
    q = robot.q0 if q is None else q
    pin.framesForwardKinematics(model, data, q)
    poses = [data.oMf[model.getFrameId(robot.profile.feet[side].frame)] for side in (Side.LEFT, Side.RIGHT)]
    up = np.array([0.0, 0.0, 1.0])
    return feet_frame(poses[0].translation, poses[1].translation, up, up)


def _effector_frames(robot: Any) -> dict[str, str]:
    profile = robot.profile
    return {"left_hand": profile.hands[Side.LEFT], "right_hand": profile.hands[Side.RIGHT], "head": profile.head_frame}


def effector_chains(robot: Any) -> dict[str, tuple[str, list[int]]]:
    """Effector name -> (its frame, the joint ids of its own chain, root first): a hand's after the torso frame's
    joint, the head's after the floating base (:func:`~wbcbench.teleop.human.workspace.chain_joints`)."""
    model = robot.model
    torso_joint = model.frames[model.getFrameId(robot.profile.torso_frame)].parentJoint
    return {name: (frame, chain_joints(model, frame, 1 if name == "head" else torso_joint))
            for name, frame in _effector_frames(robot).items()}


def robot_workspaces(
    robot: Any, *, samples: int = 2048, seed: int = 0, hand_margin: float = 0.0, head_margin: float = 0.10,
    head_tilt_margin: float = 0.0,
) -> dict[str, ReachShell]:
    """A :class:`~wbcbench.teleop.ReachShell` per effector (see :mod:`wbcbench.teleop.human.workspace`), about
    its :func:`effector_chains` chain."""
    out = {}
    for name, (frame, joints) in effector_chains(robot).items():
        head = name == "head"
        out[name] = reach_shell(robot.model, robot.q0, frame, joints, samples=samples, seed=seed,
                                margin=head_margin if head else hand_margin,
                                tilt_margin=head_tilt_margin if head else None)
    return out


class Retargeter:
    """Hand and head references for the robot from an operator's motion (see the module docstring).

    Args:
        robot: a :class:`~wbcbench.robots.Robot` (its model, reference posture ``q0`` and profile: ``hands``,
            ``head_frame``, ``feet``, ``torso_frame``).
        source: a :class:`~wbcbench.teleop.MocapRecording` or any :class:`PoseSource` (e.g. a live
            :class:`~wbcbench.teleop.UdpPoseReceiver`).
        human: the operator's model; default: scaled from ``source`` when it is a recording (segment lengths), else
            the default 1.80 m model.
        proportion: ``"shoulders"``, ``"head"`` or a number > 0 (robot/human scale ``k``).
        calibration_time: source time of the calibration frame; default the recording's first frame, or the first
            live frame.
        workspaces: effector -> ReachShell; default :func:`robot_workspaces`. Pass ``{}`` to disable clamping.
        segment_map: canonical segment name -> source segment name, when :func:`canonical_name` cannot guess.
        fit_threshold: Umeyama RMS residual [m] above which a posture from joint angles is refined by a fit.
        stride_heading: the model's feet frame takes the hips' heading when the calibration frame catches the
            operator in a stride (`HumanModel.feet_frame`, module docstring); False: the feet's direction always.

    Raises:
        ConfigError: bad ``proportion``; the calibration frame lacks an effector segment or has < 4 keypoints.
    """

    def __init__(
        self,
        robot: Any,
        source: PoseSource,
        *,
        human: HumanModel | None = None,
        proportion: str | float = "shoulders",
        calibration_time: float | None = None,
        workspaces: Mapping[str, ReachShell] | None = None,
        segment_map: Mapping[str, str] | None = None,
        fit_threshold: float = 0.03,
        stride_heading: bool = True,
    ) -> None:
        self._robot = robot
        self._source = source
        self.segment_mapping = None
        if segment_map is None and isinstance(source, MocapRecording):
            from ..io.skeleton_map import map_segments  # names first, then the skeleton's chains

            self.segment_mapping = map_segments(source.segments, source.parents, source.source)
            segment_map = self.segment_mapping.names
        if human is None:
            human = (
                HumanModel.from_recording(source, segment_map=segment_map)
                if isinstance(source, MocapRecording)
                else HumanModel()
            )
        self._human = human
        if isinstance(proportion, str):
            if proportion not in ("shoulders", "head"):
                raise ConfigError(f"proportion must be 'shoulders', 'head' or a number > 0, got {proportion!r}",
                                  key="proportion")
        elif not (np.isfinite(proportion) and proportion > 0):
            raise ConfigError(f"proportion must be > 0, got {proportion!r}", key="proportion")
        self._proportion_spec = proportion
        self._segment_map = dict(segment_map) if segment_map is not None else None
        self._fit_threshold = float(fit_threshold)
        self._stride_heading = bool(stride_heading)
        self._frames = _effector_frames(robot)
        model = robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, robot.q0)
        self._reference_poses = {
            name: pin.SE3(data.oMf[model.getFrameId(frame)]) for name, frame in self._frames.items()
        }
        self._T_world_feet = robot_feet_frame(robot)
        self._workspaces = dict(robot_workspaces(robot) if workspaces is None else workspaces)
        self._calibration: Calibration | None = None
        #: the skeleton watchdog (`watch_skeleton`): off, the calibration's bones, the last frame checked, and
        #: once it has tripped {time, frame_time, reason}
        self._watch_tolerance = 0.0
        self._calibration_bones: dict[tuple[str, str], float] = {}
        self._watched_frame: PoseFrame | None = None
        self.watchdog: dict | None = None
        if calibration_time is None and isinstance(source, MocapRecording):
            calibration_time = float(source.times[0])
        self._calibration_time = calibration_time
        if calibration_time is not None:
            self.calibrate(calibration_time)

    # ---------------------------------------------------------------------------------------- properties
    @property
    def human(self) -> HumanModel:
        """The operator's human model."""
        return self._human

    @property
    def calibration(self) -> Calibration | None:
        """The calibration, or ``None`` before it happened (live source without data yet)."""
        return self._calibration

    @property
    def workspaces(self) -> Mapping[str, ReachShell]:
        """Effector -> reachable shell used for clamping."""
        return MappingProxyType(self._workspaces)

    @property
    def reference_poses(self) -> Mapping[str, pin.SE3]:
        """Effector poses of the robot in its reference posture (what invalid samples hold before calibration)."""
        return MappingProxyType(self._reference_poses)

    # ------------------------------------------------------------------------------------------- mapping
    def _names(self, frame: PoseFrame) -> dict[str, str]:
        """canonical -> source segment name for this frame."""
        if self._segment_map is not None:
            return self._segment_map
        out: dict[str, str] = {}
        for name in frame.positions:
            canonical = canonical_name(name)
            if canonical is not None and canonical not in out:
                out[canonical] = name
        return out

    def _keypoints(self, frame: PoseFrame, names: dict[str, str]) -> dict[str, FloatArray]:
        out = {}
        for key in KEYPOINTS:
            src = names.get(key)
            if src is not None and np.all(np.isfinite(frame.positions[src])):
                out[key] = np.asarray(frame.positions[src], dtype=float)
        return out

    # ---------------------------------------------------------------------------------------- calibration
    def calibrate(self, t: float | None = None) -> Calibration:
        """Calibrate on the source frame at ``t`` (default the configured calibration time, or "now").

        Raises:
            WbcError: the source has no frame yet.
            ConfigError: missing effector segments or fewer than 4 keypoints.
        """
        t = self._calibration_time if t is None else t
        frame = self._source.frame_at(0.0 if t is None else t)
        if frame is None:
            raise WbcError("retargeting: the pose source has no frame to calibrate on yet")
        names = self._names(frame)
        where = getattr(self._source, "source", "") or None
        missing = [seg for seg in EFFECTOR_SEGMENTS.values() if seg not in names]
        if missing:
            raise ConfigError(
                f"retargeting needs segments {missing}, not found among {sorted(frame.positions)[:12]}"
                " (pass segment_map)",
                file=where,
            )
        suit = self._keypoints(frame, names)
        if len(suit) < 4:
            raise ConfigError(f"retargeting needs >= 4 of the keypoints {list(KEYPOINTS)}, found {sorted(suit)}",
                              file=where)
        human = self._human
        keys = list(suit)
        src = np.array([suit[k] for k in keys])
        q, used = human.configuration_from_channels(frame.joint_angles) if frame.joint_angles else (None, 0)
        method = "joint_angles" if used > 0 else "fit"
        if q is None or used == 0:
            q0 = human.neutral()
            model_pts = human.keypoints(q0)
            trunk = [k for k in keys if k in _TRUNK]
            if len(trunk) < 3:
                trunk = keys
            T0 = umeyama([suit[k] for k in trunk], [model_pts[k] for k in trunk], with_scale=False).transform
            q = human.fit({k: T0.apply(suit[k]) for k in keys}, q0).q
        T, rms, q = self._align(q, keys, src)
        if method == "joint_angles" and rms > self._fit_threshold:
            method = "joint_angles+fit"
        if method != "joint_angles":
            for _ in range(2):
                q = human.fit({k: T.apply(suit[k]) for k in keys}, q).q
                T, rms, q = self._align(q, keys, src)
        k = self._proportion()
        offsets = {}
        for effector, segment in EFFECTOR_SEGMENTS.items():
            R_suit = rot.to_matrix(np.asarray(frame.orientations[names[segment]], dtype=float))
            R_world = T.rotation @ R_suit
            offsets[effector] = R_world.T @ self._reference_poses[effector].rotation
        self._calibration_bones = self._bone_lengths(frame, names)
        self._calibration = Calibration(
            time=float(frame.time),
            method=method,
            T_world_suit=T,
            rms=rms,
            q_human=q,
            proportion=k,
            center=self._T_world_feet.translation.copy(),
            rotation_offsets=MappingProxyType(offsets),
        )
        return self._calibration

    def _align(self, q: FloatArray, keys: list[str], src: FloatArray) -> tuple[SimilarityTransform, float, FloatArray]:
        """Feet on the robot's feet, then the rigid suit -> world transform."""
        q = self._human.place_feet(q, self._T_world_feet, self._stride_heading)
        model_pts = self._human.keypoints(q, keys)
        result = umeyama(src, np.array([model_pts[k] for k in keys]), with_scale=False)
        return result.transform, result.rms, q

    def _proportion(self) -> float:
        spec = self._proportion_spec
        if not isinstance(spec, str):
            return float(spec)
        T_feet = self._T_world_feet
        if spec == "head":
            robot_height = T_feet.actInv(self._reference_poses["head"].translation)[2]
            return float(robot_height / self._human.head_height())
        heights = [T_feet.actInv(shell.center)[2] for name, shell in self._shoulder_shells().items()]
        return float(np.mean(heights) / self._human.shoulder_height())

    def _shoulder_shells(self) -> dict[str, ReachShell]:
        shells = {n: s for n, s in self._workspaces.items() if n != "head"}
        if len(shells) == 2:
            return shells
        return {n: s for n, s in robot_workspaces(self._robot, samples=1).items() if n != "head"}

    # ------------------------------------------------------------------------------------------ watchdog
    def watch_skeleton(self, tolerance: float = 0.15) -> None:
        """Watch every sampled frame's skeleton against the calibration's (module docstring); 0 turns it off."""
        if not (tolerance >= 0.0):
            raise ConfigError(f"the skeleton watchdog's tolerance must be >= 0, got {tolerance!r}",
                              key="skeleton_tolerance")
        self._watch_tolerance = float(tolerance)

    def _bone_lengths(self, frame: PoseFrame, names: dict[str, str]) -> dict[tuple[str, str], float]:
        out = {}
        for a, b in BONES:
            if a in names and b in names:
                d = float(np.linalg.norm(np.asarray(frame.positions[names[a]], dtype=float)
                                         - np.asarray(frame.positions[names[b]], dtype=float)))
                if np.isfinite(d) and d > 0.0:
                    out[(a, b)] = d
        return out

    def _skeleton_changed(self, frame: PoseFrame, names: dict[str, str]) -> str | None:
        """Why this frame's skeleton is not the calibration's (None: it is)."""
        bones = self._bone_lengths(frame, names)
        for bone, length in self._calibration_bones.items():
            now = bones.get(bone)
            if now is None:
                return f"segment {bone[0] if bone[0] not in names else bone[1]} is gone from the stream"
            if abs(now - length) > self._watch_tolerance * length:
                return (f"bone {bone[0]}-{bone[1]} is {now:.3f} m, {length:.3f} m at calibration "
                        f"({(now / length - 1) * 100:+.0f} %, tolerance {self._watch_tolerance * 100:.0f} %)")
        return None

    # ------------------------------------------------------------------------------------------ sampling
    def sample(self, t: float) -> TeleopSample:
        """References, validity and clamping flags at source time ``t`` [s] (see the module docstring)."""
        frame = self._source.frame_at(t)
        if self._calibration is None and frame is not None and frame.valid:
            self.calibrate(frame.time)
        return self.sample_frame(frame, t)

    def sample_frame(self, frame: PoseFrame | None, t: float) -> TeleopSample:
        """References, validity and clamping flags of a given frame (e.g. one that came through a link), labelled
        with time ``t`` [s]; the calibration must have happened (else the reference poses, invalid)."""
        cal = self._calibration
        if frame is None or cal is None:
            refs = {name: pin.SE3(pose) for name, pose in self._reference_poses.items()}
            return TeleopSample(float(t), refs, False, {name: False for name in EFFECTORS})
        names = self._names(frame)
        valid = bool(frame.valid)
        if self._watch_tolerance and valid and self.watchdog is None and frame is not self._watched_frame:
            self._watched_frame = frame
            why = self._skeleton_changed(frame, names)
            if why is not None:
                self.watchdog = {"time": float(t), "frame_time": float(frame.time),
                                 "reason": f"the stream switched skeleton: {why}; holding the robot"}
        if self.watchdog is not None:
            refs = {name: pin.SE3(pose) for name, pose in self._reference_poses.items()}
            return TeleopSample(float(t), refs, False, {name: False for name in EFFECTORS})
        refs: dict[str, pin.SE3] = {}
        clamped: dict[str, bool] = {}
        T = cal.T_world_suit
        c, k = cal.center, cal.proportion
        for effector, segment in EFFECTOR_SEGMENTS.items():
            src = names.get(segment)
            p = np.asarray(frame.positions[src], dtype=float) if src is not None else np.full(3, np.nan)
            quat = np.asarray(frame.orientations[src], dtype=float) if src is not None else np.full(4, np.nan)
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(quat))):
                valid = False
                refs[effector] = pin.SE3(self._reference_poses[effector])
                clamped[effector] = False
                continue
            p_ref = c + k * (T.apply(p) - c)
            shell = self._workspaces.get(effector)
            was_clamped = False
            if shell is not None:
                p_ref, was_clamped = shell.clamp(p_ref)
            R = T.rotation @ rot.to_matrix(quat) @ cal.rotation_offsets[effector]  # quat normalised in to_matrix
            refs[effector] = pin.SE3(R, p_ref)
            clamped[effector] = was_clamped
        return TeleopSample(float(t), refs, valid, clamped)

    def references_at(self, t: float) -> dict[str, pin.SE3]:
        """Effector name (``left_hand``, ``right_hand``, ``head``) -> ``T_world_ref`` at time ``t`` [s].

        The same "references at time t" interface as the planners; use :meth:`sample` for the validity and
        clamping flags.
        """
        return self.sample(t).references

    def valid_at(self, t: float) -> bool:
        """The validity flag of :meth:`sample` at ``t``."""
        return self.sample(t).valid
