"""A run continued from a branch point is the run that would have been made from the start: same log, same
config; the plan sees each branch's summary; a bad branch point or a failing plan is an error, not a crash."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from wbcbench.errors import ConfigError
from wbcbench.recorder import read_log
from wbcbench.runner import Branch, BranchPoint, run
from wbcbench.scenarios import load_scenario
from wbcbench.sim.push import Push


def _without_versions(path: Path) -> dict:
    cfg = json.loads((path / "config.json").read_text())
    cfg.pop("versions")
    return cfg


def test_branches_equal_runs_from_the_start(tmp_path, talos):
    """IK standing with the talos-like sensors (noise from a seeded generator, a base estimator, latency): two
    branches at 0.5 s with different pushes give the logs of the two runs made from the start with them."""
    pushes = [(Push("base", (40.0, 0.0, 0.0), 0.6, 0.1),), (Push("base", (0.0, -60.0, 0.0), 0.5, 0.1),)]
    seen = []

    def plan():
        for k, p in enumerate(pushes):
            seen.append((yield Branch(tmp_path / f"branch{k}", p)))

    parent = run("stand", "ik", duration=1.0, out=tmp_path / "approach", sensors="talos-like", seed=3,
                 branch=BranchPoint(0.5, plan))
    assert parent.summary["branches"] == 2 and parent.summary["sim_time_s"] == pytest.approx(0.5)
    assert len(parent.log["t"]) == 500
    for k, p in enumerate(pushes):
        scen = load_scenario("stand", talos, 1.0)
        scen.spec = replace(scen.spec, pushes=p)
        ref = run(scen, "ik", out=tmp_path / f"start{k}", sensors="talos-like", seed=3)
        got = read_log(tmp_path / f"branch{k}" / "log.parquet")
        assert list(got) == list(ref.log)
        for col in ref.log:
            if col != "controller_time_us":
                np.testing.assert_array_equal(got[col], ref.log[col], err_msg=col)
        assert _without_versions(tmp_path / f"branch{k}") == _without_versions(tmp_path / f"start{k}")
        assert seen[k]["fell"] is False and seen[k]["sim_time_s"] == pytest.approx(1.0)
        assert "branches" not in seen[k]
    # the pushes did something: the two branches differ after their pushes, not before
    a, b = (read_log(tmp_path / f"branch{k}" / "log.parquet")["com.y"] for k in range(2))
    assert np.array_equal(a[:500], b[:500]) and np.abs(a[600:] - b[600:]).max() > 1e-3


def test_bad_branch_point_and_failing_plan(tmp_path):
    def plan():
        yield Branch(tmp_path / "b0")
        raise RuntimeError("the plan's own bug")

    with pytest.raises(ConfigError, match="branch point"):
        run("stand", "joint-pd", duration=0.2, out=tmp_path / "a", branch=BranchPoint(0.5, plan))
    with pytest.raises(RuntimeError, match="the plan's own bug"):
        run("stand", "joint-pd", duration=0.2, out=tmp_path / "b", branch=BranchPoint(0.1, plan))
    assert (tmp_path / "b0" / "summary.json").exists()  # the branch before the error ran and wrote its run
    assert len(read_log(tmp_path / "b" / "log.parquet")["t"]) == 100  # the parent's log up to the branch point


def test_a_branch_that_cannot_run_reports_an_error_to_the_plan(tmp_path):
    """The branch's process cannot make its directory (a file is in the way): it ends, and the plan is sent an
    error with its exit code; the next branch runs."""
    (tmp_path / "a-file").write_text("not a directory")
    seen = []

    def plan():
        seen.append((yield Branch(tmp_path / "a-file" / "b0")))
        seen.append((yield Branch(tmp_path / "b1")))

    run("stand", "joint-pd", duration=0.2, out=tmp_path / "a", branch=BranchPoint(0.1, plan))
    assert "exit code 1" in seen[0]["error"] and "fell" not in seen[0]
    assert seen[1]["fell"] is False and (tmp_path / "b1" / "log.parquet").exists()
