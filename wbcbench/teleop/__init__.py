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
import importlib.abc as _abc
import importlib.util as _util
import sys as _sys

from .._lazy import lazy_exports

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


class _MovedModules(_abc.MetaPathFinder, _abc.Loader):
    """`import wbcbench.teleop.<old>` gives the module at its new place (imported when first asked for, so that
    importing the package, or the command line's `commands`, stays light)."""

    def __init__(self) -> None:
        self._specs: dict[str, object] = {}  # module name -> its own spec

    def find_spec(self, fullname, path=None, target=None):
        head, _, old = fullname.rpartition(".")
        if head == __name__ and old in _MOVED:
            return _util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        module = _importlib.import_module(f"{__name__}.{_MOVED[spec.name.rpartition('.')[2]]}")
        self._specs[module.__name__] = module.__spec__
        return module

    def exec_module(self, module) -> None:
        # the import system has given the module the old path's spec: its own back, so that its relative imports
        # keep resolving from its package (Python 3.12+ warns when __spec__ and __package__ disagree)
        module.__spec__ = self._specs[module.__name__]


if not any(isinstance(f, _MovedModules) for f in _sys.meta_path):
    _sys.meta_path.insert(0, _MovedModules())

# the public names, imported when first used
_HUMAN = ("EFFECTORS", "AlignmentError", "Calibration", "HumanModel", "PoseSource", "RecordingInfo", "Retargeter",
          "SimilarityTransform", "TeleopSample", "UmeyamaResult", "estimate_segment_lengths", "generate_recordings",
          "list_recordings", "open_recording", "recording_path", "robot_workspaces", "umeyama")
_IO = ("BvhData", "BvhJoint", "BvhSkeleton", "MocapRecording", "PoseFrame", "load_recording", "parse_bvh", "read_bvh",
       "read_mvnx", "read_pose_csv", "write_bvh", "write_mvnx", "write_pose_csv")
_LINK = ("Datagram", "DatagramError", "ImpairedLink", "ImpairedRelay", "ImpairedReplay", "NetworkImpairment",
         "PosePredictor", "ReceivedFrame", "ReceiverStats", "ReplaySender", "StreamStatus", "UdpPoseReceiver",
         "decode_datagram", "encode_datagram", "parse_impairment")
_names_getattr, __dir__ = lazy_exports(__name__, {**dict.fromkeys(_HUMAN, "human"), "ReachShell": "human.workspace",
                                                  **dict.fromkeys(_IO, "io"), **dict.fromkeys(_LINK, "link")})


def __getattr__(name: str):
    try:
        return _names_getattr(name)  # a public name first: `umeyama` stays the function
    except AttributeError:
        if name in _MOVED:  # a module of before the sub-packages, as an attribute
            return _importlib.import_module(f".{_MOVED[name]}", __name__)
        raise

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
