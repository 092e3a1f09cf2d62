"""The names of what wbcbench can run, found without importing what runs it (no numpy, pinocchio or MuJoCo), so
that `wbcbench --help` and `wbcbench list` answer at once.

Shipped scenarios, robot profiles and sensor profiles are files, listed from their folders; built-in controllers,
scenario kinds, task types and stabilizers are named here and checked against their registries by the tests
(tests/test_cli_fast.py). Installed plugins (entry points) can only be known by importing them: `has_plugins()`
tells the command line to take the registries' slower path then.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

_PACKAGE = Path(__file__).parent

BUILTIN_CONTROLLERS = ("ik", "joint-pd", "tsid-position", "tsid-teleop", "tsid-torque")
BUILTIN_KINDS = ("one-foot", "stand", "sway", "teleop", "terrain-walk", "walk", "walk-command")
TASK_TYPES = ("angular_momentum", "com", "frame", "posture", "self_collision")
STABILIZERS = ("dcm", "force")
MODES = ("torque", "position", "spd")  # ActuationMode's values, in its order
CORRECTIONS = ("base_feedback", "lift_off_wait", "plan_lead", "stabilizer", "swing_tilt", "touchdown_search")
#: the built-in engines and the package each needs (wbcbench.sim.engines.ENGINES)
ENGINES = (("mujoco", None), ("dart", "dartpy"))
PLUGIN_GROUPS = ("wbcbench.controllers", "wbcbench.scenarios", "wbcbench.robots", "wbcbench.corrections",
                 "wbcbench.engines")  # wbcbench.plugins.GROUPS


def _stems(folder: str) -> list[str]:
    return sorted(p.stem for p in (_PACKAGE / folder).glob("*.yaml"))


def scenarios() -> list[str]:
    """The shipped scenario files (wbcbench.scenarios.available_scenarios)."""
    return _stems("scenarios")


def robots() -> list[str]:
    """The shipped robot profiles (wbcbench.robots.profile.builtin_robots)."""
    return _stems("robots/profiles")


def sensor_profiles() -> list[str]:
    """The shipped sensor profiles (wbcbench.sensing.available_profiles)."""
    return _stems("sensing/profiles")


def engines() -> list[str]:
    """The built-in engines as `wbcbench list` shows them (one not installed says what it needs), without importing
    them."""
    from importlib.util import find_spec

    return [name if needs is None or find_spec(needs) else f"{name} (needs {needs})" for name, needs in ENGINES]


def has_plugins() -> bool:
    """Whether any installed package declares a wbcbench entry point."""
    return any(metadata.entry_points(group=g) for g in PLUGIN_GROUPS)
