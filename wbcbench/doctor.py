"""`wbcbench doctor`: what works on this machine, and the fix for what does not.

Each check prints one line: `ok`, `missing` (a required part: runs will fail) or `optional` (a feature is
unavailable: rendering, the browser test, Ray, the docs), with what it found and, when something is missing, the
command that fixes it. The exit code is 1 when a required part is missing, else 0.

The checks: the Python version; the simulation and control libraries (MuJoCo, pinocchio, daqp, proxsuite, numba,
example-robot-data's TALOS); OpenGL rendering (a frame rendered offscreen, in a subprocess, so a broken driver
cannot take the command down); the compiled-kernel cache (numba's, next to the sources or in NUMBA_CACHE_DIR) and
the render-model cache; the browser of the viewer's end-to-end test (Playwright and Chromium); Ray; MkDocs.
"""

from __future__ import annotations

import argparse
import importlib
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

COMMAND = "doctor"
SUPPORTED_PYTHON = ((3, 10), (3, 13))
"""The Python versions wbcbench supports (inclusive): those for which its compiled dependencies publish wheels."""

OK, MISSING, OPTIONAL = "ok", "missing", "optional"


@dataclass(frozen=True)
class Check:
    """One line of the doctor's report."""

    name: str
    status: str  # OK, MISSING or OPTIONAL
    detail: str
    fix: str = ""


def add_subcommand(sub) -> None:
    sub.add_parser(COMMAND, help="check what works on this machine (simulation, rendering, browser, kernel cache, "
                                 "Ray) and print the fix for what does not",
                   description=__doc__.split("\n\n")[1].replace("\n", " "))


def _python() -> Check:
    v = sys.version_info[:2]
    lo, hi = SUPPORTED_PYTHON
    text = f"Python {sys.version.split()[0]} ({sys.executable})"
    if lo <= v <= hi:
        return Check("python", OK, text)
    return Check("python", MISSING if v < lo else OPTIONAL, text + f"; supported: {lo[0]}.{lo[1]}-{hi[0]}.{hi[1]}",
                 "use a supported Python: python3.12 -m venv .venv && .venv/bin/pip install -e .")


def _module(name: str, dist: str, required: bool = True, fix: str | None = None) -> Check:
    try:
        mod = importlib.import_module(name)
    except Exception as exc:  # an import error of any kind is what the check reports
        return Check(dist, MISSING if required else OPTIONAL, f"cannot import {name}: {type(exc).__name__}: "
                     f"{str(exc).splitlines()[0] if str(exc) else ''}", fix or f"pip install {dist}")
    version = getattr(mod, "__version__", None)
    if version is None:
        try:
            from importlib import metadata

            version = metadata.version(dist)
        except Exception:
            version = "?"
    return Check(dist, OK, f"{name} {version}")


def _robot_model() -> Check:
    try:
        from .robots import load_robot

        robot = load_robot("talos")
        return Check("robot model", OK, f"TALOS from example-robot-data: {robot.model.nq} configuration "
                                        f"variables, {len(robot.joint_names)} joints")
    except Exception as exc:
        return Check("robot model", MISSING, f"TALOS cannot be loaded: {type(exc).__name__}: {exc}",
                     "pip install example-robot-data example-robot-data-loaders")


_RENDER_PROBE = """
import mujoco
m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><light pos='0 0 3'/><geom type='box' size='.1 .1 .1'/>"
                                   "</worldbody></mujoco>")
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
r = mujoco.Renderer(m, 32, 48)
r.update_scene(d)
img = r.render()
print(img.shape[0], img.shape[1], int(img.max()))
"""


def _rendering() -> Check:
    env = dict(os.environ)
    if sys.platform.startswith("linux") and not env.get("DISPLAY"):
        env.setdefault("MUJOCO_GL", "egl")
    backend = env.get("MUJOCO_GL", "default (glfw)")
    try:
        out = subprocess.run([sys.executable, "-c", _RENDER_PROBE], capture_output=True, text=True, env=env,
                             timeout=60)
    except subprocess.TimeoutExpired:
        return Check("OpenGL rendering", OPTIONAL, f"MUJOCO_GL={backend}: rendering a frame did not finish in 60 s",
                     "check the GL driver; headless: apt-get install libegl1 libgl1-mesa-dri and MUJOCO_GL=egl")
    if out.returncode == 0 and out.stdout.split()[:2] == ["32", "48"]:
        return Check("OpenGL rendering", OK, f"MUJOCO_GL={backend}: a frame rendered offscreen (videos, key frames)")
    err = (out.stderr.strip().splitlines() or ["no output"])[-1]
    return Check("OpenGL rendering", OPTIONAL, f"MUJOCO_GL={backend}: {err}",
                 "headless Linux: apt-get install libegl1 libgl1-mesa-dri (Mesa's EGL) and MUJOCO_GL=egl, or "
                 "apt-get install libosmesa6 and MUJOCO_GL=osmesa; with a display: MUJOCO_GL=glfw")


