"""Push-recovery protocol: phases land where the gait is, the bisection brackets the limit with a survived and a
failed push, and the command line reports it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from wbcbench.robots import load_robot
from wbcbench.robustness import PushStudy, phase_times, run_study
from wbcbench.robustness.push import PushCell
from wbcbench.scenarios import load_scenario


def test_phase_times_fall_in_their_phases(talos):
    times = phase_times("walk-20cm-quick")
    assert times["ds"] < times["ss-early"] < times["ss-mid"] < times["ss-late"]
    scen = load_scenario("walk-20cm-quick", talos)
    import pinocchio as pin
    scen.setup(talos.q0, pin.centerOfMass(talos.model, talos.model.createData(), talos.q0))
    assert len(scen.references(times["ds"]).contacts) == 2
    for p in ("ss-early", "ss-mid", "ss-late"):
        assert len(scen.references(times[p]).contacts) == 1, p
    assert phase_times("stand") == {"ds": 1.0}


def test_bisection_brackets_the_limit(tmp_path):
    """tsid-torque standing, pushed sideways: a 100 N x 0.1 s push is survived (SIM-NOTES), a 60 N s one is not;
    the bisection ends with a survived impulse below a failed one, each backed by its trial."""
    study = PushStudy("stand", ("tsid-torque",), directions=4, phases=("ds",), iterations=2, max_impulse=60.0)
    [r0, r90, *_] = run_study(study, tmp_path, jobs=2)
    for r in (r0, r90):
        assert r.failed_impulse is not None and 0.0 < r.survived_impulse < r.failed_impulse
        by_impulse = {imp: ok for imp, ok, _ in r.trials}
        assert by_impulse[r.survived_impulse] is True and by_impulse[r.failed_impulse] is False
        assert r.survived_impulse >= 10.0
    saved = json.loads((tmp_path / "push_results.json").read_text())
    assert len(saved["results"]) == 4 and saved["phase_times_s"] == {"ds": 1.0}


def test_trials_from_one_approach_equal_trials_from_the_start(tmp_path):
    """The protocol simulates the approach to the push once per controller, phase and seed and continues every
    trial from it; trials made from the start (where processes cannot fork) give the same outcomes."""
    from wbcbench.robustness.push import _bisect, _bisect_group

    study = PushStudy("stand", ("tsid-position",), directions=2, phases=("ds",), iterations=1, max_impulse=50.0,
                      settle=1.0)
    cells = [PushCell("tsid-position", d, "ds", 0, 1.0) for d in (0.0, 180.0)]
    grouped = _bisect_group(study, cells, tmp_path / "branched")
    alone = [_bisect(study, c, tmp_path / "alone") for c in cells]
    assert grouped == alone
    assert any(ok for r in alone for _, ok, _ in r.trials) and any(not ok for r in alone for _, ok, _ in r.trials)
    assert sorted(p.name for p in (tmp_path / "branched" / "runs").iterdir()) == \
        sorted(p.name for p in (tmp_path / "alone" / "runs").iterdir())


def test_cli_bad_input(tmp_path):
    def cli(*args):
        return subprocess.run([sys.executable, "-m", "wbcbench.cli", "robustness", "push", *args, "--out",
                               str(tmp_path / "o")], capture_output=True, text=True)

    for args, needle in ((("stand", "-c", "tsid-torqe"), "tsid-torque"),
                         (("stand", "-c", "tsid-torque", "--phases", "ss-mid"), "ss-mid"),
                         (("walk-20cm-quick", "-c", "ik", "--phases", "mid"), "allowed"),
                         (("stand", "-c", "ik", "--directions", "0"), "--directions")):
        out = cli(*args)
        assert out.returncode == 2, out.stderr
        assert len(out.stderr.strip().splitlines()) == 1 and needle in out.stderr, out.stderr
