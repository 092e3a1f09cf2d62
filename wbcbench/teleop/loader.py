"""Open any supported recording by its file suffix."""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError
from .bvh import read_bvh
from .csv_poses import read_pose_csv
from .mvnx import read_mvnx
from .recording import MocapRecording

__all__ = ["load_recording", "RECORDING_SUFFIXES"]

#: Suffix -> reader.
RECORDING_SUFFIXES = {".bvh": read_bvh, ".mvnx": read_mvnx, ".csv": read_pose_csv}


def load_recording(path: str | Path) -> MocapRecording:
    """Read a ``.bvh`` (centimetres), ``.mvnx`` or pose ``.csv`` file.

    Raises:
        ConfigError: unknown suffix, missing file, or any reader error (one line naming the file).
    """
    path = Path(path)
    reader = RECORDING_SUFFIXES.get(path.suffix.lower())
    if reader is None:
        raise ConfigError(
            f"unknown recording format '{path.suffix}'; known: {', '.join(sorted(RECORDING_SUFFIXES))}",
            file=str(path),
        )
    if not path.is_file():
        raise ConfigError("no such file", file=str(path))
    return reader(path)
