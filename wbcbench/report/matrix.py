"""What `reproduce` runs: the paper's matrix of controllers x scenarios, plus a sanity section.

Names that do not exist (yet) in the scenario or controller registries become MISSING jobs: nothing is run
and nothing is invented for them. The module-level constants are the defaults; tests may monkeypatch them.
"""

from __future__ import annotations

from dataclasses import dataclass

from .paper import CONTROLLERS
from .runs import QUICK_SUFFIX

PAPER_MATRIX: tuple[tuple[str, str], ...] = (
    *((c, s) for s in ("walk-20cm", "platforms", "stairs") for c in CONTROLLERS),
    ("tsid-torque", "walk-60cm"),
)
"""(controller, scenario) pairs with published numbers (Tables 2-8)."""

FAST_MATRIX: tuple[tuple[str, str], ...] = tuple((c, "walk-20cm-fast") for c in CONTROLLERS)
"""The faster 20 cm walk (single/double 0.711/0.089 s): reported as working, no numbers published."""

SANITY_SCENARIOS: tuple[str, ...] = ("stand", "sway", "push", "one-foot")
"""Standing scenarios run with every available controller (the "sanity" section)."""

SANITY_CONTROLLERS: tuple[str, ...] | None = None
"""Controllers for the sanity section; None = every registered controller."""

SENSING_MATRIX: tuple[tuple[str, str], ...] = tuple((c, s) for s in ("walk-20cm", "platforms", "stairs")
                                                    for c in CONTROLLERS)
"""(controller, scenario) pairs run again under a sensor profile by `reproduce --sensors PROFILE` (section
"sensing"), beside the ideal ones."""

SANITY_NOT_PAIRED: dict[tuple[str, str], str] = {
    ("joint-pd", "sway"): "joint-pd holds the initial posture; it has no CoM task to follow a sway",
    ("joint-pd", "one-foot"): "joint-pd holds the initial posture and has no balance: lifting a foot with the "
                              "CoM between the feet falls (that is what the whole-body controllers are for)",
    ("tsid-teleop", "sway"): "tsid-teleop follows an operator's hands and trunk, its CoM is regulated over the "
                             "feet; a scripted CoM sinusoid is not a teleoperation input (it falls following it)",
}
"""(controller, scenario) cells the sanity section skips, with the reason: each controller is paired only with
the standing scenarios it is meant for, and no shipped pairing falls."""

QUICK_WALK_CAP_S = 6.0
"""--quick: duration cap [s] of a walk that has no "<name>-quick" scenario file."""

QUICK_SANITY_CAP_S = 4.0
"""--quick: duration cap [s] of the sanity runs (long enough for the push at 1 s and one-foot's lift)."""


@dataclass(frozen=True)
class Job:
    """One cell of the matrix.

    Attributes:
        section: "paper", "fast" or "sanity".
        controller: controller registry name.
        scenario: scenario key in the report.
        scenario_run: scenario file to run (a "-quick" variant in quick mode when it exists); None if missing.
        duration_cap_s: duration override [s], None = the scenario's own duration.
        missing: why it cannot run (unknown scenario or controller), None if it can.
        sensors: the sensor profile of the run (None: ideal).
        keyframes: also render the run's key-frame strip (RUN_DIR/keyframes.png) where it ran.
        video: also render the run's video (RUN_DIR/video.mp4) where it ran.
        robot: the robot profile the job runs on.
        engine: the physics engine the job runs on (`wbcbench.sim.engines`).
        realism: the realism preset of the simulated robot (`wbcbench.sim.realism`), None for the ideal robot.
    """

    section: str
    controller: str
    scenario: str
    scenario_run: str | None
    duration_cap_s: float | None
    missing: str | None
    sensors: str | None = None
    keyframes: bool = False
    video: bool = False
    robot: str = "talos"
    engine: str = "mujoco"
    realism: str | None = None

    @property
    def name(self) -> str:
        return f"{self.section}-{self.scenario}-{self.controller}"

    @property
    def label(self) -> str:
        """The job's name in progress and messages: its robot's name first when that is not TALOS."""
        return self.name if self.robot == "talos" else f"{self.robot}/{self.name}"


