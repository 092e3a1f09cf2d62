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

from .._lazy import lazy_exports

# imported when first used, so that importing the package (or its `commands` module, for the command
# line's parser) stays light
__getattr__, __dir__ = lazy_exports(__name__, {
    **dict.fromkeys(("BvhData", "BvhJoint", "BvhSkeleton", "parse_bvh", "read_bvh", "write_bvh"), "bvh"),
    **dict.fromkeys(("read_pose_csv", "write_pose_csv"), "csv_poses"),
    **dict.fromkeys(("HumanModel", "estimate_segment_lengths"), "human_model"),
    **dict.fromkeys(("load_recording",), "loader"),
    **dict.fromkeys(("read_mvnx", "write_mvnx"), "mvnx"),
    **dict.fromkeys(("ImpairedLink", "ImpairedRelay", "ImpairedReplay", "NetworkImpairment", "parse_impairment"), "network"),
    **dict.fromkeys(("PosePredictor",), "prediction"),
    **dict.fromkeys(("Datagram", "DatagramError", "decode_datagram", "encode_datagram"), "protocol"),
    **dict.fromkeys(("ReceivedFrame", "ReceiverStats", "StreamStatus", "UdpPoseReceiver"), "receiver"),
    **dict.fromkeys(("MocapRecording", "PoseFrame"), "recording"),
    **dict.fromkeys(("RecordingInfo", "list_recordings", "open_recording", "recording_path"), "registry"),
    **dict.fromkeys(("EFFECTORS", "Calibration", "PoseSource", "Retargeter", "TeleopSample", "robot_workspaces"), "retargeting"),
    **dict.fromkeys(("ReplaySender",), "sender"),
    **dict.fromkeys(("generate_recordings",), "synthetic"),
    **dict.fromkeys(("AlignmentError", "SimilarityTransform", "UmeyamaResult", "umeyama"), "umeyama"),
    **dict.fromkeys(("ReachShell",), "workspace"),
})

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
