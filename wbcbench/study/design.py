"""A sweep design from YAML: a grid and/or seeded random samples over run parameters.

```yaml
base: {scenario: stand, controller: joint-pd, robot: talos, duration: 0.2}   # fixed for every cell
grid:                                  # full factorial
  controller: [joint-pd, ik]
  scenario.params.step_length: [0.15, 0.20]
  taskset.tasks.com_xy.kp: [50.0, 100.0]
  sim.sole_friction: [0.5, 1.0]
  seed: [0, 1]
random:                                # n samples per grid cell, drawn with `seed`
  n: 8
  seed: 0
  params:
    scenario.pushes[0].force: {min: 10, max: 60}
    taskset.stabilizer.kp_dcm: {min: 1, max: 20, log: true}
```

Parameter names: `controller`, `robot`, `scenario`, `mode`, `duration` [s], `seed`, `taskset` (a task-set YAML
path instead of the shipped one, relative to the sweep file), `engine` (the physics engine), `realism` (the
simulated robot's hidden hardware, `wbcbench.sim.realism`: `talos-real` or a preset YAML path relative to the sweep
file; absent or null: the ideal robot), or a key path into the scenario
YAML (`scenario.<path>`), the robot profile (`profile.<path>`, e.g. `profile.position_gains.kp.leg_`), the controller's task set (`taskset.<path>`; a list of named entries such as `tasks` is
indexed by name: `tasks.com_xy.kp`) or the simulator options (`sim.<field>` of wbcbench.sim.model.SimOptions, e.g.
`sim.timestep`, `sim.sole_friction`). The overridden YAML is validated by the normal loaders. `seed` seeds
numpy's global generator in the cell; the simulation has no noise source yet, so cells that differ only by seed
give the same numbers.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..config import load_yaml
from ..errors import ConfigError

TOP_KEYS = ("controller", "robot", "scenario", "mode", "duration", "seed", "taskset", "engine", "realism")
PATH_PREFIXES = ("scenario.", "taskset.", "profile.", "sim.")
MAX_CELLS = 10_000


@dataclass(frozen=True)
class Cell:
    """One run of the sweep: its id (directory name) and all its parameters (base merged with the design's)."""

    id: str
    params: dict

    def get(self, key: str, default=None):
        return self.params.get(key, default)


@dataclass(frozen=True)
class Design:
    """The parsed sweep file: `cells` in a fixed order; `varied` are the parameter names the design changes."""

    file: str
    base: dict
    grid: dict
    random: dict
    cells: tuple[Cell, ...]
    varied: tuple[str, ...]

    def manifest(self) -> dict:
        return {"file": self.file, "base": self.base, "grid": self.grid, "random": self.random,
                "varied": list(self.varied), "cells": [{"id": c.id, "params": c.params} for c in self.cells]}


def _check_name(name: object, file: str, where: str) -> str:
    if not isinstance(name, str) or not (name in TOP_KEYS or name.startswith(PATH_PREFIXES)):
        raise ConfigError(f"unknown parameter '{name}'; allowed: {', '.join(TOP_KEYS)} or a key path "
                          f"starting with {', '.join(PATH_PREFIXES)}", file=file, key=where)
    if name.startswith("sim."):
        if name == "sim.realism":
            raise ConfigError("the realism preset is the top-level parameter 'realism', not a simulator option",
                              file=file, key=where)
        allowed = [f.name for f in fields(_sim_options_cls()) if f.name not in ("extra", "realism")]
        if name[4:] not in allowed:
            raise ConfigError(f"unknown simulator option '{name[4:]}'; allowed: {', '.join(allowed)}",
                              file=file, key=f"{where}")
    return name


def _sim_options_cls():
    from ..sim.model import SimOptions
    return SimOptions


def _fmt(v: object) -> str:
    if isinstance(v, float):
        v = f"{v:.6g}"
    elif isinstance(v, str) and v.endswith((".yaml", ".yml")):
        v = Path(v).stem
    s = re.sub(r"[^A-Za-z0-9.+-]+", "_", str(v))
    return s[:40]


def cell_id(params: dict, varied: tuple[str, ...]) -> str:
    """Directory name: the varied parameters `short-name=value` joined by `,` (+ a hash when long or lossy)."""
    parts = [f"{k.split('.')[-1]}={_fmt(params[k])}" for k in varied]
    name = ",".join(parts) or "cell"
    digest = hashlib.sha1(json.dumps(params, sort_keys=True, default=str).encode()).hexdigest()[:8]
    if len(name) > 120:
        name = name[:110]
    return f"{name}-{digest}"


def _parse_range(spec: object, file: str, key: str) -> tuple[float, float, bool, bool]:
    if not isinstance(spec, dict):
        raise ConfigError("must be a mapping {min, max[, log, int]}", file=file, key=key)
    unknown = set(spec) - {"min", "max", "log", "int"}
    if unknown:
        raise ConfigError(f"unknown key '{sorted(unknown)[0]}'; allowed: min, max, log, int", file=file, key=key)
    try:
        lo, hi = float(spec["min"]), float(spec["max"])
    except (KeyError, TypeError, ValueError):
        raise ConfigError("needs numeric 'min' and 'max'", file=file, key=key) from None
    log, integer = bool(spec.get("log", False)), bool(spec.get("int", False))
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ConfigError(f"min ({lo:g}) must be <= max ({hi:g})", file=file, key=key)
    if log and lo <= 0:
        raise ConfigError(f"a log range needs min > 0, got {lo:g}", file=file, key=key)
    return lo, hi, log, integer


def load_design(path: str | Path, allow_large: bool = False) -> Design:
    """Parse and validate a sweep file; errors name the file and key. More than MAX_CELLS cells need
    `allow_large` (the CLI's --yes)."""
    file = str(path)
    data = load_yaml(path)
    unknown = set(data) - {"base", "grid", "random", "name", "description"}
    if unknown:
        raise ConfigError(f"unknown key '{sorted(unknown)[0]}'; allowed: base, grid, random, name, description",
                          file=file, key=sorted(unknown)[0])
    base = data.get("base") or {}
    grid = data.get("grid") or {}
    rnd = data.get("random") or {}
    for sec, val in (("base", base), ("grid", grid), ("random", rnd)):
        if not isinstance(val, dict):
            raise ConfigError("must be a mapping", file=file, key=sec)
    for k in base:
        _check_name(k, file, f"base.{k}")
    for k, vals in grid.items():
        _check_name(k, file, f"grid.{k}")
        if not isinstance(vals, list) or not vals:
            raise ConfigError("must be a non-empty list of values", file=file, key=f"grid.{k}")
    ranges = {}
    n_random, rseed = 0, 0
    if rnd:
        unknown = set(rnd) - {"n", "seed", "params"}
        if unknown:
            raise ConfigError(f"unknown key '{sorted(unknown)[0]}'; allowed: n, seed, params", file=file,
                              key=f"random.{sorted(unknown)[0]}")
        n_random, rseed = rnd.get("n"), rnd.get("seed", 0)
        if not isinstance(n_random, int) or isinstance(n_random, bool) or n_random < 1:
            raise ConfigError(f"must be an integer >= 1, got {n_random!r}", file=file, key="random.n")
        if not isinstance(rseed, int):
            raise ConfigError(f"must be an integer, got {rseed!r}", file=file, key="random.seed")
        params = rnd.get("params") or {}
        if not isinstance(params, dict) or not params:
            raise ConfigError("must map at least one parameter to {min, max}", file=file, key="random.params")
        for k, spec in params.items():
            _check_name(k, file, f"random.params.{k}")
            if k in grid:
                raise ConfigError("is both in grid and random", file=file, key=f"random.params.{k}")
            ranges[k] = _parse_range(spec, file, f"random.params.{k}")
    if not grid and not ranges:
        raise ConfigError("empty design: give a non-empty 'grid' and/or 'random'", file=file, key="grid")
    n_grid = math.prod(len(v) for v in grid.values())
    total = n_grid * (n_random if ranges else 1)
    if total > MAX_CELLS and not allow_large:
        raise ConfigError(f"the design has {total} cells (> {MAX_CELLS}); pass --yes to run it", file=file)
    here = Path(file).resolve().parent
    for sec in (base, grid):   # task-set, scenario, preset files relative to the sweep file (workers' cwd may differ)
        for k in ("taskset", "scenario", "realism"):
            if k in sec:
                fix = [str(here / v) if isinstance(v, str) and v.endswith((".yaml", ".yml"))
                       and not Path(v).is_absolute() else v for v in (sec[k] if sec is grid else [sec[k]])]
                sec[k] = fix if sec is grid else fix[0]
    varied = tuple(grid) + tuple(ranges)
    rng = np.random.default_rng(rseed)
    samples = []
    for _ in range(n_random if ranges else 1):
        s = {}
        for k, (lo, hi, log, integer) in ranges.items():
            u = rng.uniform(math.log(lo), math.log(hi)) if log else rng.uniform(lo, hi)
            x = math.exp(u) if log else u
            s[k] = int(round(x)) if integer else float(x)
        samples.append(s)
    cells = []
    seen = set()
    for combo in itertools.product(*grid.values()):
        for s in samples:
            params = {**base, **dict(zip(grid, combo)), **s}
            params.setdefault("robot", "talos")
            for need in ("scenario", "controller"):
                if need not in params:
                    raise ConfigError(f"'{need}' must be given in base or grid", file=file, key=f"base.{need}")
            cid = cell_id(params, varied)
            if cid in seen:
                raise ConfigError(f"two cells have the same parameters ({cid})", file=file, key="grid")
            seen.add(cid)
            cells.append(Cell(cid, params))
    return Design(file, base, grid, dict(rnd), tuple(cells), varied)
