"""TRC marker files (the text format of OpenSim and Motion Analysis Cortex): marker trajectories -> the segment
poses of the retargeting's canonical segments, built as for a C3D file (:mod:`~wbcbench.teleop.io.c3d`: Plug-in
Gait, the CMU/HDM05 Vicon waist set, OpenSim's gait set).

The layout read (tab-separated)::

    PathFileType  4  (X/Y/Z)  name.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  ...
    60.00     60.00       151        41          mm     ...
    Frame#  Time  R.ASIS        L.ASIS  ...
                  X1  Y1  Z1    X2  Y2  Z2 ...
    1       0.000 617.2 1055.3 170.8 ...

An empty or NaN cell is a gap.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .c3d import _UNITS, markers_recording
from .recording import MocapRecording

__all__ = ["read_trc", "read_trc_markers", "write_trc"]


def read_trc_markers(path: str | Path) -> tuple[list[str], np.ndarray, float]:
    """(marker labels, (N, P, 3) positions [m] with NaN gaps, frame rate [Hz]) of a TRC file.

    Raises:
        ConfigError: a missing header field, an unknown unit, a rate <= 0, no frames, or a row that is not
            numbers or is shorter than the header's markers (one line naming the file and the line).
    """
    file = str(path)
    try:
        lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise ConfigError(f"cannot read ({exc.strerror})", file=file) from None
    if not lines or not lines[0].startswith("PathFileType"):
        raise ConfigError("not a TRC file: its first line must start with 'PathFileType'", file=file)
    if len(lines) < 5:
        raise ConfigError(f"TRC header truncated: {len(lines)} line(s), the header takes 5 (file type, field names, "
                          "their values, marker names, coordinates)", file=file)
    header = dict(zip((k.strip() for k in lines[1].split("\t")), (v.strip() for v in lines[2].split("\t"))))
    for key in ("DataRate", "Units"):
        if not header.get(key):
            raise ConfigError(f"TRC: header field '{key}' not found (line 2 names the fields, line 3 their values)",
                              file=file)
    units = header["Units"].lower()
    if units not in _UNITS:
        raise ConfigError(f"TRC: unknown Units '{header['Units']}'; known: {', '.join(_UNITS)}", file=file)
    try:
        rate = float(header["DataRate"])
    except ValueError:
        rate = float("nan")
    if not (np.isfinite(rate) and rate > 0):
        raise ConfigError(f"TRC: DataRate must be a number > 0, got '{header['DataRate']}'", file=file)
    names = [s.strip() for s in lines[3].split("\t")[2:]]
    labels = [s for s in names if s]
    if not labels:
        raise ConfigError("TRC: line 4 names no markers (after Frame# and Time)", file=file)
    width = 2 + 3 * len(labels)
    rows = []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        cells = line.split("\t")
        if len(cells) < width:
            raise ConfigError(f"TRC: line {i} has {max(0, len(cells) - 2)} of the {width - 2} coordinates of its "
                              f"{len(labels)} markers (a truncated file?)", file=file)
        try:
            rows.append([float(c) if c.strip() else np.nan for c in cells[2:width]])
        except ValueError:
            raise ConfigError(f"TRC: line {i} holds a value that is not a number", file=file) from None
    if not rows:
        raise ConfigError("TRC: no frames", file=file)
    xyz = np.asarray(rows, dtype=float).reshape(len(rows), len(labels), 3) * _UNITS[units]
    return labels, xyz, rate


def read_trc(path: str | Path) -> MocapRecording:
    """Read a TRC marker file into a :class:`~wbcbench.teleop.MocapRecording` of the canonical segments
    (positions in metres; the marker sets of :mod:`~wbcbench.teleop.io.c3d`).

    Raises:
        ConfigError: a malformed file (:func:`read_trc_markers`) or missing markers (one line naming the file).
    """
    labels, xyz, rate = read_trc_markers(path)
    return markers_recording(labels, xyz, rate, str(path))


def write_trc(path: str | Path, markers: dict[str, np.ndarray], rate: float, units: str = "mm",
              decimals: int = 4) -> Path:
    """Write marker trajectories (label -> (N, 3) [m]; NaN: a gap, written as empty cells) to a TRC file in
    `units`, `decimals` decimals of that unit."""
    labels = list(markers)
    xyz = np.stack([markers[k] for k in labels], axis=1) / _UNITS[units]  # (N, P, 3)
    n = xyz.shape[0]
    out = [f"PathFileType\t4\t(X/Y/Z)\t{Path(path).name}",
           "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
           f"{rate:g}\t{rate:g}\t{n}\t{len(labels)}\t{units}\t{rate:g}\t1\t{n}",
           "\t".join(["Frame#", "Time"] + [f"{k}\t\t" for k in labels]).rstrip("\t"),
           "\t".join(["", ""] + [f"{a}{j + 1}" for j in range(len(labels)) for a in "XYZ"]),
           ""]
    for i in range(n):
        cells = ["" if not np.isfinite(v) else f"{v:.{decimals}f}" for v in xyz[i].ravel()]
        out.append("\t".join([str(i + 1), f"{i / rate:.6f}", *cells]))
    Path(path).write_text("\n".join(out) + "\n")
    return Path(path)
