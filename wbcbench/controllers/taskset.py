"""Task sets: the tasks, contacts, gains and stabilizer of a controller, from YAML (named tasks dispatched on
`type:`) or built in Python. The YAML parses into these frozen dataclasses, which are the API.

Every task entry has `name`, `type`, `weight`, `kp`, optional `kd` (default 2 sqrt(kp)) and `mask`, and:
  hard: true|false   (default false) an equality constraint of the inverse-dynamics QP instead of a weighted cost;
  level: N           (default 1) the strict-priority level in a hierarchical formulation (the IK: 1 is the first
                     level after the feet); a weighted QP accepts level 1 only.
The `type` picks a class of the task registry (`wbcbench.tasks.registry`: `com`, `frame`, `posture`,
`angular_momentum`, `self_collision`, and any type a user registers), which parses its own options: `frame` for
frame tasks (a model frame or a symbolic one of the robot profile: `base`, `torso`, `head`, `left_hand`,
`right_hand`, `left_foot`, `right_foot`), `side: left|right` for self_collision tasks (the profile's repulsion
points; one axis per point, so `kp`/`kd`/`mask` are a number or one value per point).

`corrections:` (optional) lists the plan corrections in the order they run (`wbcbench.controllers.corrections`):
  corrections:
    - {type: plan_lead, time: 0.02}
    - {type: base_feedback, time_constant: 0.3, liftoff_blend: 0.3}
    - {type: stabilizer, law: dcm, kp_adm: 15.0, kp_dcm: 8.0, ki_dcm: 1.0, kz_dcm: 1.0}
each entry a registered correction type (built-in, or a plugin's through the entry-point group
`wbcbench.corrections`) with its settings. Instead of the list, the sections `plan_lead:`, `lift_off_wait:`,
`touchdown_search:`, `base_feedback:`, `swing_tilt:` and `stabilizer:` (a stabilizer by `type:`: `dcm`, `force`,
with its gains) give the built-in stages, run in that order; a task set gives one form or the other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..config import Section, load_yaml
from ..errors import ConfigError
from ..robots import Robot
from ..tasks.contact_6d import DRIFTS, ERRORS, TSID_WRENCH_AXIS_WEIGHTS, as_wrench_metric, sole_corners, tsid_wrench_metric
from ..tasks.registry import TaskSpec, resolve_frame, task_class
from .corrections import SECTIONS, CorrectionSpec, parse_corrections, parse_settings, specs_from_sections

if TYPE_CHECKING:
    from ..estimation.base_feedback import BaseFeedbackConfig
    from ..stabilizers.base import StabilizerConfig

__all__ = ["ContactSpec", "ReachCapSpec", "TaskSetSpec", "TaskSpec", "TsidWrenchMetric", "load_taskset",
           "resolve_frame", "taskset_path", "taskset_variant_path"]

TASKSET_DIR = Path(__file__).parent / "tasksets"
#: `servo_feedforward:` none, every actuated joint, or every one but the two nearest each sole (the ankles)
SERVO_FEEDFORWARD = ("none", "all", "all_but_ankles")


@dataclass(frozen=True)
class ContactSpec:
    """Gains and limits shared by the sole contacts: motion gains (LOCAL x y z roll pitch yaw), friction
    coefficient, normal force bounds [N], and the time [s] over which a leaving/arriving contact's maximum
    normal force is ramped, and whether that ramp ends at a leaving contact's planned lift-off
    (`unload_before_lift_off`, from the references' contact schedule ahead) rather than starts there.
    `model_sole` (length, width) [m] replaces the profile's sole rectangle in the
    controller's model: position controllers relax it so a stabilizer moving the CoM does not saturate the
    model's CoP limits (SIM-NOTES); None keeps the real sole. `drift`: the contacts' drift convention
    (`Contact6D`'s: ``"spatial"``, ``"classical"``); `error`: their pose error (``"log6"``, ``"split"``). `wrench_metric`: None (the `regularization:` section's
    diagonal), a (6, 6) metric as rows, or `TsidWrenchMetric` (C++ TSID's, from the sole's corners)."""

    kp: float
    kd: float
    mu: float = 0.3
    min_normal_force: float = 0.0
    max_normal_force: float = 2000.0
    transition_time: float = 0.05
    unload_before_lift_off: bool = False
    model_sole: tuple[float, float] | None = None
    drift: str = "spatial"
    error: str = "log6"
    wrench_metric: "tuple[tuple[float, ...], ...] | TsidWrenchMetric | None" = None

    def wrench_metric_matrix(self, length: float, width: float, center) -> np.ndarray | None:
        """The contacts' wrench metric (6, 6) for a sole rectangle `length` x `width` [m] centred at `center` (the
        model's), None: the formulation's diagonal."""
        m = self.wrench_metric
        if m is None:
            return None
        if isinstance(m, TsidWrenchMetric):
            return tsid_wrench_metric(sole_corners(length, width, center), weight=m.weight,
                                      axis_weights=m.axis_weights, corner_regularization=m.corner_regularization)
        return np.array(m, dtype=float)


@dataclass(frozen=True)
class TsidWrenchMetric:
    """YAML ``contacts.wrench_metric: {form: tsid, weight, axis_weights, corner_regularization}``: C++ TSID's
    regularisation of a Contact6d on the sole's four corners (`tsid_wrench_metric`): its force regularisation
    weight (``addRigidContact``'s), its per-axis weights and its solver's Hessian regularisation."""

    weight: float = 1e-5
    axis_weights: tuple[float, ...] = TSID_WRENCH_AXIS_WEIGHTS
    corner_regularization: float = 1e-8


@dataclass(frozen=True)
class ReachCapSpec:
    """Out-of-reach caps (YAML `reach_cap:`, tsid-teleop): while a named frame task's position error exceeds
    `error[0]` [m] and its reference moves faster than `speed[0]` [m/s], its commanded linear and angular
    accelerations are scaled towards the norms `linear` [m/s^2] and `angular` [rad/s^2], fully from `error[1]`
    and `speed[1]` on; while its rotation error exceeds `rotation[0]` [rad] (fully from `rotation[1]`), its angular
    one is, whatever the reference's speed, unless its position error exceeds `rotation_within` [m] (letting go from
    the first to the second; `rotation` None: no angular trigger;
    `InverseDynamicsFormulation.set_acceleration_caps`)."""

    tasks: tuple[str, ...]
    error: tuple[float, float] = (0.10, 0.15)
    linear: float = 20.0
    angular: float = 60.0
    speed: tuple[float, float] = (0.2, 0.5)
    rotation: tuple[float, float] | None = None
    rotation_within: tuple[float, float] = (0.20, 0.30)

    def params(self) -> np.ndarray:
        """[e0, e1, a_lin, a_ang, v0, v1, r0, r1, p0, p1], as `_kernels.cap_task_accelerations` takes them (r0 = r1
        = inf without the angular trigger)."""
        rot = (np.inf, np.inf) if self.rotation is None else self.rotation
        return np.array([*self.error, self.linear, self.angular, *self.speed, *rot, *self.rotation_within],
                        dtype=float)


@dataclass(frozen=True)
class TaskSetSpec:
    """A controller's task set. `regularization_dv`, `regularization_wrench`: weights of ||dv||^2 and ||a * w||^2,
    `regularization_wrench_axes` = a (6,) per wrench axis fx fy fz tx ty tz (YAML `regularization.wrench_axes`);
    `regularization_wrench_target`: weight [1/N^2] of ||w_c - w_c*||^2 towards the references' wrench targets
    (0: off); `joint_limit_horizon` [s]; `arm_damping_injection`: tsid-teleop's arm velocity references' gain on
    the arms' tracking velocity error (0: off; `TSIDTeleop`); `arm_torque_share`: tsid-teleop's share of an arm
    joint's torque limit its acceleration bound leaves it (0: no bound; `TSIDTeleop`); `solver`: the QP backend;
    `stabilizer`: None or the configured one; `base_feedback`, `touchdown_search`, `swing_tilt`, `lift_off_wait`,
    `plan_lead`: None or their settings (position-controlled schemes); `step_adjustment`: the controller's own
    settings (key, value) of a walk's step adjustment, for the keys the scenario does not set
    (`WalkScenario.adopt_step_adjustment`), None: the defaults;
    `swing_pitch_with_leg` (YAML `swing_foot.pitch_with_leg`): the controller adds the pitch the plan offers
    (`References.swing_pitch`) to its swing feet's references (`TaskReferences`); `reach_cap`: None or tsid-teleop's
    out-of-reach caps (`ReachCapSpec`); `corrections`: the stages of a `corrections:` list in order (then the six
    sections above are None), None when the task set gives its corrections as sections (`correction_specs`);
    `servo_feedforward` (tsid-position): the joints whose QP torque is fed forward to their position servos, one
    of `SERVO_FEEDFORWARD` (`InverseDynamicsController`)."""

    tasks: tuple[TaskSpec, ...]
    contacts: ContactSpec
    swing_foot: TaskSpec
    regularization_dv: float = 1e-6
    regularization_wrench: float = 1e-5
    regularization_wrench_axes: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    joint_limit_horizon: float = 0.01
    arm_damping_injection: float = 0.0
    arm_torque_share: float = 0.0
    regularization_wrench_target: float = 0.0
    solver: str = "daqp"
    stabilizer: "StabilizerConfig | None" = None
    base_feedback: "BaseFeedbackConfig | None" = None
    touchdown_search: "TouchdownSearchConfig | None" = None
    swing_tilt: "SwingTiltConfig | None" = None
    lift_off_wait: "LiftOffWaitConfig | None" = None
    plan_lead: "PlanLeadConfig | None" = None
    step_adjustment: tuple[tuple[str, object], ...] | None = None
    swing_pitch_with_leg: bool = False
    reach_cap: ReachCapSpec | None = None
    corrections: tuple[CorrectionSpec, ...] | None = None
    servo_feedforward: str = "none"
    file: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if self.corrections is not None:
            given = [k for k in SECTIONS if getattr(self, k) is not None]
            if given:
                raise ConfigError(f"give the corrections either as the `corrections:` list or as sections, not "
                                  f"both (sections given: {', '.join(given)})", file=self.file or None,
                                  key="corrections")

    def correction_specs(self) -> tuple[CorrectionSpec, ...]:
        """The correction stages in the order they run: the `corrections:` list, or the sections mapped onto it in
        the order plan_lead, lift_off_wait, touchdown_search, base_feedback, swing_tilt, stabilizer."""
        return self.corrections if self.corrections is not None else specs_from_sections(self)

    def without_stabilizer(self) -> "TaskSetSpec":
        """This task set without its stabilizer (section or stage)."""
        from dataclasses import replace

        if self.corrections is None:
            return replace(self, stabilizer=None)
        return replace(self, corrections=tuple(c for c in self.corrections if c.type != "stabilizer"))

    def task(self, name: str) -> TaskSpec:
        for t in self.tasks:
            if t.name == name:
                return t
        raise KeyError(name)


def _shipped(robot: Robot, file_name: str) -> Path | None:
    """The shipped task set `file_name` of the robot, else of the default directory; None if neither has it."""
    for d in (TASKSET_DIR / robot.name, TASKSET_DIR / "default"):
        p = d / file_name
        if p.exists():
            return p
    return None


def taskset_variant_path(robot: Robot, controller: str, variant: str) -> Path | None:
    """The task set `<controller>-<variant>.yaml` of the robot (or the default directory), None if there is none."""
    return _shipped(robot, f"{controller}-{variant}.yaml")


def taskset_path(robot: Robot, controller: str) -> Path:
    p = _shipped(robot, f"{controller}.yaml")
    if p is None:
        raise ConfigError(f"no task set for controller '{controller}' (looked in {TASKSET_DIR / robot.name} and "
                          f"{TASKSET_DIR / 'default'})")
    return p


def _gain_vector(sec: Section, key: str, n: int, robot: Robot | None, posture: bool, default=...):
    """A gain: a number, a list of n numbers, or (posture) a mapping joint-name prefix -> number."""
    raw = sec.raw(key, default)
    if raw is None:
        return None
    if posture and isinstance(raw, dict):
        sub = Section(raw, sec.file, sec.key(key))
        table = {k: sub.float(k, min=0.0) for k in list(sub.data)}
        sub.finish()
        out = np.zeros(n)
        for i, name in enumerate(robot.joint_names):
            best = max((p for p in table if name.startswith(p)), key=len, default=None)
            if best is None:
                raise ConfigError(f"no entry matches joint '{name}'; give a prefix for every joint",
                                  file=sec.file, key=sec.key(key))
            out[i] = table[best]
        return out
    if isinstance(raw, (int, float)) and not isinstance(raw, bool):
        val = np.full(n, float(raw))
    else:
        val = sec.vector(key, length=n)
    if np.any(val < 0) or not np.all(np.isfinite(val)):
        raise sec.error(key, f"gains must be finite and >= 0, got {np.atleast_1d(raw).tolist()}")
    return val


def _parse_task(sec: Section, robot: Robot, name: str | None = None, max_level: int = 1) -> TaskSpec:
    name = name or sec.str("name")
    cls = task_class(sec.str("type"), file=sec.file, key=sec.key("type"))
    options = cls.parse_options(sec, robot)
    n = cls.axes(robot, options)
    mask = None
    if cls.maskable and sec.has("mask"):
        m = sec.raw("mask")
        items = list(m) if isinstance(m, (list, str)) else None
        if items is None or len(items) != n or not all(
                (isinstance(x, int) and x in (0, 1)) or x in ("0", "1") for x in items):
            axes = "x y z roll pitch yaw" if n == 6 else "x y z" if n == 3 else f"{n} axes"
            raise sec.error("mask", f"must have {n} entries of 0 or 1 ({axes}), got {m!r}")
        mask = tuple(x in (1, "1") for x in items)
    weight = sec.float("weight", min=0.0)
    kp = _gain_vector(sec, "kp", n, robot, cls.per_joint_gains)
    kd = _gain_vector(sec, "kd", n, robot, cls.per_joint_gains, default=None)
    if sec.has("priority"):
        raise sec.error("priority", "was replaced by `hard: true` (an equality constraint of the inverse-dynamics "
                                    "QP) and `level: N` (the strict-priority level of a hierarchical formulation)")
    hard = sec.bool("hard", False)
    level = sec.int("level", 1, min=1)
    if level > max_level:
        raise sec.error("level", f"must be between 1 and {max_level} for this controller"
                        + (" (a weighted QP has one level; use weights)" if max_level == 1 else ""))
    sec.finish()
    return TaskSpec(name=name, type=cls.yaml_type, weight=weight, kp=kp, kd=kd, mask=mask, hard=hard, level=level,
                    options=options)


def load_taskset(path: str | Path, robot: Robot, max_level: int = 1) -> TaskSetSpec:
    """Parse and validate a task-set file for `robot`; errors name the file and key. `max_level` is the largest
    level the controller accepts (1 for a weighted QP; the number of levels of a hierarchy)."""
    file = str(path)
    root = Section(load_yaml(path), file)
    tasks = []
    names = set()
    for i, raw in enumerate(root.list("tasks")):
        t = _parse_task(Section(raw, file, f"tasks[{i}]"), robot, max_level=max_level)
        if t.name in names:
            raise ConfigError(f"task name '{t.name}' used twice", file=file, key=f"tasks[{i}].name")
        names.add(t.name)
        tasks.append(t)
    c = root.section("contacts")
    contacts = ContactSpec(kp=c.float("kp", min=0.0), kd=c.float("kd", 0.0, min=0.0), mu=c.float("mu", 0.3, positive=True),
                           min_normal_force=c.float("min_normal_force", 0.0, min=0.0),
                           max_normal_force=c.float("max_normal_force", 2000.0, positive=True),
                           transition_time=c.float("transition_time", 0.05, min=0.0),
                           unload_before_lift_off=c.bool("unload_before_lift_off", False),
                           model_sole=tuple(c.vector("model_sole", length=2)) if c.has("model_sole") else None,
                           drift=c.str("drift", "spatial", choices=DRIFTS),
                           error=c.str("error", "log6", choices=ERRORS),
                           wrench_metric=_wrench_metric(c) if c.has("wrench_metric") else None)
    if contacts.model_sole is not None and min(contacts.model_sole) <= 0:
        raise c.error("model_sole", "length and width must be > 0")
    if contacts.max_normal_force < contacts.min_normal_force:
        raise c.error("max_normal_force", "must be >= min_normal_force")
    c.finish()
    sw = root.section("swing_foot")
    sw.data.setdefault("type", "frame")
    sw.data.setdefault("frame", "left_foot")
    pitch_with_leg = sw.bool("pitch_with_leg", False)
    swing = _parse_task(sw, robot, name="swing_foot")
    reg = root.section("regularization", {})
    if contacts.wrench_metric is not None:
        for k in ("wrench", "wrench_axes"):
            if reg.has(k):
                raise reg.error(k, "the contacts' wrench_metric replaces the wrench regularisation: give one or "
                                   "the other")
    corrections = None
    if root.has("corrections"):
        both = [k for k in SECTIONS if root.has(k)]
        if both:
            raise root.error("corrections", f"the corrections are given twice: as this list and as the section(s) "
                                            f"{', '.join(both)}; move them into the list (in the order they run)")
        corrections = parse_corrections(root)
    stab = None
    if root.has("stabilizer"):
        from ..stabilizers.base import parse_stabilizer

        stab = parse_stabilizer(root.section("stabilizer"))
    base_feedback = None
    if root.has("base_feedback"):
        from ..estimation.base_feedback import BaseFeedbackConfig

        bf = root.section("base_feedback")
        if bf.bool("enabled", True):
            base_feedback = BaseFeedbackConfig(time_constant=bf.float("time_constant", 1.0, positive=True),
                                               liftoff_blend=bf.float("liftoff_blend", 0.0, min=0.0))
        bf.finish()
    from .liftoff import LiftOffWaitConfig
    from .plan_lead import PlanLeadConfig
    from .swing_tilt import SwingTiltConfig
    from .touchdown import TouchdownSearchConfig

    touchdown = _positive_section(root, "touchdown_search", TouchdownSearchConfig)
    swing_tilt = _positive_section(root, "swing_tilt", SwingTiltConfig)
    lift_off_wait = _positive_section(root, "lift_off_wait", LiftOffWaitConfig, upper={"max_load": (
        1.0, "is a share of the feet's summed load: must be in (0, 1)")})
    plan_lead = _positive_section(root, "plan_lead", PlanLeadConfig, required=("time",))
    step_adjustment = None
    if root.has("step_adjustment"):  # the controller's own settings of a walk's step adjustment (when it is on)
        from ..errors import PlanningError
        from ..planning.step_adjustment import StepAdjustmentConfig, parse_settings

        sa = root.section("step_adjustment")
        settings = parse_settings(sa)
        sa.finish()
        try:
            StepAdjustmentConfig(**settings)
        except PlanningError as exc:
            raise sa.error(None, str(exc)) from None
        step_adjustment = tuple(sorted(settings.items()))
    reach_cap = None
    if root.has("reach_cap"):
        rc = root.section("reach_cap")
        cap_tasks = rc.list("tasks")
        for i, n in enumerate(cap_tasks):
            if not isinstance(n, str) or n not in names:
                raise rc.error(f"tasks[{i}]", f"{n!r} is not a task of this set; its tasks: {', '.join(sorted(names))}")
        pairs = {}
        if rc.has("rotation_within") and not rc.has("rotation"):
            raise rc.error("rotation_within", "needs `rotation: [start, full]` [rad], the angular trigger it limits")
        for k, default in (("error", (0.10, 0.15)), ("speed", (0.2, 0.5)), ("rotation", None),
                           ("rotation_within", (0.20, 0.30))):
            if default is None and not rc.has(k):
                pairs[k] = None
                continue
            v = rc.vector(k, None if default is None else list(default), length=2, nonnegative=True)
            if not v[0] < v[1]:
                raise rc.error(k, f"must be [start, full] with start < full, got {v.tolist()}")
            pairs[k] = (float(v[0]), float(v[1]))
        reach_cap = ReachCapSpec(tuple(cap_tasks), pairs["error"], rc.float("linear", 20.0, positive=True),
                                 rc.float("angular", 60.0, positive=True), pairs["speed"], pairs["rotation"],
                                 pairs["rotation_within"])
        rc.finish()
    spec = TaskSetSpec(tasks=tuple(tasks), contacts=contacts, swing_foot=swing,
                       regularization_dv=reg.float("dv", 1e-6, positive=True),
                       regularization_wrench=reg.float("wrench", 1e-5, positive=True),
                       regularization_wrench_axes=tuple(reg.vector("wrench_axes", [1.0] * 6, length=6,
                                                                   nonnegative=True).tolist()),
                       regularization_wrench_target=reg.float("wrench_target", 0.0, min=0.0),
                       joint_limit_horizon=root.float("joint_limit_horizon", 0.01, positive=True),
                       arm_damping_injection=root.float("arm_damping_injection", 0.0, min=0.0),
                       arm_torque_share=root.float("arm_torque_share", 0.0, min=0.0),
                       solver=root.str("solver", "daqp", choices=["daqp", "proxsuite"]), stabilizer=stab,
                       base_feedback=base_feedback, touchdown_search=touchdown, swing_tilt=swing_tilt,
                       lift_off_wait=lift_off_wait, plan_lead=plan_lead, step_adjustment=step_adjustment,
                       swing_pitch_with_leg=pitch_with_leg, reach_cap=reach_cap, corrections=corrections,
                       servo_feedforward=root.str("servo_feedforward", "none", choices=list(SERVO_FEEDFORWARD)),
                       file=file)
    reg.finish()
    root.finish()
    return spec


def _wrench_metric(c: Section) -> "tuple[tuple[float, ...], ...] | TsidWrenchMetric":
    """`contacts.wrench_metric`: a 6 x 6 list (symmetric positive semi-definite) or `{form: tsid, ...}`."""
    raw = c.raw("wrench_metric")
    if isinstance(raw, dict):
        sec = c.section("wrench_metric")
        sec.str("form", choices=["tsid"])
        out = TsidWrenchMetric(
            weight=sec.float("weight", 1e-5, min=0.0),
            axis_weights=tuple(sec.vector("axis_weights", list(TSID_WRENCH_AXIS_WEIGHTS), length=6,
                                          nonnegative=True).tolist()),
            corner_regularization=sec.float("corner_regularization", 1e-8, min=0.0))
        sec.finish()
        return out
    try:
        W = as_wrench_metric(raw)
    except ValueError as exc:
        raise c.error("wrench_metric", f"{exc}, or {{form: tsid, weight, axis_weights, corner_regularization}}; "
                                       f"got {raw!r}") from None
    return tuple(tuple(float(x) for x in row) for row in W)


def _positive_section(root, key: str, cls, required: tuple[str, ...] = (), upper: dict | None = None):
    """The settings `cls` (a dataclass of floats) from the task set's section `key`, None when it has none: each
    field a positive number, the dataclass's default when absent (unless `required`); `upper`: field -> (bound,
    message) for a field that must stay below a bound."""
    if not root.has(key):
        return None
    sec = root.section(key)
    out = parse_settings(sec, cls, required, upper)
    sec.finish()
    return out
