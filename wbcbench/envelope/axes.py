"""The axes of difficulty of a capability envelope: a registry (`AXES`, `register_axis`) of named axes, each turning
one value into a scenario description (the YAML mapping a scenario file holds: terrain, params, sensors,
model_error, pushes) plus run parameters (`profile.<path>` overrides of the robot profile, as a sweep cell takes).

An axis runs from an `easy` value (expected to pass) to a `hard` one; the envelope is the value nearest `hard` at
which the controller still completes the scenario. `allowed(robot)` is the interval of values the axis can take
at all (a friction below 0, a riser taller than the leg): a range outside it is a ConfigError.

A user adds an axis with `register_axis(Axis(...))` in a module imported before the command runs (with `--jobs`
above 1 or Ray, the worker processes must import it too: the searches name their axis, the workers look it up):

    def build(data, value):
        data["model_error"] = {"payloads": [{"link": "arm_left_7_link", "mass": value}]}
        return data, {}
    register_axis(Axis("hand-payload", "kg", "a mass in the left hand", "stand", 0.0, 20.0, 1.0, build,
                       allowed=lambda robot: (0.0, 100.0)))
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError, UnknownNameError

__all__ = ["AXES", "Axis", "available_axes", "get_axis", "register_axis"]

Build = Callable[[dict, float], "tuple[dict, dict]"]


@dataclass(frozen=True)
class Axis:
    """One axis: `scenario` the base scenario (name or path) whose YAML `build(data, value)` changes (returns the new
    mapping and extra run parameters); `easy` / `hard` the default search range; `resolution` the default bracket
    width at which the bisection stops; `allowed(robot_name)` the values the axis can take."""

    name: str
    unit: str
    description: str
    scenario: str
    easy: float
    hard: float
    resolution: float
    build: Build
    allowed: Callable[[str], tuple[float, float]] = lambda robot: (-math.inf, math.inf)
    random: bool = False
    #: the terrain itself is drawn at random: `build(data, value, seed=...)` gets the study's seed
    seeded: bool = False
    #: [s] the trials share their run up to this time and differ only in their `pushes` (which start at or after
    #: it): a search simulates that start once and branches every trial from it (`wbcbench.runner.BranchPoint`)
    branch_at: float | None = None

    @property
    def largest(self) -> bool:
        """True: the envelope is the largest passing value (hard > easy); False: the smallest."""
        return self.hard > self.easy

    def check_range(self, easy: float, hard: float, robot: str) -> None:
        lo, hi = self.allowed(robot)
        for what, v in (("easy", easy), ("hard", hard)):
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ConfigError(f"axis '{self.name}': {what} value {v:g} {self.unit} outside what the axis can take "
                                  f"for robot {robot}: [{lo:g}, {hi:g}] {self.unit}", key="--range")
        if easy == hard:
            raise ConfigError(f"axis '{self.name}': the range is empty ({easy:g} to {hard:g})", key="--range")

    def trial(self, value: float, robot: str = "talos", seed: int = 0) -> tuple[dict, dict]:
        """(scenario mapping, run parameters) of the trial at `value` for `robot` (a payload on the link `@torso`
        goes on the robot profile's torso frame); `seed` draws a `seeded` axis' terrain."""
        from ..config import load_yaml
        from ..scenarios.base import scenario_path

        from ..robots import load_robot
        from ..scenarios.base import robot_sized

        path = scenario_path(self.scenario)
        # the base scenario as the robot's profile sizes it (its `scenarios:` section), then changed by the value
        data = copy.deepcopy(robot_sized(load_yaml(path), Path(path), load_robot(robot)))
        data["name"] = f"envelope-{self.name}-{value:g}"
        data["description"] = f"{self.description} at {value:g} {self.unit} (generated from {Path(path).name})."
        data, extra = self.build(data, float(value), seed=seed) if self.seeded else self.build(data, float(value))
        for p in (data.get("model_error") or {}).get("payloads") or []:
            if p.get("link") == TORSO:
                p["link"] = load_robot(robot).profile.torso_frame
        return data, extra


AXES: dict[str, Axis] = {}
TORSO = "@torso"
"""A payload's link in a built scenario that stands for the robot's torso frame."""


def register_axis(axis: Axis) -> Axis:
    """Add (or replace) an axis in the registry; returns it."""
    AXES[axis.name] = axis
    return axis


def available_axes() -> list[str]:
    return list(AXES)


def get_axis(name: str) -> Axis:
    if name not in AXES:
        raise UnknownNameError("envelope axis", name, AXES, key="AXES", sort=False)
    return AXES[name]


# ---------------------------------------------------------------------------------------------- the built-in axes

def _leg_length(robot: str) -> float:
    """Hip-to-sole distance of the robot's straight leg [m] (at the reference posture, hip joint to sole frame)."""
    import numpy as np
    import pinocchio as pin

    from ..robots import load_robot
    from ..side import Side

    rob = load_robot(robot)
    data = rob.model.createData()
    pin.framesForwardKinematics(rob.model, data, rob.q0)
    sole = data.oMf[rob.sole_frame_id(Side.LEFT)].translation
    base = data.oMi[1].translation
    return float(np.linalg.norm(base - sole))


def _stairs_up(data: dict, v: float) -> tuple[dict, dict]:
    data["terrain"] = {**data["terrain"], "height": v}
    data["params"]["max_step_height"] = max(0.15, v + 0.02)   # the planner's bound is not the limit measured
    return data, {}


def _stairs_down(data: dict, v: float) -> tuple[dict, dict]:
    """stairs-quick's treads going down by `v` each: the robot starts on a landing whose top is the ground (z = 0,
    no floor plane), and each tread is `v` lower than the one before, the last one long enough to stop on."""
    t = data["terrain"]
    count, depth = int(t.get("count", 6)), float(t.get("depth", 0.3))
    width, start = float(t.get("width", 1.0)), float(t.get("start_x", 0.3))
    thick = 1.0 + count * v   # deep enough that no tread's bottom shows above the lowest one
    boxes = [{"name": "landing", "center": [round((start - 1.0) / 2, 6), 0.0, -thick / 2],
              "size": [start + 1.0, width, thick]}]
    for i in range(count):
        x0 = start + i * depth
        x1 = x0 + (depth if i < count - 1 else 2.0)
        top = -(i + 1) * v
        boxes.append({"name": f"tread_{i + 1}", "center": [round((x0 + x1) / 2, 6), 0.0, round(top - thick / 2, 6)],
                      "size": [round(x1 - x0, 6), width, thick]})
    data["terrain"] = {"type": "boxes", "floor": False, "boxes": boxes}
    data["params"]["max_step_height"] = max(0.15, v + 0.02)
    return data, {}


ROUGH_TILE = 0.3   # [m] a rough-ground tile's length along the walk


def _rough(data: dict, v: float, seed: int = 0) -> tuple[dict, dict]:
    """Rough ground of roughness `v` [m]: from x = 0.15 to 1.95, six 0.3 m tiles across the walk (1 m wide, both feet
    on the same tile), each tilted by U(-a, a) in pitch and U(-a/2, a/2) in roll, a = atan(v / 0.3) / 2, and raised
    by U(0, v) above the height at which its lowest top edge meets the floor; drawn with `seed`; the floor before
    and after them."""
    import numpy as np

    rng = np.random.default_rng([seed, 7])
    a = math.atan(v / ROUGH_TILE) / 2
    thick = 0.1 + v
    boxes = []
    for i in range(6):
        h, pitch, roll = rng.uniform(0.0, v), rng.uniform(-a, a), rng.uniform(-a / 2, a / 2)
        # raised so that its lowest top edge is on or above the floor (the floor never shows through a tile)
        h += ROUGH_TILE / 2 * math.sin(abs(pitch)) + 0.5 * math.sin(abs(roll))
        boxes.append({"name": f"tile_{i + 1}", "center": [round(0.15 + (i + 0.5) * ROUGH_TILE, 6), 0.0,
                                                           round(h - thick / 2, 6)],
                      "size": [ROUGH_TILE, 1.0, thick], "rpy": [round(roll, 6), round(pitch, 6), 0.0]})
    data["terrain"] = {"type": "boxes", "floor": True, "boxes": boxes}
    data["params"]["max_step_height"] = max(float(data["params"].get("max_step_height", 0.15)), v + 0.02)
    data["params"]["goal"] = [0.15 + 2.5 * ROUGH_TILE, 0.0]   # the middle of the third tile
    return data, {}


def _tread(data: dict, v: float) -> tuple[dict, dict]:
    t = data["terrain"]
    data["terrain"] = {**t, "depth": v}
    data["params"]["goal"] = [float(t.get("start_x", 0.3)) + 1.5 * v, 0.0]   # the middle of the second tread
    return data, {}


def _platforms(data: dict, deg: float, roll: bool) -> tuple[dict, dict]:
    """Six platforms 0.3 m long from x = 0.15; pitch: the paper's zigzag (valleys at z = 0, rising and falling
    alternately by `deg`); roll: each rolled alternately by +-`deg` about x, the top's centre line 2 cm above the
    lowest point of a foot 10 cm off it, so neither sole meets the floor."""
    th = math.radians(deg)
    w, thick = 0.3, 0.1
    boxes = []
    for i in range(6):
        xm = 0.15 + (i + 0.5) * w
        if roll:
            sign = 1.0 if i % 2 == 0 else -1.0
            ztop = 0.02 + 0.15 * math.tan(th)
            c = (xm, -thick / 2 * math.sin(sign * th) * -1.0, ztop - thick / 2 * math.cos(th))
            boxes.append({"name": f"platform_{i + 1}", "center": [round(c[0], 6), round(c[1], 6), round(c[2], 6)],
                          "size": [w, 1.0, thick], "rpy": [round(sign * th, 6), 0.0, 0.0]})
        else:
            rising = i % 2 == 0
            h = w * math.tan(th)
            n = (-math.sin(th), math.cos(th)) if rising else (math.sin(th), math.cos(th))
            c = (xm - thick / 2 * n[0], h / 2 - thick / 2 * n[1])
            boxes.append({"name": f"platform_{i + 1}", "center": [round(c[0], 6), 0.0, round(c[1], 6)],
                          "size": [round(w / math.cos(th), 6), 1.0, thick],
                          "rpy": [0.0, round(-th if rising else th, 6), 0.0]})
    data["terrain"] = {"type": "boxes", "floor": True, "boxes": boxes}
    return data, {}


def _walk_speed(data: dict, v: float) -> tuple[dict, dict]:
    """The base walk's gait (walk-fast-0.8: 0.6 m steps in 0.75 s, 0.8 m/s; as the robot's profile sizes it) scaled
    to `v`: step length L0 sqrt(v / v0), the period that gives v, single and double support in the base's ratio."""
    p = data["params"]
    length0, ss0, ds0 = float(p["step_length"]), float(p["single_support"]), float(p["double_support"])
    v0 = length0 / (ss0 + ds0)
    length = length0 * math.sqrt(v / v0)
    period = length / v
    p.update(step_length=round(length, 6), single_support=round(period * ss0 / (ss0 + ds0), 6),
             double_support=round(period * ds0 / (ss0 + ds0), 6),
             max_step_length=max(float(p.get("max_step_length", 0.65)), length + 0.05))
    return data, {}


_PERIOD = 0.9   # [s] single + double support of the command walks (turn-90, side-step-1m)


def _command(data: dict, vy: float, yaw_rate: float) -> dict:
    data["params"].pop("path", None)
    data["params"]["command"] = [[0.0, 0.0, vy, yaw_rate], [4 * _PERIOD, 0.0, vy, yaw_rate]]
    return data


def _turn(data: dict, v: float) -> tuple[dict, dict]:
    """A velocity command turning at `v` deg/s for 3.6 s; the profile's per-step turn raised so that it does not
    clip the rate (the inside foot turns every second step)."""
    rate = math.radians(v)
    return _command(data, 0.0, rate), {"profile.stepping.max_turn": max(0.35, 1.05 * rate * 2 * _PERIOD)}


def _lateral(data: dict, v: float) -> tuple[dict, dict]:
    """A velocity command side-stepping right at `v` m/s for 3.6 s; the profile's lateral step raised likewise."""
    return _command(data, -v, 0.0), {"profile.stepping.max_lateral": max(0.12, 1.05 * v * 2 * _PERIOD)}


def _model_error(data: dict, **kw) -> dict:
    data["model_error"] = {**(data.get("model_error") or {}), **kw}
    return data


def _talos_like() -> dict:
    from ..config import load_yaml
    from ..sensing.profile import PROFILE_DIR

    prof = load_yaml(PROFILE_DIR / "talos-like.yaml")
    prof.pop("name", None)
    return prof


def _delay(data: dict, v: float) -> tuple[dict, dict]:
    prof = _talos_like()
    prof["latency"] = v
    data["sensors"] = prof
    return data, {}


_NOISE_KEYS = ("noise", "bias", "drift", "resolution")


def _noise(data: dict, v: float) -> tuple[dict, dict]:
    prof = _talos_like()
    for group in ("force_torque", "imu", "encoders"):
        prof[group] = {k: x * v if any(k.endswith(s) for s in _NOISE_KEYS) else x for k, x in prof[group].items()}
    data["sensors"] = prof
    return data, {}


def _ft_bias(data: dict, v: float) -> tuple[dict, dict]:
    prof = _talos_like()
    ft = prof["force_torque"]
    prof["force_torque"] = {**ft, "force_bias": v, "torque_bias": ft["torque_bias"] * v / ft["force_bias"]}
    data["sensors"] = prof
    return data, {}


PUSH_TIME, PUSH_DURATION, PUSH_SETTLE = 1.0, 0.1, 2.0


def _push(data: dict, v: float) -> tuple[dict, dict]:
    """The push protocol's trial (wbcbench.robustness.push): a push of `v` N s over 0.1 s on the base, to the
    robot's left, in double support at 1 s; survived when standing 2 s later, CoM back on the plan."""
    data["pushes"] = [{"body": "base", "force": [0.0, round(v / PUSH_DURATION, 6), 0.0], "start": PUSH_TIME,
                       "duration": PUSH_DURATION}]
    data["duration"] = PUSH_TIME + PUSH_DURATION + PUSH_SETTLE
    return data, {}


_POS = lambda robot: (0.0, math.inf)  # noqa: E731


for _axis in (
    Axis("stair-up", "m", "climbing two treads of stairs-quick, riser height", "stairs-quick", 0.05, 0.30, 0.01,
         _stairs_up, allowed=lambda robot: (1e-3, _leg_length(robot))),
    Axis("stair-down", "m", "descending two treads of stairs-quick, riser height", "stairs-quick", 0.05, 0.45, 0.01,
         _stairs_down, allowed=lambda robot: (1e-3, _leg_length(robot))),
    Axis("rough", "m", "walking over rough ground (0.3 m tiles raised by up to the value and tilted, seeded), "
         "roughness", "platforms-quick", 0.0, 0.30, 0.01, _rough, allowed=lambda robot: (0.0, 0.5),
         seeded=True),
    Axis("stair-tread", "m", "climbing two 10 cm stairs, tread depth", "stairs-quick", 0.40, 0.15, 0.01, _tread,
         allowed=lambda robot: (0.05, 2.0)),
    Axis("platform-pitch", "deg", "walking over the paper's alternately pitched platforms, slope", "platforms-quick",
         5.0, 35.0, 2.0, lambda d, v: _platforms(d, v, roll=False), allowed=lambda robot: (0.0, 60.0)),
    Axis("platform-roll", "deg", "walking over platforms rolled alternately left and right, roll angle",
         "platforms-quick", 5.0, 35.0, 2.0, lambda d, v: _platforms(d, v, roll=True),
         allowed=lambda robot: (0.0, 60.0)),
    Axis("walk-speed", "m/s", "walking forward on flat ground (walk-fast-0.8's gait scaled), speed",
         "walk-fast-0.8-quick", 0.3, 1.2, 0.05, _walk_speed, allowed=lambda robot: (0.01, 3.0)),
    Axis("turn-rate", "deg/s", "turning in place on a velocity command, rate", "turn-90-quick", 5.0, 60.0, 2.5,
         _turn, allowed=lambda robot: (0.1, 360.0)),
    Axis("lateral-speed", "m/s", "side-stepping on a velocity command, speed", "side-step-1m-quick", 0.03, 0.30,
         0.01, _lateral, allowed=lambda robot: (0.001, 2.0)),
    Axis("friction", "", "walk-20cm-quick on soles and ground of one friction coefficient", "walk-20cm-quick",
         1.0, 0.05, 0.05, lambda d, v: (_model_error(d, friction=v), {}), allowed=lambda robot: (1e-3, 5.0)),
    Axis("payload", "kg", "walk-20cm-quick with a point mass fixed on the torso", "walk-20cm-quick", 0.0, 60.0,
         2.5, lambda d, v: (_model_error(d, payloads=[{"link": TORSO, "mass": v, "offset": [0.0, 0.0, 0.1]}]
                                          if v > 0 else []), {}), allowed=lambda robot: (0.0, 500.0)),
    Axis("sensor-delay", "s", "walk-20cm-quick with the talos-like sensors, latency", "walk-20cm-quick", 0.0, 0.05,
         0.002, _delay, allowed=lambda robot: (0.0, 0.1)),
    Axis("noise-scale", "x", "walk-20cm-quick with the talos-like sensors' noise, bias, drift and quantisation "
         "scaled", "walk-20cm-quick", 1.0, 30.0, 1.0, _noise, allowed=lambda robot: (0.0, 1000.0), random=True),
    Axis("ft-bias", "N", "walk-20cm-quick with the talos-like sensors, std of the F/T force bias (torque bias in "
         "proportion)", "walk-20cm-quick", 3.0, 100.0, 5.0, _ft_bias, allowed=lambda robot: (0.0, 1000.0),
         random=True),
    Axis("push", "N s", "standing, a lateral push on the base in double support (the push protocol's trial), "
         "impulse", "push", 0.0, 60.0, 2.0, _push, allowed=lambda robot: (0.0, 1000.0), branch_at=PUSH_TIME),
):
    register_axis(_axis)
