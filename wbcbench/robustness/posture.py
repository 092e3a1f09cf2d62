"""Paper 000 Section 7.3.2 (Tables 9-10): the posture gains that broke the real TALOS, on the simulated one.

On the real robot, TSID torque with the Table 9 task set (the feet's contacts, a posture task about half-sitting)
diverged after a few sinusoidal arm motions with the "Fail" posture gains (legs and arms 800, torso 1000, head 100)
and broke two harmonic drives; the "Success" gains (50, 100, 50, 10) were stable and compliant. The simulation used
to tune them had not shown it. This study runs the `posture-sinusoid` scenario (`wbcbench.scenarios.kinds`) with
both gain sets on the ideal robot and on a realistic one (`--realism`, `wbcbench.sim.realism`), and answers:

- outcome: does each gain set hold (no fall, no joint further than the scenario's `divergence_error` from its
  reference, no velocity or position limit reached), on which robot; and its chatter (the largest joint's RMS
  velocity error after the ramp);
- mechanism (`ablation`): the Fail gains on the realistic robot with one mechanism of the preset removed at a time
  (actuators: friction and drive elasticity; the torque loop; the hip flexibility; the sensors), and with one alone:
  what it takes for the divergence to appear;
- the CoM task (`com_task`): on the robot, adding one to the Success set diverged, which the paper blames on
  calibration and identification errors; here the Success gains with a CoM task
  (`tsid-torque-posture-com.yaml`) on both robots, without error, with the model's masses and CoMs wrong
  (`wbcbench.sim.model_error`) and with the encoders' zeros wrong (the sensor profile's `encoders.offset`);
- the largest safe gain per body part (legs, torso, arms, head): the others at their Success values, a bisection
  in log scale between the Success gain (must hold) and the Fail gain, `iterations` steps (resolution
  (Fail / Success) ** (1 / 2 ** iterations)), and the joint at which the first failing gain diverged;
- the unpublished values (`ranges`): the preset's values that no TALOS publication gives (drive stiffness and
  friction, the torque loop's bandwidth, delay and sensor noise, the hip spring's damping; `RANGES`, the ranges its
  file names) one at a time at the ends of their ranges, the others at the preset's: whether the Success gains
  still hold and the Fail gains still fail, i.e. whether the conclusion depends on a value nobody measured.

Every trial is a normal run directory under OUT/runs/; the task sets it wrote are under OUT/tasksets/ and the
derived presets under OUT/presets/. `write_report` gives OUT/posture-gains.md and .json.
"""

from __future__ import annotations

import json
import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..errors import ConfigError, WbcError

#: body parts of the Table 10 gains: the joint-name prefixes of the posture task's `kp` mapping (TALOS)
PARTS: dict[str, tuple[str, ...]] = {"legs": ("leg_",), "torso": ("torso_",), "arms": ("arm_", "gripper_"),
                                     "head": ("head_",)}
#: paper 000 Table 10, posture Kp (the paper's numbers, the inputs of the experiment)
SUCCESS = {"legs": 50.0, "torso": 100.0, "arms": 50.0, "head": 10.0}
FAIL = {"legs": 800.0, "torso": 1000.0, "arms": 800.0, "head": 100.0}
#: the preset sections an ablation removes, in the report's order
MECHANISMS = ("actuators", "torque_loop", "hip_flexibility", "sensors")
#: the errors the CoM task meets: label -> (model error settings, encoder calibration offset std [rad])
COM_ERRORS = {"none": (None, 0.0),
              "masses 10 %, CoMs 1 cm": ({"mass_error": 0.1, "com_offset": 0.01}, 0.0),
              "masses 30 %, CoMs 3 cm": ({"mass_error": 0.3, "com_offset": 0.03}, 0.0),
              "encoder zeros 0.02 rad": (None, 0.02)}


