"""Concrete scenario kinds. Each is registered under its `kind` string."""

from __future__ import annotations

import numpy as np

from ..recorder import channel
from ..robots import Side
from ..types import References
from .base import Scenario, register_kind


@register_kind
class SwayScenario(Scenario):
    """Stand on both feet while the CoM follows a sinusoid about its initial position.

    params: amplitude [m] (per axis x y z), frequency [Hz]. The reference starts at zero velocity by
    ramping the amplitude in over `ramp` seconds (default 0: the pure sinusoid, as the paper's test).
    """

    kind = "sway"

    def parse(self, params):
        self.amplitude = params.vector("amplitude", [0.0, 0.05, 0.0], length=3)
        self.frequency = params.float("frequency", 0.5, positive=True)
        self.settle = params.float("skip_for_error", 0.0, min=0.0)

    def references(self, t: float) -> References:
        w = 2 * np.pi * self.frequency
        s, c = np.sin(w * t), np.cos(w * t)
        a = self.amplitude
        return References(t=t, contacts=frozenset(Side), com=self.com0 + a * s, com_vel=a * w * c,
                          com_acc=-a * w * w * s)

    def metrics(self, log):
        com = channel(log, "com")
        ref = channel(log, "com_ref")
        t = log["t"]
        keep = t >= self.settle
        err = np.linalg.norm((com - ref)[keep], axis=1)
        return {"com_rms_error_m": float(np.sqrt(np.mean(err ** 2))), "com_max_error_m": float(err.max())}


@register_kind
class OneFootScenario(Scenario):
    """Shift the CoM over one foot, lift the other `lift` m, hold it, until the end.

    params: support (left|right), shift_time [s], lift [m], lift_time [s].
    """

    kind = "one-foot"

    def parse(self, params):
        self.support = Side(params.str("support", "left", choices=["left", "right"]))
        self.shift_time = params.float("shift_time", 1.5, positive=True)
        self.lift = params.float("lift", 0.05, min=0.0)
        self.lift_time = params.float("lift_time", 1.0, positive=True)

    def setup(self, q0, com0):
        super().setup(q0, com0)
        import pinocchio as pin
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        self.feet0 = {s: data.oMf[self.robot.sole_frame_id(s)].copy() for s in Side}
        self.swing = Side.RIGHT if self.support is Side.LEFT else Side.LEFT
        target = self.feet0[self.support].translation
        self.com_target = np.array([target[0], target[1], com0[2]])

    def references(self, t):
        s, ds, dds = _min_jerk(t / self.shift_time)
        d = self.com_target - self.com0
        com, com_vel, com_acc = self.com0 + s * d, d * ds / self.shift_time, d * dds / self.shift_time ** 2
        contacts = frozenset(Side)
        feet = {}
        if t >= self.shift_time:
            contacts = frozenset({self.support})
            u, du, ddu = _min_jerk((t - self.shift_time) / self.lift_time)
            p0 = self.feet0[self.swing].translation
            up = np.array([0, 0, self.lift])
            feet[self.swing] = (p0 + u * up, up * du / self.lift_time, up * ddu / self.lift_time ** 2)
        return References(t=t, contacts=contacts, com=com, com_vel=com_vel, com_acc=com_acc, feet=feet)

    def metrics(self, log):
        com = channel(log, "com")
        ref = channel(log, "com_ref")
        err = np.linalg.norm(com - ref, axis=1)
        return {"com_rms_error_m": float(np.sqrt(np.mean(err ** 2))), "com_max_error_m": float(err.max())}


def _min_jerk(s: float) -> tuple[float, float, float]:
    """Minimum-jerk profile on [0, 1]: value, first and second derivative w.r.t. s (clamped outside)."""
    if s <= 0:
        return 0.0, 0.0, 0.0
    if s >= 1:
        return 1.0, 0.0, 0.0
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3)
