"""The simulated robot as hardware is (`--realism PRESET`): actuator chains and structural flexibility that the
controller never sees (it keeps the nominal pinocchio model; the measurement keeps the nominal joint layout).

A preset (`talos-real.yaml` here, or a user's YAML file) has five optional sections and one solver setting, and may
start from another preset (`extends: talos-real`: its sections, each replaced by this file's; a section set to null
is removed):

    sensors: talos-like          # the sensor profile used unless the run names one (--sensors)
    actuators:                   # joint-name pattern (fnmatch) -> parameters; later patterns override earlier
      "leg_*": {coulomb: N m, viscous: N m s/rad, stiffness: N m/rad, damping: N m s/rad, torque_limit: N m}
    torque_loop: {bandwidth: Hz, delay: s, sensor_noise: N m, seed: int}   # torque mode only
    hip_flexibility: {joints: [hip joint names], stiffness: N m/rad, damping: N m s/rad}
    motors:                      # the electrical model of the metrics only (nothing simulated): every joint
      convention: dq             # dq (default) or dc, see `Motors`
      regeneration: false        # false (default): no drive returns energy; true: negative power counts
      joints: {"leg_*": {torque_constant: N m/A, gear_ratio: -, resistance: ohm}}
    stiction_damping: 100000.0   # [N m s/rad] how hard the Coulomb friction holds below break-away (creep tau / it)
    stiction_impedance: 0.999    # instead: the friction as MuJoCo's frictionloss constraint (0.9 to 0.9999; slower)

How each mechanism is simulated, and why this way:

- Harmonic-drive elasticity (`stiffness` > 0): a hidden hinge `<joint>:drive` is added to the joint's MuJoCo body,
  on the same axis through the same point, with the drive's stiffness and damping (MuJoCo joint spring). The
  nominal joint is the motor side (rotor inertia through the gear ratio: its armature; the actuator; the
  encoder), the hidden joint is the deflection, and the link angle is their sum. The two coordinates (motor
  angle, deflection) describe the two-inertia chain exactly: the armature sits on the motor coordinate only, the
  link's inertia on the sum. MuJoCo integrates the spring and damper with the rest of the dynamics (its
  implicit-in-velocity integrator treats the damping implicitly), so no explicitly integrated motor state at the
  control rate is needed and nothing is lagged by one step. Cost: one more degree of freedom per elastic joint.
- Friction (`wbcbench/sim/friction_kernel.py`): Coulomb with stiction and viscous, on the motor side. Viscous:
  MuJoCo's joint `damping`. Coulomb (break-away torque: the URDF's `frictionloss` plus `coulomb`): a switch per
  joint decided before each physics step from its velocity (after Karnopp's stick-slip model). Sticking or
  stopping, the friction is a saturated damper -min(`stiction_damping` |v|, break-away) sign(v), put into MuJoCo's
  joint damping (implicit in velocity under implicitfast, so any value is stable): a torque below break-away
  moves the joint at only torque / `stiction_damping` (16 urad/s for 1.6 N m at the default 1e5 N m s/rad), and a
  stopping joint does not overshoot through zero. Breaking away, the joint slides against a constant
  -break-away sign(v) (MuJoCo's `qfrc_applied`) until its velocity changes sign. The friction force the contact
  solution sees is never above the break-away torque. Cost: one compiled call per physics step.
  `stiction_impedance` selects the former formulation instead, MuJoCo's `frictionloss` constraint made near-hard
  (impedance d, `solimp` = [d, 1 - (1 - d) / 10, ...]; a joint at 80 % of its break-away torque creeps about
  0.03 (1 - d) rad/s): solved jointly with the contacts, but its Newton solver then needs 3-4 iterations per
  physics step instead of 1, the switch's largest cost (docs/results/real-robot.md, "Cost").
- Current/torque limit: the actuator's force range (the smaller of the profile's effort limit and the preset's).
- Torque loop (torque mode): the commanded torque reaches the joint through a pure delay and a first-order lag
  of the given bandwidth; the loop servoes the joint torque sensor's reading, so the sensor's noise enters the
  delivered torque (with the opposite sign). Computed in `Simulator.step` at the physics rate.
- Position mode: the servo PD (the profile's gains) acts on the nominal joint, i.e. on the motor side.
- Hip flexibility: a hidden hinge `<hip joint>:hip_flex` with stiffness and damping in the hip joint's body, on
  that joint's axis (a passive spring in series), unseen by the encoders.

The hidden joints are logged only as extra channels for metrics (`hidden_deflection`, `RealismProbe`).
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...config import Section, load_yaml
from ...errors import ConfigError, UnknownNameError

PRESET_DIR = Path(__file__).parent


def preset_names() -> list[str]:
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


@dataclass(frozen=True)
class TorqueLoop:
    """The low-level torque loop of torque mode: bandwidth [Hz] (0: none), pure delay [s], sensor noise [N m]."""

    bandwidth: float = 0.0
    delay: float = 0.0
    sensor_noise: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class HipFlexibility:
    joints: tuple[str, ...] = ()
    stiffness: float = 973.0
    damping: float = 0.0


@dataclass(frozen=True)
class Motors:
    """The electrical side of the actuators, per joint (robot order), for the electrical energy and cost of
    transport (`wbcbench.metrics.energy.electrical_energy`): motor torque constant k_t [N m/A], gear ratio N,
    winding resistance R [ohm]. `convention` fixes what k_t and R refer to: `dq` (three-phase motor, R per phase,
    k_t per ampere of q-axis current amplitude in the amplitude-invariant Park transform: copper loss
    3/2 R i^2) or `dc` (R and k_t of an equivalent DC motor: R i^2). `regeneration`: whether a drive's negative
    power (braking) is returned to the supply."""

    torque_constant: tuple[float, ...]
    gear_ratio: tuple[float, ...]
    resistance: tuple[float, ...]
    convention: str = "dq"
    regeneration: bool = False

    def describe(self, joints) -> dict:
        return {"convention": self.convention, "regeneration": self.regeneration,
                "joints": {j: {"torque_constant": k, "gear_ratio": n, "resistance": r}
                           for j, k, n, r in zip(joints, self.torque_constant, self.gear_ratio, self.resistance)}}


MOTOR_CONVENTIONS = ("dq", "dc")


@dataclass(frozen=True)
class Realism:
    """A parsed preset, resolved per joint (robot joint order)."""

    name: str
    file: str | None
    joints: tuple[str, ...]
    sensors: str | None = None
    coulomb: tuple[float, ...] = ()
    viscous: tuple[float, ...] = ()
    stiffness: tuple[float, ...] = ()
    damping: tuple[float, ...] = ()
    torque_limit: tuple[float, ...] = ()   # inf: the profile's effort limit only
    torque_loop: TorqueLoop | None = None
    hip: HipFlexibility | None = None
    motors: Motors | None = None
    stiction_damping: float = 1.0e5
    stiction_impedance: float | None = None  # set: the friction as MuJoCo's frictionloss constraint instead
    raw: dict = field(default_factory=dict, compare=False)

    def describe(self) -> dict:
        """For config.json: the preset's name and file and its resolved values."""
        return {"name": self.name, "file": self.file, "sensors": self.sensors,
                "joints": {j: {"coulomb": c, "viscous": v, "stiffness": k, "damping": d,
                               "torque_limit": (None if not np.isfinite(t) else t)}
                           for j, c, v, k, d, t in zip(self.joints, self.coulomb, self.viscous, self.stiffness,
                                                       self.damping, self.torque_limit)},
                "torque_loop": self.torque_loop.__dict__ if self.torque_loop else None,
                "hip_flexibility": ({"joints": list(self.hip.joints), "stiffness": self.hip.stiffness,
                                     "damping": self.hip.damping} if self.hip else None),
                "stiction_damping": self.stiction_damping, "stiction_impedance": self.stiction_impedance,
                **({"motors": self.motors.describe(self.joints)} if self.motors is not None else {})}


