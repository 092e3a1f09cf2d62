"""Event-based lift-off for the position-controlled schemes: a leaving foot whose ankle F/T sensor still reads a
share of the robot's weight at its planned lift-off stays in contact until it is unloaded (for a bounded time); its
swing then starts from the plan's lift-off and catches up with the plan's clock before touch-down.

A position-controlled robot lags the plan's weight transfer: the model's CoM is over the stance foot at the planned
lift-off (the leaving contact unloaded in the model), while the real joints yield under load and the real leaving
foot still carries a large share of the weight (TALOS' TSID position on the stairs: 33-52 % at the planned
lift-off). Lifting it then moves the weight onto the stance foot in a few tens of milliseconds, which kicks the
single-support ZMP swing (README, Uneven terrain). Here the contact is held (in the references: the foot stays in
`contacts`, with its lift-off set to the planned one, so that a controller unloading its leaving contacts keeps it
unloaded) while the sensor's normal load exceeds `max_load` of the two feet's summed load, for at most `max_wait`;
then the swing runs as planned from its lift-off, delayed by the wait, and a time warp brings it back onto the
plan's clock over `catch_up` seconds: tau(t) = t - d (1 - b(u)), u = (t - t_release) / catch_up, b the quintic
blend, so that the swing reference is the plan's at tau with its velocity and acceleration scaled accordingly
(tau' = 1 at both ends). The CoM, the ZMP and the other foot keep the plan's clock.

The controller needs only what a robot has: the ankle F/T sensors' normal forces. The plan's swing references from
the planned lift-off on are kept (the warp only looks back: tau <= t).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from ..planning.swing import quintic_blend
from ..side import Side
from ..config import Section
from ..types import Measurement, PoseReference, References
from .corrections import Correction, CorrectionContext, parse_settings
from .touchdown import foot_load

__all__ = ["LiftOffWaitConfig", "LiftOffWait"]


@dataclass(frozen=True)
class LiftOffWaitConfig:
    """Attributes:
        max_load: the share of the two feet's summed normal load (ankle F/T) above which a leaving foot waits
            (0 < max_load < 1).
        max_wait: the longest wait after the planned lift-off [s] (> 0).
        catch_up: the time over which the delayed swing comes back onto the plan's clock [s] (> 0).
    """

    max_load: float = 0.2
    max_wait: float = 0.1
    catch_up: float = 0.5

    def __post_init__(self) -> None:
        for name in ("max_wait", "catch_up"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0.0:
                raise ValueError(f"LiftOffWaitConfig.{name} must be > 0 s, got {v!r}")
        if not np.isfinite(self.max_load) or not 0.0 < self.max_load < 1.0:
            raise ValueError(f"LiftOffWaitConfig.max_load must be in (0, 1), got {self.max_load!r}")


@dataclass
class _Swing:
    """A leaving foot's state: its planned lift-off t0, the plan's swing references since (times, feet, pitch),
    and, once released, the release time and the delay d."""

    t0: float
    times: list = field(default_factory=list)
    feet: list = field(default_factory=list)
    pitch: list = field(default_factory=list)
    released: float | None = None
    delay: float = 0.0


class LiftOffWait(Correction):
    """Per tick, `correct(meas, refs)` returns the references with a loaded leaving foot held in contact, or its
    swing on the warped clock (module docstring). Stateful: `reset()` between runs. The correction stage
    `lift_off_wait` (`{type: lift_off_wait, max_load: 0.2, max_wait: 0.1, catch_up: 0.5}`)."""

    type = "lift_off_wait"
    needs_integrated_model = True

    def __init__(self, config: LiftOffWaitConfig):
        super().__init__(config)
        self.reset()

    @classmethod
    def parse(cls, sec: Section) -> LiftOffWaitConfig:
        return parse_settings(sec, LiftOffWaitConfig, upper={"max_load": (
            1.0, "is a share of the feet's summed load: must be in (0, 1)")})

    @classmethod
    def build(cls, config: LiftOffWaitConfig, robot, dt: float) -> "LiftOffWait":
        return cls(config)

    def status(self) -> dict:
        """The lift-offs delayed and their summed delay [s]."""
        return {"lift_off_waits": self.n_waits, "lift_off_wait_s": round(self.total_wait, 4)}

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self._swing: dict[Side, _Swing] = {}
        self._prev: frozenset = frozenset(Side)
        self.n_waits = 0
        self.total_wait = 0.0

    @property
    def waiting(self) -> frozenset:
        return frozenset(s for s, w in self._swing.items() if w.released is None)

    def _loaded(self, meas: Measurement, side: Side) -> bool:
        # the feet's normal loads (a hanging foot's negative reading counted as none)
        f, g = max(foot_load(meas, side), 0.0), max(foot_load(meas, side.other), 0.0)
        return f + g > 0.0 and f > self.config.max_load * (f + g)

    def correct(self, meas: Measurement, refs: References) -> References:
        """The stage's `apply` outside a controller."""
        return self.apply(CorrectionContext.of(refs, meas))

    def apply(self, ctx: CorrectionContext) -> References:
        meas, refs = ctx.meas, ctx.refs
        c = self.config
        contacts, t = refs.contacts, refs.t
        held, warped = [], {}
        for s in Side:
            if s in contacts:
                self._swing.pop(s, None)
                continue
            w = self._swing.get(s)
            if w is None:
                if s not in self._prev or s.other not in contacts or not self._loaded(meas, s):
                    continue
                w = self._swing[s] = _Swing(t0=t)
                self.n_waits += 1
            foot = refs.feet.get(s)
            if foot is None:  # the plan gives no swing reference: nothing to hold or warp
                del self._swing[s]
                continue
            w.times.append(t)
            w.feet.append(foot)
            w.pitch.append(refs.swing_pitch.get(s))
            if w.released is None:
                if self._loaded(meas, s) and t - w.t0 < c.max_wait and s.other in contacts:
                    held.append(s)
                    continue
                w.released, w.delay = t, t - w.t0
                self.total_wait += w.delay
            u = (t - w.released) / c.catch_up
            if u >= 1.0 or w.delay <= 0.0:
                del self._swing[s]
                continue
            warped[s] = self._warped(w, t, u)
        self._prev = contacts
        if not held and not warped:
            return refs
        feet = dict(refs.feet)
        pitch = dict(refs.swing_pitch)
        lift_off = dict(refs.lift_off)
        for s in held:
            w = self._swing[s]
            del feet[s]
            p0 = w.pitch[0]
            pitch.pop(s, None)
            if p0 is not None and len(p0) > 3 and p0[3] != 0.0:  # a toe-off: the foot stays on its edge, still
                pitch[s] = np.array([p0[0], 0.0, 0.0, p0[3]])
            lift_off[s] = w.t0
        for s, (foot, p) in warped.items():
            feet[s] = foot
            if p is not None:
                pitch[s] = p
        return replace(refs, contacts=contacts | frozenset(held), feet=feet, swing_pitch=pitch, lift_off=lift_off)

    def _warped(self, w: _Swing, t: float, u: float) -> tuple[PoseReference, np.ndarray | None]:
        """The plan's swing reference at tau(t) (module docstring), with its rates scaled by the warp."""
        b, db, ddb = (float(x) for x in quintic_blend(u))
        T = self.config.catch_up
        tau = t - w.delay * (1.0 - b)
        r1 = 1.0 + w.delay * db / T          # dtau/dt
        r2 = w.delay * ddb / T ** 2          # d2tau/dt2
        i = max(bisect_right(w.times, tau) - 1, 0)
        j = min(i + 1, len(w.times) - 1)
        a = 0.0 if j == i else min(max((tau - w.times[i]) / (w.times[j] - w.times[i]), 0.0), 1.0)
        f0, f1 = w.feet[i], w.feet[j]
        pos = f0.position + a * (f1.position - f0.position)
        vel = f0.velocity + a * (f1.velocity - f0.velocity)
        acc = f0.acceleration + a * (f1.acceleration - f0.acceleration)
        rot = f0.rotation
        if rot is not None and f1.rotation is not None and a > 0.0:
            rot = rot @ pin.exp3(a * pin.log3(rot.T @ f1.rotation))
        foot = PoseReference(pos, rot, vel * r1, acc * r1 * r1 + vel * r2)
        p0, p1 = w.pitch[i], w.pitch[j]
        pitch = None
        if p0 is not None and p1 is not None:
            p = np.asarray(p0, dtype=float) + a * (np.asarray(p1, dtype=float) - np.asarray(p0, dtype=float))
            pitch = p.copy()
            pitch[1] = p[1] * r1
            pitch[2] = p[2] * r1 * r1 + p[1] * r2
        return foot, pitch
