"""Scenarios: YAML files (wbcbench/scenarios/*.yaml or a user's path) dispatched on `kind:` to a Python class
that gives the per-tick references and the scenario's own metrics."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..catalogue import BUILTIN_KINDS  # the built-ins: name -> "module:Attr", imported when first used
from ..config import Section, load_yaml
from ..errors import ConfigError, UnknownNameError
from ..robots import Robot, Side
from ..scene import Push, Terrain, parse_push, parse_terrain
from ..types import PointReference, References

SCENARIO_DIR = Path(__file__).parent


@dataclass(frozen=True)
class ScenarioSpec:
    """The parts every scenario has; `params` holds the kind-specific section, validated by the kind."""

    name: str
    kind: str
    description: str
    duration: float
    control_dt: float
    terrain: Terrain
    pushes: tuple[Push, ...]
    file: str
    #: simulator settings the scene needs (`sim:` section; only `noslip_iterations` for now), applied by the runner
    sim: Mapping[str, Any] = field(default_factory=dict)
    #: the sensor profile of the scene (`sensors:` a profile name, file or mapping; None: ideal sensing)
    sensors: Any = None
    #: how the simulated robot differs from the controller's model (`model_error:`; None: it does not)
    model_error: Any = None
    #: scheduled faults (`faults:`, wbcbench/faults.py)
    faults: tuple = ()
    #: `taskset_variant:` a controller run on this scene without an explicit task set takes
    #: `tasksets/<robot>/<controller>-<variant>.yaml` when that file exists (e.g. the paper's stairs gains), else its own
    taskset_variant: str | None = None


class Scenario:
    """Base scenario: stand on both feet; subclasses override `references` and `metrics`."""

    kind = "stand"
    #: the names of the frame-task targets its references carry (logged every tick as `target_<name>`)
    target_names: tuple[str, ...] = ()

    def __init__(self, spec: ScenarioSpec, params: Section, robot: Robot):
        self.spec = spec
        self.robot = robot
        self.parse(params)
        params.finish()

    def parse(self, params: Section) -> None:
        """Read kind-specific keys from `params` (unknown keys are rejected afterwards)."""

    def setup(self, q0: np.ndarray, com0: np.ndarray) -> None:
        """Called once with the initial configuration and CoM, before the first tick."""
        self.q0 = q0
        self.com0 = com0
        self._ground = None
        self._standing = None

    def ground_height(self) -> float:
        """Height [m] of the lower sole at the initial configuration (the ground under the robot)."""
        if self._ground is None:
            import pinocchio as pin

            data = self.robot.model.createData()
            pin.framesForwardKinematics(self.robot.model, data, self.q0)
            self._ground = min(float(data.oMf[self.robot.sole_frame_id(s)].translation[2]) for s in Side)
        return self._ground

    def references(self, t: float) -> References:
        """Stand still: both feet in contact, the CoM held where it starts, the ZMP under it."""
        if self._standing is None:
            com = self.com0
            self._standing = References(t=0.0, contacts=frozenset(Side), com=PointReference(com.copy()),
                                        zmp=np.array([com[0], com[1], self.ground_height()]))
        return replace(self._standing, t=t)

    def metrics(self, log: dict[str, np.ndarray]) -> dict:
        """Scenario-specific metrics computed from the run log."""
        return {}


GROUP = "wbcbench.scenarios"

_KINDS: dict[str, type[Scenario]] = {}
"""Scenario kinds registered in Python (`register_kind`), by name."""
_LOADED: dict[str, type[Scenario]] = {}


def register_kind(cls: type[Scenario]) -> type[Scenario]:
    """Class decorator: make `cls` a scenario kind, `kind: <cls.kind>` in scenario files (a package of yours
    registers through the `wbcbench.scenarios` entry point instead; a built-in's kind stays the built-in's)."""
    _KINDS[cls.kind] = cls
    return cls


def kind_class(name: str) -> type[Scenario] | None:
    """The class of a built-in or registered kind (only its own module is imported); None when it is neither."""
    if name in BUILTIN_KINDS:
        cls = _LOADED.get(name)
        if cls is None:
            from ..plugins import load

            cls = _LOADED[name] = load(BUILTIN_KINDS[name])
        return cls
    return _KINDS.get(name)


def _plugins() -> list:
    from ..plugins import discover

    return discover(GROUP, {*BUILTIN_KINDS, *_KINDS}, Scenario)


def builtin_kinds() -> dict[str, type[Scenario]]:
    """The built-in scenario kinds and those registered in Python (`register_kind`), by name."""
    out = dict(_KINDS)
    out.update({name: kind_class(name) for name in BUILTIN_KINDS})
    return out


def available_kinds() -> dict[str, type[Scenario]]:
    """Scenario kinds by name: the built-in ones, those registered in Python and the `wbcbench.scenarios` entry
    points (wbcbench/plugins.py)."""
    out = builtin_kinds()
    for p in _plugins():
        if p.error is None:
            out[p.name] = p.obj
    return out


def kind_plugin_errors() -> dict[str, str]:
    from ..plugins import message

    return {p.name: message(p) for p in _plugins() if p.error is not None}


def _kind(kind: str, file: str) -> type[Scenario]:
    """The class of scenario kind `kind` (a built-in's, a registered one's or a plugin's); an unknown kind is an
    `UnknownNameError`, a broken plugin a `PluginError` (both naming `file` and the key `kind`)."""
    cls = kind_class(kind)
    if cls is not None:
        return cls
    for p in _plugins():
        if p.name == kind:
            if p.error is not None:
                from ..plugins import PluginError, message

                raise PluginError(message(p), file=file, key="kind")
            return p.obj
    raise UnknownNameError("scenario kind", kind, available_kinds(), file=file, key="kind")


def available_scenarios() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def scenario_path(name_or_path: str) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        return p
    path = SCENARIO_DIR / f"{name_or_path}.yaml"
    if not path.exists():
        raise UnknownNameError("scenario", name_or_path, available_scenarios(), key="SCENARIO")
    return path


def _parse_sim(sec: Section) -> dict:
    """The scenario's `sim:` section. noslip_iterations: MuJoCo's no-slip solver passes (default: the simulator's,
    0). The soft contacts otherwise let a loaded foot creep down a slope (on the 15 deg platforms about 2 cm per
    1.5 s step), which a real sole with mu = 1 does not."""
    out = {}
    if sec.has("noslip_iterations"):
        out["noslip_iterations"] = sec.int("noslip_iterations", min=0)
    sec.finish()
    return out


def _parse_sensors(root: Section):
    """The `sensors:` key: a profile name (`ideal`, `talos-like`), a profile file, or an inline profile."""
    if not root.has("sensors"):
        return None
    from ..sensing import load_sensor_profile, parse_sensor_profile

    raw = root.raw("sensors")
    if isinstance(raw, str):
        return load_sensor_profile(raw, key="sensors")
    return parse_sensor_profile(root.section("sensors"), name="inline")


def _parse_faults(root: Section, robot: Robot) -> tuple:
    if not root.has("faults"):
        return ()
    from ..faults import parse_faults

    return parse_faults(root.list("faults"), root.file, joints=robot.joint_names)


def _parse_taskset_variant(root: Section) -> str | None:
    raw = root.raw("taskset_variant", None)
    if raw is None:
        return None
    if not (isinstance(raw, str) and re.fullmatch(r"[a-z0-9][a-z0-9_-]*", raw)):
        raise root.error("taskset_variant", f"must be a name of lower-case letters, digits, '-' or '_', got {raw!r}")
    return raw


def _parse_model_error(root: Section):
    if not root.has("model_error"):
        return None
    from ..sim.model_error import parse_model_error

    return parse_model_error(root.section("model_error"))


def robot_sizes(name: str, robot: Robot) -> dict[str, dict]:
    """The robot profile's sizes of scenario `name` (its `scenarios:` entry: {"params": ..., "terrain": ...}), or
    {} when it runs the file's."""
    return robot.profile.scenario_overrides.get(name, {})


def robot_sized(data: Any, path: Path, robot: Robot) -> Any:
    """The scenario file's mapping with the keys the robot profile gives for it replaced (`params` and `terrain`
    key by key) and the description saying so."""
    if not isinstance(data, dict):
        return data
    sizes = robot_sizes(str(data.get("name", path.stem)), robot) if isinstance(data.get("name", ""), str) else {}
    if not sizes:
        return data
    data = dict(data)
    for part, values in sizes.items():
        base = data.get(part) or {}
        data[part] = {**base, **values} if isinstance(base, dict) else base
    said = "; ".join(f"{part} {', '.join(f'{k}: {v}' for k, v in values.items())}" for part, values in sizes.items())
    data["description"] = (f"{data.get('description', '')} Sized for {robot.name} by its profile: {said}.").strip()
    return data


def load_scenario(name_or_path: str, robot: Robot, duration: float | None = None) -> Scenario:
    """Load and validate a scenario by name or path; `duration` overrides the file's. A scenario the robot's profile
    sizes (`scenarios:` in the profile) runs with the profile's `params` and `terrain` keys in place of the file's."""
    path = scenario_path(name_or_path)
    file = str(path)
    data = load_yaml(path)
    sized = robot_sized(data, path, robot)
    # an error in a value the profile replaced names both files
    root = Section(sized, file if sized is data else f"{file} (with the sizes of {robot.profile.file})")
    kind = root.str("kind", "stand")
    cls = _kind(kind, file)
    pushes = tuple(parse_push(Section(p, file, f"pushes[{i}]")) for i, p in enumerate(root.list("pushes", [])))
    spec = ScenarioSpec(
        name=root.str("name", path.stem),
        kind=kind,
        description=root.str("description", ""),
        duration=duration if duration is not None else (root.float("duration", positive=True)
                                                        if root.has("duration") else 0.0),
        control_dt=root.float("control_dt", 1e-3, positive=True),
        terrain=parse_terrain(root.section("terrain", {})),
        pushes=pushes,
        file=file,
        sim=_parse_sim(root.section("sim", {})),
        sensors=_parse_sensors(root),
        model_error=_parse_model_error(root),
        faults=_parse_faults(root, robot),
        taskset_variant=_parse_taskset_variant(root),
    )
    if duration is not None:
        root.raw("duration", None)
    params = root.section("params", {})
    root.finish()
    scen = cls(spec, params, robot)
    if spec.duration <= 0:
        if not hasattr(type(scen), "planned_duration"):
            raise root.error("duration", "is required")
    return scen


def make_scenario(kind: str, robot: Robot, *, name: str = "python", params: Mapping[str, Any] | None = None,
                  duration: float = 0.0, control_dt: float = 1e-3, terrain: Terrain | None = None,
                  pushes: tuple[Push, ...] = (), sim: Mapping[str, Any] | None = None, sensors: Any = None,
                  model_error: Any = None, faults: tuple = (), description: str = "") -> Scenario:
    """A scenario built in Python, without a file: the kind (built-in or a plugin's) parses and validates `params`
    exactly as it does a YAML file's `params:` (errors name `<python:NAME>` and the key). `duration` 0 means the
    kind's planned duration (walks); `sensors` a profile name or `SensorProfile`; `model_error` a `ModelError`;
    `faults` `wbcbench.faults.Fault`s."""
    file = f"<python:{name}>"
    cls = _kind(kind, file)
    if isinstance(sensors, str):
        from ..sensing import load_sensor_profile

        sensors = load_sensor_profile(sensors, key="sensors")
    spec = ScenarioSpec(name=name, kind=kind, description=description, duration=float(duration),
                        control_dt=float(control_dt), terrain=terrain or Terrain(), pushes=tuple(pushes), file=file,
                        sim=dict(sim or {}), sensors=sensors, model_error=model_error, faults=tuple(faults))
    scen = cls(spec, Section(dict(params or {}), file, "params"), robot)
    if spec.duration <= 0 and not hasattr(type(scen), "planned_duration"):
        raise ConfigError(f"kind '{kind}' has no planned duration: give duration > 0", file=file, key="duration")
    return scen
