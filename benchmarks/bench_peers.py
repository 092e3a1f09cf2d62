"""wbcbench's controllers beside their peers on one standing problem, in one run, each measurement in its own
process pinned to one core with OPENBLAS_NUM_THREADS=1, the sides alternating round by round:

- the problem: TALOS on both feet, the CoM reference following a lateral sine (2 cm, 0.5 Hz), waist orientation,
  posture to half-sitting (and angular momentum, joint bounds where the peer has them); the control step timed
  (references in, command out), the first 10 % of the ticks discarded;
- ours: tsid-torque, ik (with its DCM stabilizer and base feedback), tsid-position, fed by the simulator in closed
  loop (`bench_controllers.py`'s set-up); the peers integrate their own solution
  (benchmarks/peers/*_stand.py, run in the environments benchmarks/peers/setup.sh makes);
- the ratios the project tracks: tsid-torque / C++ TSID, tsid-torque / PlaCo's dynamics solver, ik / PlaCo's
  kinematics solver, ik's core (its step without the plan corrections, i.e. the formulation and solve alone:
  `bench_controllers.py`'s "core", timed in the same runs) / PlaCo's kinematics solver, ik / pink,
  tsid-position / tsid-torque.

    bash benchmarks/peers/setup.sh /tmp/wbcbench-peers
    .venv/bin/python benchmarks/bench_peers.py --peers /tmp/wbcbench-peers [--rounds 3] [--ticks 3000] [--core 1]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OURS = ("tsid-torque", "ik", "tsid-position")
RATIOS = (("tsid-torque", "tsid"), ("tsid-torque", "placo-dynamics"), ("ik", "placo-kinematics"),
          ("ik core", "placo-kinematics"), ("ik", "pink"), ("tsid-position", "tsid-torque"))


def ours(name: str, ticks: int) -> dict:
    """One of our controllers on the problem, fed by the simulator (in this process)."""
    import pinocchio as pin

    from wbcbench import types
    from wbcbench.controllers.base import make_controller
    from wbcbench.robots import load_robot
    from wbcbench.side import Side
    from wbcbench.sim.simulator import Simulator

    robot = load_robot("talos")
    ctrl = make_controller(name, robot, None, 1e-3)
    sim = Simulator(robot, mode=ctrl.mode)
    meas = sim.measure()
    data = robot.model.createData()
    com0 = pin.centerOfMass(robot.model, data, meas.q).copy()
    pin.framesForwardKinematics(robot.model, data, meas.q)
    ground = min(data.oMf[robot.sole_frame_id(s)].translation[2] for s in Side)
    w = 2 * np.pi * 0.5

    def refs(t: float):
        c = com0 + [0.0, 0.02 * np.sin(w * t), 0.0]
        return types.References(t=t, com=types.PointReference(c, [0.0, 0.02 * w * np.cos(w * t), 0.0],
                                                              [0.0, -0.02 * w * w * np.sin(w * t), 0.0]),
                                zmp=np.array([c[0], c[1], ground]))

    ctrl.reset(meas, refs(0.0))
    times = np.empty(ticks)
    corrections = np.zeros(ticks)
    from bench_controllers import _time_corrections

    timed = _time_corrections(ctrl, corrections)  # [tick, whether the controller has plan corrections]
    for k in range(ticks):
        r = refs(k * 1e-3)
        timed[0] = k
        t0 = time.perf_counter()
        cmd = ctrl.step(meas, r)
        times[k] = (time.perf_counter() - t0) * 1e6
        sim.apply(cmd)
        sim.step()
        meas = sim.measure()
    warm = slice(ticks // 10, None)
    out = {"median_us": float(np.median(times[warm])), "p99_us": float(np.percentile(times[warm], 99))}
    if timed[1]:
        core = (times - corrections)[warm]
        out["core"] = {"median_us": float(np.median(core)), "p99_us": float(np.percentile(core, 99))}
    return out


def _peer_files(tmp: Path) -> tuple[str, str]:
    """TALOS' URDF without visuals and collision meshes (the peers need no meshes) and its half-sitting q."""
    from wbcbench.robots import load_robot

    robot = load_robot("talos")
    txt = robot.files.urdf.read_text()
    txt = re.sub(r"<(visual|collision)\b.*?</\1>", "", txt, flags=re.S)
    urdf, q0 = tmp / "talos.urdf", tmp / "q0.npy"
    urdf.write_text(txt)
    np.save(q0, robot.q0)
    return str(urdf), str(q0)


def _run(cmd: list[str], core: str) -> dict:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run((["taskset", "-c", core] if core else []) + cmd, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:3])}: {out.stderr.strip().splitlines()[-1] if out.stderr else 'failed'}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--peers", default="/tmp/wbcbench-peers", help="the directory benchmarks/peers/setup.sh made")
    p.add_argument("--ticks", type=int, default=3000)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--core", default="1", help="CPU core to pin every measurement to ('' for none)")
    p.add_argument("--json", default=None)
    p.add_argument("--ours", default=None, help=argparse.SUPPRESS)  # internal: time one of ours, print JSON
    args = p.parse_args()
    if args.ours:
        print(json.dumps(ours(args.ours, args.ticks)))
        return
    peers = Path(args.peers)
    for env in ("tsid", "placo"):
        if not (peers / env / "bin" / "python").exists():
            raise SystemExit(f"no peers' environment {peers / env}: run bash benchmarks/peers/setup.sh {peers}")
    with tempfile.TemporaryDirectory() as tmp:
        urdf, q0 = _peer_files(Path(tmp))
        t = ["--ticks", str(args.ticks)]
        cmds = {name: [sys.executable, __file__, "--ours", name, *t] for name in OURS}
        cmds["tsid"] = [str(peers / "tsid/bin/python"), str(HERE / "peers/tsid_stand.py"), urdf, q0, *t]
        for solver in ("dynamics", "kinematics"):
            cmds[f"placo-{solver}"] = [str(peers / "placo/bin/python"), str(HERE / "peers/placo_stand.py"), solver,
                                       urdf, q0, *t]
        cmds["pink"] = [str(peers / "placo/bin/python"), str(HERE / "peers/pink_stand.py"), urdf, q0, *t]
        rounds: dict[str, list[dict]] = {k: [] for k in cmds}
        versions = {}
        for r in range(args.rounds):
            for name, cmd in cmds.items():
                res = _run(cmd, args.core)
                rounds[name].append(res)
                versions[name] = res.get("version")
                if "core" in res:  # the step without its plan corrections, from the same run
                    rounds.setdefault(f"{name} core", []).append(res["core"])
            print(f"  round {r + 1}/{args.rounds} done", flush=True)
    med = {k: float(np.median([x["median_us"] for x in v])) for k, v in rounds.items()}
    p99 = {k: float(np.median([x["p99_us"] for x in v])) for k, v in rounds.items()}
    print(f"TALOS standing, CoM on a lateral sine; {args.ticks} ticks per run, {args.rounds} alternating rounds, "
          f"core {args.core or 'any'}; median of the rounds' medians [us]")
    for k in rounds:
        print(f"  {k:18s} {med[k]:7.1f}   p99 {p99[k]:7.1f}" + (f"   ({versions[k]})" if versions.get(k) else ""))
    ratios = {f"{a} / {b}": med[a] / med[b] for a, b in RATIOS}
    for key, val in ratios.items():
        print(f"  {key:34s} {val:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"median_us": med, "p99_us": p99, "ratios": ratios,
                                               "versions": versions}, indent=2))


if __name__ == "__main__":
    main()