_ACT_KEYS = ("coulomb", "viscous", "stiffness", "damping", "torque_limit")


def _joint_groups(sec: Section, joints: list[str]):
    """(pattern, its section, the indices of the joints it matches) of a mapping joint-name pattern (fnmatch) ->
    settings; a pattern matching no joint is an error naming its key."""
    for pattern in list(sec.data):
        hit = [i for i, j in enumerate(joints) if fnmatch.fnmatchcase(j, str(pattern))]
        if not hit:
            raise UnknownNameError("joint (or pattern matching no joint)", str(pattern), joints, file=sec.file,
                                   key=sec.key(str(pattern)))
        yield pattern, sec.section(pattern), hit


def parse_realism(sec: Section, robot, name: str | None = None) -> Realism:
    """A preset's mapping for `robot` (errors name the file and key)."""
    joints = list(robot.joint_names)
    effort = np.asarray(robot.effort_limit, dtype=float)
    n = len(joints)
    vals = {k: np.zeros(n) for k in _ACT_KEYS}
    vals["torque_limit"][:] = np.inf
    sensors = sec.raw("sensors", None)
    if sensors is not None and not isinstance(sensors, str):
        raise sec.error("sensors", f"must be a sensor profile name or file, got {sensors!r}")
    act = sec.section("actuators", {})
    for pattern, group, hit in _joint_groups(act, joints):
        for k in _ACT_KEYS:
            if group.has(k):
                vals[k][hit] = group.float(k, min=0.0) if k != "torque_limit" else group.float(k, positive=True)
        group.finish()
        # friction above what the motor can give: the joint could never move
        limit = np.minimum(effort, vals["torque_limit"])
        bad = [i for i in hit if vals["coulomb"][i] >= limit[i]]
        if bad:
            raise act.error(f"{pattern}.coulomb", f"Coulomb friction {vals['coulomb'][bad[0]]} N m of "
                            f"{joints[bad[0]]} is not below its torque limit {limit[bad[0]]} N m")
    act.finish()
    loop = None
    if sec.has("torque_loop"):
        ls = sec.section("torque_loop")
        loop = TorqueLoop(ls.float("bandwidth", 0.0, min=0.0), ls.float("delay", 0.0, min=0.0),
                          ls.float("sensor_noise", 0.0, min=0.0), ls.int("seed", 0, min=0))
        ls.finish()
    hip = None
    if sec.has("hip_flexibility"):
        hs = sec.section("hip_flexibility")
        names = hs.list("joints")
        for k, j in enumerate(names):
            if j not in joints:
                raise UnknownNameError("joint", str(j), joints, file=sec.file, key=hs.key(f"joints[{k}]"))
        hip = HipFlexibility(tuple(names), hs.float("stiffness", positive=True), hs.float("damping", 0.0, min=0.0))
        hs.finish()
    motors = _parse_motors(sec.section("motors"), joints) if sec.has("motors") else None
    stiction = sec.float("stiction_damping", 1.0e5, positive=True)
    impedance = sec.float("stiction_impedance", 0.999, min=0.9, max=0.9999) if sec.has("stiction_impedance") else None
    if impedance is not None and sec.has("stiction_damping"):
        raise sec.error("stiction_impedance", "give either stiction_damping (the default friction model) or "
                        "stiction_impedance (MuJoCo's frictionloss constraint), not both")
    sec.finish()
    return Realism(name or Path(sec.file or "realism").stem, sec.file, tuple(joints), sensors,
                   *(tuple(float(x) for x in vals[k]) for k in _ACT_KEYS), loop, hip, motors, stiction, impedance,
                   dict(sec.data))


