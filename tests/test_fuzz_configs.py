"""Fuzzing of every YAML loader (scenario, task set, robot profile, sensor profile) and of raw YAML text: tens of
thousands of generated inputs, mutations of the shipped files. Each must load or fail with a WbcError (one line
at the command line), never another exception. The budget is bounded: derandomized draws, fixed counts."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbcbench.config import load_yaml
from wbcbench.controllers.taskset import TASKSET_DIR, load_taskset
from wbcbench.errors import WbcError
from wbcbench.robots.profile import load_profile
from wbcbench.scenarios import load_scenario
from wbcbench.scenarios.base import SCENARIO_DIR
from wbcbench.sensing import load_sensor_profile
from wbcbench.sensing.profile import PROFILE_DIR as SENSOR_DIR

ROBOT_DIR = Path(load_profile.__code__.co_filename).parent / "profiles"


def fuzz_settings(n: int):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                           HealthCheck.data_too_large])


SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
                    st.sampled_from(["", "left", "right", "frame", "com", "flat", "stairs", "ideal", "daqp", "1e9",
                                     "-1", "base", "torso", "nan", "walk", "dcm", "force"]))
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=8), inner, max_size=3)),
                      max_leaves=6)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


@st.composite
def mutated(draw, base: dict):
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        key = path[-1]
        op = draw(st.sampled_from(["replace", "delete", "add", "wrap", "number"]))
        if op == "replace":
            parent[key] = draw(VALUES)
        elif op == "delete":
            del parent[key]
        elif op == "add" and isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=10))] = draw(VALUES)
        elif op == "wrap":
            parent[key] = [parent[key]]
        elif op == "number":
            parent[key] = draw(st.sampled_from([0, -1, -1e-9, 1e12, float("nan"), float("inf"), 0.5, 3, True]))
    return data


def _check(load, tmp_path: Path, data, name="f.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data, allow_unicode=True) if not isinstance(data, str) else data)
    try:
        load(p)
    except WbcError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg.strip(), msg
        assert "Traceback" not in msg


def _base(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


@pytest.mark.parametrize("name", ["walk-20cm", "platforms", "stairs", "sway", "one-foot", "push"])
def test_fuzz_scenarios(talos, tmp_path, name):
    base = _base(SCENARIO_DIR / f"{name}.yaml")

    @fuzz_settings(1500)
    @given(mutated(base))
    def run(data):
        _check(lambda p: load_scenario(str(p), talos), tmp_path, data, f"{name}.yaml")

    run()


@pytest.mark.parametrize("name", ["tsid-torque", "tsid-position", "ik", "teleop"])
def test_fuzz_tasksets(talos, tmp_path, name):
    base = _base(TASKSET_DIR / "talos" / f"{name}.yaml")

    @fuzz_settings(1500)
    @given(mutated(base))
    def run(data):
        _check(lambda p: load_taskset(p, talos, max_level=8 if name == "ik" else 1), tmp_path, data)

    run()


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_fuzz_robot_profiles(tmp_path, name):
    base = _base(ROBOT_DIR / f"{name}.yaml")

    @fuzz_settings(800)
    @given(mutated(base))
    def run(data):
        _check(load_profile, tmp_path, data)

    run()


def test_fuzz_sensor_profiles(tmp_path):
    base = _base(SENSOR_DIR / "talos-like.yaml")

    @fuzz_settings(2000)
    @given(mutated(base))
    def run(data):
        _check(load_sensor_profile, tmp_path, data)

    run()


@fuzz_settings(3000)
@given(text=st.one_of(st.text(max_size=200),
                      st.binary(max_size=120).map(lambda b: b.decode("latin-1")),
                      st.sampled_from(["a: [", "{", "- - -", "key: !!python/object:os.system {}", "x: *a",
                                       "\t- 1", "? [a]\n: 1", "%YAML 9.9\n---\n1"])))
def test_fuzz_raw_yaml_text(tmp_path_factory, text):
    d = tmp_path_factory.mktemp("raw")
    _check(load_yaml, d, text)
