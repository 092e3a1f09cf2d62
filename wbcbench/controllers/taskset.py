"""Task sets: the tasks, contacts and gains of a controller, from YAML (inria_wbc style: named tasks dispatched
on `type:`) or built in Python. The YAML parses into these frozen dataclasses, which are the API.

Frames may be given symbolically, resolved through the robot profile: `base`, `torso`, `head`, `left_hand`,
`right_hand`, `left_foot`, `right_foot`; any other string is a frame name of the model.

Task types: `com`, `frame`, `posture`, `angular_momentum`, and `self_collision` (paper 004 Eq. 8-13): `side:
left|right` picks the robot profile's `repulsors` set for that side (protected point, r_frame, exponent, the
repulsion points and their radii); the task has one axis per repulsion point, so `kp`/`kd`/`mask` are a number
or one value per point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..config import Section, load_yaml
from ..errors import ConfigError, UnknownNameError
from ..robots import RepulsorSpec, Robot, Side

TASKSET_DIR = Path(__file__).parent / "tasksets"
TASK_TYPES = ("com", "frame", "posture", "angular_momentum", "self_collision")
MASK_LENGTH = {"com": 3, "frame": 6, "angular_momentum": 3}


@dataclass(frozen=True)
class TaskSpec:
    """One task. `kp`/`kd` are per-axis arrays (posture: per joint, resolved from joint-name prefixes);
    `kd` None means 2 sqrt(kp). `repulsors` (self_collision tasks): the profile's repulsor set of the task's
side. `priority`: for the inverse-dynamics QP, 0 makes the task a hard equality
    constraint and 1 a weighted cost; for the hierarchical IK it is the task's level (0 is the feet, tasks of
    one level are weighted against each other)."""

    name: str
    type: str
    weight: float
    kp: np.ndarray
    kd: np.ndarray | None
    mask: tuple[bool, ...] | None = None
    frame: str | None = None
    priority: int = 1
    repulsors: RepulsorSpec | None = None


@dataclass(frozen=True)
class ContactSpec:
    """Gains and limits shared by the sole contacts: motion gains (LOCAL x y z roll pitch yaw), friction
    coefficient, normal force bounds [N], and the time [s] over which a leaving/arriving contact's maximum
    normal force is ramped. `model_sole` (length, width) [m] replaces the profile's sole rectangle in the
    controller's model: position controllers relax it so a stabilizer moving the CoM does not saturate the
    model's CoP limits (SIM-NOTES); None keeps the real sole."""

    kp: float
    kd: float
    mu: float = 0.3
    min_normal_force: float = 0.0
    max_normal_force: float = 2000.0
    transition_time: float = 0.05
    model_sole: tuple[float, float] | None = None


@dataclass(frozen=True)
class TaskSetSpec:
    tasks: tuple[TaskSpec, ...]
    contacts: ContactSpec
    swing_foot: TaskSpec
    regularization_dv: float = 1e-6
    regularization_wrench: float = 1e-5
    joint_limit_horizon: float = 0.01
    solver: str = "daqp"
    stabilizer: "DcmGains | None" = None
    teleop: "TeleopSpec | None" = None
    base_feedback: "BaseFeedbackConfig | None" = None
    file: str = field(default="", compare=False)

    def task(self, name: str) -> TaskSpec:
        for t in self.tasks:
            if t.name == name:
                return t
        raise KeyError(name)


def resolve_frame(robot: Robot, frame: str) -> str:
    p = robot.profile
    symbolic = {"base": p.base_frame, "torso": p.torso_frame, "head": p.head_frame,
                "left_hand": p.hands[Side.LEFT], "right_hand": p.hands[Side.RIGHT],
                "left_foot": p.feet[Side.LEFT].frame, "right_foot": p.feet[Side.RIGHT].frame}
    return symbolic.get(frame, frame)


def taskset_path(robot: Robot, controller: str) -> Path:
    for d in (TASKSET_DIR / robot.name, TASKSET_DIR / "default"):
        p = d / f"{controller}.yaml"
        if p.exists():
            return p
    raise ConfigError(f"no task set for controller '{controller}' (looked in {TASKSET_DIR / robot.name} and "
                      f"{TASKSET_DIR / 'default'})")


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


