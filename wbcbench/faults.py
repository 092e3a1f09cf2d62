"""Fault injection and the measurement guard (issue: robustness). A scenario's `faults:` list (or `--fault`)
schedules faults; the runner applies them and logs, per tick, which are active.

    faults:
      - {type: sensor_nan, target: ft_left, start: 1.0, duration: 0.2}     # ft_left|ft_right|imu|encoders
      - {type: sensor_freeze, target: imu, start: 2.0, duration: 0.5}      # the reading stops changing
      - {type: qp_failure, start: 3.0, duration: 0.05}                     # the controller's QP solves fail
      - {type: joint_locked, target: leg_left_4_joint, start: 1.0}         # braked where it is
      - {type: joint_cut, target: arm_left_2_joint, start: 1.0}            # no actuator torque (limp)
      - {type: joint_passive, target: arm_left_2_joint, start: 1.0}        # the actuator only damps

Documented safe behaviours:
* A measurement with non-finite values (a sensor returning NaN) never reaches the controller: the guard
  hands it the last finite measurement (counted, `guard_held` channel); a reading that stops changing for
  `freeze_ticks` ticks is flagged (`sensor_frozen` channel) but passed on (a real robot cannot tell a still
  robot from a frozen sensor at once). If the measurement stays invalid for `safe_stop_after` seconds, the run
  switches to the safe stop for good, whatever the controller: joint-pd about the last valid posture (position
  and SPD modes: the servos hold those angles with zero velocity; torque mode: PD plus gravity and contact
  compensation on the last valid measurement), and the summary says when.
* A failing QP: the controller's own fallback (the inverse-dynamics controllers: the relaxed QP, then
  joint-pd about the current posture in torque mode or holding the posture in position mode; the IK: holding
  the posture), counted in its status.
* Joint faults: the controller is not told (as on a robot whose driver fails silently); the log shows what the
  joint did.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .config import Section
from .errors import ConfigError
from .side import Side
from .types import Command, Measurement

__all__ = ["Fault", "FaultInjector", "parse_faults"]

SENSOR_TARGETS = ("ft_left", "ft_right", "imu", "encoders")
TYPES = ("sensor_nan", "sensor_freeze", "qp_failure", "joint_locked", "joint_cut", "joint_passive")


@dataclass(frozen=True)
class Fault:
    """One scheduled fault: `type` (see TYPES), `target` (a sensor or joint name; none for qp_failure), from
    `start` [s] for `duration` [s] (None: to the end)."""

    type: str
    start: float
    duration: float | None = None
    target: str | None = None

    def active(self, t: float) -> bool:
        return t >= self.start and (self.duration is None or t < self.start + self.duration)


def parse_faults(items: list, file: str | None, key: str = "faults", joints: list[str] | None = None) -> tuple:
    out = []
    for i, raw in enumerate(items):
        sec = Section(raw, file, f"{key}[{i}]")
        ftype = sec.str("type", choices=list(TYPES))
        target = None
        if ftype.startswith("sensor"):
            target = sec.str("target", choices=list(SENSOR_TARGETS))
        elif ftype.startswith("joint"):
            target = sec.str("target")
            if joints is not None and target not in joints:
                from .errors import UnknownNameError

                raise UnknownNameError("joint", target, joints, file=file, key=sec.key("target"))
        duration = sec.float("duration", positive=True) if sec.has("duration") else None
        out.append(Fault(ftype, sec.float("start", min=0.0), duration, target))
        sec.finish()
    return tuple(out)


def parse_fault_option(text: str, joints: list[str]) -> Fault:
    """`--fault TYPE[:TARGET]@START[+DURATION]`, e.g. `sensor_nan:ft_left@1.0+0.2`, `qp_failure@2+0.05`."""
    try:
        head, when = text.split("@", 1)
        ftype, _, target = head.partition(":")
        start, _, dur = when.partition("+")
        item = {"type": ftype, "start": float(start)}
        if target:
            item["target"] = target
        if dur:
            item["duration"] = float(dur)
    except ValueError:
        raise ConfigError(f"'{text}' is not TYPE[:TARGET]@START[+DURATION] (e.g. sensor_nan:ft_left@1.0+0.2)",
                          key="--fault") from None
    return parse_faults([item], None, key="--fault", joints=joints)[0]


class FaultInjector:
    """Applies a fault schedule each tick: to the measurement (sensor faults, then the guard), to the simulator
    (joint faults), to the controller's QP solves (qp_failure, through its solve hook). The run loop calls it in
    its ``sense`` and ``safety`` phases (`wbcbench.loop_hooks.FaultHook`). `log` holds this tick's flags:
    (faults active, guard held the measurement, a reading frozen, safe stop on)."""

    LOG_LABELS = ("faults_active", "guard_held", "sensor_frozen", "safe_stop")

    def __init__(self, faults: tuple, robot, dt: float, *, freeze_ticks: int = 50, safe_stop_after: float = 0.1):
        self.faults = tuple(faults)
        self.robot = robot
        self.dt = dt
        self.freeze_ticks = freeze_ticks
        self.safe_stop_ticks = int(round(safe_stop_after / dt))
        self.events: list[dict] = []
        self._started = [False] * len(self.faults)
        self._ended = [False] * len(self.faults)
        self._frozen_value: dict[int, Measurement] = {}
        self._last_good: Measurement | None = None
        self._prev: Measurement | None = None
        self._same = [0] * len(SENSOR_TARGETS)
        self._bad = 0
        self.guard_ticks = 0
        self.safe_stop_t: float | None = None
        self.log = np.zeros(len(self.LOG_LABELS))
        self._qp_wrapped = False
        self._pd = None

    @property
    def enabled(self) -> bool:
        return bool(self.faults)

    # ------------------------------------------------------------------ schedule
    def update(self, t: float, sim, ctrl) -> None:
        """Start and end the faults due at time t (events logged once); joint faults act on the simulator."""
        self.log[:] = 0.0
        for i, f in enumerate(self.faults):
            on = f.active(t)
            if on:
                self.log[0] += 1
            if on and not self._started[i]:
                self._started[i] = True
                self.events.append({"t": round(t, 6), "event": "start", "type": f.type, "target": f.target})
                if f.type.startswith("joint"):
                    sim.set_joint_fault(f.target, f.type.removeprefix("joint_"))
                if f.type == "qp_failure":
                    self._wrap_solvers(ctrl)
            if self._started[i] and not on and not self._ended[i]:
                self._ended[i] = True
                self.events.append({"t": round(t, 6), "event": "end", "type": f.type, "target": f.target})
                if f.type.startswith("joint"):
                    sim.set_joint_fault(f.target, None)
        self._t = t

    def _wrap_solvers(self, ctrl) -> None:
        """qp_failure: every QP solve of the controller (its solve hook, `Controller.set_solve_hook`) reports a
        failure while a qp_failure fault is active."""
        if self._qp_wrapped:
            return
        set_hook = getattr(ctrl, "set_solve_hook", None)
        if set_hook is not None:
            set_hook(self._solve)
        self._qp_wrapped = True

    def _solve(self, solver, args: tuple):
        """The solve hook: a failure while a qp_failure fault is active, else the solver's own result."""
        if any(f.type == "qp_failure" and f.active(self._t) for f in self.faults):
            from .qp import QPResult, QPStatus

            return QPResult.failure(QPStatus.INFEASIBLE, solver="injected", raw_status=-1)
        return solver.solve(*args)

    # ------------------------------------------------------------------ measurement
    def measurement(self, meas: Measurement) -> Measurement:
        """Sensor faults applied, then the guard (module docstring)."""
        t = self._t
        for i, f in enumerate(self.faults):
            if not f.type.startswith("sensor"):
                continue
            if not f.active(t):
                self._frozen_value.pop(i, None)
                continue
            if f.type == "sensor_nan":
                meas = _with_sensor(meas, f.target, None)
            else:
                held = self._frozen_value.setdefault(i, meas)
                meas = _with_sensor(meas, f.target, held)
        # a frozen sensor: its reading has not changed for freeze_ticks ticks (a live sensor's never repeats)
        if self._prev is not None:
            for k, same in enumerate(_same_readings(meas, self._prev)):
                self._same[k] = self._same[k] + 1 if same else 0
        self._prev = meas
        if max(self._same) >= self.freeze_ticks:
            self.log[2] = 1.0
        if _finite(meas):
            self._last_good = meas
            self._bad = 0
            return meas
        self._bad += 1
        self.guard_ticks += 1
        self.log[1] = 1.0
        if self._bad >= self.safe_stop_ticks and self.safe_stop_t is None:
            self.safe_stop_t = t
            self.events.append({"t": round(t, 6), "event": "safe_stop", "type": "measurement invalid",
                                "target": None})
        if self._last_good is None:
            raise ConfigError("the first measurement of the run is invalid (a sensor fault at t = 0)", key="faults")
        return replace(self._last_good, t=meas.t)

    def safe_stop(self, meas: Measurement, mode, contacts) -> Command | None:
        """The safe-stop command once it is on (module docstring); None otherwise."""
        if self.safe_stop_t is None:
            return None
        self.log[3] = 1.0
        if self._pd is None:
            from .controllers.joint_pd import JointPD
            from .types import References

            self._pd = JointPD(self.robot, mode, self.dt)
            self._pd.q_ref = self._last_good.q[7:].copy()
            self._pd_refs = References(t=0.0, contacts=frozenset(contacts))
        return self._pd.step(self._last_good, self._pd_refs)

    def summary(self) -> dict:
        return {"events": self.events, "guard_held_ticks": self.guard_ticks, "safe_stop_t": self.safe_stop_t}


