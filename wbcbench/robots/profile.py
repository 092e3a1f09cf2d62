"""Robot profiles: everything robot-specific, read from one YAML file per robot."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..catalogue import BUILTIN_ROBOTS  # the built-ins: name -> profile file of profiles/
from ..config import Section, load_yaml
from ..errors import UnknownNameError
from ..side import Side

PROFILE_DIR = Path(__file__).parent / "profiles"


@dataclass(frozen=True)
class FootSpec:
    """One foot: its sole frame (centre of the sole rectangle, z = contact normal) and its ankle F/T sensor.

    If `parent_frame` is set, the sole frame does not exist in the URDF and is added at `offset` [m]
    (expressed in the parent frame), turned by `rpy` [rad] from the parent frame's orientation.
    """

    frame: str
    ft_sensor_frame: str
    parent_frame: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SoleSpec:
    """The sole rectangle in the sole frame [m]: length along x, width along y, centre offset (x, y)."""

    length: float
    width: float
    center: tuple[float, float]
    thickness: float

    @property
    def corners(self) -> np.ndarray:
        """(4, 3) corners of the rectangle in the sole frame, counter-clockwise from (-x, -y)."""
        cx, cy = self.center
        hl, hw = self.length / 2, self.width / 2
        return np.array([[cx - hl, cy - hw, 0], [cx + hl, cy - hw, 0], [cx + hl, cy + hw, 0],
                         [cx - hl, cy + hw, 0]])


@dataclass(frozen=True)
class GainSpec:
    """Per-joint gains by joint-name prefix (longest prefix wins); kd = kd_ratio * kp."""

    kp: dict[str, float]
    kd_ratio: float

    def resolve(self, joint_names: list[str], file: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        kp = np.zeros(len(joint_names))
        for i, name in enumerate(joint_names):
            best = max((p for p in self.kp if name.startswith(p)), key=len, default=None)
            if best is None:
                raise UnknownNameError("gain pattern for joint", name, self.kp, file=file, key="kp")
            kp[i] = self.kp[best]
        return kp, self.kd_ratio * kp


@dataclass(frozen=True)
class RepulsionPointSpec:
    """One repulsion point of a self-collision repulsor set (paper 004 Eq. 13): `radius` r_rep [m] around the
    point at `offset` [m] in `frame`; `name` labels the task axis (None: the frame name)."""

    frame: str
    radius: float
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str | None = None


@dataclass(frozen=True)
class RepulsorSpec:
    """The self-collision repulsors protecting one point of the robot (a gripper), paper 004 Section IV.

    frame, offset: the protected point (`offset` [m] in `frame`); radius: r_frame [m] around it; exponent: p of
    Eq. 13; normalized: True for C = exp(-(d / a)^p) (inria_wbc, `a` is the radius of influence), False for
    C = exp(-d^p / a) as printed; points: the repulsion points it is kept away from.
    """

    frame: str
    radius: float
    points: tuple[RepulsionPointSpec, ...]
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    exponent: float = 3.0
    normalized: bool = True


@dataclass(frozen=True)
class CollisionCheckSpec:
    """Links whose URDF collision meshes are added to the MuJoCo model to count self-collisions of one
    effector: `effector` (the gripper's links) against `bodies` (the links it must not touch)."""

    effector: tuple[str, ...]
    bodies: tuple[str, ...]


@dataclass(frozen=True)
class SteppingSpec:
    """What one step may do, for footstep planning from a command or a path (walking frame per step):
    forward / backward advance [m], lateral advance of the leading foot [m] (the trailing foot closes), turn of
    the inside foot [rad] (the outside foot closes), and the minimum clearance between the two soles' edges [m]
    (the planner rejects footprints closer than this)."""

    max_forward: float = 0.30
    max_backward: float = 0.20
    max_lateral: float = 0.12
    max_turn: float = 0.35
    min_clearance: float = 0.0
    #: default of the terrain walks' `max_leg_extension` (largest hip-ankle distance of a loaded leg the centroidal
    #: plan may ask for, a fraction of the leg at its joints' zero); None: the scenario kind's default
    max_leg_extension: float | None = None


@dataclass(frozen=True)
class RobotProfile:
    """Everything wbcbench needs to know about one robot, validated on load."""

    name: str
    description: str
    loader: str
    reference_posture: str | dict[str, float]
    base_frame: str
    torso_frame: str
    imu_frame: str
    head_frame: str
    feet: dict[Side, FootSpec]
    hands: dict[Side, str]
    sole: SoleSpec
    position_limit_overrides: dict[str, tuple[float, float]]
    armature: float | None
    position_gains: GainSpec
    torque_pd_gains: GainSpec
    min_base_height: float
    max_tilt: float
    repulsors: dict[Side, RepulsorSpec] = field(default_factory=dict)
    collision_check: dict[Side, CollisionCheckSpec] = field(default_factory=dict)
    stepping: SteppingSpec = field(default_factory=SteppingSpec)
    #: scenario name -> {"params": {...}, "terrain": {...}}: this robot's sizes of a scenario (`scenarios:`)
    scenario_overrides: dict[str, dict[str, dict]] = field(default_factory=dict)
    file: str = field(default="", compare=False)
    #: joint-name prefix -> effort [N m] / velocity [rad/s] limit, for joints whose URDF gives none (or a wrong one)
    effort_overrides: dict[str, float] = field(default_factory=dict)
    velocity_overrides: dict[str, float] = field(default_factory=dict)
    #: lower bounds on every moving body's mass [kg] and principal inertias [kg m^2], for URDFs with massless
    #: links (applied to the pinocchio and the MuJoCo model alike); 0: none
    min_body_mass: float = 0.0
    min_body_inertia: float = 0.0


def builtin_robots() -> list[str]:
    return sorted(BUILTIN_ROBOTS)


def plugin_robots() -> dict[str, Path]:
    """Robot profiles of installed packages (`wbcbench.robots` entry points): name -> profile YAML path."""
    from ..plugins import discover

    return {p.name: Path(p.obj() if callable(p.obj) else p.obj)
            for p in discover("wbcbench.robots", set(builtin_robots())) if p.error is None}


def robot_plugin_errors() -> dict[str, str]:
    from ..plugins import discover, message

    return {p.name: message(p) for p in discover("wbcbench.robots", set(builtin_robots())) if p.error is not None}


def available_robots() -> list[str]:
    return sorted({*builtin_robots(), *plugin_robots()})


def _gains(sec: Section) -> GainSpec:
    kp_sec = sec.section("kp")
    kp = {k: kp_sec.float(k, min=0.0) for k in list(kp_sec.data)}
    kp_sec.finish()
    if not kp:
        raise sec.error("kp", "needs at least one joint-name prefix")
    g = GainSpec(kp=kp, kd_ratio=sec.float("kd_ratio", min=0.0))
    sec.finish()
    return g


def _offset(sec: Section, key: str = "offset") -> tuple[float, float, float]:
    return tuple(float(x) for x in sec.vector(key, [0.0, 0.0, 0.0], length=3))


def _repulsors(root: Section) -> dict[Side, RepulsorSpec]:
    """The optional `repulsors` section: per side, the protected point and its repulsion points."""
    if not root.has("repulsors"):
        return {}
    sec = root.section("repulsors")
    out = {}
    for side in Side:
        if not sec.has(side.value):
            continue
        rs = sec.section(side.value)
        points = []
        for i, raw in enumerate(rs.list("points")):
            ps = Section(raw, rs.file, rs.key(f"points[{i}]"))
            points.append(RepulsionPointSpec(frame=ps.str("frame"), radius=ps.float("radius", min=0.0),
                                             offset=_offset(ps), name=ps.str("name") if ps.has("name") else None))
            ps.finish()
        if not points:
            raise rs.error("points", "needs at least one repulsion point")
        spec = RepulsorSpec(frame=rs.str("frame"), radius=rs.float("radius", min=0.0), points=tuple(points),
                            offset=_offset(rs), exponent=rs.float("exponent", 3.0, min=2.0),
                            normalized=rs.bool("normalized", True))
        if any(spec.radius + p.radius <= 0 for p in points):
            raise rs.error("radius", "r_frame + r_rep must be > 0 for every repulsion point")
        rs.finish()
        out[side] = spec
    sec.finish()
    return out


def _collision_check(root: Section) -> dict[Side, CollisionCheckSpec]:
    """The optional `collision_check` section: per side, effector links and the body links they must not touch."""
    if not root.has("collision_check"):
        return {}
    sec = root.section("collision_check")
    out = {}
    for side in Side:
        if not sec.has(side.value):
            continue
        cs = sec.section(side.value)
        names = {}
        for key in ("effector", "bodies"):
            val = cs.list(key)
            if not val or not all(isinstance(v, str) for v in val):
                raise cs.error(key, "must be a non-empty list of link names")
            names[key] = tuple(val)
        both = set(names["effector"]) & set(names["bodies"])
        if both:
            raise cs.error("bodies", f"links listed as both effector and body: {sorted(both)}")
        cs.finish()
        out[side] = CollisionCheckSpec(effector=names["effector"], bodies=names["bodies"])
    sec.finish()
    return out


def _stepping(root: Section) -> SteppingSpec:
    st = root.section("stepping", {})
    d = SteppingSpec()
    spec = SteppingSpec(
        max_forward=st.float("max_forward", d.max_forward, positive=True, max=1.0),
        max_backward=st.float("max_backward", d.max_backward, positive=True, max=1.0),
        max_lateral=st.float("max_lateral", d.max_lateral, positive=True, max=1.0),
        max_turn=st.float("max_turn", d.max_turn, positive=True, max=1.5),
        min_clearance=st.float("min_clearance", d.min_clearance, min=0.0, max=0.2),
        max_leg_extension=(st.float("max_leg_extension", min=0.0, max=1.0) if st.has("max_leg_extension")
                           else None))
    st.finish()
    return spec


SCENARIO_OVERRIDE_KEYS = ("params", "terrain")
"""What a profile's `scenarios:` entry may replace in a scenario file."""


def _scenario_overrides(root: Section) -> dict[str, dict[str, dict]]:
    """`scenarios:` scenario name -> {params: {...}, terrain: {...}}: keys replaced in that scenario's file when it
    runs on this robot (the robot's sizes of a shipped scenario). The scenario validates the merged values."""
    sec = root.section("scenarios", {})
    out = {}
    for name in list(sec.data):
        entry = sec.section(name)
        parts = {}
        for k in SCENARIO_OVERRIDE_KEYS:
            if entry.raw(k, None) is not None:
                parts[k] = dict(entry.section(k).data)
        entry.finish()
        if not parts:
            raise sec.error(name, f"give at least one of {', '.join(SCENARIO_OVERRIDE_KEYS)}")
        out[str(name)] = parts
    sec.finish()
    return out


def load_profile(name_or_path: str | Path) -> RobotProfile:
    """Load a robot profile by robot name (a file in wbcbench/robots/profiles, or a `wbcbench.robots` plugin) or by
    path to a YAML file."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        path = p
    else:
        builtin = BUILTIN_ROBOTS.get(str(name_or_path))
        if builtin is not None:
            path = PROFILE_DIR / builtin
        else:
            plugins = plugin_robots()
            if str(name_or_path) in plugins:
                path = plugins[str(name_or_path)]
            else:
                broken = robot_plugin_errors().get(str(name_or_path))
                if broken is not None:
                    from ..plugins import PluginError

                    raise PluginError(broken, key="--robot")
                raise UnknownNameError("robot", str(name_or_path), available_robots(), key="--robot")
    file = str(path)
    root = Section(load_yaml(path), file)
    posture = root.raw("reference_posture")
    if isinstance(posture, dict):
        posture_sec = Section(posture, file, "reference_posture")
        posture = {k: posture_sec.float(k) for k in list(posture_sec.data)}
    elif not isinstance(posture, str):
        raise root.error("reference_posture", "must be an SRDF state name or a mapping joint -> angle [rad]")
    feet_sec = root.section("feet")
    feet = {}
    for side in Side:
        fs = feet_sec.section(side.value)
        offset = fs.vector("offset", [0.0, 0.0, 0.0], length=3)
        feet[side] = FootSpec(frame=fs.str("frame"), ft_sensor_frame=fs.str("ft_sensor_frame"),
                              parent_frame=fs.str("parent_frame", None) if fs.has("parent_frame") else None,
                              offset=tuple(offset), rpy=tuple(fs.vector("rpy", [0.0, 0.0, 0.0], length=3)))
        fs.finish()
    feet_sec.finish()
    hands_sec = root.section("hands")
    hands = {side: hands_sec.str(side.value) for side in Side}
    hands_sec.finish()
    sole_sec = root.section("sole")
    sole = SoleSpec(length=sole_sec.float("length", positive=True), width=sole_sec.float("width", positive=True),
                    center=tuple(sole_sec.vector("center", [0.0, 0.0], length=2)),
                    thickness=sole_sec.float("thickness", 0.02, positive=True))
    sole_sec.finish()
    lim = root.section("limits", {})
    overrides = {}
    ov = lim.section("position_overrides", {})
    for jname in list(ov.data):
        lo_hi = ov.vector(jname, length=2)
        if lo_hi[0] >= lo_hi[1]:
            raise ov.error(jname, f"lower limit must be below upper, got {lo_hi.tolist()}")
        overrides[jname] = (float(lo_hi[0]), float(lo_hi[1]))
    ov.finish()
    armature = lim.float("armature", min=0.0) if lim.has("armature") else None
    limit_overrides = {}
    for key in ("effort_overrides", "velocity_overrides"):
        sec = lim.section(key, {})
        limit_overrides[key] = {k: sec.float(k, positive=True) for k in list(sec.data)}
        sec.finish()
    min_mass = lim.float("min_body_mass", 0.0, min=0.0)
    min_inertia = lim.float("min_body_inertia", 0.0, min=0.0)
    lim.finish()
    fall = root.section("fall")
    prof = RobotProfile(
        name=root.str("name"),
        description=root.str("description", ""),
        loader=root.str("loader"),
        reference_posture=posture,
        base_frame=root.str("base_frame"),
        torso_frame=root.str("torso_frame"),
        imu_frame=root.str("imu_frame"),
        head_frame=root.str("head_frame"),
        feet=feet,
        hands=hands,
        sole=sole,
        position_limit_overrides=overrides,
        armature=armature,
        effort_overrides=limit_overrides["effort_overrides"],
        velocity_overrides=limit_overrides["velocity_overrides"],
        min_body_mass=min_mass,
        min_body_inertia=min_inertia,
        position_gains=_gains(root.section("position_gains")),
        torque_pd_gains=_gains(root.section("torque_pd_gains")),
        min_base_height=fall.float("min_base_height", positive=True),
        max_tilt=fall.float("max_tilt", positive=True),
        repulsors=_repulsors(root),
        collision_check=_collision_check(root),
        stepping=_stepping(root),
        scenario_overrides=_scenario_overrides(root),
        file=file,
    )
    fall.finish()
    root.finish()
    return prof


GENERATED_HEADER = "# Robot profile generated by `wbcbench robot init"
"""The first line `wbcbench robot init` writes (wbcbench.robots.generate)."""
HAND_TUNED_TAG = "# hand-tuned:"
"""The comment line of a generated profile naming the top-level keys edited by hand after generation
(`# hand-tuned: key, key (why)`, or `none`)."""


def profile_provenance(path: str | Path) -> dict:
    """Which of a profile's top-level keys `wbcbench robot init` wrote and which were tuned by hand since, read
    from its comments: {"kind": "generated" | "hand-written", "generated": [...], "hand_tuned": [...]}. A profile
    without the generator's header line is hand-written (every key by hand)."""
    import yaml

    text = Path(path).read_text()
    keys = list((yaml.safe_load(text) or {}).keys())
    if not text.startswith(GENERATED_HEADER):
        return {"kind": "hand-written", "generated": [], "hand_tuned": keys}
    tuned: list[str] = []
    for line in text.splitlines():
        if line.startswith(HAND_TUNED_TAG):
            listed = line[len(HAND_TUNED_TAG):].split("(")[0]
            tuned = [k.strip() for k in listed.split(",") if k.strip() in keys]
            break
    return {"kind": "generated", "generated": [k for k in keys if k not in tuned], "hand_tuned": tuned}
