"""Xsens MVNX (MVN Analyze XML export): reader and a minimal writer.

The elements read (MVNX version 4; an XML namespace, if any, is ignored)::

    <mvnx version="4">
      <subject label="..." frameRate="60" segmentCount="23">
        <segments>
          <segment label="Pelvis" id="1"> ... </segment>            one per segment, in data order
        </segments>
        <joints>                                                     optional
          <joint label="jL5S1"> <connector1>Pelvis/jL5S1</connector1> <connector2>L5/jL5S1</connector2> </joint>
        </joints>
        <frames segmentCount="23" jointCount="22">
          <frame time="0" index="0" type="normal">                  time in ms
            <orientation> q0 q1 q2 q3 ... </orientation>           4 per segment: w x y z (scalar FIRST)
            <position> x y z ... </position>                       3 per segment [m]
            <jointAngle> ... </jointAngle>                          3 per joint [deg], optional
          </frame>
        </frames>
      </subject>
    </mvnx>

Frames whose ``type`` is not ``normal`` (the ``identity``, ``tpose`` and ``tpose-isb`` calibration frames MVN
writes first) are skipped. Joint angles become channels ``"<joint label>:x|y|z"`` (the file's three values in
order), in radians. Orientations are converted to (x, y, z, w).

Malformed XML, a truncated file, missing elements or attributes, and wrong value counts raise a one-line
:class:`~wbcbench.errors.ConfigError` naming the file, the line and the element.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np

from ...errors import ConfigError
from .recording import MocapRecording, parents_from_names
from .segments import MVN_PARENTS

__all__ = ["read_mvnx", "write_mvnx"]


@dataclass
class _Node:
    tag: str
    attrib: dict[str, str]
    line: int
    children: list["_Node"] = field(default_factory=list)
    text_parts: list[str] = field(default_factory=list)

    @property
    def text(self) -> str:
        return "".join(self.text_parts)

    def find(self, tag: str) -> "_Node | None":
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag: str) -> list["_Node"]:
        return [c for c in self.children if c.tag == tag]

    def describe(self) -> str:
        keys = [k for k in ("label", "index", "id") if k in self.attrib]
        attrs = "".join(f' {k}="{self.attrib[k]}"' for k in keys)
        return f"<{self.tag}{attrs}>"


def _local(tag: str) -> str:
    """Tag without its namespace (expat with namespace processing off keeps ``prefix:tag``)."""
    return tag.rsplit("}", 1)[-1].rsplit(":", 1)[-1]


def _parse_xml(data: bytes, file: str) -> _Node:
    """A small element tree that remembers each element's line (ElementTree does not)."""
    parser = expat.ParserCreate()
    root: list[_Node] = []
    stack: list[_Node] = []

    def start(tag: str, attrib: dict[str, str]) -> None:
        node = _Node(_local(tag), dict(attrib), parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(tag: str) -> None:
        stack.pop()

    def chars(text: str) -> None:
        if stack:
            stack[-1].text_parts.append(text)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    # No DTD, no external entities: MVNX never needs them.
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        reason = expat.ErrorString(exc.code)
        hint = " (truncated?)" if "no element found" in reason or "unclosed token" in reason else ""
        raise ConfigError(f"line {exc.lineno}: malformed XML: {reason}{hint}", file=file) from None
    return root[0]


def _floats(node: _Node, expected: int, file: str, where: str) -> np.ndarray:
    fields = node.text.split()
    if len(fields) != expected:
        raise ConfigError(
            f"line {node.line}: {where} <{node.tag}> has {len(fields)} values, expected {expected}", file=file
        )
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        raise ConfigError(f"line {node.line}: {where} <{node.tag}> holds a non-number", file=file) from None
    if not np.all(np.isfinite(values)):
        raise ConfigError(f"line {node.line}: {where} <{node.tag}> holds non-finite values", file=file)
    return values


def _required(node: _Node, tag: str, file: str) -> _Node:
    child = node.find(tag)
    if child is None:
        raise ConfigError(f"line {node.line}: {node.describe()} has no <{tag}> element", file=file)
    return child


def _attribute(node: _Node, key: str, file: str) -> str:
    if key not in node.attrib:
        raise ConfigError(f"line {node.line}: {node.describe()} has no '{key}' attribute", file=file)
    return node.attrib[key]


def _number_attribute(node: _Node, key: str, file: str) -> float:
    text = _attribute(node, key, file)
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(
            f"line {node.line}: {node.describe()}: '{key}' is not a number: {text!r}", file=file
        ) from None
    if not math.isfinite(value):
        raise ConfigError(f"line {node.line}: {node.describe()}: '{key}' must be finite", file=file)
    return value


def read_mvnx(path: str | Path) -> MocapRecording:
    """Read an Xsens MVNX file into a :class:`~wbcbench.teleop.MocapRecording` (see the module docstring).

    Raises:
        ConfigError: unreadable, malformed or truncated file, or inconsistent content (one line naming the file,
            the line and the element).
    """
    file = str(path)
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    root = _parse_xml(data, file)
    if root.tag != "mvnx":
        raise ConfigError(f"line {root.line}: root element is <{root.tag}>, expected <mvnx>", file=file)
    subject = _required(root, "subject", file)
    frame_rate = _number_attribute(subject, "frameRate", file)
    if frame_rate <= 0.0:
        raise ConfigError(f"line {subject.line}: <subject>: frameRate must be > 0, got {frame_rate:g}", file=file)
    segments_node = _required(subject, "segments", file)
    segment_nodes = segments_node.findall("segment")
    if not segment_nodes:
        raise ConfigError(f"line {segments_node.line}: <segments> lists no <segment>", file=file)
    segments = tuple(_attribute(s, "label", file) for s in segment_nodes)
    if len(set(segments)) != len(segments):
        raise ConfigError(f"line {segments_node.line}: <segments> has duplicate labels", file=file)
    joints_node = subject.find("joints")
    joint_labels = (
        tuple(_attribute(j, "label", file) for j in joints_node.findall("joint")) if joints_node is not None else ()
    )
    frames_node = _required(subject, "frames", file)
    n_seg = len(segments)
    times, positions, orientations, angles = [], [], [], []
    has_angles: bool | None = None
    for frame in frames_node.findall("frame"):
        if frame.attrib.get("type", "normal") != "normal":
            continue
        where = frame.describe()
        t_ms = _number_attribute(frame, "time", file)
        q = _floats(_required(frame, "orientation", file), 4 * n_seg, file, where).reshape(n_seg, 4)
        norms = np.linalg.norm(q, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-2):
            raise ConfigError(
                f"line {frame.line}: {where} <orientation> holds a non-unit quaternion", file=file
            )
        p = _floats(_required(frame, "position", file), 3 * n_seg, file, where).reshape(n_seg, 3)
        ja_node = frame.find("jointAngle")
        frame_has_angles = ja_node is not None and bool(joint_labels)
        if has_angles is None:
            has_angles = frame_has_angles
        elif has_angles != frame_has_angles:
            raise ConfigError(f"line {frame.line}: {where}: <jointAngle> present in some frames only", file=file)
        if frame_has_angles:
            assert ja_node is not None
            angles.append(np.radians(_floats(ja_node, 3 * len(joint_labels), file, where)))
        if times and t_ms / 1000.0 <= times[-1]:
            raise ConfigError(f"line {frame.line}: {where}: time {t_ms:g} ms does not increase", file=file)
        times.append(t_ms / 1000.0)
        orientations.append(np.concatenate([q[:, 1:], q[:, :1]], axis=1) / norms[:, None])
        positions.append(p)
    if not times:
        raise ConfigError(f"line {frames_node.line}: <frames> holds no frame of type 'normal'", file=file)
    joint_names: tuple[str, ...] = ()
    joint_angles = np.zeros((len(times), 0))
    if has_angles:
        joint_names = tuple(f"{label}:{axis}" for label in joint_labels for axis in "xyz")
        joint_angles = np.array(angles)
    return MocapRecording(
        source=file,
        frame_rate=frame_rate,
        times=np.array(times),
        segments=segments,
        parents=parents_from_names(segments, MVN_PARENTS),
        positions=np.array(positions),
        orientations=np.array(orientations),
        joint_names=joint_names,
        joint_angles=joint_angles,
        up_axis="z",
    )


def write_mvnx(path: str | Path, recording: MocapRecording, *, decimals: int = 6) -> Path:
    """Write ``recording`` as a minimal MVNX 4 file that :func:`read_mvnx` (and MVN-style tools) can read.

    Joint angles are written only when every channel is named ``"<joint>:x|y|z"`` in complete x, y, z triplets.
    Returns the path written.
    """
    from xml.sax.saxutils import quoteattr

    fmt = f"{{:.{decimals}f}}"
    labels: list[str] = []
    names = list(recording.joint_names)
    split = [name.rsplit(":", 1) for name in names]
    triplets = len(names) % 3 == 0 and all(
        len(part) == 2 and part[1] == "xyz"[k % 3] and part[0] == split[k - k % 3][0] for k, part in enumerate(split)
    )
    if triplets:
        labels = [split[k][0] for k in range(0, len(names), 3)]
    out = ['<?xml version="1.0" encoding="UTF-8"?>', '<mvnx version="4">']
    out.append(
        f'<subject label="wbcbench" frameRate={quoteattr(f"{recording.frame_rate:g}")} '
        f'segmentCount="{len(recording.segments)}">'
    )
    out.append("<segments>")
    for k, name in enumerate(recording.segments):
        out.append(f"<segment label={quoteattr(name)} id=\"{k + 1}\"/>")
    out.append("</segments>")
    if labels:
        out.append("<joints>")
        for label in labels:
            out.append(f"<joint label={quoteattr(label)}/>")
        out.append("</joints>")
    out.append(f'<frames segmentCount="{len(recording.segments)}" jointCount="{len(labels)}">')
    for i in range(recording.n_frames):
        q = recording.orientations[i]
        wxyz = np.concatenate([q[:, 3:], q[:, :3]], axis=1).reshape(-1)
        out.append(f'<frame time="{recording.times[i] * 1000.0:.6f}" index="{i}" type="normal">')
        out.append("<orientation>" + " ".join(fmt.format(v) for v in wxyz) + "</orientation>")
        out.append("<position>" + " ".join(fmt.format(v) for v in recording.positions[i].reshape(-1)) + "</position>")
        if labels:
            deg = np.degrees(recording.joint_angles[i])
            out.append("<jointAngle>" + " ".join(fmt.format(v) for v in deg) + "</jointAngle>")
        out.append("</frame>")
    out += ["</frames>", "</subject>", "</mvnx>"]
    path = Path(path)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