#: the preset's unpublished values and the ends of the ranges its file gives (talos-real.yaml): label -> (the
#: sections and keys to set, the values); an actuator key applies to the listed joint patterns
RANGES: dict[str, tuple[tuple, tuple[float, ...]]] = {
    "leg and torso drive stiffness [N m/rad]": ((("actuators", ("leg_*", "torso_*"), "stiffness"),), (1e4, 1e5)),
    "arm drive stiffness [N m/rad]": ((("actuators", ("arm_*",), "stiffness"),), (3e3, 3e4)),
    "leg and torso Coulomb friction [N m]": ((("actuators", ("leg_*", "torso_*"), "coulomb"),), (0.0, 5.0)),
    "leg and torso viscous friction [N m s/rad]": ((("actuators", ("leg_*", "torso_*"), "viscous"),), (0.0, 5.0)),
    "arm Coulomb friction [N m]": ((("actuators", ("arm_*",), "coulomb"),), (0.0, 2.0)),
    "torque loop bandwidth [Hz]": ((("torque_loop", None, "bandwidth"),), (20.0, 200.0)),
    "torque loop delay, s": ((("torque_loop", None, "delay"),), (0.0, 0.005)),
    "torque sensor noise [N m]": ((("torque_loop", None, "sensor_noise"),), (0.0, 1.0)),
    "hip spring damping [N m s/rad]": ((("hip_flexibility", None, "damping"),), (0.0, 50.0)),
}


@dataclass(frozen=True)
class PostureStudy:
    """What to run. `realism`: the realistic robot (a preset name or file); `iterations`: bisection steps per part
    (0: no bisection); `ablation`: the mechanism table; `com_task`: the Success gains with a CoM task under
    identification and calibration errors (`COM_ERRORS`); `ranges`: the unpublished values at the ends of their
    ranges (`RANGES`)."""

    realism: str = "talos-actuation"
    robot: str = "talos"
    controller: str = "tsid-torque"
    scenario: str = "posture-sinusoid"
    duration: float | None = None
    iterations: int = 4
    ablation: bool = True
    parts: tuple[str, ...] = tuple(PARTS)
    com_task: bool = True
    ranges: bool = False


@dataclass
class Trial:
    label: str
    gains: dict
    realism: str | None
    held: bool = False
    fell: bool = False
    reason: str = ""
    divergence_joint: str | None = None
    divergence_time_s: float | None = None
    posture_max_error_rad: float = math.nan
    chatter_rad_s: float = math.nan
    chatter_joint: str | None = None
    run_dir: str = ""


@dataclass
class PartLimit:
    """The largest gain found to hold for one body part (None: not even the Success gain holds) and the smallest
    found to fail (None: the Fail gain holds), with the joint where that failure started."""

    part: str
    safe: float | None
    unsafe: float | None
    joint: str | None
    trials: list = field(default_factory=list)


def _taskset(study: PostureStudy) -> Path:
    from ..controllers.taskset import taskset_variant_path
    from ..robots import load_robot

    path = taskset_variant_path(load_robot(study.robot), study.controller, "posture")
    if path is None:
        raise ConfigError(f"no Table 9 task set {study.controller}-posture.yaml for robot {study.robot}",
                          key="--robot")
    return path


def validate(study: PostureStudy) -> None:
    """Every input checked before anything runs (one-line errors)."""
    from ..robots import load_robot
    from ..sim.realism import load_realism

    _taskset(study)
    load_realism(study.realism, load_robot(study.robot))
    bad = [p for p in study.parts if p not in PARTS]
    if bad:
        raise ConfigError(f"unknown body part(s) {', '.join(bad)}; allowed: {', '.join(PARTS)}", key="--parts")
    if study.iterations < 0:
        raise ConfigError(f"must be >= 0, got {study.iterations}", key="--iterations")
    if study.duration is not None and not study.duration > 0:
        raise ConfigError(f"must be > 0, got {study.duration}", key="--duration")


def _write_taskset(study: PostureStudy, gains: dict, out: Path, label: str) -> Path:
    """The Table 9 task set with these posture gains (per part), written under OUT/tasksets/."""
    import yaml

    from ..config import load_yaml

    data = load_yaml(_taskset(study))
    posture = [t for t in data.get("tasks", []) if t.get("type") == "posture"]
    if len(posture) != 1:
        raise WbcError(f"{_taskset(study)}: expected one posture task, found {len(posture)}")
    posture[0]["kp"] = {prefix: float(gains[part]) for part, prefixes in PARTS.items() for prefix in prefixes}
    path = out / "tasksets" / f"{label}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"# {study.controller} posture task set with gains {gains} (wbcbench.robustness.posture)\n"
                    + yaml.safe_dump(data, sort_keys=False))
    return path


