"""The operator's body: the ``human`` model of example-robot-data, posed from joint angles, scaled per operator.

The model (``human_description/robots/human.urdf``, 36 revolute joints + a free-flyer, 1.80 m by default) follows
the ISB segment conventions of the Xsens suit: in each segment frame x points forward, y up along the segment,
z to the right; each anatomical joint is a chain of revolute joints in Z, X, Y order (flexion, abduction, axial
rotation), with mirrored axes on the left so that a positive angle has the same anatomical meaning on both sides
(e.g. ``*_shoulder_Z`` > 0 is flexion, ``*_shoulder_X`` > 0 abduction, ``*_elbow_Z`` > 0 flexion). The free-flyer
is placed under a fixed rotation (+90 deg about x, as example-robot-data's loader enforces) so that the model's
world is z-up, x forward, y to the left, while the BVH world of :meth:`HumanModel.bvh_skeleton` is the y-up frame
before that rotation.

Segments are named with the canonical MVN names (:mod:`wbcbench.teleop.io.segments`); :data:`SKELETON` maps each to a
model frame and its joints.

Per-operator scaling (paper 004: "a script adapts the human model size to each new user"): :data:`LINKS` lists
14 segment lengths, each the distance between two consecutive segment origins (e.g. shoulder to elbow) that no
joint angle changes (except the clavicle elevation for the two shoulder-girdle links). Each length scales the
translations of the joint placements of its ``joints`` by ``length / default_length``; no placement belongs to two
links, so lengths are independent. Only the kinematics is scaled (masses and inertias are untouched: the model
is used for geometry only). :func:`estimate_segment_lengths` takes the median, over the frames, of each recorded
distance.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.spatial.transform import Rotation

from ...errors import ConfigError
from ..io.bvh import BvhJoint, BvhSkeleton
from ..io.recording import MocapRecording, PoseFrame
from ..io.segments import KEYPOINTS, canonical_name

__all__ = [
    "SKELETON",
    "LINKS",
    "KEYPOINT_FRAMES",
    "MVNX_ANGLE_MAP",
    "SegmentSpec",
    "LinkSpec",
    "FitResult",
    "HumanModel",
    "estimate_segment_lengths",
    "feet_frame",
]

FloatArray = npt.NDArray[np.float64]
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class SegmentSpec:
    """One segment of the human model.

    Attributes:
        name: canonical (MVN) name, also the BVH joint name.
        parent: parent segment, ``None`` for the pelvis (the free-flyer).
        frame: model frame at the segment origin.
        joints: ``(axis, model joint)`` pairs, in chain order (the BVH channel order).
        end_site: BVH ``End Site`` offset in the segment frame [m] at default size, or ``None``.
    """

    name: str
    parent: str | None
    frame: str
    joints: tuple[tuple[str, str], ...]
    end_site: tuple[float, float, float] | None = None


def _arm(side: str) -> tuple[SegmentSpec, ...]:
    s, S = side.lower(), side
    return (
        SegmentSpec(f"{S}Shoulder", "T8", f"{s}_clavicle", (("X", f"{s}_clavicle_joint_X"),)),
        SegmentSpec(f"{S}UpperArm", f"{S}Shoulder", f"{s}_upperarm",
                    (("Z", f"{s}_shoulder_Z"), ("X", f"{s}_shoulder_X"), ("Y", f"{s}_shoulder_Y"))),
        SegmentSpec(f"{S}ForeArm", f"{S}UpperArm", f"{s}_lowerarm", (("Z", f"{s}_elbow_Z"), ("Y", f"{s}_elbow_Y"))),
        SegmentSpec(f"{S}Hand", f"{S}ForeArm", f"{s}_hand", (("Z", f"{s}_wrist_Z"), ("X", f"{s}_wrist_X")),
                    (0.0, -0.08, 0.0)),
    )


def _leg(side: str) -> tuple[SegmentSpec, ...]:
    s, S = side.lower(), side
    return (
        SegmentSpec(f"{S}UpperLeg", "Pelvis", f"{s}_upperleg",
                    (("Z", f"{s}_hip_Z"), ("X", f"{s}_hip_X"), ("Y", f"{s}_hip_Y"))),
        SegmentSpec(f"{S}LowerLeg", f"{S}UpperLeg", f"{s}_lowerleg", (("Z", f"{s}_knee_Z"),)),
        SegmentSpec(f"{S}Foot", f"{S}LowerLeg", f"{s}_foot", (("Z", f"{s}_ankle_Z"), ("X", f"{s}_ankle_X")),
                    (0.15, -0.07, 0.0)),
    )


#: The human model's segments, in depth-first order (the BVH hierarchy order).
SKELETON: tuple[SegmentSpec, ...] = (
    SegmentSpec("Pelvis", None, "middle_pelvis", ()),
    SegmentSpec("L5", "Pelvis", "middle_abdomen", (("Z", "middle_lumbar_Z"), ("X", "middle_lumbar_X"))),
    SegmentSpec("T8", "L5", "middle_thorax",
                (("Z", "middle_thoracic_Z"), ("X", "middle_thoracic_X"), ("Y", "middle_thoracic_Y"))),
    SegmentSpec("Head", "T8", "middle_head",
                (("Z", "middle_cervical_Z"), ("X", "middle_cervical_X"), ("Y", "middle_cervical_Y")),
                (0.0, 0.2, 0.0)),
    *_arm("Left"),
    *_arm("Right"),
    *_leg("Left"),
    *_leg("Right"),
)

#: Keypoint (canonical segment) -> model frame at its origin.
KEYPOINT_FRAMES: Mapping[str, str] = {s.name: s.frame for s in SKELETON if s.name in KEYPOINTS}


@dataclass(frozen=True)
class LinkSpec:
    """A segment length: distance between the origins of two segments, and the joint placements it scales."""

    name: str
    proximal: str
    distal: str
    joints: tuple[str, ...]


#: The 14 lengths that scale the model to an operator.
LINKS: tuple[LinkSpec, ...] = (
    LinkSpec("lower_trunk", "Pelvis", "T8", ("middle_thoracic_Z",)),
    LinkSpec("neck", "T8", "Head", ("middle_cervical_Z",)),
    LinkSpec("left_shoulder_girdle", "T8", "LeftUpperArm", ("left_clavicle_joint_X", "left_shoulder_Z")),
    LinkSpec("right_shoulder_girdle", "T8", "RightUpperArm", ("right_clavicle_joint_X", "right_shoulder_Z")),
    LinkSpec("left_upper_arm", "LeftUpperArm", "LeftForeArm", ("left_elbow_Z",)),
    LinkSpec("right_upper_arm", "RightUpperArm", "RightForeArm", ("right_elbow_Z",)),
    LinkSpec("left_forearm", "LeftForeArm", "LeftHand", ("left_wrist_Z",)),
    LinkSpec("right_forearm", "RightForeArm", "RightHand", ("right_wrist_Z",)),
    LinkSpec("left_hip", "Pelvis", "LeftUpperLeg", ("left_hip_Z",)),
    LinkSpec("right_hip", "Pelvis", "RightUpperLeg", ("right_hip_Z",)),
    LinkSpec("left_thigh", "LeftUpperLeg", "LeftLowerLeg", ("left_knee_Z",)),
    LinkSpec("right_thigh", "RightUpperLeg", "RightLowerLeg", ("right_knee_Z",)),
    LinkSpec("left_shank", "LeftLowerLeg", "LeftFoot", ("left_ankle_Z",)),
    LinkSpec("right_shank", "RightLowerLeg", "RightFoot", ("right_ankle_Z",)),
)


def _mvnx_side(side: str) -> dict[str, tuple[tuple[str, float], ...]]:
    s, S = side.lower(), side
    return {
        f"j{S}T4Shoulder:x": ((f"{s}_clavicle_joint_X", 1.0),),
        f"j{S}Shoulder:z": ((f"{s}_shoulder_Z", 1.0),),
        f"j{S}Shoulder:x": ((f"{s}_shoulder_X", 1.0),),
        f"j{S}Shoulder:y": ((f"{s}_shoulder_Y", 1.0),),
        f"j{S}Elbow:z": ((f"{s}_elbow_Z", 1.0),),
        f"j{S}Elbow:y": ((f"{s}_elbow_Y", 1.0),),
        f"j{S}Wrist:z": ((f"{s}_wrist_Z", 1.0),),
        f"j{S}Wrist:x": ((f"{s}_wrist_X", 1.0),),
        f"j{S}Hip:z": ((f"{s}_hip_Z", 1.0),),
        f"j{S}Hip:x": ((f"{s}_hip_X", 1.0),),
        f"j{S}Hip:y": ((f"{s}_hip_Y", 1.0),),
        f"j{S}Knee:z": ((f"{s}_knee_Z", 1.0),),
        f"j{S}Ankle:z": ((f"{s}_ankle_Z", 1.0),),
        f"j{S}Ankle:x": ((f"{s}_ankle_X", 1.0),),
    }


#: Xsens MVNX joint-angle channel -> ((model joint, factor), ...): the model angle is the sum of
#: ``factor * value`` over the channels mapped to it (the four lumbar-thoracic MVN joints feed the model's two
#: spine joints, the two cervical ones its neck). ASSUMED from the ISB conventions both follow (anatomical signs,
#: Z X Y order) and not checked against a real suit: the retargeting verifies the posture through the alignment
#: residual and fits the model to the segment positions when it is too large.
MVNX_ANGLE_MAP: Mapping[str, tuple[tuple[str, float], ...]] = {
    "jL5S1:z": (("middle_lumbar_Z", 1.0),), "jL5S1:x": (("middle_lumbar_X", 1.0),),
    "jL4L3:z": (("middle_lumbar_Z", 1.0),), "jL4L3:x": (("middle_lumbar_X", 1.0),),
    "jL1T12:z": (("middle_thoracic_Z", 1.0),), "jL1T12:x": (("middle_thoracic_X", 1.0),),
    "jL1T12:y": (("middle_thoracic_Y", 1.0),),
    "jT9T8:z": (("middle_thoracic_Z", 1.0),), "jT9T8:x": (("middle_thoracic_X", 1.0),),
    "jT9T8:y": (("middle_thoracic_Y", 1.0),),
    "jT1C7:z": (("middle_cervical_Z", 1.0),), "jT1C7:x": (("middle_cervical_X", 1.0),),
    "jT1C7:y": (("middle_cervical_Y", 1.0),),
    "jC1Head:z": (("middle_cervical_Z", 1.0),), "jC1Head:x": (("middle_cervical_X", 1.0),),
    "jC1Head:y": (("middle_cervical_Y", 1.0),),
    **_mvnx_side("Left"),
    **_mvnx_side("Right"),
}  # fmt: skip


@functools.lru_cache(maxsize=1)
def _reference_model() -> pin.Model:
    """The unscaled human model (kinematics only: no meshes are loaded)."""
    from example_robot_data.robots_loader import ROBOTS
    from example_robot_data.utils import getModelPath

    loader = ROBOTS["human"]
    relative = str(Path(loader.path) / loader.urdf_subpath / loader.urdf_filename)
    urdf = Path(getModelPath(relative)) / relative
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    root = model.getJointId("root_joint")
    placement = model.jointPlacements[root]
    placement.rotation = np.array(loader.freeflyer_ori, dtype=float)
    model.jointPlacements[root] = placement
    return model


class FitResult(NamedTuple):
    """Result of :meth:`HumanModel.fit`.

    Attributes:
        q: fitted configuration (nq,).
        rms: root mean square distance between model keypoints and targets [m].
        iterations: Gauss-Newton iterations done.
    """

    q: FloatArray
    rms: float
    iterations: int


#: the largest angle [deg] between the right-to-left foot direction and the hips' for the feet frame to take its
#: heading from the feet (`feet_frame`): beyond 45 deg the feet's direction is closer to the hips' forward axis
#: than to their left-right one (a stride)
STRIDE_ANGLE = 45.0


def feet_frame(p_left: FloatArray, p_right: FloatArray, up_left: FloatArray, up_right: FloatArray,
               hips_left: FloatArray | None = None) -> pin.SE3:
    """The frame between two feet: origin at the midpoint of the sole points, z the mean up direction, y from
    the right foot to the left one (made orthogonal to z), x = y cross z (forward).

    `hips_left` (optional, the right-to-left hip vector): when the feet's direction is more than
    :data:`STRIDE_ANGLE` from it (about the vertical), the feet stand in a stride (one ahead of the other, as in a
    walk) and point the walking direction, not the body's left: y is then the hips' direction."""
    z = np.asarray(up_left, dtype=float) + np.asarray(up_right, dtype=float)
    z /= np.linalg.norm(z)
    y = np.asarray(p_left, dtype=float) - np.asarray(p_right, dtype=float)
    y -= (y @ z) * z
    norm = np.linalg.norm(y)
    if norm < 1e-6 and hips_left is None:
        raise ConfigError("the two feet coincide: no feet frame")
    if hips_left is not None:
        h = np.asarray(hips_left, dtype=float) - (np.asarray(hips_left, dtype=float) @ z) * z
        if np.linalg.norm(h) > 1e-6:
            h /= np.linalg.norm(h)
            if norm < 1e-6 or (y / norm) @ h < np.cos(np.radians(STRIDE_ANGLE)):
                y, norm = h, 1.0
    y /= norm
    x = np.cross(y, z)
    return pin.SE3(np.column_stack([x, y, z]), 0.5 * (np.asarray(p_left) + np.asarray(p_right)))


def estimate_segment_lengths(
    recording: MocapRecording, segment_map: Mapping[str, str] | None = None
) -> dict[str, float]:
    """Median distance between the origins of each :data:`LINKS` pair over the recording's frames [m].

    Args:
        recording: a recording with segment positions.
        segment_map: canonical name -> recording segment name; by default names are matched with
            :func:`~wbcbench.teleop.io.segments.canonical_name`.

    Returns:
        link name -> length, for the links whose two segments the recording has (others are absent).
    """
    names = _segment_names(recording.segments, segment_map)
    lengths: dict[str, float] = {}
    for link in LINKS:
        a, b = names.get(link.proximal), names.get(link.distal)
        if a is None or b is None:
            continue
        d = np.linalg.norm(recording.position(b) - recording.position(a), axis=1)
        d = d[np.isfinite(d)]
        if len(d):
            lengths[link.name] = float(np.median(d))
    return lengths


def _segment_names(segments: Iterable[str], segment_map: Mapping[str, str] | None) -> dict[str, str]:
    """canonical name -> source segment name."""
    if segment_map is not None:
        return dict(segment_map)
    out: dict[str, str] = {}
    for name in segments:
        canonical = canonical_name(name)
        if canonical is not None and canonical not in out:
            out[canonical] = name
    return out


class HumanModel:
    """The human model of example-robot-data, scaled to one operator.

    Args:
        lengths: link name (:data:`LINKS`) -> length [m]; links not given keep the default (1.80 m model).
        ankle_height: height of the ankle joint above the sole [m]; default 0.08 m times the shank scale.

    Raises:
        ConfigError: unknown link name, or a length outside [0.4, 2.5] times the default (wrong unit?).
    """

    def __init__(self, lengths: Mapping[str, float] | None = None, *, ankle_height: float | None = None) -> None:
        reference = _reference_model()
        self.model: pin.Model = pin.Model(reference)
        self.data: pin.Data = self.model.createData()
        defaults = self.default_lengths()
        lengths = dict(lengths or {})
        unknown = sorted(set(lengths) - set(defaults))
        if unknown:
            raise ConfigError(f"unknown segment length(s) {unknown}; known: {', '.join(defaults)}", key="lengths")
        self._lengths = dict(defaults)
        for link in LINKS:
            if link.name not in lengths:
                continue
            value = float(lengths[link.name])
            ratio = value / defaults[link.name]
            if not (np.isfinite(ratio) and 0.4 <= ratio <= 2.5):
                raise ConfigError(
                    f"segment length {link.name} = {value:.4g} m is implausible (default {defaults[link.name]:.3f}"
                    " m; wrong length unit?)",
                    key="lengths",
                )
            self._lengths[link.name] = value
            for joint in link.joints:
                j = self.model.getJointId(joint)
                placement = pin.SE3(reference.jointPlacements[j])
                placement.translation = placement.translation * ratio
                self.model.jointPlacements[j] = placement
        shank = 0.5 * (self._lengths["left_shank"] / defaults["left_shank"]
                       + self._lengths["right_shank"] / defaults["right_shank"])
        self.ankle_height = 0.08 * shank if ankle_height is None else float(ankle_height)
        self._frame_ids = {s.name: self.model.getFrameId(s.frame) for s in SKELETON}
        self._root_placement = pin.SE3(self.model.jointPlacements[self.model.getJointId("root_joint")])

    # ---------------------------------------------------------------------------------------- construction
    @staticmethod
    @functools.lru_cache(maxsize=1)
    def _defaults() -> tuple[tuple[str, float], ...]:
        model = _reference_model()
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        specs = {s.name: s for s in SKELETON}
        out = []
        for link in LINKS:
            a = data.oMf[model.getFrameId(specs[link.proximal].frame)].translation
            b = data.oMf[model.getFrameId(specs[link.distal].frame)].translation
            out.append((link.name, float(np.linalg.norm(b - a))))
        return tuple(out)

    @classmethod
    def default_lengths(cls) -> dict[str, float]:
        """Segment lengths of the unscaled model [m] (example-robot-data's 1.80 m human)."""
        return dict(cls._defaults())

    @classmethod
    def from_recording(
        cls, recording: MocapRecording, *, segment_map: Mapping[str, str] | None = None
    ) -> "HumanModel":
        """The model scaled to the operator of ``recording`` (:func:`estimate_segment_lengths`)."""
        try:
            return cls(estimate_segment_lengths(recording, segment_map))
        except ConfigError as exc:
            raise ConfigError(str(exc), file=recording.source or None) from None

    @property
    def lengths(self) -> dict[str, float]:
        """Segment lengths of this model [m]."""
        return dict(self._lengths)

    # ------------------------------------------------------------------------------------ configurations
    def neutral(self) -> FloatArray:
        """Standing straight, arms hanging along the body, root at the world origin (nq,)."""
        return pin.neutral(self.model)

    def configuration_from_angles(self, angles: Mapping[str, float], q: FloatArray | None = None) -> FloatArray:
        """``q`` (default neutral) with the given model joints set [rad], clipped to the model's limits.

        Raises:
            ConfigError: unknown joint name.
        """
        q = self.neutral() if q is None else np.array(q, dtype=float)
        for name, value in angles.items():
            if not self.model.existJointName(name):
                raise ConfigError(f"unknown human joint {name!r}", key="angles")
            idx = self.model.idx_qs[self.model.getJointId(name)]
            q[idx] = float(value)
        return self.clip(q)

    def clip(self, q: FloatArray) -> FloatArray:
        """Joint coordinates clipped to the model's position limits (the free-flyer untouched)."""
        q = np.array(q, dtype=float)
        q[7:] = np.clip(q[7:], self.model.lowerPositionLimit[7:], self.model.upperPositionLimit[7:])
        return q

    def channel_map(self) -> dict[str, tuple[tuple[str, float], ...]]:
        """Recording channel -> ((model joint, factor), ...) for the BVH skeleton of :meth:`bvh_skeleton`
        (``"<Segment>:<X|Y|Z>rotation"``, factor = the joint axis sign) and for MVNX (:data:`MVNX_ANGLE_MAP`)."""
        out: dict[str, tuple[tuple[str, float], ...]] = dict(MVNX_ANGLE_MAP)
        for spec in SKELETON:
            for axis, joint in spec.joints:
                out[f"{spec.name}:{axis}rotation"] = ((joint, self._axis_sign(joint)),)
        return out

    def configuration_from_channels(self, channels: Mapping[str, float]) -> tuple[FloatArray, int]:
        """Pose the model from recorded joint-angle channels (BVH of this skeleton, or MVNX).

        Returns:
            ``(q, used)``: the configuration (root at the origin, clipped to the limits) and the number of channels
            that mapped to a model joint (0 means the recording's angles do not fit this model).
        """
        mapping = self.channel_map()
        angles: dict[str, float] = {}
        used = 0
        for name, value in channels.items():
            targets = mapping.get(name)
            if targets is None or not np.isfinite(value):
                continue
            used += 1
            for joint, factor in targets:
                angles[joint] = angles.get(joint, 0.0) + factor * float(value)
        return self.configuration_from_angles(angles), used

    def _axis_sign(self, joint: str) -> float:
        jmodel = self.model.joints[self.model.getJointId(joint)]
        short = jmodel.shortname()
        if short.startswith("JointModelR") and short[-1] in "XYZ" and "Unaligned" not in short:
            return 1.0
        axis = np.asarray(jmodel.extract().axis, dtype=float)
        return float(np.sign(axis[np.argmax(np.abs(axis))]))

    # ----------------------------------------------------------------------------------------- kinematics
    def root_placement(self, q: FloatArray) -> pin.SE3:
        """World placement of the pelvis (root joint) for ``q``."""
        ff = pin.XYZQUATToSE3(np.asarray(q[:7], dtype=float))
        return self._root_placement * ff

    def with_root_placement(self, q: FloatArray, T_world_pelvis: pin.SE3) -> FloatArray:
        """``q`` with the free-flyer set so that the pelvis is at ``T_world_pelvis``."""
        q = np.array(q, dtype=float)
        q[:7] = pin.SE3ToXYZQUAT(self._root_placement.inverse() * T_world_pelvis)
        return q

    def placements(self, q: FloatArray) -> dict[str, pin.SE3]:
        """World placement of every segment of :data:`SKELETON` (copies)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return {name: pin.SE3(self.data.oMf[fid]) for name, fid in self._frame_ids.items()}

    def keypoints(self, q: FloatArray, names: Iterable[str] = KEYPOINTS) -> dict[str, FloatArray]:
        """World positions (3,) of the segment origins ``names`` (default the :data:`KEYPOINTS`) [m]."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return {name: self.data.oMf[self._frame_ids[name]].translation.copy() for name in names}

    def sole_points(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(p_left, p_right, up_left, up_right)``: points under the ankles at :attr:`ankle_height` along each
        foot's up axis (segment y), and those axes, in the world."""
        poses = self.placements(q)
        out = []
        for side in ("Left", "Right"):
            M = poses[f"{side}Foot"]
            up = M.rotation[:, 1]
            out.append((M.translation - self.ankle_height * up, up))
        (pl, ul), (pr, ur) = out
        return pl, pr, ul, ur

    def feet_frame(self, q: FloatArray, stride: bool = False) -> pin.SE3:
        """:func:`feet_frame` of the model's soles for ``q``; `stride`: the hips' heading when the feet stand in a
        stride."""
        if not stride:
            return feet_frame(*self.sole_points(q))
        hips = self.keypoints(q, ("LeftUpperLeg", "RightUpperLeg"))
        return feet_frame(*self.sole_points(q), hips_left=hips["LeftUpperLeg"] - hips["RightUpperLeg"])

    def place_feet(self, q: FloatArray, T_world_feet: pin.SE3, stride: bool = False) -> FloatArray:
        """``q`` moved rigidly (root only) so that its :meth:`feet_frame` (`stride`: of a stride) is
        ``T_world_feet``."""
        T_feet = self.feet_frame(q, stride)
        return self.with_root_placement(q, T_world_feet * T_feet.inverse() * self.root_placement(q))

    def shoulder_height(self) -> float:
        """Height of the shoulders (mean of the two upper-arm origins) above the feet frame, standing neutral [m]."""
        q = self.neutral()
        T_feet = self.feet_frame(q)
        points = self.keypoints(q, ("LeftUpperArm", "RightUpperArm"))
        local = [T_feet.actInv(p)[2] for p in points.values()]
        return float(np.mean(local))

    def head_height(self) -> float:
        """Height of the head origin (upper neck joint) above the feet frame, standing neutral [m]."""
        q = self.neutral()
        return float(self.feet_frame(q).actInv(self.keypoints(q, ("Head",))["Head"])[2])

    # ----------------------------------------------------------------------------------------------- fit
    def fit(
        self,
        targets: Mapping[str, npt.ArrayLike],
        q_init: FloatArray | None = None,
        *,
        iterations: int = 100,
        damping: float = 1e-4,
        tolerance: float = 1e-9,
    ) -> FitResult:
        """Configuration whose keypoints best match ``targets`` (world positions, same frame as the model).

        Damped Gauss-Newton (Levenberg-Marquardt) on the free-flyer and every joint, joints clipped to their limits
        after each step. Degrees of freedom the points do not see (axial rotations, wrists) stay near
        ``q_init``.

        Args:
            targets: segment name -> (3,) target position [m]; non-finite targets are ignored.
            q_init: starting configuration (default neutral).

        Raises:
            ConfigError: fewer than 3 usable targets.
        """
        names = [n for n in targets if n in self._frame_ids and np.all(np.isfinite(targets[n]))]
        if len(names) < 3:
            raise ConfigError(f"fitting the human model needs >= 3 keypoints, got {len(names)}")
        ids = [self._frame_ids[n] for n in names]
        target = np.array([np.asarray(targets[n], dtype=float) for n in names])
        model, data = self.model, self.data
        q = self.neutral() if q_init is None else np.array(q_init, dtype=float)
        J = np.empty((3 * len(ids), model.nv))
        lam = damping
        cost = np.inf
        it = 0
        for it in range(1, iterations + 1):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            r = np.concatenate([data.oMf[f].translation for f in ids]) - target.reshape(-1)
            cost = float(r @ r)
            for k, f in enumerate(ids):
                J[3 * k: 3 * k + 3] = pin.getFrameJacobian(model, data, f, _LWA)[:3]
            H = J.T @ J
            H[np.diag_indices_from(H)] += lam
            dq = -np.linalg.solve(H, J.T @ r)
            q_new = self.clip(pin.integrate(model, q, dq))
            pin.framesForwardKinematics(model, data, q_new)
            r_new = np.concatenate([data.oMf[f].translation for f in ids]) - target.reshape(-1)
            cost_new = float(r_new @ r_new)
            if cost_new < cost:
                q, lam = q_new, max(lam * 0.3, 1e-9)
                if cost - cost_new < tolerance * max(cost, 1e-12) or np.linalg.norm(dq) < 1e-10:
                    cost = cost_new
                    break
                cost = cost_new
            else:
                lam *= 10.0
                if lam > 1e6:
                    break
        return FitResult(q, float(np.sqrt(cost / len(ids))), it)

    # ------------------------------------------------------------------------------------------------ BVH
    def bvh_skeleton(self, unit: float = 0.01) -> BvhSkeleton:
        """The model's skeleton as a BVH hierarchy in length unit ``unit`` [m] (0.01: centimetres).

        Joints are the :data:`SKELETON` segments; the pelvis has 6 channels (position, then Z X Y rotation of the
        free-flyer in the y-up frame before the root's fixed rotation), each other segment one rotation channel
        per model joint, in chain order.
        """
        index = {s.name: k for k, s in enumerate(SKELETON)}
        joints = []
        for spec in SKELETON:
            if spec.parent is None:
                offset = np.zeros(3)
                channels = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
            else:
                first = self.model.getJointId(spec.joints[0][1])
                offset = self.model.jointPlacements[first].translation
                channels = tuple(f"{axis}rotation" for axis, _ in spec.joints)
            end = None
            if spec.end_site is not None:
                scale = self._end_scale(spec.name)
                end = tuple(float(v) * scale / unit for v in spec.end_site)
            joints.append(BvhJoint(
                spec.name, -1 if spec.parent is None else index[spec.parent],
                tuple(float(v) / unit for v in offset), channels, end,  # type: ignore[arg-type]
            ))
        return BvhSkeleton(tuple(joints))

    def _end_scale(self, segment: str) -> float:
        defaults = self.default_lengths()
        link = {"LeftHand": "left_forearm", "RightHand": "right_forearm", "Head": "neck",
                "LeftFoot": "left_shank", "RightFoot": "right_shank"}[segment]
        return self._lengths[link] / defaults[link]

    def bvh_motion(self, qs: npt.ArrayLike, unit: float = 0.01) -> FloatArray:
        """BVH channel values (N, C) (``unit`` lengths, degrees) of configurations ``qs`` (N, nq), matching
        :meth:`bvh_skeleton`."""
        qs = np.atleast_2d(np.asarray(qs, dtype=float))
        columns = []
        ff = qs[:, :7]
        columns.append(ff[:, :3] / unit)
        euler = Rotation.from_quat(ff[:, 3:7]).as_euler("ZXY", degrees=True)  # intrinsic: R = Rz Rx Ry
        columns.append(euler)
        for spec in SKELETON[1:]:
            for _, joint in spec.joints:
                idx = self.model.idx_qs[self.model.getJointId(joint)]
                columns.append((self._axis_sign(joint) * np.degrees(qs[:, idx]))[:, None])
        return np.hstack(columns)

    def configuration_from_frame(self, frame: PoseFrame) -> tuple[FloatArray, int]:
        """:meth:`configuration_from_channels` of a frame's joint angles."""
        return self.configuration_from_channels(frame.joint_angles)
