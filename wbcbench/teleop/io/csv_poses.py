"""Plain CSV of segment poses ("long" format: one row per segment per frame).

Format::

    # wbcbench pose csv 1                 optional comment lines start with '#'
    # frame_rate: 60                      optional metadata 'key: value' in comments: frame_rate [Hz],
    # up_axis: z                          up_axis (x|y|z)
    t,segment,x,y,z,qx,qy,qz,qw           header, exactly these nine columns in this order
    0.0,Pelvis,0.0,0.0,0.97,0,0,0,1
    0.0,LeftHand,...

* ``t``: time [s], non-decreasing; rows with the same ``t`` form one frame;
* ``segment``: segment name (canonical MVN names recommended, see :mod:`wbcbench.teleop.io.segments`);
* ``x, y, z``: world position of the segment origin [m];
* ``qx, qy, qz, qw``: world orientation, unit quaternion, scalar last (normalised on read if within 1 %).

Every frame must list the same set of segments as the first frame, each once. Without ``frame_rate`` metadata
the rate is 1 / median time step. Errors name the file and the line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .bvh import _is_float
from .recording import MocapRecording, parents_from_names
from .segments import MVN_PARENTS

__all__ = ["read_pose_csv", "write_pose_csv", "CSV_COLUMNS"]

CSV_COLUMNS = ("t", "segment", "x", "y", "z", "qx", "qy", "qz", "qw")


def read_pose_csv(path: str | Path) -> MocapRecording:
    """Read a pose CSV (see the module docstring) into a :class:`~wbcbench.teleop.MocapRecording`.

    Raises:
        ConfigError: unreadable file, wrong header, bad row, inconsistent frames, truncated last frame (one line
            naming the file and the line).
    """
    file = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file (byte {exc.start} is not UTF-8)", file=file) from None

    def fail(lineno: int, message: str) -> ConfigError:
        return ConfigError(f"line {lineno}: {message}", file=file)

    meta: dict[str, str] = {}
    header_seen = False
    frames: list[tuple[float, int, dict[str, tuple[np.ndarray, np.ndarray]]]] = []
    segments: list[str] | None = None
    lines = text.splitlines()
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if ":" in body:
                key, value = body.split(":", 1)
                meta[key.strip().lower()] = value.strip()
            continue
        fields = [f.strip() for f in line.split(",")]
        if not header_seen:
            if tuple(f.lower() for f in fields) != CSV_COLUMNS:
                raise fail(lineno, f"header must be '{','.join(CSV_COLUMNS)}', found {line[:80]!r}")
            header_seen = True
            continue
        if len(fields) != len(CSV_COLUMNS):
            raise fail(lineno, f"{len(fields)} columns, expected {len(CSV_COLUMNS)} (truncated row?)")
        try:
            numbers = [float(fields[0])] + [float(f) for f in fields[2:]]
        except ValueError:
            bad = next(f for k, f in enumerate(fields) if k != 1 and not _is_float(f))
            raise fail(lineno, f"{bad!r} is not a number") from None
        if not all(math.isfinite(v) for v in numbers):
            raise fail(lineno, "non-finite value")
        t, name = numbers[0], fields[1]
        if not name:
            raise fail(lineno, "empty segment name")
        position = np.array(numbers[1:4])
        quat = np.array(numbers[4:8])
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-2:
            raise fail(lineno, f"quaternion norm {norm:.4g} is not 1 (qx, qy, qz, qw expected)")
        if frames and t < frames[-1][0]:
            raise fail(lineno, f"time {t:g} s goes backwards (previous frame at {frames[-1][0]:g} s)")
        if not frames or t > frames[-1][0]:
            if frames:
                _check_complete(frames[-1], segments, fail)
                if segments is None:
                    segments = list(frames[-1][2])
            frames.append((t, lineno, {}))
        current = frames[-1][2]
        if name in current:
            raise fail(lineno, f"segment {name!r} appears twice at t = {t:g} s")
        if segments is not None and name not in segments:
            raise fail(lineno, f"segment {name!r} is not in the first frame")
        current[name] = (position, quat / norm)
    if not header_seen:
        raise ConfigError(f"line {len(lines) or 1}: no header line '{','.join(CSV_COLUMNS)}'", file=file)
    if not frames:
        raise ConfigError(f"line {len(lines)}: no data row", file=file)
    if segments is None:
        segments = list(frames[-1][2])
    _check_complete(frames[-1], segments, fail, last=True, last_line=len(lines))
    n, s = len(frames), len(segments)
    times = np.array([f[0] for f in frames])
    positions = np.empty((n, s, 3))
    orientations = np.empty((n, s, 4))
    for i, (_, _, poses) in enumerate(frames):
        for k, name in enumerate(segments):
            positions[i, k], orientations[i, k] = poses[name]
    if "frame_rate" in meta:
        try:
            frame_rate = float(meta["frame_rate"])
        except ValueError:
            raise ConfigError(f"metadata frame_rate is not a number: {meta['frame_rate']!r}", file=file) from None
        if not (math.isfinite(frame_rate) and frame_rate > 0):
            raise ConfigError(f"metadata frame_rate must be > 0, got {meta['frame_rate']!r}", file=file)
    elif n > 1:
        frame_rate = 1.0 / float(np.median(np.diff(times)))
    else:
        frame_rate = 1.0
    up_axis = meta.get("up_axis", "z").lower()
    if up_axis not in ("x", "y", "z"):
        raise ConfigError(f"metadata up_axis must be x, y or z, got {up_axis!r}", file=file)
    return MocapRecording(
        source=file,
        frame_rate=frame_rate,
        times=times,
        segments=tuple(segments),
        parents=parents_from_names(segments, MVN_PARENTS),
        positions=positions,
        orientations=orientations,
        up_axis=up_axis,
    )


def _check_complete(frame, segments, fail, *, last: bool = False, last_line: int = 0) -> None:
    t, lineno, poses = frame
    if segments is None or len(poses) == len(segments):
        return
    missing = [s for s in segments if s not in poses]
    where = last_line if last else lineno
    hint = " (truncated?)" if last else ""
    raise fail(where, f"frame at t = {t:g} s lacks segments {missing[:4]}{'...' if len(missing) > 4 else ''}{hint}")




def write_pose_csv(path: str | Path, recording: MocapRecording, *, decimals: int = 6) -> Path:
    """Write ``recording``'s segment poses as a pose CSV (joint angles are not part of the format).

    Segments with non-finite poses in a frame are an error (the format has no missing values).
    Returns the path written.
    """
    if not (np.all(np.isfinite(recording.positions)) and np.all(np.isfinite(recording.orientations))):
        raise ValueError("the pose CSV format has no missing values: positions and orientations must be finite")
    fmt = f"{{:.{decimals}f}}"
    out = [
        "# wbcbench pose csv 1",
        f"# frame_rate: {recording.frame_rate:.10g}",
        f"# up_axis: {recording.up_axis}",
        ",".join(CSV_COLUMNS),
    ]
    for i in range(recording.n_frames):
        t = f"{recording.times[i]:.9g}"
        for k, name in enumerate(recording.segments):
            values = list(recording.positions[i, k]) + list(recording.orientations[i, k])
            out.append(f"{t},{name}," + ",".join(fmt.format(v) for v in values))
    path = Path(path)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