def _ablated_presets(study: PostureStudy, out: Path) -> dict[str, str]:
    """Presets derived from the study's (files under OUT/presets/ that extend it): `without <mechanism>` and
    `<mechanism> only` for the mechanisms the preset has, and `rigid <part> drives` (the drive elasticity of one
    body part removed, its friction kept) to find whose elasticity matters."""
    import yaml

    from ..sim.realism import PRESET_DIR, preset_names, resolved_preset

    name = str(study.realism)
    base = (PRESET_DIR / f"{name}.yaml") if name in preset_names() else Path(name).resolve()
    full = resolved_preset(base)
    has = [m for m in MECHANISMS if m in full and not (m == "sensors" and full[m] == "ideal")]
    removed = {m: ("ideal" if m == "sensors" else None) for m in has}
    variants = {}
    for m in has:
        variants[f"without {m}"] = {m: removed[m]}
        if len(has) > 1:
            variants[f"{m} only"] = {k: v for k, v in removed.items() if k != m}
    act = full.get("actuators")
    if isinstance(act, dict):
        for part, prefixes in PARTS.items():
            keys = [k for k in act if str(k).startswith(prefixes)]
            if any(isinstance(act[k], dict) and act[k].get("stiffness", 0) for k in keys):
                rigid = {k: ({**v, "stiffness": 0.0, "damping": 0.0} if k in keys and isinstance(v, dict) else v)
                         for k, v in act.items()}
                variants[f"rigid {part} drives"] = {"actuators": rigid}
    (out / "presets").mkdir(parents=True, exist_ok=True)
    presets = {}
    for kind, body in variants.items():
        path = out / "presets" / f"{kind.replace(' ', '-')}.yaml"
        path.write_text(yaml.safe_dump({"extends": str(base), **body}, sort_keys=False))
        presets[kind] = str(path)
    return presets


def _range_presets(study: PostureStudy, out: Path) -> list[tuple[str, float, str]]:
    """(parameter, value, preset file) for each end of each unpublished range (`RANGES`) the study's preset has:
    files under OUT/presets/ that extend it with the one value changed."""
    import yaml

    from ..sim.realism import PRESET_DIR, preset_names, resolved_preset

    name = str(study.realism)
    base = (PRESET_DIR / f"{name}.yaml") if name in preset_names() else Path(name).resolve()
    full = resolved_preset(base)
    (out / "presets").mkdir(parents=True, exist_ok=True)
    rows = []
    for k, (label, (targets, values)) in enumerate(RANGES.items()):
        if any(not isinstance(full.get(section), dict) for section, _, _ in targets):
            continue  # the preset has no such mechanism
        for value in values:
            body = {}
            for section, patterns, key in targets:
                sec = dict(body.get(section) or full[section])
                if patterns is None:
                    sec[key] = value
                else:
                    for pat in patterns:
                        if isinstance(sec.get(pat), dict):
                            sec[pat] = {**sec[pat], key: value}
                body[section] = sec
            path = out / "presets" / f"range-{k}-{value:g}.yaml"
            path.write_text(yaml.safe_dump({"extends": str(base), **body}, sort_keys=False))
            rows.append((label, value, str(path)))
    return rows


def _nominal(study: PostureStudy, label: str):
    """The study preset's value of an unpublished parameter (`RANGES`), None if it has none."""
    from ..sim.realism import PRESET_DIR, preset_names, resolved_preset

    name = str(study.realism)
    full = resolved_preset((PRESET_DIR / f"{name}.yaml") if name in preset_names() else Path(name).resolve())
    section, patterns, key = RANGES[label][0][0]
    sec = full.get(section)
    if not isinstance(sec, dict):
        return None
    return sec.get(key) if patterns is None else (sec.get(patterns[0]) or {}).get(key)


