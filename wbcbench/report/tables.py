"""results.json: every number, ours beside the paper's, keyed by table, controller, scenario and metric.

A leaf is {"ours": value, "paper": value, "unit": ...}. Our value is a number, None (the run exists but the
metric is undefined or its inputs were not logged), "missing" (no such scenario or controller yet: nothing
run) or "error" (the run produced no usable log). When our run fell, `status` says so beside the value.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

from ..metrics.from_log import PAPER_MASS_KG, json_ready
from .paper import FAST_WALK_NOTE, PAPER_CITATION, PAPER_REFERENCE_ROWS, PAPER_TABLES, MetricSpec
from .runs import ERROR, MISSING, RunOutcome

MISSING_VALUE = "missing"
ERROR_VALUE = "error"


def dig(d: dict, path: str):
    """d["a"]["b"]["c"] for path "a.b.c"; None if any level is absent."""
    cur = d
    for part in path.split("."):
        if not isinstance(cur, dict) or part not in cur:
            return None
        cur = cur[part]
    return cur


def index_outcomes(outcomes: Iterable[RunOutcome]) -> dict[tuple[str, str], RunOutcome]:
    """(controller, scenario) -> outcome; a later outcome for the same cell replaces an earlier one."""
    return {(o.controller, o.scenario): o for o in outcomes}


def ours(outcome: RunOutcome | None, spec: MetricSpec):
    """Our value of a published metric, in the paper's unit, or the reason there is none."""
    if outcome is None or outcome.status == MISSING:
        return MISSING_VALUE
    if outcome.status == ERROR or not outcome.metrics:
        return ERROR_VALUE
    v = dig(outcome.metrics, spec.ours_path)
    return None if not isinstance(v, (int, float)) else v * spec.scale


def table_results(table_id: str, cells: dict[tuple[str, str], RunOutcome]) -> dict:
    """One published table with our numbers: values[controller][scenario][metric] = {ours, paper, unit}."""
    t = PAPER_TABLES[table_id]
    values: dict = {}
    paper_cells = t.cells()
    table_scenarios = {s for _, s in paper_cells}
    paper_controllers = {c for c, _ in paper_cells}
    extra = sorted((c, s) for c, s in cells if c not in paper_controllers and s in table_scenarios)
    for controller, scenario in paper_cells + extra:
        o = cells.get((controller, scenario))
        row = {"status": o.status if o else MISSING_VALUE}
        published = t.values.get(controller, {}).get(scenario, {})
        for spec in t.metrics:
            row[spec.key] = {"ours": ours(o, spec), "paper": published.get(spec.key), "unit": spec.unit}
        if table_id == "table6":  # the model-mass costs of transport, ours only
            for key in ("C_et", "C_mt"):
                row[f"{key}_robot_mass"] = {"ours": ours(o, MetricSpec(key, key, "J/kg/m")), "paper": None,
                                            "unit": "J/kg/m"}
            if o is not None and o.metrics and "E_el" in o.metrics:   # a realism preset with a motor model
                for key, unit in (("E_el", "J"), ("C_el_paper_mass", "J/kg/m")):
                    row[key] = {"ours": ours(o, MetricSpec(key, key, unit)), "paper": None, "unit": unit}
        values.setdefault(controller, {})[scenario] = row
    return {"number": t.number, "title": t.title, "notes": t.notes, "values": values,
            "paper_reference_rows": PAPER_REFERENCE_ROWS.get(table_id, {})}