def _parse_task(sec: Section, robot: Robot, name: str | None = None, max_priority: int = 1) -> TaskSpec:
    name = name or sec.str("name")
    ttype = sec.str("type", choices=TASK_TYPES)
    repulsors = None
    if ttype == "self_collision":
        side = Side(sec.str("side", choices=[s.value for s in Side]))
        repulsors = robot.profile.repulsors.get(side)
        if repulsors is None:
            raise sec.error("side", f"the robot profile {robot.profile.file} has no `repulsors.{side.value}` "
                                    "section (the repulsion points of a self_collision task come from the profile)")
        n = len(repulsors.points)
    else:
        n = robot.na if ttype == "posture" else MASK_LENGTH[ttype]
    mask = None
    if ttype != "posture" and sec.has("mask"):
        m = sec.raw("mask")
        if isinstance(m, str):
            m = [c for c in m]
        try:
            mask = tuple(bool(int(x)) for x in m)
        except (TypeError, ValueError):
            raise sec.error("mask", f"must be {n} zeros/ones, got {m!r}") from None
        if len(mask) != n or any(int(x) not in (0, 1) for x in m):
            axes = ("one per repulsion point" if ttype == "self_collision" else
                    "x y z roll pitch yaw" if n == 6 else "x y z")
            raise sec.error("mask", f"must have {n} entries of 0 or 1 (axes {axes}), got {m!r}")
    frame = None
    if ttype == "frame":
        frame = resolve_frame(robot, sec.str("frame"))
        if not robot.model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in robot.model.frames], file=sec.file,
                                   key=sec.key("frame"))
    weight = sec.float("weight", min=0.0)
    kp = _gain_vector(sec, "kp", n, robot, ttype == "posture")
    kd = _gain_vector(sec, "kd", n, robot, ttype == "posture", default=None)
    priority = sec.int("priority", 1, min=0)
    if priority > max_priority:
        raise sec.error("priority", f"must be between 0 and {max_priority} for this controller "
                        + ("(0: hard constraint, 1: weighted cost)" if max_priority == 1 else "(0 is the feet)"))
    sec.finish()
    return TaskSpec(name=name, type=ttype, weight=weight, kp=kp, kd=kd, mask=mask, frame=frame, priority=priority,
                    repulsors=repulsors)


def load_taskset(path: str | Path, robot: Robot, max_priority: int = 1) -> TaskSetSpec:
    """Parse and validate a task-set file for `robot`; errors name the file and key. `max_priority` is the
    largest priority the controller accepts (1 for the weighted QP; the number of levels for the IK)."""
    file = str(path)
    root = Section(load_yaml(path), file)
    tasks = []
    names = set()
    for i, raw in enumerate(root.list("tasks")):
        t = _parse_task(Section(raw, file, f"tasks[{i}]"), robot, max_priority=max_priority)
        if t.name in names:
            raise ConfigError(f"task name '{t.name}' used twice", file=file, key=f"tasks[{i}].name")
        names.add(t.name)
        tasks.append(t)
    c = root.section("contacts")
    contacts = ContactSpec(kp=c.float("kp", min=0.0), kd=c.float("kd", 0.0, min=0.0), mu=c.float("mu", 0.3, positive=True),
                           min_normal_force=c.float("min_normal_force", 0.0, min=0.0),
                           max_normal_force=c.float("max_normal_force", 2000.0, positive=True),
                           transition_time=c.float("transition_time", 0.05, min=0.0),
                           model_sole=tuple(c.vector("model_sole", length=2)) if c.has("model_sole") else None)
    if contacts.model_sole is not None and min(contacts.model_sole) <= 0:
        raise c.error("model_sole", "length and width must be > 0")
    if contacts.max_normal_force < contacts.min_normal_force:
        raise c.error("max_normal_force", "must be >= min_normal_force")
    c.finish()
    sw = root.section("swing_foot")
    sw.data.setdefault("type", "frame")
    sw.data.setdefault("frame", "left_foot")
    swing = _parse_task(sw, robot, name="swing_foot", max_priority=max_priority)
    reg = root.section("regularization", {})
    stab = None
    if root.has("stabilizer"):
        from ..stabilizers import DcmGains

        st = root.section("stabilizer")
        cutoff = st.raw("zmp_cutoff_hz", None)
        stab = DcmGains(kp_adm=st.float("kp_adm", min=0.0), kp_dcm=st.float("kp_dcm", min=0.0),
                        ki_dcm=st.float("ki_dcm", min=0.0), kz_dcm=st.float("kz_dcm", min=0.0),
                        integral_limit=st.float("integral_limit", 0.1, positive=True),
                        zmp_cutoff_hz=None if cutoff is None else st.float("zmp_cutoff_hz", positive=True))
        st.finish()
    teleop = None
    if root.has("teleop"):
        from ..stabilizers.teleop import parse_teleop_section

        teleop = parse_teleop_section(root.section("teleop"))
    base_feedback = None
    if root.has("base_feedback"):
        from ..estimation.base_feedback import BaseFeedbackConfig

        bf = root.section("base_feedback")
        if bf.bool("enabled", True):
            base_feedback = BaseFeedbackConfig(time_constant=bf.float("time_constant", 1.0, positive=True))
        bf.finish()
    spec = TaskSetSpec(tasks=tuple(tasks), contacts=contacts, swing_foot=swing,
                       regularization_dv=reg.float("dv", 1e-6, positive=True),
                       regularization_wrench=reg.float("wrench", 1e-5, positive=True),
                       joint_limit_horizon=root.float("joint_limit_horizon", 0.01, positive=True),
                       solver=root.str("solver", "daqp", choices=["daqp", "proxsuite"]), stabilizer=stab,
                       teleop=teleop, base_feedback=base_feedback, file=file)
    reg.finish()
    root.finish()
    return spec