def _trial(study: PostureStudy, label: str, gains: dict | None, realism: str | None, out: Path,
           error: str = "none") -> Trial:
    """One run: the Table 9 task set with `gains` (None: the Success set with the CoM task, `error` one of
    `COM_ERRORS`)."""
    from ..runner import run

    model_error, sensors = None, None
    if gains is None:
        from ..controllers.taskset import taskset_variant_path
        from ..robots import load_robot

        taskset = taskset_variant_path(load_robot(study.robot), study.controller, "posture-com")
        model_error, sensors = _com_error(study, error, realism)
    else:
        taskset = _write_taskset(study, gains, out, label)
    run_dir = out / "runs" / label
    res = run(study.scenario, study.controller, robot=study.robot, duration=study.duration, out=run_dir,
              taskset=taskset, realism=realism, overwrite=True, model_error=model_error, sensors=sensors)
    gains = gains or dict(SUCCESS)
    s, m = res.summary, res.summary.get("metrics", {})
    trial = Trial(label, dict(gains), realism, fell=bool(s["fell"]), run_dir=str(run_dir),
                  divergence_joint=m.get("divergence_joint"), divergence_time_s=m.get("divergence_time_s"),
                  posture_max_error_rad=float(m.get("posture_max_error_rad", math.nan)),
                  chatter_rad_s=float(m.get("chatter_rad_s", math.nan)), chatter_joint=m.get("chatter_joint"))
    trial.held = not trial.fell and not m.get("diverged", True)
    if trial.fell:
        trial.reason = f"fell at {s['sim_time_s']:.2f} s: {s['fall_reason']}"
    elif not trial.held:
        trial.reason = f"diverged at {trial.divergence_time_s:.2f} s ({trial.divergence_joint})"
    else:
        trial.reason = "held"
    return trial


def _job(args) -> Trial:
    return _trial(*args)


def _com_error(study: PostureStudy, error: str, realism: str | None):
    """(model error, sensor profile or None) of one `COM_ERRORS` entry on a robot (the realistic one's sensors,
    with the calibration offset added)."""
    from dataclasses import replace

    from ..robots import load_robot
    from ..sensing import load_sensor_profile
    from ..sensing.profile import SensorProfile
    from ..sim.model_error import ModelError
    from ..sim.realism import load_realism

    settings, offset = COM_ERRORS[error]
    model_error = ModelError(**settings, seed=0) if settings else None
    if not offset:
        return model_error, None
    name = load_realism(realism, load_robot(study.robot)).sensors if realism is not None else None
    base = load_sensor_profile(name) if name else SensorProfile()
    return model_error, replace(base, name=f"{base.name}+encoder-offset", encoder_offset=offset)


def _bisect_part(study: PostureStudy, part: str, out: Path, success: dict) -> PartLimit:
    """Largest holding gain of one part, the others at Success (log-scale bisection); `success`: the trial of the
    Success gains on the same robot (the bisection's lower end, already run)."""
    lo, hi = SUCCESS[part], FAIL[part]
    if not success["held"]:
        return PartLimit(part, None, lo, success["divergence_joint"] or success["chatter_joint"], [])

    def gains(k: float) -> dict:
        return {**SUCCESS, part: k}

    trials = []

    def attempt(k: float) -> Trial:
        t = _trial(study, f"{part}-{k:g}", gains(k), study.realism, out)
        trials.append(t)
        return t

    top = attempt(hi)
    if top.held:
        return PartLimit(part, hi, None, None, trials)
    joint = top.divergence_joint
    for _ in range(study.iterations):
        mid = math.sqrt(lo * hi)
        t = attempt(mid)
        if t.held:
            lo = mid
        else:
            hi, joint = mid, t.divergence_joint
    return PartLimit(part, lo, hi, joint, trials)


def _part_job(args) -> PartLimit:
    return _bisect_part(*args)


def scaled_gains(s: float) -> dict:
    """The gains a fraction `s` of the way from Success (0) to Fail (1), per part, in log scale."""
    return {p: SUCCESS[p] * (FAIL[p] / SUCCESS[p]) ** s for p in PARTS}


def _bisect_together(study: PostureStudy, out: Path, success_held: bool, fail_held: bool) -> dict:
    """All parts scaled together from Success towards Fail (`scaled_gains`): the largest fraction that holds."""
    if fail_held:
        return {"safe": 1.0, "unsafe": None, "joint": None, "trials": []}
    if not success_held:
        return {"safe": None, "unsafe": 0.0, "joint": None, "trials": []}
    lo, hi, joint, trials = 0.0, 1.0, None, []
    for _ in range(study.iterations):
        mid = 0.5 * (lo + hi)
        t = _trial(study, f"together-{mid:.4f}", scaled_gains(mid), study.realism, out)
        trials.append(asdict(t))
        if t.held:
            lo = mid
        else:
            hi, joint = mid, t.divergence_joint
    return {"safe": lo, "unsafe": hi, "joint": joint, "trials": trials,
            "safe_gains": scaled_gains(lo), "unsafe_gains": scaled_gains(hi)}


