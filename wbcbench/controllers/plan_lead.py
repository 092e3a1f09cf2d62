"""Plan lead for the position-controlled schemes: the CoM and ZMP references taken a little ahead along the plan, so
that the real robot, which lags its integrated model, follows the plan on time.

A position-controlled robot reaches what its model does through the joint servos' compliance, a few tens of
milliseconds late: the ZMP measured by the ankle F/T sensors follows the planned one with a lag (TALOS' TSID position,
the lag that best fits the measured ZMP to the plan: platforms x 25 ms, y 50 ms; stairs x 10 ms, y 60 ms), most of
all in the double supports, where the plan moves the ZMP from foot to foot. Here the CoM reference is replaced by
its value `time` ahead, from the reference's own velocity and acceleration (c + T c' + T^2 / 2 c'', c' + T c''), and
the ZMP reference's horizontal components by z + T z', with z' their rate from the previous tick's reference (none
on the first tick or after a gap; the ZMP's height, the ground's, may jump between ticks). The contact schedule and
the swing feet keep the plan's clock.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config import Section
from ..types import PointReference, References
from .corrections import Correction, CorrectionContext, parse_settings

__all__ = ["PlanLeadConfig", "PlanLead"]


@dataclass(frozen=True)
class PlanLeadConfig:
    """Attributes:
        time: the lead of the CoM and ZMP references [s] (> 0).
    """

    time: float = 0.02

    def __post_init__(self) -> None:
        if not np.isfinite(self.time) or self.time <= 0.0:
            raise ValueError(f"PlanLeadConfig.time must be > 0 s, got {self.time!r}")


class PlanLead(Correction):
    """Per tick, `correct(refs)` returns the references with the CoM and the horizontal ZMP led (module docstring).
    Stateful (the previous ZMP reference): `reset()` between runs. The correction stage `plan_lead`
    (`{type: plan_lead, time: 0.02}`)."""

    type = "plan_lead"
    needs_integrated_model = True

    def __init__(self, config: PlanLeadConfig, dt: float):
        super().__init__(config, None, dt)
        self._zmp_lead = np.array([config.time, config.time, 0.0])
        self.reset()

    @classmethod
    def parse(cls, sec: Section) -> PlanLeadConfig:
        return parse_settings(sec, PlanLeadConfig, required=("time",))

    @classmethod
    def build(cls, config: PlanLeadConfig, robot, dt: float) -> "PlanLead":
        return cls(config, dt)

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self._prev: tuple[float, np.ndarray] | None = None

    def correct(self, refs: References) -> References:
        """`refs` with the CoM and the horizontal ZMP led (the stage's `apply` outside a controller)."""
        return self.apply(CorrectionContext.of(refs))

    def apply(self, ctx: CorrectionContext) -> References:
        refs = ctx.refs
        T = self.config.time
        com, zmp = refs.com, refs.zmp
        if com is not None:
            com = PointReference(com.position + T * com.velocity + 0.5 * T * T * com.acceleration,
                                 com.velocity + T * com.acceleration, com.acceleration)
        if zmp is not None:
            prev, self._prev = self._prev, (refs.t, zmp)
            if prev is not None and abs(refs.t - prev[0] - self.dt) < 1e-6 * self.dt:
                zmp = zmp + self._zmp_lead * (zmp - prev[1]) / self.dt
        else:
            self._prev = None
        if com is refs.com and zmp is refs.zmp:
            return refs
        return replace(refs, com=com, zmp=zmp)