def _with_sensor(meas: Measurement, target: str, source: Measurement | None) -> Measurement:
    """`meas` with one sensor's reading replaced by NaN (source None) or by `source`'s."""
    def nan(x):
        return np.full_like(x, np.nan)

    if target in ("ft_left", "ft_right"):
        s = Side.LEFT if target == "ft_left" else Side.RIGHT
        force, torque = dict(meas.ft_force), dict(meas.ft_torque)
        force[s] = nan(force[s]) if source is None else source.ft_force[s]
        torque[s] = nan(torque[s]) if source is None else source.ft_torque[s]
        return replace(meas, ft_force=force, ft_torque=torque)
    if target == "imu":
        if source is None:
            return replace(meas, imu_quat=nan(meas.imu_quat), gyro=nan(meas.gyro),
                           accelerometer=nan(meas.accelerometer))
        return replace(meas, imu_quat=source.imu_quat, gyro=source.gyro, accelerometer=source.accelerometer)
    q, v = meas.q.copy(), meas.v.copy()  # encoders
    if source is None:
        q[7:] = np.nan
        v[6:] = np.nan
    else:
        q[7:], v[6:] = source.q[7:], source.v[6:]
    return replace(meas, q=q, v=v)


def _finite(m: Measurement) -> bool:
    return bool(np.isfinite(m.q).all() and np.isfinite(m.v).all() and np.isfinite(m.imu_quat).all()
                and np.isfinite(m.gyro).all() and all(np.isfinite(m.ft_force[s]).all() for s in Side)
                and all(np.isfinite(m.ft_torque[s]).all() for s in Side))


def _same_readings(a: Measurement, b: Measurement) -> tuple[bool, ...]:
    """Per sensor of SENSOR_TARGETS: whether its reading is identical in a and b."""
    return (np.array_equal(a.ft_force[Side.LEFT], b.ft_force[Side.LEFT]),
            np.array_equal(a.ft_force[Side.RIGHT], b.ft_force[Side.RIGHT]),
            np.array_equal(a.gyro, b.gyro) and np.array_equal(a.imu_quat, b.imu_quat),
            np.array_equal(a.q[7:], b.q[7:]))
