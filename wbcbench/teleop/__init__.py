"""Operator side of whole-body teleoperation (paper 004): motion capture in, hand and head references out.

* recordings: :func:`read_bvh`, :func:`read_mvnx`, :func:`read_pose_csv` (and writers) -> :class:`MocapRecording`;
  :func:`load_recording` picks the reader by suffix; shipped synthetic recordings in :func:`list_recordings`;
* live stream: :class:`UdpPoseReceiver` (non-blocking, counts lost / reordered / duplicated / malformed datagrams,
  ``stale`` detection) and :class:`ReplaySender` (a recording over loopback); datagram format in
  :mod:`wbcbench.teleop.protocol`;
* network realism: :class:`NetworkImpairment` (latency, jitter, loss and bursts, reordering, duplication,
  corruption, sender stalls; :func:`parse_impairment`) on a loopback relay (:class:`ImpairedRelay`) or in simulated
  time (:class:`ImpairedReplay`), and :class:`PosePredictor` (constant-velocity or spline extrapolation);
* :func:`umeyama` similarity / rigid alignment of point sets;
* :class:`HumanModel`: example-robot-data's human, posed from joint angles, scaled to the operator;
* :class:`Retargeter`: ``references_at(t) -> {"left_hand", "right_hand", "head": pin.SE3}`` for the robot, with
  validity and workspace-clamping flags (:meth:`Retargeter.sample`).

See ``wbcbench/teleop/README.md`` for the formats and conventions.
"""

from .bvh import BvhData, BvhJoint, BvhSkeleton, parse_bvh, read_bvh, write_bvh
from .csv_poses import read_pose_csv, write_pose_csv
from .human_model import HumanModel, estimate_segment_lengths
from .loader import load_recording
from .mvnx import read_mvnx, write_mvnx
from .network import ImpairedLink, ImpairedRelay, ImpairedReplay, NetworkImpairment, parse_impairment
from .prediction import PosePredictor
from .protocol import Datagram, DatagramError, decode_datagram, encode_datagram
from .receiver import ReceivedFrame, ReceiverStats, StreamStatus, UdpPoseReceiver
from .recording import MocapRecording, PoseFrame
from .registry import RecordingInfo, list_recordings, open_recording, recording_path
from .retargeting import EFFECTORS, Calibration, PoseSource, Retargeter, TeleopSample, robot_workspaces
from .sender import ReplaySender
from .synthetic import generate_recordings
from .umeyama import AlignmentError, SimilarityTransform, UmeyamaResult, umeyama
from .workspace import ReachShell

__all__ = [
    "EFFECTORS",
    "AlignmentError",
    "BvhData",
    "BvhJoint",
    "BvhSkeleton",
    "Calibration",
    "Datagram",
    "DatagramError",
    "HumanModel",
    "ImpairedLink",
    "ImpairedRelay",
    "ImpairedReplay",
    "MocapRecording",
    "NetworkImpairment",
    "PoseFrame",
    "PosePredictor",
    "PoseSource",
    "ReachShell",
    "ReceivedFrame",
    "ReceiverStats",
    "RecordingInfo",
    "ReplaySender",
    "Retargeter",
    "SimilarityTransform",
    "StreamStatus",
    "TeleopSample",
    "UdpPoseReceiver",
    "UmeyamaResult",
    "decode_datagram",
    "encode_datagram",
    "estimate_segment_lengths",
    "generate_recordings",
    "list_recordings",
    "load_recording",
    "open_recording",
    "parse_impairment",
    "parse_bvh",
    "read_bvh",
    "read_mvnx",
    "read_pose_csv",
    "recording_path",
    "robot_workspaces",
    "umeyama",
    "write_bvh",
    "write_mvnx",
    "write_pose_csv",
]
