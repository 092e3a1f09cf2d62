"""`wbcbench doctor`: one line per check, the fix printed for what is missing, exit 1 only when a required part is
missing."""

from __future__ import annotations

import sys

from wbcbench import doctor
from wbcbench.cli import main


def test_doctor_reports_every_check(capsys):
    rc = main(["doctor"])
    out = capsys.readouterr().out
    assert rc == 0, out  # this environment has every required part
    for name in ("python", "mujoco", "pin", "daqp", "proxsuite", "numba", "robot model", "compiled kernels",
                 "OpenGL rendering", "render-model cache", "browser (viewer test)", "ray", "mkdocs"):
        assert f" {name} " in out, name
    assert "ok       mujoco" in out and "ok       robot model" in out


def test_doctor_names_what_is_missing_and_the_fix(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)     # import ray fails
    monkeypatch.setitem(sys.modules, "daqp", None)    # a required solver is missing
    monkeypatch.setenv("MUJOCO_GL", "no-such-backend")
    monkeypatch.setenv("WBCBENCH_CHROMIUM", "")
    monkeypatch.setattr(doctor.shutil, "which", lambda name: None)
    monkeypatch.setattr(doctor.os.path, "isfile", lambda p: False)
    rc = main(["doctor"])
    captured = capsys.readouterr()
    lines = captured.out.splitlines()

    def line_of(name):
        i = next(i for i, line in enumerate(lines) if f" {name} " in line)
        return lines[i], lines[i + 1] if i + 1 < len(lines) else ""

    assert rc == 1 and "required parts missing: daqp" in captured.err
    status, fix = line_of("daqp")
    assert status.split()[0] == "missing" and "fix: pip install daqp" in fix
    status, fix = line_of("ray")
    assert status.split()[0] == "optional" and "fix: pip install 'wbcbench[ray]'" in fix
    status, fix = line_of("OpenGL rendering")
    assert status.split()[0] == "optional" and "MUJOCO_GL=no-such-backend" in status and "MUJOCO_GL=egl" in fix
    status, fix = line_of("browser (viewer test)")
    assert status.split()[0] == "optional" and "apt-get install chromium" in fix


def test_supported_python_is_the_one_stated():
    from pathlib import Path

    import pytest

    tomllib = pytest.importorskip("tomllib", reason="Python 3.10 has no tomllib")

    meta = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]
    lo, hi = doctor.SUPPORTED_PYTHON
    assert meta["requires-python"] == f">={lo[0]}.{lo[1]}"
    stated = {c.rsplit(":: ", 1)[1] for c in meta["classifiers"] if c.startswith("Programming Language :: Python :: 3.")}
    assert stated == {f"3.{m}" for m in range(lo[1], hi[1] + 1)}
    assert lo <= sys.version_info[:2] <= hi
