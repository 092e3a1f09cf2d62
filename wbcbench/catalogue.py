"""The names of what wbcbench can run, found without importing what runs it (no numpy, pinocchio or MuJoCo), so
that `wbcbench --help` and `wbcbench list` answer at once.

Shipped scenarios and sensor profiles are files, listed from their folders. The built-in controllers, scenario
kinds, task types, stabilizers, corrections, engines and robots are the tables here, which their registries read
(each entry "module:Attr", imported when first used), so that a name is written once. Installed plugins (entry
points) can only be known by importing them: `has_plugins()` tells the command line to take the registries' slower
path then.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

_PACKAGE = Path(__file__).parent

# The built-ins of each registry, in one table each: name -> "package.module:Attr", imported by the registry when
# first used (wbcbench.plugins.load). The registries read these tables (none imports its built-ins to fill
# itself); plugins come through entry points (wbcbench/plugins.py).

#: controllers (wbcbench.controllers.base)
BUILTIN_CONTROLLERS: dict[str, str] = {
    "ik": "wbcbench.controllers.ik:IKController",
    "joint-pd": "wbcbench.controllers.joint_pd:JointPD",
    "tsid-position": "wbcbench.controllers.inverse_dynamics:TSIDPosition",
    "tsid-teleop": "wbcbench.controllers.teleop:TSIDTeleop",
    "tsid-torque": "wbcbench.controllers.inverse_dynamics:TSIDTorque",
}
#: scenario kinds (wbcbench.scenarios.base)
BUILTIN_KINDS: dict[str, str] = {
    "one-foot": "wbcbench.scenarios.kinds:OneFootScenario",
    "posture-sinusoid": "wbcbench.scenarios.kinds:PostureSinusoidScenario",
    "stand": "wbcbench.scenarios.base:Scenario",
    "sway": "wbcbench.scenarios.kinds:SwayScenario",
    "teleop": "wbcbench.scenarios.teleop_kind:TeleopScenario",
    "terrain-walk": "wbcbench.scenarios.kinds:TerrainWalkScenario",
    "walk": "wbcbench.scenarios.kinds:WalkScenario",
    "walk-command": "wbcbench.scenarios.kinds:CommandWalkScenario",
}
#: task types, the YAML `type:` of a task set's tasks (wbcbench.tasks.registry)
BUILTIN_TASKS: dict[str, str] = {
    "angular_momentum": "wbcbench.tasks.angular_momentum_task:AngularMomentumTask",
    "com": "wbcbench.tasks.com_task:CoMTask",
    "frame": "wbcbench.tasks.frame_task:FrameTask",
    "posture": "wbcbench.tasks.posture_task:PostureTask",
    "self_collision": "wbcbench.tasks.self_collision:SelfCollisionTask",
}
#: stabilizer types (wbcbench.stabilizers.base)
BUILTIN_STABILIZERS: dict[str, str] = {
    "dcm": "wbcbench.stabilizers.balance:BalanceStabilizer",
    "force": "wbcbench.stabilizers.teleop:TeleopStabilizer",
}
#: plan correction types (wbcbench.controllers.corrections), in the order the task sets' old sections put them
BUILTIN_CORRECTIONS: dict[str, str] = {
    "plan_lead": "wbcbench.controllers.plan_lead:PlanLead",
    "lift_off_wait": "wbcbench.controllers.liftoff:LiftOffWait",
    "touchdown_search": "wbcbench.controllers.touchdown:TouchdownSearch",
    "base_feedback": "wbcbench.controllers.corrections:BaseFeedbackStage",
    "swing_tilt": "wbcbench.controllers.swing_tilt:SwingTilt",
    "hip_compensation": "wbcbench.controllers.hip_compensation:HipCompensation",
    "stabilizer": "wbcbench.controllers.corrections:StabilizerStage",
}
#: physics engines (wbcbench.sim.engines): name -> ("module:Attr", the package it needs installed or None)
BUILTIN_ENGINES: dict[str, tuple[str, str | None]] = {
    "mujoco": ("wbcbench.sim.simulator:Simulator", None),
    "dart": ("wbcbench.sim.dart_engine:DartSimulator", "dartpy"),
}
#: robots (wbcbench.robots.profile): name -> its profile, a file of wbcbench/robots/profiles
BUILTIN_ROBOTS: dict[str, str] = {
    "alexander": "alexander.yaml",
    "g1": "g1.yaml",
    "gr1t2": "gr1t2.yaml",
    "gr2t2": "gr2t2.yaml",
    "gr2t2d": "gr2t2d.yaml",
    "gr2t2v2": "gr2t2v2.yaml",
    "gr3": "gr3.yaml",
    "qinglong": "qinglong.yaml",
    "romeo": "romeo.yaml",
    "talos": "talos.yaml",
}

TASK_TYPES = tuple(BUILTIN_TASKS)
STABILIZERS = tuple(BUILTIN_STABILIZERS)
CORRECTIONS = tuple(sorted(BUILTIN_CORRECTIONS))
MODES = ("torque", "position", "spd")  # ActuationMode's values, in its order
#: the built-in engines and the package each needs
ENGINES = tuple((name, needs) for name, (_, needs) in BUILTIN_ENGINES.items())
PLUGIN_GROUPS = ("wbcbench.controllers", "wbcbench.scenarios", "wbcbench.robots", "wbcbench.corrections",
                 "wbcbench.engines")  # wbcbench.plugins.GROUPS


def _stems(folder: str) -> list[str]:
    return sorted(p.stem for p in (_PACKAGE / folder).glob("*.yaml"))


def scenarios() -> list[str]:
    """The shipped scenario files (wbcbench.scenarios.available_scenarios)."""
    return _stems("scenarios")


def robots() -> list[str]:
    """The shipped robot profiles (wbcbench.robots.profile.builtin_robots)."""
    return sorted(BUILTIN_ROBOTS)


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