MEDIA_SECTIONS: tuple[str, ...] = ("paper", "fast")
"""Sections whose cells get a key-frame strip (and with --video a clip) in the report: the tables' cells."""


def available_scenarios() -> list[str]:
    from ..scenarios import available_scenarios as _scen

    return _scen()


def available_controllers() -> list[str]:
    from ..controllers.base import available_controllers as _ctrl

    return list(_ctrl())


def section_of(scenario: str) -> str:
    if any(s == scenario for _, s in PAPER_MATRIX):
        return "paper"
    if any(s == scenario for _, s in FAST_MATRIX):
        return "fast"
    return "sanity"


def _job(section: str, controller: str, scenario: str, quick: bool, cap: float | None,
         scenarios: list[str], controllers: list[str]) -> Job:
    missing = []
    if scenario not in scenarios:
        missing.append(f"scenario '{scenario}' does not exist yet")
    if controller not in controllers:
        missing.append(f"controller '{controller}' does not exist yet")
    if missing:
        return Job(section, controller, scenario, None, None, "; ".join(missing))
    if quick and scenario + QUICK_SUFFIX in scenarios:
        return Job(section, controller, scenario, scenario + QUICK_SUFFIX, None, None)
    return Job(section, controller, scenario, scenario, cap if quick else None, None)


def _select(pairs, only_controllers, only_scenarios) -> list[tuple[str, str]]:
    """`pairs` restricted to the given controllers and scenarios; a controller the pairs do not have (a user's)
    gets every scenario of the pairs, so that it is measured where the paper's controllers are."""
    pairs = list(pairs)
    if only_controllers is not None:
        known = {c for c, _ in pairs}
        scen = list(dict.fromkeys(s for _, s in pairs))
        pairs = [(c, s) for c, s in pairs if c in only_controllers]
        pairs += [(c, s) for c in only_controllers if c not in known for s in scen]
    if only_scenarios is not None:
        pairs = [(c, s) for c, s in pairs if s in only_scenarios]
    return pairs


def plan_jobs(quick: bool = False, sanity: bool = True, sensors: str | None = None,
              controllers: list[str] | None = None, scenarios: list[str] | None = None) -> list[Job]:
    """The jobs of a reproduction: paper matrix, fast walk, then (if `sanity`) the sanity section, then (if
    `sensors`) the sensing section: the paper's walk, platforms and stairs under that sensor profile.
    `controllers` / `scenarios` restrict every section to those (a controller outside the paper's three is run on
    the paper's scenarios: its rows join the tables, with no published number beside them)."""
    only_c, only_s = controllers, scenarios
    scenarios, controllers = available_scenarios(), available_controllers()
    jobs = [_job("paper", c, s, quick, QUICK_WALK_CAP_S, scenarios, controllers)
            for c, s in _select(PAPER_MATRIX, only_c, only_s)]
    jobs += [_job("fast", c, s, quick, QUICK_WALK_CAP_S, scenarios, controllers)
             for c, s in _select(FAST_MATRIX, only_c, only_s)]
    if sanity:
        sanity_ctrls = list(SANITY_CONTROLLERS) if SANITY_CONTROLLERS is not None else controllers
        if only_c is not None:
            sanity_ctrls = list(only_c)
        jobs += [_job("sanity", c, s, quick, QUICK_SANITY_CAP_S, scenarios, controllers)
                 for s in SANITY_SCENARIOS for c in sanity_ctrls
                 if (only_s is None or s in only_s) and (c, s) not in SANITY_NOT_PAIRED]
    if sensors:
        from dataclasses import replace

        jobs += [replace(_job("sensing", c, s, quick, QUICK_WALK_CAP_S, scenarios, controllers), sensors=sensors)
                 for c, s in _select(SENSING_MATRIX, only_c, only_s)]
    return jobs
