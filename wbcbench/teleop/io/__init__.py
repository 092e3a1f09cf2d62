"""Recordings in: the :class:`MocapRecording` container, the canonical segment names, the readers and writers of
BVH, Xsens MVNX and pose CSV files and of C3D and TRC marker files, :func:`load_recording` (any supported file),
and :func:`map_segments` (which segment of a file's skeleton is which)."""

from . import bvh as _bvh
from . import c3d as _c3d
from . import conventions as _conventions
from . import csv_poses as _csv_poses
from . import loader as _loader
from . import mvnx as _mvnx
from . import recording as _recording
from . import segments as _segments
from . import skeleton_map as _skeleton_map
from . import trc as _trc
from .bvh import *  # noqa: F403
from .c3d import *  # noqa: F403
from .conventions import *  # noqa: F403
from .csv_poses import *  # noqa: F403
from .loader import *  # noqa: F403
from .mvnx import *  # noqa: F403
from .recording import *  # noqa: F403
from .segments import *  # noqa: F403
from .skeleton_map import *  # noqa: F403
from .trc import *  # noqa: F403

__all__ = [*_recording.__all__, *_segments.__all__, *_bvh.__all__, *_c3d.__all__, *_mvnx.__all__,
           *_csv_poses.__all__, *_loader.__all__, *_conventions.__all__, *_skeleton_map.__all__,
           *_trc.__all__]
