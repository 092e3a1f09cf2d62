"""Touch-down search for the position-controlled schemes: a foot whose planned touch-down comes while its ankle
F/T sensor reads no load keeps descending as a swing foot until it is loaded.

A position-controlled robot holds a contact where the integrated model's foot touched down. When the real foot
arrives above the terrain (TALOS' TSID position on the downhill platforms: the sole 2-5 mm above the slope, the real
foot 6-12 mm ahead of its plan and pitched 12 mrad less than the slope), nothing presses it down: the double support
passes with the leading foot unloaded, the stabilizer moves the CoM away from the unloaded foot to bring the
measured ZMP to the planned one (which lifts that foot further), and the whole weight lands on it when the trailing
foot lifts off. The search delays the model's contact instead: from the planned touch-down the foot's last swing
reference moves down along the sole's normal at `speed` until the ankle F/T sensor reads `min_force` (a real robot's
sensor), the search has gone `max_depth`, or the other foot is about to leave the ground (its contact no longer
planned); the contact is then made where the model's foot is.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..side import Side
from ..config import Section
from ..types import Measurement, PoseReference, References
from .corrections import Correction, CorrectionContext, parse_settings

__all__ = ["TouchdownSearchConfig", "TouchdownSearch"]

_SIDES = tuple(Side)


@dataclass(frozen=True)
class TouchdownSearchConfig:
    """Attributes:
        speed: descent speed of the searching foot along its sole normal [m/s] (> 0).
        max_depth: the longest descent below the planned touch-down [m] (> 0).
        min_force: the ankle F/T normal load that counts as touched down [N] (> 0).
    """

    speed: float = 0.1
    max_depth: float = 0.02
    min_force: float = 100.0

    def __post_init__(self) -> None:
        for name in ("speed", "max_depth", "min_force"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0.0:
                raise ValueError(f"TouchdownSearchConfig.{name} must be > 0, got {v!r}")


def foot_load(meas: Measurement, side: Side) -> float:
    """The normal load on a foot from its ankle F/T sensor [N]: the force the leg exerts on the foot along the
    sensor's z axis, sign flipped (a hanging foot reads about -15 N, the weight below the sensor)."""
    f = meas.ft_force.get(side)
    return -float(f[2]) if f is not None else np.inf


class TouchdownSearch(Correction):
    """Per tick, `correct(meas, refs)` returns the references with a searching foot out of `contacts` and its
    reference descending (module docstring). Stateful: `reset()` between runs. The correction stage
    `touchdown_search` (`{type: touchdown_search, speed: 0.1, max_depth: 0.02, min_force: 100.0}`)."""

    type = "touchdown_search"
    needs_integrated_model = True

    def __init__(self, config: TouchdownSearchConfig):
        super().__init__(config)
        self._last: dict[Side, PoseReference] = {}      # each foot's last swing reference
        self._search: dict[Side, float] = {}            # searching foot -> time its touch-down was planned
        self._prev: frozenset = frozenset(Side)
        self.n_searches = 0

    @classmethod
    def parse(cls, sec: Section) -> TouchdownSearchConfig:
        return parse_settings(sec, TouchdownSearchConfig)

    @classmethod
    def build(cls, config: TouchdownSearchConfig, robot, dt: float) -> "TouchdownSearch":
        return cls(config)

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self._last, self._search, self._prev = {}, {}, frozenset(Side)
        self.n_searches = 0

    def status(self) -> dict:
        """The touch-down searches made."""
        return {"touchdown_searches": self.n_searches}

    @property
    def searching(self) -> frozenset:
        return frozenset(self._search)

    def correct(self, meas: Measurement, refs: References) -> References:
        """The stage's `apply` outside a controller."""
        return self.apply(CorrectionContext.of(refs, meas))

    def apply(self, ctx: CorrectionContext) -> References:
        meas, refs = ctx.meas, ctx.refs
        c = self.config
        contacts = refs.contacts
        if not self._search and contacts <= self._prev:
            # the usual tick: no search under way and no foot newly in contact (none can start one)
            if len(contacts) < 2:
                for s in _SIDES:
                    if s not in contacts:
                        f = refs.feet.get(s)
                        if f is not None:
                            self._last[s] = f
            self._prev = contacts
            return refs
        feet = None
        for s in Side:
            if s not in contacts:
                self._search.pop(s, None)
                f = refs.feet.get(s)
                if f is not None:
                    self._last[s] = f
                continue
            last = self._last.get(s)
            if s not in self._search:
                if s in self._prev or last is None or foot_load(meas, s) >= c.min_force:
                    continue
                self._search[s] = refs.t
                self.n_searches += 1
            depth = c.speed * (refs.t - self._search[s])
            if (foot_load(meas, s) >= c.min_force or depth >= c.max_depth or s.other not in contacts):
                del self._search[s]  # the contact is made this tick, where the model's foot is
                continue
            n = last.rotation[:, 2] if last.rotation is not None else np.array([0.0, 0.0, 1.0])
            vel = np.zeros(6)
            vel[:3] = -c.speed * n
            if feet is None:
                feet = dict(refs.feet)
            feet[s] = PoseReference(last.position - depth * n, last.rotation, vel, np.zeros(6))
        self._prev = contacts
        if feet is None:
            return refs
        return replace(refs, contacts=frozenset(s for s in contacts if s not in self._search), feet=feet)
