"""Registry of the recordings shipped in ``wbcbench/teleop/recordings/`` (the synthetic operator recordings)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ...errors import ConfigError, UnknownNameError
from ..io.bvh import read_bvh
from ..io.recording import MocapRecording
from .synthetic import MOTIONS, OPERATORS

__all__ = ["RECORDINGS_DIR", "RecordingInfo", "list_recordings", "recording_path", "open_recording"]

#: Where the shipped recordings live.
RECORDINGS_DIR = Path(__file__).parent.parent / "recordings"


@dataclass(frozen=True)
class RecordingInfo:
    """One shipped recording.

    Attributes:
        name: registry key.
        description: one line.
        path: the file.
        operator: synthetic operator (see :data:`~wbcbench.teleop.human.synthetic.OPERATORS`).
        duration: [s].
        frame_rate: [Hz].
    """

    name: str
    description: str
    path: Path
    operator: str
    duration: float
    frame_rate: float


def list_recordings() -> list[RecordingInfo]:
    """The shipped recordings, in registry order."""
    return [
        RecordingInfo(m.name, m.description, RECORDINGS_DIR / f"{m.name}.bvh",
                      f"{m.operator} (x{OPERATORS[m.operator].scale:g})", m.duration, m.rate)
        for m in MOTIONS.values()
    ]


def recording_path(name: str) -> Path:
    """The file of recording ``name``.

    Raises:
        UnknownNameError: no such recording (the message lists them).
        ConfigError: the file is missing (regenerate with :func:`~wbcbench.teleop.generate_recordings`).
    """
    if name not in MOTIONS:
        raise UnknownNameError("recording", name, MOTIONS)
    path = RECORDINGS_DIR / f"{name}.bvh"
    if not path.is_file():
        raise ConfigError("missing; regenerate with wbcbench.teleop.generate_recordings(RECORDINGS_DIR)",
                          file=str(path))
    return path


def open_recording(name: str) -> MocapRecording:
    """Read the shipped recording ``name``."""
    return read_bvh(recording_path(name))
