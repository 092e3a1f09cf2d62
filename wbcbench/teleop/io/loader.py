"""Open any supported recording by its file suffix."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .bvh import read_bvh
from .csv_poses import read_pose_csv
from .mvnx import read_mvnx
from .recording import MocapRecording

__all__ = ["LENGTH_UNITS", "RECORDING_SUFFIXES", "detect_length_unit", "load_recording", "parse_length_unit"]

#: Suffix -> reader.
RECORDING_SUFFIXES = {".bvh": read_bvh, ".mvnx": read_mvnx, ".csv": read_pose_csv}


#: Length units a BVH file may use: name -> metres per unit.
LENGTH_UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
#: [m] the vertical extent of a standing adult's joints (ankle or toe to head joint), for the unit detection
_STANDING_EXTENT = 1.6


def detect_length_unit(recording: MocapRecording, up_axis: str = "auto") -> tuple[float, str, str]:
    """(metres per file unit, how it was chosen, up axis) of a recording read in file units: the up axis is the
    one along which the skeleton extends most (when "auto"); its standing extent (95th percentile over the frames)
    in the standard unit that makes it closest to a standing adult's 1.6 m, if one is within a factor 1.6, else
    the scale that makes it 1.6 m."""
    P = np.asarray(recording.positions, dtype=float)
    finite = np.isfinite(P).all(axis=2)
    ext = np.array([[np.ptp(P[i, finite[i], a]) if finite[i].any() else 0.0 for a in range(3)]
                    for i in range(P.shape[0])])
    axis = "xyz".index(up_axis) if up_axis in ("x", "y", "z") else int(np.argmax(np.median(ext, axis=0)))
    height = float(np.percentile(ext[:, axis], 95))
    if not (np.isfinite(height) and height > 0):
        raise ConfigError("cannot detect the length unit: the skeleton has no vertical extent",
                          file=recording.source or None, key="--length-unit")
    name, unit = min(LENGTH_UNITS.items(), key=lambda kv: abs(np.log(height * kv[1] / _STANDING_EXTENT)))
    if abs(np.log(height * unit / _STANDING_EXTENT)) <= np.log(1.6):
        return unit, f"{name} (detected: standing extent {height * unit:.2f} m)", "xyz"[axis]
    unit = _STANDING_EXTENT / height
    return unit, (f"{unit:.4g} m per unit (no standard unit fits: the skeleton's standing extent of "
                  f"{height:.4g} units scaled to {_STANDING_EXTENT} m)"), "xyz"[axis]


def parse_length_unit(text: str | float) -> float | str:
    """--length-unit: auto, a unit name (m, dm, cm, mm, in, ft) or metres per unit (a number > 0)."""
    if isinstance(text, (int, float)):
        value = float(text)
    elif text in ("auto",) or text in LENGTH_UNITS:
        return LENGTH_UNITS.get(text, "auto")
    else:
        try:
            value = float(text)
        except ValueError:
            raise ConfigError(f"length unit '{text}': use auto, {', '.join(LENGTH_UNITS)} or metres per unit",
                              key="--length-unit") from None
    if not (np.isfinite(value) and value > 0):
        raise ConfigError(f"length unit must be > 0 metres per unit, got {text}", key="--length-unit")
    return value


def load_recording(path: str | Path, *, length_unit: float | str = "auto", up_axis: str = "auto") -> MocapRecording:
    """Read a ``.bvh``, ``.mvnx`` or pose ``.csv`` file. A BVH file's length unit and up axis are detected from
    its skeleton (:func:`detect_length_unit`) unless given; ``length_unit_note`` says what was used.

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
    if up_axis not in ("auto", "x", "y", "z"):
        raise ConfigError(f"up axis '{up_axis}': use auto, x, y or z", key="--up-axis")
    if reader is not read_bvh:
        return reader(path)
    unit = parse_length_unit(length_unit)
    raw = read_bvh(path, length_unit=1.0, up_axis="y" if up_axis == "auto" else up_axis)
    if unit == "auto":
        unit, note, axis = detect_length_unit(raw, up_axis)
    else:
        axis = raw.up_axis if up_axis == "auto" else up_axis
        note = f"{unit:g} m per unit (given)"
    return dataclasses.replace(raw, positions=np.asarray(raw.positions) * unit, up_axis=axis, length_unit_note=note)