def _together_job(args) -> dict:
    return _bisect_together(*args)


def run_study(study: PostureStudy, out_dir: str | Path, jobs: int | None = None) -> dict:
    """All the study's runs (on `jobs` processes); the results as a mapping (also OUT/posture-gains.json)."""
    validate(study)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = max(1, jobs or os.cpu_count() or 1)
    label = Path(str(study.realism)).stem
    table = [(f"{g}-{r_label}", gains, realism) for r_label, realism in (("ideal", None), (label, study.realism))
             for g, gains in (("success", SUCCESS), ("fail", FAIL))]
    presets = _ablated_presets(study, out) if study.ablation else {}
    ablation = [(f"fail-{k.replace(' ', '-')}", FAIL, p) for k, p in presets.items()]
    range_rows = _range_presets(study, out) if study.ranges else []
    ranges = [(f"{g}-{Path(path).stem}", gains, path) for _, _, path in range_rows
              for g, gains in (("success", SUCCESS), ("fail", FAIL))]
    com = ([(f"com-{r_label}-error{k}", None, realism, out, e) for r_label, realism in (("ideal", None),
                                                                                       (label, study.realism))
            for k, e in enumerate(COM_ERRORS)] if study.com_task else [])
    singles = [(study, *row, out) for row in table + ablation + ranges] + [(study, *row) for row in com]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        trials = list(pool.map(_job, singles))
        together = None
        limits: list[PartLimit] = []
        if study.iterations > 0:
            # the Success and Fail gains on the realistic robot
            both = pool.submit(_together_job, (study, out, trials[2].held, trials[3].held))
            limits = list(pool.map(_part_job, [(study, p, out, asdict(trials[2])) for p in study.parts]))
            together = both.result()
    result = {"study": asdict(study), "realism_label": label,
              "table": [asdict(t) for t in trials[:len(table)]],
              "ablation": [{"variant": k, **asdict(t)} for k, t in zip(presets, trials[len(table):])],
              "ranges": [{"parameter": p, "value": v, "nominal": _nominal(study, p),
                          "success": asdict(trials[len(table) + len(ablation) + 2 * i]),
                          "fail": asdict(trials[len(table) + len(ablation) + 2 * i + 1])}
                         for i, (p, v, _) in enumerate(range_rows)],
              "com_task": [{"robot": label if row[2] else "ideal", "error": row[4], **asdict(t)}
                           for row, t in zip(com, trials[len(table) + len(ablation) + len(ranges):])],
              "limits": [{**asdict(p), "trials": [asdict(t) for t in p.trials]} for p in limits],
              "together": together}
    result = _finite(result)
    (out / "posture-gains.json").write_text(json.dumps(result, indent=2, allow_nan=False))
    return result


def _finite(x):
    """NaN (a metric a failed run did not give) as None, for strict JSON."""
    if isinstance(x, float):
        return None if math.isnan(x) else x
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x


def _fmt_trial(t: dict) -> str:
    chat = f"{t['chatter_rad_s']:.3f} rad/s ({t['chatter_joint']})" if t.get("chatter_joint") else "-"
    err = "-" if t.get("posture_max_error_rad") is None else f"{t['posture_max_error_rad']:.3f}"
    return f"{t['reason']} | {err} | {chat}"


