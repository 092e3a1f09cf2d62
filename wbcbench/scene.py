"""The scene description: a flat floor, tilted platforms (boxes with poses), stairs; parsed from a scenario's
`terrain:`. Plain data read by both the simulator (`sim/`, which builds MuJoCo geoms from it) and the planners
(`planning/`, which turn it into contact surfaces), so neither imports the other. Also the external pushes a
scenario declares (`pushes:`), which the simulator applies."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import Section


@dataclass(frozen=True)
class Box:
    """A box obstacle/platform: centre [m], full size [m], orientation as roll-pitch-yaw [rad]."""

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = ""


@dataclass(frozen=True)
class Terrain:
    """A floor plane at z = 0 (unless `floor` is False) plus boxes."""

    kind: str = "flat"
    floor: bool = True
    boxes: tuple[Box, ...] = field(default_factory=tuple)
    friction: float = 1.0


def stairs(count: int, height: float, depth: float, width: float = 1.0, start_x: float = 0.3) -> tuple[Box, ...]:
    """`count` steps going up along +x, the first riser at x = start_x; each tread `depth` deep."""
    boxes = []
    for i in range(count):
        top = (i + 1) * height
        x0 = start_x + i * depth
        # each step is a solid block from the floor to its tread
        boxes.append(Box(center=(x0 + depth / 2, 0.0, top / 2), size=(depth, width, top), name=f"step_{i + 1}"))
    return tuple(boxes)


TERRAIN_TYPES = ("flat", "boxes", "stairs")


def parse_terrain(sec: Section) -> Terrain:
    """Build a Terrain from a `terrain:` mapping (see TERRAIN_TYPES); errors name the file and key."""
    kind = sec.str("type", "flat", choices=TERRAIN_TYPES)
    friction = sec.float("friction", 1.0, positive=True)
    if kind == "flat":
        sec.finish()
        return Terrain(kind="flat", friction=friction)
    if kind == "stairs":
        t = Terrain(kind="stairs", friction=friction,
                    boxes=stairs(sec.int("count", min=1), sec.float("height", positive=True),
                                 sec.float("depth", positive=True), sec.float("width", 1.0, positive=True),
                                 sec.float("start_x", 0.3)))
        sec.finish()
        return t
    boxes = []
    for i, raw in enumerate(sec.list("boxes")):
        b = Section(raw, sec.file, f"{sec.key('boxes')}[{i}]")
        boxes.append(Box(center=tuple(b.vector("center", length=3)),
                         size=tuple(_positive(b, "size")),
                         rpy=tuple(b.vector("rpy", [0.0, 0.0, 0.0], length=3)),
                         name=b.str("name", f"box_{i}")))
        b.finish()
    t = Terrain(kind="boxes", friction=friction, boxes=tuple(boxes), floor=sec.bool("floor", True))
    sec.finish()
    return t


def _positive(b: Section, key: str) -> np.ndarray:
    v = b.vector(key, length=3)
    if np.any(v <= 0):
        raise b.error(key, f"sizes must be > 0, got {v.tolist()}")
    return v


@dataclass(frozen=True)
class Push:
    """A constant force [N] (world frame) on `body`'s centre of mass from `start` for `duration` [s].

    `body` is a body (link) name of the robot, or "base" for the profile's base frame.
    """

    body: str
    force: tuple[float, float, float]
    start: float
    duration: float

    def active(self, t: float) -> bool:
        return self.start <= t < self.start + self.duration

    @property
    def impulse(self) -> float:
        return float(np.linalg.norm(self.force) * self.duration)


def parse_push(sec: Section) -> Push:
    p = Push(body=sec.str("body"), force=tuple(sec.vector("force", length=3)),
             start=sec.float("start", min=0.0), duration=sec.float("duration", positive=True))
    sec.finish()
    return p