def _parse_motors(ms: Section, joints: list[str]) -> Motors:
    """The `motors:` section: every joint needs its three values (the electrical energy sums all joints, as the
    mechanical one does)."""
    convention = ms.str("convention", "dq", choices=MOTOR_CONVENTIONS)
    regeneration = ms.bool("regeneration", False)
    js = ms.section("joints")
    vals = {k: np.full(len(joints), np.nan) for k in ("torque_constant", "gear_ratio", "resistance")}
    for _pattern, group, hit in _joint_groups(js, joints):
        for k in ("torque_constant", "gear_ratio"):
            if group.has(k):
                vals[k][hit] = group.float(k, positive=True)
        if group.has("resistance"):
            vals["resistance"][hit] = group.float("resistance", min=0.0)
        group.finish()
    for k, v in vals.items():
        if np.isnan(v).any():
            missing = joints[int(np.flatnonzero(np.isnan(v))[0])]
            raise js.error(None, f"no {k} for joint {missing} (every joint needs torque_constant, gear_ratio and "
                                 "resistance)")
    js.finish()
    ms.finish()
    return Motors(*(tuple(float(x) for x in vals[k]) for k in ("torque_constant", "gear_ratio", "resistance")),
                  convention, regeneration)


def load_realism(preset: "str | Path | Realism", robot) -> Realism:
    """A shipped preset by name (`talos-real`), a preset YAML file, or a `Realism` (returned as is)."""
    if isinstance(preset, Realism):
        return preset
    text = str(preset)
    path = Path(text)
    if not (text.endswith((".yaml", ".yml")) or path.is_file()):
        if text not in preset_names():
            raise UnknownNameError("realism preset", text, preset_names(), key="--realism")
        path = PRESET_DIR / f"{text}.yaml"
    return parse_realism(Section(resolved_preset(path), str(path)), robot, path.stem)


#: Top-level keys that are one setting given in alternative ways (a preset gives at most one of each group).
_ALTERNATIVES = (frozenset({"stiction_damping", "stiction_impedance"}),)


