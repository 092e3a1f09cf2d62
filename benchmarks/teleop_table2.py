"""Paper 004 Table II on its 8 shipped recordings: hand position and rotation errors (mean, std, min, max) with the
repulsors off and on, self-collisions and falls, one `wbcbench teleop` run per recording (in parallel).

    .venv/bin/python benchmarks/teleop_table2.py                      # both conditions, speed 1, full length
    .venv/bin/python benchmarks/teleop_table2.py --anchor rest absolute --jobs 2   # the paper's overlay too
    .venv/bin/python benchmarks/teleop_table2.py --repulsors off --jobs 2 --out reports/teleop
    .venv/bin/python benchmarks/teleop_table2.py --speed 2 --stabilizer both   # Figure 2's condition on Table II's set
    .venv/bin/python benchmarks/teleop_table2.py --speed 2 --stabilizer both --repulsors on --recordings push_pull
                                                         # the Figure 2 experiment: falls without, stands with

Writes <out>/table2.md and <out>/table2.json; the run directories go to <out>/runs/.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

#: the 8 recordings of Table II (the shipped set may hold more, e.g. for the Figure 2 experiment)
TABLE2_RECORDINGS = ("reach_forward", "reach_sideways", "waving", "crossing_arms", "arms_down", "head_turning",
                     "bimanual_lift", "slow_circle")
PAPER = {"position": (0.034, 0.016, 1e-5, 0.099), "rotation": (0.025, 0.021, 1.4e-6, 0.134)}


def one(job: dict) -> dict:
    from wbcbench.teleop.commands import run_session

    t0 = time.perf_counter()
    result = run_session(job["recording"], speed=job["speed"], repulsors=job["repulsors"],
                         stabilizer=job["stabilizer"], mode=job["mode"], duration=job["duration"],
                         out=job["out"], quiet=True, anchor=job["anchor"], engine=job.get("engine", "mujoco"))
    s = result.summary
    m = s.get("metrics", {})
    log = result.log
    com = (np.hypot(log["com.x"] - log["com.x"][0], log["com.y"] - log["com.y"][0]) if log else np.zeros(1))
    return {**job, "com_excursion_max": float(com.max()), "com_excursion_mean": float(com.mean()), "fell": s["fell"], "fall_reason": s["fall_reason"], "sim_time_s": s["sim_time_s"],
            "wall_s": time.perf_counter() - t0, "position": m.get("hand_position_error_m"),
            "rotation": m.get("hand_rotation_error"),
            "position_outside": m.get("hand_position_error_outside_body_m"),
            "rotation_outside": m.get("hand_rotation_error_outside_body"),
            "inside_fraction": m.get("hand_reference_inside_body_fraction"), "self_collisions": m.get("self_collisions"),
            "self_collision_ticks": m.get("self_collision_ticks"), "self_collision_pairs": m.get("self_collision_pairs"),
            "run_dir": str(result.run_dir), "pos_samples": _samples(result.run_dir),
            "step_median_us": s["step_time_us"]["median"]}


def _samples(run_dir) -> str:
    return str(Path(run_dir) / "hand_errors.npz")


def pooled(rows: list[dict], key: str, outside_only: bool = False) -> dict:
    """Mean, std, min, max over all ticks of all runs (the per-tick errors saved by the runs); `outside_only`:
    the ticks whose reference lies outside the robot's body."""
    arrays = []
    for r in rows:
        p = Path(r["run_dir"]) / "hand_errors.npz"
        if p.exists():
            z = np.load(p)
            x = z[key]
            arrays.append((x[~z["reference_inside_body"]] if outside_only else x).ravel())
    if not arrays:
        return {}
    x = np.concatenate(arrays)
    return {"mean": float(x.mean()), "std": float(x.std()), "min": float(x.min()), "max": float(x.max())}


