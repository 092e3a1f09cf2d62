"""Open any supported recording by its file suffix."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .bvh import bvh_recording, parse_bvh, read_bvh
from .c3d import read_c3d
from .conventions import LENGTH_UNITS, detect_conventions
from .csv_poses import read_pose_csv
from .mvnx import read_mvnx
from .recording import MocapRecording
from .skeleton_map import map_segments
from .trc import read_trc

__all__ = ["LENGTH_UNITS", "RECORDING_SUFFIXES", "detect_length_unit", "load_recording", "parse_length_unit"]

#: Suffix -> reader.
RECORDING_SUFFIXES = {".bvh": read_bvh, ".mvnx": read_mvnx, ".csv": read_pose_csv, ".c3d": read_c3d,
                      ".trc": read_trc}


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
    """Read a ``.bvh``, ``.mvnx``, pose ``.csv``, or a ``.c3d`` or ``.trc`` marker file. Its conventions are
    detected from the data (:func:`~wbcbench.teleop.io.conventions.detect_conventions`: a BVH file's length unit
    and up axis, unless given; for every format the forward axis, rest pose, rotation orders and naming family)
    and kept in the recording's ``conventions`` (``conventions["line"]``: one line saying what was found);
    ``length_unit_note`` says which unit was used.

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
        rec = reader(path)
        conv = detect_conventions(rec, mapping=_mapping(rec), length_unit=1.0, up_axis=up_axis, unit_method="file")
        if reader in (read_c3d, read_trc):  # the segments are built from the markers under the canonical names
            conv = dataclasses.replace(conv, naming=f"{rec.conventions.get('marker_set', 'Plug-in Gait')} markers",
                                       notes=tuple(rec.conventions.get("notes", ())))
        return dataclasses.replace(rec, conventions=conv.as_dict())
    unit = parse_length_unit(length_unit)
    data = parse_bvh(path)
    raw = bvh_recording(data, str(path), length_unit=1.0, up_axis="y" if up_axis == "auto" else up_axis)
    conv = detect_conventions(raw, skeleton=data.skeleton, mapping=_mapping(raw), up_axis=up_axis,
                              length_unit=None if unit == "auto" else unit,
                              unit_method="detected" if unit == "auto" else "given")
    if unit == "auto":
        unit = conv.length_unit
        note = (f"{conv.unit_name or f'{unit:.4g} m per unit'} (detected: stature {conv.stature_m:.2f} m, "
                f"confidence {conv.unit_confidence:.2f})")
    else:
        note = f"{unit:g} m per unit (given)"
    if not (np.isfinite(unit) and unit > 0):
        raise ConfigError("cannot detect the length unit: the skeleton has no size", file=str(path),
                          key="--length-unit")
    return dataclasses.replace(raw, positions=np.asarray(raw.positions) * unit, up_axis=conv.up_axis,
                               length_unit_note=note, conventions=conv.as_dict())


def _mapping(recording: MocapRecording):
    """The recording's segment mapping (names, then hierarchy), or None when neither finds every segment."""
    try:
        return map_segments(recording.segments, recording.parents, recording.source)
    except ConfigError:
        return None
