"""A release a user can pip install: `python -m build` makes an sdist and, from it, a wheel; the wheel installs
into a fresh virtual environment outside the repository, and `wbcbench run stand -c tsid-torque` runs from there
(the package data, the scenarios, profiles, task sets and recordings, must all be in it).

The fresh environment gets wbcbench from the wheel alone; its dependencies (MuJoCo, pinocchio, numba, ...) are
the test environment's, made visible through a .pth line (which adds that directory, not its own .pth files: the
checkout's editable install stays out), so the test needs no network. One test; about a minute. It builds what is committed (a clone of the checkout)."""

from __future__ import annotations

import json
import os
import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _sh(*args, cwd=None, env=None, timeout=900) -> subprocess.CompletedProcess:
    out = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert out.returncode == 0, f"{' '.join(map(str, args))}\n{out.stdout[-3000:]}\n{out.stderr[-5000:]}"
    return out


def _dependency_pth_lines() -> list[str]:
    """.pth lines that make this environment's packages importable elsewhere: its site directories, then the lines
    of their own .pth files (e.g. pinocchio's cmeel prefix), except this checkout's editable install."""
    lines = []
    dirs = [Path(p) for p in site.getsitepackages() if Path(p).is_dir()]
    lines += [str(d) for d in dirs]
    for d in dirs:
        for pth in sorted(d.glob("*.pth")):
            if pth.name.startswith("__editable__") or "wbcbench" in pth.name:
                continue
            for line in pth.read_text().splitlines():
                if not line.strip() or line.startswith("#"):
                    continue
                lines.append(line if line.startswith(("import ", "import\t")) else str(d / line))
    return lines


@pytest.mark.release
def test_wheel_installs_in_a_fresh_venv_and_runs(tmp_path):
    pytest.importorskip("build", reason="the build frontend is not installed (pip install -e '.[test]')")
    pytest.importorskip("setuptools_scm", reason="setuptools-scm is not installed (pip install -e '.[test]')")
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the version and the sdist's file list come from git")
    # what is released is what is committed: a clone (its tags included), which also keeps the build's files
    # (egg-info, wbcbench/_version.py) out of the checkout that the other tests import
    src, dist = tmp_path / "src", tmp_path / "dist"
    _sh("git", "clone", "--quiet", "--no-hardlinks", ROOT, src)
    # the build dependencies of pyproject.toml are this environment's (no isolation: no download)
    _sh(sys.executable, "-m", "build", "--no-isolation", "--outdir", dist, src, cwd=tmp_path)
    wheels, sdists = sorted(dist.glob("wbcbench-*.whl")), sorted(dist.glob("wbcbench-*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, sorted(p.name for p in dist.iterdir())
    version = wheels[0].name.split("-")[1]

    env_dir = tmp_path / "fresh-venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    fresh_site = Path(_sh(py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    (fresh_site / "zz-test-dependencies.pth").write_text("\n".join(_dependency_pth_lines()) + "\n")
    _sh(sys.executable, "-m", "pip", "--python", py, "--disable-pip-version-check", "install", "--no-deps",
        "--no-index", wheels[0])

    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    where = _sh(py, "-c", "import wbcbench; print(wbcbench.__file__); print(wbcbench.__version__)", cwd=work,
                env=env).stdout.split()
    assert Path(where[0]).is_relative_to(env_dir), f"wbcbench imported from {where[0]}, not the fresh venv"
    assert where[1] == version
    out = _sh(env_dir / "bin" / "wbcbench", "run", "stand", "-c", "tsid-torque", "--duration", "0.5", "--quiet",
              "--out", work / "run", cwd=work, env=env)
    summary = json.loads((work / "run" / "summary.json").read_text())
    assert summary["fell"] is False and summary["sim_time_s"] == pytest.approx(0.5), out.stdout
    listed = _sh(env_dir / "bin" / "wbcbench", "list", cwd=work, env=env).stdout
    assert "walk-20cm" in listed and "tsid-torque" in listed and "talos-like" in listed