def _kernel_cache() -> Check:
    from . import jit

    if not jit.JIT_ENABLED:
        return Check("compiled kernels", OPTIONAL, "off (WBCBENCH_JIT=0 or numba missing): the same code runs as "
                     "plain Python, several times slower", "unset WBCBENCH_JIT; pip install numba")
    root = Path(__file__).parent
    cache_dir = os.environ.get("NUMBA_CACHE_DIR")
    if cache_dir:
        where, files = Path(cache_dir), list(Path(cache_dir).rglob("*.nbi"))
    else:
        where, files = root, list(root.rglob("__pycache__/*.nbi"))
    writable = os.access(where if where.exists() else where.parent, os.W_OK)
    if not writable and not cache_dir:
        return Check("compiled kernels", OPTIONAL, f"{where} is not writable: numba falls back to its user-wide "
                     "cache", "export NUMBA_CACHE_DIR=~/.cache/wbcbench/numba (a writable directory)")
    if not files:
        return Check("compiled kernels", OK, f"cache in {where}: empty; the first run compiles the kernels "
                     "(about 5-10 s), later runs load them", "optional: warm it with `wbcbench run stand -c "
                     "tsid-torque --duration 0.1`")
    return Check("compiled kernels", OK, f"cache in {where}: {len(files)} kernel signatures compiled")


def _render_cache() -> Check:
    from .viz.render import cache_dir

    d = cache_dir()
    if d is None:
        return Check("render-model cache", OK, "off (WBCBENCH_CACHE_DIR is empty): models are rebuilt per process")
    probe = d
    while not probe.exists():
        probe = probe.parent
    if os.access(probe, os.W_OK):
        n = len(list(d.glob("*"))) if d.exists() else 0
        return Check("render-model cache", OK, f"{d} ({n} models)")
    return Check("render-model cache", OPTIONAL, f"{d} is not writable: each render rebuilds its model",
                 "export WBCBENCH_CACHE_DIR=/a/writable/directory")


def _browser() -> Check:
    chromium = next((p for p in (os.environ.get("WBCBENCH_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium"),
                                 shutil.which("chromium-browser")) if p and os.path.isfile(p)), None)
    try:
        importlib.import_module("playwright.sync_api")
        playwright = True
    except Exception:
        playwright = False
    if chromium and playwright:
        return Check("browser (viewer test)", OK, f"Playwright and Chromium at {chromium}")
    missing = [what for what, ok in (("the Python package playwright", playwright), ("a Chromium executable",
                                                                                     chromium)) if not ok]
    fix = []
    if not playwright:
        fix.append("pip install -e '.[test]'")
    if not chromium:
        fix.append("apt-get install chromium (or WBCBENCH_CHROMIUM=/path/to/chromium)")
    return Check("browser (viewer test)", OPTIONAL, "missing " + " and ".join(missing) + ": the browser end-to-end "
                 "tests are skipped (`wbcbench view` itself needs only a browser of yours)", "; ".join(fix))


def checks() -> list[Check]:
    """Every check, in the order printed."""
    return [
        _python(),
        _module("mujoco", "mujoco"),
        _module("pinocchio", "pin"),
        _module("daqp", "daqp"),
        _module("proxsuite", "proxsuite"),
        _module("numba", "numba"),
        _robot_model(),
        _kernel_cache(),
        _rendering(),
        _render_cache(),
        _browser(),
        _module("ray", "ray", required=False, fix="pip install 'wbcbench[ray]' (sweeps and tuning on Ray)"),
        _module("mkdocs", "mkdocs", required=False, fix="pip install 'wbcbench[docs]' (make docs)"),
    ]


def run_command(args: argparse.Namespace | None = None) -> int:
    from . import __version__

    print(f"wbcbench {__version__} on {sys.platform}")
    results = checks()
    width = max(len(c.name) for c in results)
    for c in results:
        print(f"  {c.status:8s} {c.name:{width}s}  {c.detail}")
        if c.fix and c.status != OK:
            print(f"  {'':8s} {'':{width}s}  fix: {c.fix}")
        elif c.fix:
            print(f"  {'':8s} {'':{width}s}  {c.fix}")
    missing = [c.name for c in results if c.status == MISSING]
    if missing:
        print(f"required parts missing: {', '.join(missing)}", file=sys.stderr)
    return 1 if missing else 0
