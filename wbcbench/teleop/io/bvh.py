"""BVH (Biovision Hierarchy) motion files: reader, writer and forward kinematics.

Format (as written by most exporters, and by :func:`write_bvh`)::

    HIERARCHY
    ROOT Pelvis
    {
      OFFSET 0 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      JOINT L5
      {
        OFFSET 0 0 0
        CHANNELS 2 Zrotation Xrotation
        ...
        End Site
        {
          OFFSET 0 -8 0
        }
      }
    }
    MOTION
    Frames: 600
    Frame Time: 0.02
    <one line per frame: every channel value, in hierarchy order>

Conventions followed here:

* angles are in degrees; a joint's local rotation is the product of its rotation channels **in the listed
  order**, ``R = R_ch1 R_ch2 R_ch3`` (intrinsic rotations: "Zrotation Xrotation Yrotation" is the ZXY Euler
  sequence). Any order and any subset of the three axes is accepted;
* a joint's local translation is ``OFFSET`` plus its position channels (axes without a channel keep the offset
  value), so a root with ``OFFSET 0 0 0`` gets its position from the channels;
* ``p_world(child) = p_world(parent) + R_world(parent) t_local(child)``, ``R_world(child) = R_world(parent) R``;
* lengths are in the file's unit; :func:`read_bvh` converts with ``length_unit`` (default 0.01: centimetres,
  the common BVH unit and the one :func:`write_bvh` is used with in this package).

Every malformed or truncated file raises a one-line :class:`~wbcbench.errors.ConfigError` naming the file and the
line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ...errors import ConfigError
from .. import _rotations as rot
from .recording import MocapRecording

__all__ = ["BvhJoint", "BvhSkeleton", "BvhData", "bvh_recording", "parse_bvh", "read_bvh", "write_bvh"]

FloatArray = npt.NDArray[np.float64]

CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_CHANNEL_LOWER = {name.lower(): name for name in CHANNEL_NAMES}


@dataclass(frozen=True)
class BvhJoint:
    """One joint of a BVH hierarchy.

    Attributes:
        name: joint name (unique in the file).
        parent: index of the parent joint in :attr:`BvhSkeleton.joints`, -1 for a root.
        offset: translation from the parent joint, in the parent's frame (file length unit).
        channels: channel names in file order, from ``Xposition Yposition Zposition Xrotation Yrotation
            Zrotation``.
        end_site: ``End Site`` offset (file length unit), or ``None``.
    """

    name: str
    parent: int
    offset: tuple[float, float, float]
    channels: tuple[str, ...]
    end_site: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class BvhSkeleton:
    """A BVH hierarchy: joints in file order (every parent before its children)."""

    joints: tuple[BvhJoint, ...]

    def __post_init__(self) -> None:
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise ValueError("BVH joint names must be unique")
        for k, joint in enumerate(self.joints):
            if not -1 <= joint.parent < k:
                raise ValueError(f"joint {joint.name!r}: parent must come before it")
            for ch in joint.channels:
                if ch not in CHANNEL_NAMES:
                    raise ValueError(f"joint {joint.name!r}: unknown channel {ch!r}")

    @property
    def channel_count(self) -> int:
        """Total number of channels (values per motion frame)."""
        return sum(len(j.channels) for j in self.joints)

    @property
    def channel_names(self) -> tuple[str, ...]:
        """``"<joint>:<channel>"`` for every channel, in motion-line order."""
        return tuple(f"{j.name}:{ch}" for j in self.joints for ch in j.channels)

    def forward_kinematics(self, motion: FloatArray, length_unit: float = 1.0) -> tuple[FloatArray, FloatArray]:
        """World positions and rotations of every joint for each motion frame.

        Args:
            motion: (N, channel_count) channel values (file unit, degrees).
            length_unit: multiplies offsets and position channels (e.g. 0.01 for centimetres to metres).

        Returns:
            ``(positions (N, J, 3), rotations (N, J, 3, 3))`` in the BVH world frame.
        """
        motion = np.asarray(motion, dtype=float)
        n = motion.shape[0]
        nj = len(self.joints)
        positions = np.zeros((n, nj, 3))
        rotations = np.zeros((n, nj, 3, 3))
        col = 0
        for k, joint in enumerate(self.joints):
            t_local = np.tile(np.asarray(joint.offset, dtype=float), (n, 1))
            R_local = np.tile(np.eye(3), (n, 1, 1))
            for ch in joint.channels:
                values = motion[:, col]
                col += 1
                axis = ch[0].lower()
                if ch.endswith("position"):
                    t_local[:, "xyz".index(axis)] = joint.offset["xyz".index(axis)] + values
                else:
                    R_local = R_local @ rot.axis_rotations(axis, np.radians(values))
            t_local = t_local * length_unit
            if joint.parent < 0:
                positions[:, k] = t_local
                rotations[:, k] = R_local
            else:
                R_parent = rotations[:, joint.parent]
                positions[:, k] = positions[:, joint.parent] + np.einsum("nij,nj->ni", R_parent, t_local)
                rotations[:, k] = R_parent @ R_local
        return positions, rotations


class BvhData(NamedTuple):
    """Content of a BVH file: hierarchy, raw motion (file unit, degrees) and frame period [s]."""

    skeleton: BvhSkeleton
    motion: FloatArray
    frame_time: float


# ---------------------------------------------------------------------------------------------------- parsing
class _Tokens:
    """Whitespace tokens of the hierarchy part with their line numbers."""

    def __init__(self, lines: Sequence[str], file: str) -> None:
        self.items: list[tuple[str, int]] = []
        self.file = file
        self.pos = 0
        self.last_line = max(len(lines), 1)
        for lineno, line in enumerate(lines, start=1):
            for tok in line.split():
                self.items.append((tok, lineno))

    def error(self, message: str, line: int | None = None) -> ConfigError:
        if line is None:
            line = self.items[self.pos][1] if self.pos < len(self.items) else self.last_line
        return ConfigError(f"line {line}: {message}", file=self.file)

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise self.error(f"unexpected end of file, expected {what} (truncated?)")
        item = self.items[self.pos]
        self.pos += 1
        return item

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.error(f"expected {word!r}, found {tok!r}", line)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise self.error(f"expected a number for {what}, found {tok!r}", line) from None
        if not math.isfinite(value):
            raise self.error(f"{what} must be finite, found {tok!r}", line)
        return value

    def peek(self) -> str | None:
        return self.items[self.pos][0] if self.pos < len(self.items) else None

    def name(self, what: str) -> tuple[str, int]:
        """A joint name: the rest of its line (3ds Max Biped names hold spaces: ``JOINT Bip01 L Thigh``)."""
        tok, line = self.next(what)
        while self.pos < len(self.items) and self.items[self.pos][1] == line and self.items[self.pos][0] != "{":
            tok = f"{tok} {self.items[self.pos][0]}"
            self.pos += 1
        return tok, line


def _parse_joint(tokens: _Tokens, name: str, parent: int, joints: list[BvhJoint], line: int) -> None:
    if any(j.name == name for j in joints):
        raise tokens.error(f"joint {name!r} defined twice", line)
    tokens.expect("{")
    tokens.expect("OFFSET")
    offset = tuple(tokens.number(f"OFFSET of {name!r}") for _ in range(3))
    channels: tuple[str, ...] = ()
    if (tokens.peek() or "").upper() == "CHANNELS":
        tokens.next("CHANNELS")
        count_f = tokens.number(f"channel count of {name!r}")
        if count_f != int(count_f) or not 0 <= count_f <= 6:
            raise tokens.error(f"channel count of {name!r} must be an integer in [0, 6], found {count_f:g}")
        names = []
        for _ in range(int(count_f)):
            tok, tline = tokens.next(f"a channel name of {name!r}")
            canonical = _CHANNEL_LOWER.get(tok.lower())
            if canonical is None:
                raise tokens.error(
                    f"unknown channel {tok!r} in joint {name!r}; allowed: {', '.join(CHANNEL_NAMES)}", tline
                )
            if canonical in names:
                raise tokens.error(f"channel {tok!r} listed twice in joint {name!r}", tline)
            names.append(canonical)
        channels = tuple(names)
    index = len(joints)
    joints.append(BvhJoint(name, parent, offset, channels))  # type: ignore[arg-type]
    end_site = None
    while True:
        tok, tline = tokens.next(f"'JOINT', 'End Site' or '}}' in joint {name!r}")
        upper = tok.upper()
        if upper == "}":
            break
        if upper == "JOINT":
            child, cline = tokens.name("a joint name")
            _parse_joint(tokens, child, index, joints, cline)
        elif upper == "END":
            tokens.expect("Site")
            tokens.expect("{")
            tokens.expect("OFFSET")
            end_site = tuple(tokens.number(f"End Site OFFSET of {name!r}") for _ in range(3))
            tokens.expect("}")
        else:
            raise tokens.error(f"expected 'JOINT', 'End Site' or '}}' in joint {name!r}, found {tok!r}", tline)
    if end_site is not None:
        joints[index] = BvhJoint(name, parent, offset, channels, end_site)  # type: ignore[arg-type]


def parse_bvh(path: str | Path) -> BvhData:
    """Read a BVH file without interpreting it (file units, degrees).

    Raises:
        ConfigError: unreadable, malformed or truncated file; the message names the file and the line.
    """
    file = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="strict")
    except OSError as exc:
        raise ConfigError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file (byte {exc.start} is not UTF-8)", file=file) from None
    lines = text.splitlines()
    motion_line = next((i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    if motion_line is None:
        raise ConfigError(f"line {len(lines) or 1}: no 'MOTION' section (truncated?)", file=file)
    tokens = _Tokens(lines[:motion_line], file)
    if tokens.peek() is None:
        raise tokens.error("no 'HIERARCHY' section", 1)
    tokens.expect("HIERARCHY")
    joints: list[BvhJoint] = []
    while tokens.peek() is not None:
        tok, line = tokens.next("'ROOT'")
        if tok.upper() != "ROOT":
            raise tokens.error(f"expected 'ROOT', found {tok!r}", line)
        name, nline = tokens.name("a root name")
        _parse_joint(tokens, name, -1, joints, nline)
    if not joints:
        raise tokens.error("the hierarchy has no joint", motion_line + 1)
    skeleton = BvhSkeleton(tuple(joints))

    def header(offset: int, key: str) -> tuple[float, int]:
        k = motion_line + offset
        if k >= len(lines):
            raise ConfigError(f"line {k + 1}: missing '{key}' (truncated?)", file=file)
        line = lines[k].strip()
        if not line.lower().startswith(key.lower()):
            raise ConfigError(f"line {k + 1}: expected '{key}', found {line[:40]!r}", file=file)
        value_text = line[len(key):].strip()
        try:
            value = float(value_text)
        except ValueError:
            raise ConfigError(f"line {k + 1}: '{key}' needs a number, found {value_text!r}", file=file) from None
        return value, k

    n_frames_f, _ = header(1, "Frames:")
    if n_frames_f != int(n_frames_f) or n_frames_f < 1:
        raise ConfigError(f"line {motion_line + 2}: 'Frames:' must be a positive integer", file=file)
    frame_time, ft_line = header(2, "Frame Time:")
    if not (math.isfinite(frame_time) and frame_time > 0.0):
        raise ConfigError(f"line {ft_line + 1}: 'Frame Time' must be > 0 s, found {frame_time:g}", file=file)
    n_frames = int(n_frames_f)
    n_channels = skeleton.channel_count
    motion = np.empty((n_frames, n_channels))
    k = 0
    for lineno in range(ft_line + 1, len(lines)):
        line = lines[lineno]
        if not line.strip():
            continue
        if k >= n_frames:
            raise ConfigError(
                f"line {lineno + 1}: more motion lines than the {n_frames} frames declared", file=file
            )
        fields = line.split()
        if len(fields) != n_channels:
            raise ConfigError(
                f"line {lineno + 1}: frame {k} has {len(fields)} values, expected {n_channels} (one per channel)",
                file=file,
            )
        try:
            row = np.array([float(f) for f in fields])
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            raise ConfigError(f"line {lineno + 1}: frame {k}: {bad!r} is not a number", file=file) from None
        if not np.all(np.isfinite(row)):
            raise ConfigError(f"line {lineno + 1}: frame {k} has non-finite values", file=file)
        motion[k] = row
        k += 1
    if k < n_frames:
        raise ConfigError(
            f"line {len(lines)}: {n_frames} frames declared, {k} found (truncated?)", file=file
        )
    return BvhData(skeleton, motion, float(frame_time))


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_bvh(path: str | Path, *, length_unit: float = 0.01, up_axis: str = "y") -> MocapRecording:
    """Read a BVH file into a :class:`~wbcbench.teleop.MocapRecording`.

    Segments are the BVH joints (End Sites are not segments); world poses come from the hierarchy's forward
    kinematics; joint angles are the rotation channels, named ``"<joint>:<X|Y|Z>rotation"``, in radians (file
    degrees). Time starts at 0 with the file's ``Frame Time`` period.

    Args:
        path: the ``.bvh`` file.
        length_unit: metres per file length unit (0.01: centimetres, the common BVH unit; 1.0 for metres).
        up_axis: vertical axis of the file's world frame (BVH convention: "y"); informative only.

    Raises:
        ConfigError: unreadable, malformed or truncated file (one line naming the file and the line).
    """
    if not (math.isfinite(length_unit) and length_unit > 0.0):
        raise ConfigError(f"length_unit must be > 0, got {length_unit!r}", file=str(path))
    return bvh_recording(parse_bvh(path), str(path), length_unit=length_unit, up_axis=up_axis)


def bvh_recording(data: BvhData, source: str, *, length_unit: float = 0.01, up_axis: str = "y") -> MocapRecording:
    """The :class:`~wbcbench.teleop.MocapRecording` of parsed BVH content (:func:`read_bvh` without the file)."""
    skeleton, motion = data.skeleton, data.motion
    positions, rotations = skeleton.forward_kinematics(motion, length_unit)
    orientations = rot.from_matrix(rotations)
    rotation_columns = [
        k for k, name in enumerate(skeleton.channel_names) if name.endswith("rotation")
    ]
    names = tuple(skeleton.channel_names[k] for k in rotation_columns)
    angles = np.radians(motion[:, rotation_columns])
    times = np.arange(motion.shape[0]) * data.frame_time
    return MocapRecording(
        source=source,
        frame_rate=1.0 / data.frame_time,
        times=times,
        segments=tuple(j.name for j in skeleton.joints),
        parents=tuple(j.parent for j in skeleton.joints),
        positions=positions,
        orientations=orientations,
        joint_names=names,
        joint_angles=angles,
        up_axis=up_axis,
    )


def _fmt(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def write_bvh(
    path: str | Path, skeleton: BvhSkeleton, motion: npt.ArrayLike, frame_time: float, *, decimals: int = 4
) -> Path:
    """Write a BVH file; ``motion`` (N, channel_count) in the file unit and degrees, columns in the order of
    ``skeleton.joints``. The hierarchy is written depth-first (children in their order in ``skeleton.joints``) and
    the motion columns follow it, so reading the file back gives the joints in depth-first order.

    Values are written with at most ``decimals`` decimals and trailing zeros dropped (compact files).
    Returns the path written.
    """
    motion = np.asarray(motion, dtype=float)
    if motion.ndim != 2 or motion.shape[1] != skeleton.channel_count:
        raise ValueError(f"motion must have shape (N, {skeleton.channel_count}), got {motion.shape}")
    if not (frame_time > 0.0):
        raise ValueError("frame_time must be > 0")
    children: dict[int, list[int]] = {k: [] for k in range(-1, len(skeleton.joints))}
    for k, joint in enumerate(skeleton.joints):
        children[joint.parent].append(k)
    out: list[str] = ["HIERARCHY"]

    def emit(k: int, depth: int) -> None:
        joint = skeleton.joints[k]
        pad = "  " * depth
        out.append(f"{pad}{'ROOT' if joint.parent < 0 else 'JOINT'} {joint.name}")
        out.append(f"{pad}{{")
        out.append(f"{pad}  OFFSET {' '.join(_fmt(v, decimals) for v in joint.offset)}")
        if joint.channels:
            out.append(f"{pad}  CHANNELS {len(joint.channels)} {' '.join(joint.channels)}")
        for child in children[k]:
            emit(child, depth + 1)
        if joint.end_site is not None:
            out.append(f"{pad}  End Site")
            out.append(f"{pad}  {{")
            out.append(f"{pad}    OFFSET {' '.join(_fmt(v, decimals) for v in joint.end_site)}")
            out.append(f"{pad}  }}")
        out.append(f"{pad}}}")

    order: list[int] = []  # joints in emission (depth-first) order, which is the motion-line order on read

    def visit(k: int) -> None:
        order.append(k)
        for child in children[k]:
            visit(child)

    for root in children[-1]:
        emit(root, 0)
        visit(root)
    starts = np.cumsum([0] + [len(j.channels) for j in skeleton.joints])
    columns = [c for k in order for c in range(starts[k], starts[k + 1])]
    out.append("MOTION")
    out.append(f"Frames: {motion.shape[0]}")
    out.append(f"Frame Time: {frame_time:.8g}")
    for row in motion[:, columns]:
        out.append(" ".join(_fmt(v, decimals) for v in row))
    path = Path(path)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
