"""Hand error against added latency and loss, with and without operator-pose prediction (issue 17 item 4).

Each run replays a shipped recording through the simulated impaired link (wbcbench/teleop/network.py: fixed
latency, Bernoulli loss, one seed, so every cell loses the same datagrams) into `tsid-teleop` (SPD, repulsors and
stabilizer on, the default `rest` anchor), and measures the hand position error against the operator's undelayed
reference (the recording's spline at the tick: what the robot should be doing now; `hand_position_error_true_m`)
and the reference's own lag behind it (`hand_reference_lag_m`). A run of the recording without the link (its
spline and feed-forward, the usual replay) is the floor.

    .venv/bin/python benchmarks/teleop_network.py                  # reach_forward 0.5-3.5 s (the right reach), 2 jobs
    .venv/bin/python benchmarks/teleop_network.py --recordings reach_forward waving --start 0 --duration 6
    .venv/bin/python benchmarks/teleop_network.py --latency 0 50 --loss 0 --predict none spline   # a corner

Writes <out>/network.md and <out>/network.json; the run directories go to <out>/runs/.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def one(job: dict) -> dict:
    done = Path(job["out"]) / "network_row.json"
    if job["resume"] and done.exists():
        return json.loads(done.read_text())
    row = _run(job)
    done.write_text(json.dumps(row, default=str))
    return row


def _run(job: dict) -> dict:
    from wbcbench.teleop.commands import run_session
    from wbcbench.teleop.network import NetworkImpairment

    t0 = time.perf_counter()
    params = {}
    if job["latency_ms"] is not None:
        params = {"network": NetworkImpairment(latency=job["latency_ms"] * 1e-3, loss=job["loss_pct"] / 100.0,
                                               seed=job["seed"]),
                  "predict": job["predict"]}
    result = run_session(job["recording"], duration=job["duration"], start=job["start"], out=job["out"], quiet=True,
                         overwrite=True, **params)
    s = result.summary
    m = s.get("metrics", {})
    true = m.get("hand_position_error_true_m") or m.get("hand_position_error_m")
    lag = m.get("hand_reference_lag_m") or {"mean": 0.0, "max": 0.0}
    pred = m.get("teleop", {}).get("prediction") or {}
    stream = m.get("teleop", {}).get("stream") or {}
    return {**job, "fell": s["fell"], "fall_reason": s["fall_reason"], "wall_s": time.perf_counter() - t0,
            "error_true": true, "error_target": m.get("hand_position_error_m"), "lag": lag,
            "horizon_ms": pred.get("horizon_ms"), "received": stream.get("received"), "lost": stream.get("lost"),
            "invalid_ticks": m.get("teleop", {}).get("invalid_ticks"), "step_median_us": s["step_time_us"]["median"]}


def cell(r: dict) -> str:
    e = r["error_true"]
    return f"{1e3 * e['mean']:.1f} / {1e3 * e['max']:.0f}" + (" FELL" if r["fell"] else "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recordings", nargs="+", default=["reach_forward"])
    ap.add_argument("--start", type=float, default=0.5, help="recording time to start from [s]")
    ap.add_argument("--duration", type=float, default=3.0, help="seconds of each recording from --start")
    ap.add_argument("--latency", type=float, nargs="+", default=[0, 20, 50, 100], help="added latency [ms]")
    ap.add_argument("--loss", type=float, nargs="+", default=[0, 5, 20], help="loss [%%]")
    ap.add_argument("--predict", nargs="+", default=["none", "velocity", "spline"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--out", default="reports/teleop-network")
    ap.add_argument("--resume", action="store_true", help="reuse the rows of runs already done in --out")
    args = ap.parse_args(argv)
    out = Path(args.out)
    jobs = []
    for rec in args.recordings:
        jobs.append({"recording": rec, "latency_ms": None, "loss_pct": None, "predict": "-", "seed": args.seed,
                     "duration": args.duration, "start": args.start, "out": str(out / "runs" / f"{rec}-nolink"),
                     "resume": args.resume})
        for lat in args.latency:
            for loss in args.loss:
                for pred in args.predict:
                    jobs.append({"recording": rec, "latency_ms": lat, "loss_pct": loss, "predict": pred,
                                 "seed": args.seed, "duration": args.duration, "start": args.start,
                                 "resume": args.resume,
                                 "out": str(out / "runs" / f"{rec}-{lat:g}ms-{loss:g}pct-{pred}")})
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    wall = time.perf_counter() - t0
    lines = [f"# Hand error against added latency and loss, seed {args.seed}, {args.duration:g} s from "
             f"recording time {args.start:g} s", "",
             "Hand position error against the operator's undelayed reference [mm], mean / max over both hands and "
             "every tick (tsid-teleop, SPD, repulsors and stabilizer on, `rest` anchor); the stream's frames at "
             "50 Hz through the simulated link (fixed latency, Bernoulli loss), the newest received frame low-pass "
             "filtered (30 ms) with or without prediction.", ""]
    for rec in args.recordings:
        sel = [r for r in rows if r["recording"] == rec]
        base = next(r for r in sel if r["latency_ms"] is None)
        lines += [f"## {rec}", "",
                  f"Without the link (the recording's spline and feed-forward): {cell(base)} mm.", "",
                  "| latency | loss | " + " | ".join(f"predict {p}" for p in args.predict)
                  + " | reference lag, " + " / ".join(args.predict) + " (mean, mm) |",
                  "|---|---|" + "---|" * len(args.predict) + "---|"]
        for lat in args.latency:
            for loss in args.loss:
                cells = {r["predict"]: r for r in sel if r["latency_ms"] == lat and r["loss_pct"] == loss}
                lines.append(f"| {lat:g} ms | {loss:g} % | "
                             + " | ".join(cell(cells[p]) for p in args.predict) + " | "
                             + " / ".join(f"{1e3 * cells[p]['lag']['mean']:.1f}" for p in args.predict) + " |")
        lines.append("")
    fell = sum(r["fell"] for r in rows)
    lines.append(f"{len(rows)} runs, {fell} fell; wall time {wall:.0f} s with {args.jobs} processes "
                 f"({sum(r['wall_s'] for r in rows):.0f} s of process time)")
    out.mkdir(parents=True, exist_ok=True)
    (out / "network.md").write_text("\n".join(lines) + "\n")
    (out / "network.json").write_text(json.dumps(rows, indent=2, default=str))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
