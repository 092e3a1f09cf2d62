"""`wbcbench --help` and `wbcbench list` answer without importing the simulator, the controllers or numpy (their
time is measured by benchmarks/bench_cli.py, not here): the names they print come from wbcbench/catalogue.py,
which must agree with the registries, and from the same code path when plugins are installed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from wbcbench import catalogue, cli

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "pinocchio", "mujoco", "numba", "scipy", "matplotlib", "wbcbench.controllers.base",
         "wbcbench.runner")


@pytest.fixture
def only_builtins(monkeypatch):
    """The registries without the types other test modules register in Python when they are collected (a
    command-line process has none: its extensions come by entry point, which takes the registries' path)."""
    import wbcbench.controllers.base as controllers
    import wbcbench.controllers.corrections as corrections
    import wbcbench.scenarios.base as scenarios
    import wbcbench.stabilizers.base as stabilizers
    import wbcbench.tasks.registry as tasks

    for module, name in ((controllers, "_REGISTRY"), (corrections, "_REGISTERED"), (scenarios, "_KINDS"),
                         (stabilizers, "_TYPES"), (tasks, "_TYPES")):
        monkeypatch.setattr(module, name, {})


def test_catalogue_names_are_the_registries(only_builtins):
    from wbcbench.controllers.base import builtin_controllers
    from wbcbench.robots.profile import builtin_robots
    from wbcbench.scenarios import available_scenarios
    from wbcbench.scenarios.base import available_kinds
    from wbcbench.sensing import available_profiles
    from wbcbench.stabilizers.base import available_stabilizers
    from wbcbench.tasks import task_types
    from wbcbench.plugins import GROUPS
    from wbcbench.types import ActuationMode

    assert list(catalogue.BUILTIN_CONTROLLERS) == sorted(builtin_controllers())
    assert list(catalogue.BUILTIN_KINDS) == sorted(n for n, k in available_kinds().items()
                                                  if k.__module__.startswith("wbcbench."))
    assert list(catalogue.TASK_TYPES) == list(task_types())
    assert list(catalogue.STABILIZERS) == list(available_stabilizers())
    assert list(catalogue.MODES) == [m.value for m in ActuationMode]
    assert catalogue.PLUGIN_GROUPS == tuple(GROUPS)
    assert catalogue.scenarios() == available_scenarios()
    assert catalogue.robots() == builtin_robots()
    assert catalogue.sensor_profiles() == available_profiles()
    from wbcbench.controllers.corrections import BUILTIN_CORRECTIONS
    from wbcbench.sim.engines import ENGINES, engine_label

    assert list(catalogue.CORRECTIONS) == sorted(BUILTIN_CORRECTIONS)
    assert [name for name, _ in catalogue.ENGINES] == list(ENGINES)
    assert catalogue.engines() == [engine_label(e) for e in ENGINES]


def test_list_prints_the_same_on_the_fast_and_the_registry_path(capsys, monkeypatch, only_builtins):
    if catalogue.has_plugins():
        pytest.skip("plugins are installed in this environment: `list` takes the registry path anyway")
    has_plugins = catalogue.has_plugins
    assert cli.main(["list"]) == 0
    fast = capsys.readouterr().out
    monkeypatch.setattr(catalogue, "has_plugins", lambda: True)
    assert cli.main(["list"]) == 0
    assert capsys.readouterr().out == fast
    monkeypatch.setattr(catalogue, "has_plugins", has_plugins)
    fast_help = cli.build_parser().format_help()
    monkeypatch.setattr(catalogue, "has_plugins", lambda: True)
    assert cli.build_parser().format_help() == fast_help


@pytest.mark.parametrize("argv", [["--help"], ["list"], ["run", "--help"]])
def test_help_and_list_import_nothing_heavy(argv):
    code = (f"import sys\nfrom wbcbench.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
            f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
            "print('HEAVY', heavy, file=sys.stderr)\nassert not heavy, heavy\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "scenarios" in out.stdout


def test_lazy_packages_keep_their_public_names():
    """report, teleop and robustness import their modules when a name is first used; every name of __all__ is
    there, and a function named like its module stays the function after the module is imported."""
    import wbcbench.report as report
    import wbcbench.robustness as robustness
    import wbcbench.teleop as teleop
    import wbcbench.report.reproduce  # noqa: F401  (imports report/compare.py as a submodule)
    import wbcbench.teleop.retargeting  # noqa: F401  (imports teleop/umeyama.py)

    for pkg in (report, teleop, robustness):
        for name in pkg.__all__:
            assert getattr(pkg, name) is not None, f"{pkg.__name__}.{name}"
        assert set(pkg.__all__) <= set(dir(pkg))
    from wbcbench.report import compare, reproduce
    from wbcbench.teleop import umeyama

    assert callable(compare) and compare.__module__ == "wbcbench.report.compare"
    assert callable(reproduce) and reproduce.__module__ == "wbcbench.report.reproduce"
    assert callable(umeyama) and umeyama.__module__ == "wbcbench.teleop.human.umeyama"
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        report.nope  # noqa: B018