def build_results(outcomes: list[RunOutcome], *, command: str, quick: bool | None = None,
                  jobs: int | None = None, wall_time_s: float | None = None,
                  errors: list[str] | None = None, robot=None) -> dict:
    """The whole results.json content (JSON-ready: NaN already replaced by None). `robot`: a `Robot` other than
    TALOS, whose report has no published numbers (every "paper" value None or "n/a", printed n/a) and states the
    sizes its profile gives the scenarios (results["robot"])."""
    sensed = [o for o in outcomes if o.section == "sensing"]
    outcomes = [o for o in outcomes if o.section != "sensing"]
    cells = index_outcomes(outcomes)
    results = {
        "paper": PAPER_CITATION,
        "note": ("'paper' values are the published numbers of paper 000 (Tables 2-8); 'ours' are computed by "
                 "wbcbench from our MuJoCo runs. Costs of transport compared with the paper use m = "
                 f"{PAPER_MASS_KG:g} kg (see Table 6 notes)."),
        "generated_at": time.strftime("%Y-%m-%d %H:%M:%S"),
        "command": command,
        "quick": quick,
        "jobs": jobs,
        "wall_time_s": wall_time_s,
        "runs": [o.brief() for o in outcomes + sensed],
        "errors": list(errors or []),
        "tables": {tid: table_results(tid, cells) for tid in PAPER_TABLES},
        "fast_walk": {
            "note": FAST_WALK_NOTE,
            "values": {o.controller: {"status": o.status, "reason": o.reason,
                                      "zmp_error_m": dig(o.metrics, "zmp_error_m"),
                                      "paper": "reported as working (no numbers)"}
                       for o in outcomes if o.section == "fast"},
        },
        "sanity": {},
        "metrics": {},
    }
    for o in outcomes:
        if o.section == "sanity":
            results["sanity"].setdefault(o.controller, {})[o.scenario] = {
                "status": o.status, "reason": o.reason, "scenario_metrics": (o.summary or {}).get("metrics"),
                "metrics": o.metrics or None}
        if o.metrics:
            results["metrics"].setdefault(o.controller, {})[o.scenario] = o.metrics
    if robot is not None:
        _robot_only(results, robot)
    if sensed:
        results["sensing"] = sensing_results(sensed, cells)
    teleop = {o.scenario_run or o.scenario: {"controller": o.controller, "status": o.status, **o.metrics["teleop"]}
              for o in outcomes if o.metrics and o.metrics.get("teleop")}
    if teleop:
        results["teleop"] = teleop
    from .verdict import verdict

    results["verdict"] = verdict(json_ready(results))
    return json_ready(results)


def _robot_only(results: dict, robot) -> None:
    """Our numbers only for a robot other than the paper's: the published values out, the robot and the scenario
    sizes of its profile in."""
    for t in results["tables"].values():
        t["paper_reference_rows"] = {}
        for row in (r for per_c in t["values"].values() for r in per_c.values()):
            for leaf in row.values():
                if isinstance(leaf, dict) and "paper" in leaf:
                    leaf["paper"] = None
    for v in results["fast_walk"]["values"].values():
        v["paper"] = "n/a"
    results["note"] = (f"Robot: {robot.name}. The published numbers are TALOS' (paper 000): every 'paper' value is "
                       f"n/a here; 'ours' are computed by wbcbench from our MuJoCo runs of {robot.name}.")
    results["robot"] = {"name": robot.name, "description": robot.profile.description,
                        "scenario_sizes": robot.profile.scenario_overrides}


SENSING_METRICS = (("zmp x mean [m]", "zmp_error_m.x.mean"), ("zmp y mean [m]", "zmp_error_m.y.mean"),
                   ("zmp x peak [m]", "zmp_error_m.x.peak"), ("com x mean [m]", "com_error_m.x.mean"),
                   ("E_m [J]", "E_m"))


def sensing_results(sensed: list[RunOutcome], ideal: dict[tuple[str, str], RunOutcome]) -> dict:
    """The sensing section: per controller and scenario, survived or not, and a few metrics under the sensor
    profile beside the ideal run's."""
    values: dict = {}
    for o in sensed:
        ref = ideal.get((o.controller, o.scenario))
        summary = o.summary or {}
        values.setdefault(o.controller, {})[o.scenario] = {
            "status": o.status, "reason": o.reason, "ideal_status": ref.status if ref else None,
            "base_estimate_error": dig(summary, "metrics.base_estimate_error"),
            "metrics": {label: {"sensed": dig(o.metrics or {}, path),
                                "ideal": dig(ref.metrics or {}, path) if ref else None}
                        for label, path in SENSING_METRICS}}
    profile = next((dig(o.summary or {}, "sensors.profile") for o in sensed if o.summary), None) or "the profile"
    return {"profile": profile, "values": values,
            "note": "The paper's scenarios with the sensor profile between the simulator and the controller (noise, "
                    "bias, drift, delay, dropped samples, base estimated from IMU and leg kinematics), beside "
                    "the same runs with ideal sensing. Metrics from ground truth."}
