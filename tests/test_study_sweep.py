"""Sweeps: pool and Ray give the same results table, a killed sweep resumes with only the rest, a crashing cell is
recorded, bad sweep files and Ray addresses are one-line errors (exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from wbcbench.cli import main
from wbcbench.study.cell import DONE_FILE, TIMING_PREFIXES
from wbcbench.study.execute import Executor, PoolExecutor, RayExecutor
from wbcbench.study.sweep import run_sweep

STAND_2X2 = """
base: {scenario: stand, controller: joint-pd, robot: talos, duration: 0.2}
grid:
  sim.sole_friction: [0.8, 1.0]
  scenario.pushes: [[], [{body: base_link, force: [60.0, 0.0, 0.0], start: 0.05, duration: 0.05}]]
"""


def _write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _deterministic(table) -> list[dict]:
    keep = [c for c in table.column_names if not c.startswith(TIMING_PREFIXES)]
    rows = table.select(keep).to_pylist()
    return sorted(rows, key=lambda r: r["cell_id"])


def test_pool_and_ray_give_identical_tables(tmp_path):
    ray = pytest.importorskip("ray", reason="ray is not importable (pip install 'wbcbench[ray]')")
    f = _write(tmp_path, STAND_2X2)
    with PoolExecutor(2) as ex:
        _, pool_table, n_pool = run_sweep(f, tmp_path / "pool", ex)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        with RayExecutor("auto") as ex:
            _, ray_table, n_ray = run_sweep(f, tmp_path / "ray", ex)
    finally:
        ray.shutdown()
    assert n_pool == n_ray == 4
    a, b = _deterministic(pool_table), _deterministic(ray_table)
    assert len(a) == 4 and all(r["status"] == "ok" for r in a)
    assert a == b
    # the push moved the robot: the cells differ from each other, so equality is not trivial
    assert len({r["metrics.E_m"] for r in a}) >= 2


def test_killed_sweep_resumes_only_unfinished_cells(tmp_path):
    f = _write(tmp_path, """
base: {scenario: stand, controller: joint-pd, duration: 0.1}
grid: {seed: [0, 1, 2, 3]}
""")
    out = tmp_path / "sw"

    def kill_after_two(done, total, row):
        if done == 2 and row:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(f, out, Executor(), on_cell=kill_after_two)
    finished = sorted(out.glob(f"cells/*/{DONE_FILE}"))
    assert len(finished) == 2
    stamps = {p: p.stat().st_mtime_ns for p in finished}
    with pytest.raises(Exception, match="--resume"):
        run_sweep(f, out, Executor())
    _, table, n = run_sweep(f, out, Executor(), resume=True)
    assert n == 2 and table.num_rows == 4
    assert {p: p.stat().st_mtime_ns for p in finished} == stamps   # finished cells not recomputed
    assert pq.read_table(out / "results.parquet").num_rows == 4
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["cells"]) == 4 and manifest["code_version"]
    assert len(set(table.column("code_version").to_pylist())) == 1


def test_crashing_cell_is_recorded_and_sweep_completes(tmp_path, monkeypatch):
    import wbcbench.runner as runner

    real = runner.run

    def flaky(scen, controller, *a, **kw):
        if "seed=1" in str(kw.get("out", a[3] if len(a) > 3 else "")):
            raise RuntimeError("boom in cell")
        return real(scen, controller, *a, **kw)

    monkeypatch.setattr(runner, "run", flaky)
    f = _write(tmp_path, "base: {scenario: stand, controller: joint-pd, duration: 0.1}\ngrid: {seed: [0, 1, 2]}\n")
    _, table, n = run_sweep(f, tmp_path / "sw", Executor())
    rows = {r["param.seed"]: r for r in table.to_pylist()}
    assert n == 3 and len(rows) == 3
    assert rows[1]["status"] == "error" and "boom in cell" in rows[1]["error"]
    assert rows[0]["status"] == rows[2]["status"] == "ok"
    assert list((tmp_path / "sw" / "cells").glob("seed=1-*/error.txt"))
    from wbcbench.study.report import sweep_report
    md = sweep_report(tmp_path / "sw", metric="metrics.E_m")
    # per-seed table from DuckDB: seed 1 has success rate 0 and no metric, the others 1
    assert "| 1 | 1 | 0 |" in md and "| 0 | 1 | 1 |" in md and "## Crashed cells" in md and "boom in cell" in md
    assert (tmp_path / "sw" / "metric-vs-seed.png").stat().st_size > 1000
    assert (tmp_path / "sw" / "report.html").read_text().count("<table>") >= 2


def test_taskset_and_scenario_overrides_reach_the_run(tmp_path):
    f = _write(tmp_path, """
base: {scenario: walk-20cm-quick, controller: ik, duration: 0.05}
grid:
  taskset.tasks.com_xy.kp: [50.0]
  scenario.params.step_length: [0.1]
  profile.position_gains.kp.leg_: [12345.0]