def write_report(result: dict, out_dir: str | Path) -> Path:
    """OUT/posture-gains.md: the Tables 9-10 outcome ideal vs realistic, the mechanism ablation, the largest safe
    gains per part."""
    study, label = result["study"], result["realism_label"]
    lines = [f"# Paper 000 Tables 9-10 on the simulated TALOS: posture gains, ideal robot vs {label}", "",
             f"Scenario `{study['scenario']}` ({study['controller']}, the Table 9 task set), realistic robot "
             f"`{study['realism']}`. Paper 000 Table 10 posture Kp (the paper's, the inputs): Success "
             f"{SUCCESS}, Fail {FAIL}. On the real robot (the paper's result): the Fail gains diverged after a few "
             "arm motions and broke two harmonic drives (waist, right shoulder); the Success gains were stable.", "",
             "Held: no fall, no joint (link side) further than the scenario's divergence error from its reference, "
             "no velocity or position limit reached. Chatter: the largest joint RMS velocity error after the ramp.",
             "", "| gains | robot | outcome (ours) | max posture error [rad] | chatter |", "|---|---|---|---|---|"]
    for t in result["table"]:
        gains, robot = t["label"].split("-", 1)
        lines.append(f"| {gains} | {robot} | {_fmt_trial(t)} |")
    if result["ablation"]:
        lines += ["", f"## What it takes: the Fail gains on {label} with one mechanism removed, or alone, or one "
                  "part's drives made rigid", "",
                  "| variant | outcome | max posture error [rad] | chatter |", "|---|---|---|---|"]
        lines += [f"| {a['variant']} | {_fmt_trial(a)} |" for a in result["ablation"]]
    if result.get("ranges"):
        lines += ["", f"## The unpublished values at the ends of their ranges, on {label}", "",
                  "One value at a time (the preset's file gives each range; the others at the preset's values): "
                  "does the conclusion (Success holds, Fail fails) depend on a value no TALOS publication gives?", "",
                  "| parameter | preset's value | value | Success gains | Fail gains |", "|---|---|---|---|---|"]
        for r in result["ranges"]:
            lines.append(f"| {r['parameter']} | {r['nominal']:g} | {r['value']:g} | {r['success']['reason']} | "
                         f"{r['fail']['reason']} |" if r["nominal"] is not None else
                         f"| {r['parameter']} | - | {r['value']:g} | {r['success']['reason']} | "
                         f"{r['fail']['reason']} |")
    if result.get("com_task"):
        lines += ["", "## The Success gains with a CoM task, under identification and calibration errors", "",
                  "`tsid-torque-posture-com.yaml` (the Success posture task and a CoM task of weight 1000, Kp 20). On "
                  "the robot (the paper's result) this diverged; the paper blames calibration and identification.",
                  "", "| robot | error | outcome | max posture error [rad] | chatter |", "|---|---|---|---|---|"]
        lines += [f"| {c['robot']} | {c['error']} | {_fmt_trial(c)} |" for c in result["com_task"]]
    if result["limits"]:
        res = 2 ** study["iterations"]
        lines += ["", f"## Largest safe posture gain per body part on {label}", "",
                  f"The other parts at their Success gains; log-scale bisection between Success and Fail, "
                  f"{study['iterations']} steps (each limit within a factor (Fail/Success)^(1/{res})).", "",
                  "| part | Success (paper) | Fail (paper) | largest holding gain | smallest failing gain | "
                  "first diverging joint |", "|---|---|---|---|---|---|"]
        for p in result["limits"]:
            safe = "none (the Success gain fails)" if p["safe"] is None else f"{p['safe']:.0f}"
            unsafe = "none (the Fail gain holds)" if p["unsafe"] is None else f"{p['unsafe']:.0f}"
            lines.append(f"| {p['part']} | {SUCCESS[p['part']]:.0f} | {FAIL[p['part']]:.0f} | {safe} | {unsafe} | "
                         f"{p['joint'] or '-'} |")
    tog = result.get("together")
    if tog:
        lines += ["", f"## All parts together, from Success (0) to Fail (1) on {label}", "",
                  "Each part's gain at a fraction s of the way in log scale (Success * (Fail / Success)^s); "
                  f"bisection on s, {study['iterations']} steps.", ""]
        if tog["unsafe"] is None:
            lines.append("The Fail gains hold on this robot: nothing to bisect.")
        elif tog["safe"] is None:
            lines.append("The Success gains already fail on this robot: nothing holds on the way.")
        else:
            fmt = lambda g: ", ".join(f"{p} {g[p]:.0f}" for p in PARTS)  # noqa: E731
            lines.append(f"Largest holding s = {tog['safe']:.3f} ({fmt(tog['safe_gains'])}); smallest failing "
                         f"s = {tog['unsafe']:.3f} ({fmt(tog['unsafe_gains'])}); first diverging joint: "
                         f"{tog['joint'] or '-'}.")
    md = Path(out_dir) / "posture-gains.md"
    md.write_text("\n".join(lines) + "\n")
    return md
