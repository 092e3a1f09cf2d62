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

Sub-packages, by job: :mod:`.io` (recordings and their readers), :mod:`.human` (human model, retargeting, synthetic
recordings), :mod:`.link` (datagrams, receiver, sender, network impairment, prediction), :mod:`.safety` (command
filter), :mod:`.session` (the reference source, metrics, the ``wbcbench teleop`` command). The modules' former flat
paths (``wbcbench.teleop.bvh``, ``wbcbench.teleop.commands`` ...) stay importable: they name the same module objects.

See ``wbcbench/teleop/README.md`` for the formats and conventions.
"""

import importlib as _importlib
import sys as _sys

from .human import (EFFECTORS, AlignmentError, Calibration, HumanModel, PoseSource, RecordingInfo, Retargeter,
                    SimilarityTransform, TeleopSample, UmeyamaResult, estimate_segment_lengths, generate_recordings,
                    list_recordings, open_recording, recording_path, robot_workspaces, umeyama)
from .human.workspace import ReachShell
from .io import (BvhData, BvhJoint, BvhSkeleton, MocapRecording, PoseFrame, load_recording, parse_bvh, read_bvh,
                 read_mvnx, read_pose_csv, write_bvh, write_mvnx, write_pose_csv)
from .link import (Datagram, DatagramError, ImpairedLink, ImpairedRelay, ImpairedReplay, NetworkImpairment,
                   PosePredictor, ReceivedFrame, ReceiverStats, ReplaySender, StreamStatus, UdpPoseReceiver,
                   decode_datagram, encode_datagram, parse_impairment)

#: The flat module paths of before the sub-packages -> where each module lives now (same module object).
_MOVED = {
    "recording": "io.recording", "segments": "io.segments", "bvh": "io.bvh", "mvnx": "io.mvnx",
    "csv_poses": "io.csv_poses", "loader": "io.loader", "skeleton_map": "io.skeleton_map",
    "human_model": "human.model", "umeyama": "human.umeyama", "workspace": "human.workspace",
    "retargeting": "human.retargeting", "synthetic": "human.synthetic", "registry": "human.registry",
    "protocol": "link.protocol", "receiver": "link.receiver", "sender": "link.sender", "network": "link.network",
    "prediction": "link.prediction",
    "source": "session.source", "metrics": "session.metrics", "commands": "session.commands",
}
for _old, _new in _MOVED.items():
    _sys.modules[f"{__name__}.{_old}"] = _importlib.import_module(f".{_new}", __name__)
    globals().setdefault(_old, _sys.modules[f"{__name__}.{_old}"])  # `umeyama` stays the function, as before
del _old, _new

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
