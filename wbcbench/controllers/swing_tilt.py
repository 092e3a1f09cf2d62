"""Swing-foot tilt compensation for the position-controlled schemes: in single support, the swing foot's
orientation reference turned against the roll and pitch that the stance leg's yielding joints give the real swing
foot, so that it lands flatter; the contact is turned back to the plan's orientation once made.

A position-controlled robot's joints yield under load (the servos' compliance), so the real stance leg is not the
integrated model's: relative to the stance sole, the real swing sole is turned (and lowered) against the model's.
TALOS' TSID position on the platforms lands each swing foot 0.07-0.11 s before its planned touch-down on the outer
corner of its heel (the ankle F/T sensor's centre of pressure at x -0.10...-0.15, |y| 0.07-0.10 m for the first
0.04 s, the sole 0.20 x 0.13 m) and bounces. In single support the tilt is measured from the encoders: the swing
sole's rotation in the stance sole's frame with the model's configuration, against the same with the stance leg's
joints as measured (the swing leg's own tracking error left out), its roll and pitch (about the sole's x and y)
low-passed with `time_constant`; the swing foot's reference is turned by -`gain` times that (at most `max_tilt`).
When the contact is made, the model's contact takes its turned foot; its reference is turned back to the plan's
orientation over `settle` seconds (a quintic).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..planning.geometry import so3_exp, so3_log
from ..planning.swing import quintic_blend
from ..robots import Robot
from ..side import Side
from ..config import Section
from ..types import Measurement, PoseReference, References
from .corrections import Correction, CorrectionContext, parse_settings

__all__ = ["SwingTiltConfig", "SwingTilt"]


@dataclass(frozen=True)
class SwingTiltConfig:
    """Attributes:
        gain: the share of the measured tilt the swing foot's reference is turned against (> 0).
        max_tilt: the largest turn [rad] (> 0).
        time_constant: of the tilt's low-pass filter [s] (> 0).
        settle: the time over which a made contact is turned back to the plan's orientation [s] (> 0).
    """

    gain: float = 0.3
    max_tilt: float = 0.05
    time_constant: float = 0.05
    settle: float = 0.1

    def __post_init__(self) -> None:
        for name in ("gain", "max_tilt", "time_constant", "settle"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0.0:
                raise ValueError(f"SwingTiltConfig.{name} must be > 0, got {v!r}")


class SwingTilt(Correction):
    """Per tick, `correct(meas, refs, q_model)` returns the references with the swing feet turned and the contacts
    just made from a turned foot turning back (module docstring). References in the integrated model's world (after
    the base feedback). Stateful: `reset()` between runs. The correction stage `swing_tilt` (`{type: swing_tilt,
    gain: 0.3, max_tilt: 0.05, time_constant: 0.05, settle: 0.1}`)."""

    type = "swing_tilt"
    needs_integrated_model = True

    def __init__(self, config: SwingTiltConfig, robot: Robot, dt: float):
        super().__init__(config, robot, dt)
        self._alpha = min(1.0, dt / config.time_constant)
        m = robot.model
        self._model = m
        self._data_model, self._data_meas = m.createData(), m.createData()
        self._sole = {s: robot.sole_frame_id(s) for s in Side}
        # each leg's joints' configuration indices (the joints between the floating base and the sole)
        self._leg_q = {}
        for s in Side:
            j, idx = m.frames[self._sole[s]].parentJoint, []
            while j > 1:  # joint 1: the floating base
                idx.append(m.joints[j].idx_q)
                j = m.parents[j]
            self._leg_q[s] = np.array(sorted(idx))
        self.reset()

    @classmethod
    def parse(cls, sec: Section) -> SwingTiltConfig:
        return parse_settings(sec, SwingTiltConfig)

    def status(self) -> dict:
        """The largest measured tilt [rad]."""
        return {"swing_tilt_max_rad": round(self.max_tilt, 5)}

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self._tilt: dict[Side, np.ndarray] = {}     # each swing foot's filtered tilt (rotation vector, sole frame)
        self._ref: dict[Side, PoseReference] = {}   # each swing foot's last (turned) reference
        self._plan: dict[Side, np.ndarray] = {}     # and the plan's orientation then
        self._settle: dict[Side, tuple] = {}        # contact turning back -> (start time, turned pose, plan's R)
        self.max_tilt = 0.0                         # the largest measured tilt [rad]

    def _relative(self, data, q: np.ndarray, s: Side) -> np.ndarray:
        """The rotation of the sole of `s` in the other sole's frame, in configuration q."""
        pin.forwardKinematics(self._model, data, q)
        a = pin.updateFramePlacement(self._model, data, self._sole[s]).rotation
        b = pin.updateFramePlacement(self._model, data, self._sole[s.other]).rotation
        return b.T @ a

    def correct(self, meas: Measurement, refs: References, q_model: np.ndarray | None) -> References:
        """The stage's `apply` outside a controller."""
        return self.apply(CorrectionContext.of(refs, meas, q_model))

    def apply(self, ctx: CorrectionContext) -> References:
        meas, refs, q_model = ctx.meas, ctx.refs, ctx.q_model
        c = self.config
        feet = None
        poses = None
        for s in Side:
            f = refs.feet.get(s)
            if s in refs.contacts or f is None:
                self._tilt.pop(s, None)
                last = self._ref.pop(s, None)
                if s in refs.contacts and last is not None:
                    self._settle[s] = (refs.t, last, self._plan[s])
                st = self._settle.get(s)
                if st is None:
                    continue
                if s not in refs.contacts:
                    del self._settle[s]
                    continue
                t0, last, R_plan = st
                u = (refs.t - t0) / c.settle
                if u >= 1.0:
                    del self._settle[s]
                b = float(quintic_blend(u)[0])
                if poses is None:
                    poses = dict(refs.contact_poses)
                R = last.rotation
                poses[s] = PoseReference(last.position, R @ so3_exp(b * so3_log(R.T @ R_plan)))
                continue
            if q_model is None or s.other not in refs.contacts:
                continue
            q = q_model.copy()  # the model with the stance leg's joints as measured
            k = self._leg_q[s.other]
            q[k] = meas.q[k]
            A_model = self._relative(self._data_model, q_model, s)
            e = so3_log(A_model.T @ self._relative(self._data_meas, q, s))
            e[2] = 0.0
            prev = self._tilt.get(s, e)
            self._tilt[s] = e = prev + self._alpha * (e - prev)
            self.max_tilt = max(self.max_tilt, float(np.linalg.norm(e)))
            if f.rotation is None:
                self._ref.pop(s, None)
                continue
            turn = -c.gain * e
            n = float(np.linalg.norm(turn))
            if n > c.max_tilt:
                turn *= c.max_tilt / n
            if feet is None:
                feet = dict(refs.feet)
            feet[s] = self._ref[s] = PoseReference(f.position, f.rotation @ so3_exp(turn), f.velocity,
                                                   f.acceleration)
            self._plan[s] = f.rotation
        if feet is None and poses is None:
            return refs
        return refs.corrected(refs.com, refs.targets, refs.wrench_targets,
                              refs.contact_poses if poses is None else poses, feet=feet)