def resolved_preset(path: Path, seen: tuple = ()) -> dict:
    """A preset file's mapping with its `extends:` resolved: the named preset (a shipped name, or a path relative to
    this file) is loaded first and this file's sections replace its sections; a section set to null removes it
    (`hip_flexibility: null`: the same robot without the hip spring). `stiction_impedance` replaces the base's
    `stiction_damping` and the other way round (the two friction models)."""
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError("a realism preset must be a mapping of sections", file=str(path))
    base = data.pop("extends", None)
    if base is not None:
        if not isinstance(base, str):
            raise ConfigError(f"must be a preset name or file, got {base!r}", file=str(path), key="extends")
        if base in preset_names() and not base.endswith((".yaml", ".yml")):
            base_path = PRESET_DIR / f"{base}.yaml"
        else:
            base_path = (path.parent / base).resolve()
            if not base_path.is_file():
                raise UnknownNameError("realism preset", base, preset_names(), file=str(path), key="extends")
        if base_path.resolve() in seen:
            raise ConfigError(f"extends itself through {base}", file=str(path), key="extends")
        inherited = resolved_preset(base_path, seen + (path.resolve(),))
        for group in _ALTERNATIVES:  # one setting given two ways: this file's replaces the base's
            if group & data.keys():
                for k in group:
                    inherited.pop(k, None)
        data = {**inherited, **data}
    return {k: v for k, v in data.items() if v is not None}


def check_realism(preset: "str | Path | Realism", robot, engine: str = "mujoco", key: str = "--realism") -> Realism:
    """A preset loaded for `robot` and checked against the run's `engine` (the hidden mechanisms are MuJoCo
    joints), for a command to call before anything runs. ConfigError (file and key) otherwise."""
    if engine != "mujoco":
        raise ConfigError(f"a realism preset needs the mujoco engine, not '{engine}'", key=key)
    return load_realism(preset, robot)


def realism_label(preset: "str | Path | Realism | None") -> str:
    """How a report header names the simulated robot: 'ideal', or the preset's name (a file's stem)."""
    if preset is None:
        return "ideal"
    if isinstance(preset, Realism):
        return preset.name
    return Path(str(preset)).stem


class RealismProbe:
    """Logs, for metrics only (the controller never sees them): the hidden joints' deflections (channel
    `hidden_deflection`, one component per hidden joint in MuJoCo's order: `<joint>:drive`, `<joint>:hip_flex`)
    and the foot frames' true positions (`true_foot_left`, `true_foot_right`: x, y, z, from the sole geoms, as of
    the last physics step's kinematics), which the logged q (the encoders' motor side) cannot give. Its metrics:
    the largest hip deflections and the landing errors (`wbcbench.metrics.landing`)."""

    def attach(self, sim) -> dict[str, list[str]]:
        import mujoco

        from ..model import sole_geom_name
        from ...robots import Side
        from .probe_kernel import realism_probe_values

        m = sim.model
        self._sim = sim
        self._kernel = realism_probe_values
        names, adr = [], []
        for j in range(m.njnt):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or ""
            if name.endswith((":drive", ":hip_flex")):
                names.append(name)
                adr.append(int(m.jnt_qposadr[j]))
        self._adr = np.array(adr, dtype=np.int64)
        sole = sim.robot.profile.sole
        self._offset = np.array([sole.center[0], sole.center[1], sole.thickness / 2])  # sole centre in foot frame
        self._soles = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s)) for s in Side]
        channels = {"hidden_deflection": names} if names else {}
        channels.update({f"true_foot_{s.value}": ["x", "y", "z"] for s in Side})
        return channels

    _data = None

    def values(self) -> list:
        d = self._sim.data
        if d is not self._data:  # MuJoCo's arrays viewed once per MjData (each attribute access makes a new view)
            self._data = d
            self._arrays = (d.qpos, d.geom_xpos, d.geom_xmat)
            n = len(self._adr)
            self._out = np.empty(n + 6)
            self._soles_arr = np.array(self._soles, dtype=np.int64)
            parts = [self._out[n:n + 3], self._out[n + 3:]]
            self._parts = [self._out[:n], *parts] if n else parts
        qpos, xpos, xmat = self._arrays
        self._kernel(qpos, self._adr, xpos, xmat, self._soles_arr, self._offset, self._out)
        return self._parts

    def metrics(self, log: dict) -> dict:
        from ...metrics.landing import landing_errors
        from ...robots import Side

        out = {}
        for k, v in log.items():
            if k.startswith("hidden_deflection.") and k.endswith(":hip_flex"):
                out[f"max_abs_{k.split('.', 1)[1].replace(':', '_')}_rad"] = float(np.max(np.abs(v))) if len(v) else 0.0
        if "t" in log and len(log["t"]) > 1:
            feet = {s: np.stack([np.asarray(log[f"true_foot_{s.value}.{a}"]) for a in "xyz"], axis=1) for s in Side}
            out["landing"] = landing_errors(log, feet)["summary"]
        return out