""")
    out, table, _ = run_sweep(f, tmp_path / "sw", Executor())
    cell = next((out / "cells").iterdir())
    import yaml
    assert yaml.safe_load((cell / "scenario.yaml").read_text())["params"]["step_length"] == 0.1
    ts = yaml.safe_load((cell / "taskset.yaml").read_text())
    assert next(t for t in ts["tasks"] if t["name"] == "com_xy")["kp"] == 50.0
    prof = yaml.safe_load((cell / "profile.yaml").read_text())
    assert prof["position_gains"]["kp"]["leg_"] == 12345.0
    assert table.column("status").to_pylist() == ["ok"]


@pytest.mark.parametrize("text, expect", [
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {scenario.params.nope.kp: [1.0]}\n", "unknown key path"),
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {taskset.tasks.no_task.kp: [1.0]}\n", "controller"),
    ("base: {scenario: stand, controller: ik}\ngrid: {taskset.tasks.no_task.kp: [1.0]}\n", "no entry named"),
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {gains.kp: [1.0]}\n", "unknown parameter"),
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {profile.no_such.kp: [1.0]}\n", "unknown key path"),
    ("base: {scenario: stand, controller: joint-pd}\n", "empty design"),
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {seed: []}\n", "non-empty list"),
    ("base: {scenario: stand, controller: joint-pd}\nrandom: {n: 3, params: {sim.sole_friction: {min: 2, max: 1}}}\n",
     "min (2) must be <= max (1)"),
    ("base: {scenario: stand, controller: joint-pd}\ngrid: {seed: [%s], sim.sole_friction: [%s]}\n"
     % (",".join(map(str, range(101))), ",".join(str(0.5 + i / 1000) for i in range(100))), "pass --yes"),
])
def test_bad_sweep_file_is_one_line_exit_2(tmp_path, capsys, text, expect):
    f = _write(tmp_path, text)
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expect in err and "sweep.yaml" in err, err


def test_unreachable_ray_address_is_one_line_exit_2(tmp_path, capsys):
    pytest.importorskip("ray", reason="ray is not importable (pip install 'wbcbench[ray]')")
    f = _write(tmp_path, STAND_2X2)
    assert main(["sweep", str(f), "--ray", "127.0.0.1:9", "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot reach a Ray cluster" in err, err


@pytest.mark.parametrize("text, expect", [
    ("base: {scenario: stand, controller: ik}\nparams: {taskset.tasks.nope.kp: {min: 1, max: 2}}\n"
     "objective: {metrics.E_m: 1}\n", "no entry named 'nope'"),
    ("base: {scenario: stand, controller: ik}\nparams: {taskset.tasks.com_xy.kp: {min: 5, max: 2}}\n"
     "objective: {metrics.E_m: 1}\n", "min (5) must be <= max (2)"),
    ("base: {scenario: stand, controller: ik}\nparams: {}\nobjective: {metrics.E_m: 1}\n", "at least one key path"),
    ("base: {scenario: stand, controller: ik}\nparams: {taskset.tasks.com_xy.kp: {min: 1, max: 2}}\n",
     "objective"),
])
def test_bad_tune_file_is_one_line_exit_2(tmp_path, capsys, text, expect):
    f = _write(tmp_path, text, "tune.yaml")
    assert main(["tune", str(f), "--trials", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expect in err and "tune.yaml" in err, err


def test_tune_two_trials_write_best_taskset_and_report(tmp_path):
    from wbcbench.study.tune import tune
    f = _write(tmp_path, """
base: {scenario: stand, controller: ik, duration: 0.1}
params: {taskset.tasks.com_xy.kp: {min: 20, max: 200, log: true}}
objective: {metrics.E_m: 1.0}
""", "tune.yaml")
    res = tune(f, 2, tmp_path / "t")
    assert res["n_trials"] == 2 and res["best"] is not None and res["baseline"] is not None
    import yaml
    best = yaml.safe_load((tmp_path / "t" / "best-taskset.yaml").read_text())
    kp = next(t for t in best["tasks"] if t["name"] == "com_xy")["kp"]
    assert kp == pytest.approx(res["best"]["params"]["taskset.tasks.com_xy.kp"]) and 20 <= kp <= 200
    assert "shipped gains" in (tmp_path / "t" / "report.md").read_text()
    res2 = tune(f, 3, tmp_path / "t")   # resumes the SQLite study: one more trial
    assert res2["n_trials"] == 3


def test_reproduce_unreachable_ray_is_one_line_exit_2(tmp_path, capsys):
    pytest.importorskip("ray", reason="ray is not importable (pip install 'wbcbench[ray]')")
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "r"), "--ray", "127.0.0.1:9", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot reach a Ray cluster" in err, err
