"""External pushes applied to a body for a time window."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import Section


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