def fmt(d: dict | None) -> str:
    if not d or d.get("mean") is None:
        return "-"
    return f"{d['mean']:.4f} / {d['std']:.4f} / {d['min']:.1e} / {d['max']:.4f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repulsors", choices=["on", "off", "both"], default="both")
    ap.add_argument("--stabilizer", choices=["on", "off", "both"], default="off")
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--mode", default="spd")
    ap.add_argument("--engine", default="mujoco", help="physics engine (mujoco, dart: paper 004's own)")
    ap.add_argument("--anchor", nargs="+", choices=["absolute", "offset", "rest"], default=["rest"],
                    help="one table per anchor (default rest; absolute is the paper's plain overlay)")
    ap.add_argument("--duration", type=float, default=None, help="cut every replay to this many seconds")
    ap.add_argument("--recordings", nargs="*", default=None)
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--out", default="reports/teleop")
    args = ap.parse_args(argv)
    names = args.recordings or list(TABLE2_RECORDINGS)
    out = Path(args.out)
    conds = []
    for anchor in args.anchor:
        for rep in ([False, True] if args.repulsors == "both" else [args.repulsors == "on"]):
            for stab in ([False, True] if args.stabilizer == "both" else [args.stabilizer == "on"]):
                conds.append((anchor, rep, stab))
    jobs = [{"recording": n, "speed": args.speed, "repulsors": rep, "stabilizer": stab, "mode": args.mode,
             "duration": args.duration, "anchor": anchor, "engine": args.engine,
             "out": str(out / "runs" / (f"{n}-{anchor}-x{args.speed:g}-rep_{'on' if rep else 'off'}"
                                        f"-stab_{'on' if stab else 'off'}"))}
            for anchor, rep, stab in conds for n in names]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    lines = [f"# Paper 004 Table II on the shipped recordings (speed {args.speed:g}, mode {args.mode}, engine "
             f"{args.engine})", "",
             "Hand position error [m] and rotation error ||I - R_ref R^-1||_F, mean / std / min / max over both "
             "hands and every control tick; then over the ticks whose reference lies outside the robot's body "
             "(gripper centre farther than r_rep + r_frame from every repulsion point). CoM excursion: horizontal distance "
             "of the CoM from its start (paper Figure 2).", ""]
    for anchor, rep, stab in conds:
        sel = [r for r in rows if r["repulsors"] == rep and r["stabilizer"] == stab and r["anchor"] == anchor]
        steps = [r["step_median_us"] for r in sel if r.get("step_median_us")]
        lines += [f"## anchor {anchor}, repulsors {'on' if rep else 'off'}, stabilizer {'on' if stab else 'off'}"
                  f" (controller step median of the runs' medians {np.median(steps):.0f} us)", "",
                  "| recording | position [m], all ticks | rotation, all ticks | reference inside the body | "
                  "position [m], reference outside the body | rotation, outside | self-collisions (events / ticks) "
                  "| CoM excursion max / mean [m] | fell |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in sel:
            frac = r.get("inside_fraction")
            lines.append(f"| {r['recording']} | {fmt(r['position'])} | {fmt(r['rotation'])} | "
                         f"{'-' if frac is None else f'{100 * frac:.0f} %'} | {fmt(r.get('position_outside'))} | "
                         f"{fmt(r.get('rotation_outside'))} | "
                         f"{r['self_collisions']} / {r['self_collision_ticks']} | "
                         f"{r['com_excursion_max']:.4f} / {r['com_excursion_mean']:.4f} | "
                         f"{'yes: ' + str(r['fall_reason']) if r['fell'] else 'no'} |")
        fr = [r["inside_fraction"] for r in sel if r.get("inside_fraction") is not None]
        lines.append(f"| **all (pooled)** | {fmt(pooled(sel, 'position'))} | {fmt(pooled(sel, 'rotation'))} | "
                     f"{100 * np.mean(fr):.0f} % | {fmt(pooled(sel, 'position', True))} | "
                     f"{fmt(pooled(sel, 'rotation', True))} | "
                     f"{sum(r['self_collisions'] or 0 for r in sel)} | "
                     f"{max(r['com_excursion_max'] for r in sel):.4f} / "
                     f"{np.mean([r['com_excursion_mean'] for r in sel]):.4f} | {sum(r['fell'] for r in sel)} fell |")
        lines.append(f"| paper Table II (repulsors off) | {PAPER['position'][0]} / {PAPER['position'][1]} / "
                     f"{PAPER['position'][2]:.0e} / {PAPER['position'][3]} | {PAPER['rotation'][0]} / "
                     f"{PAPER['rotation'][1]} / {PAPER['rotation'][2]:.1e} / {PAPER['rotation'][3]} | | | | | | |")
        lines.append("")
    lines.append(f"wall time {time.perf_counter() - t0:.0f} s with {args.jobs} processes")
    out.mkdir(parents=True, exist_ok=True)
    (out / "table2.md").write_text("\n".join(lines) + "\n")
    (out / "table2.json").write_text(json.dumps(rows, indent=2, default=str))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
