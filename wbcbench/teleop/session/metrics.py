"""Teleoperation metrics (paper 004 Table II statistics) from a run's log alone: the ground-truth configuration
and the hand and head references the controller was handed (the runner logs them: `target_<task>` channels,
position and rotation matrix). Used by the `teleop` scenario kind at the end of a run and by `wbcbench report` on
any run directory, so that both give the same numbers.

Alignment: log row i (the state after tick i) is compared with the reference of tick i - 1 (row 0: tick 0's),
as the run-time metrics always did.

Through an impaired link (a recording replayed through wbcbench/teleop/link/network.py's simulated link), the log
also holds the hands' undelayed reference (`teleop_truth` channels: the recording's spline at the tick, what the
robot should be doing now): the hand errors are then also measured against it (`*_true`), and the reference's
own error against it (`reference_lag`: what the link and the prediction left in the target).

Reachability (wbcbench/teleop/human/reachability.py): every `REACH_STRIDE` ticks (10 ms), whether each hand's
reference pose and the head's reference position are reachable by the effector's own chain (an arm from where the
torso was, the torso and neck from where the base was) within its joint limits, and for the hands whether it is
reachable in time: whether a speed-limited follower of the reference (the arm moving each joint at most at its
velocity limit, from where the robot's arm was at the first sample; `ChainReach.track`) is at it. The errors are
then split: reachable (and outside the body) against out of reach, and reachable in time (and outside the body).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ...side import Side
from ..human.reachability import ChainReach
from ..human.retargeting import effector_chains
from .source import HANDS, rotation_error, stats

__all__ = ["EFFECTORS", "REACH_STRIDE", "has_targets", "has_truth", "reach_checks", "teleop_errors_from_log",
           "teleop_metrics_from_log"]

#: reachability is checked every this many ticks (10 ms at 1 kHz)
REACH_STRIDE = 10
EFFECTORS = ("left_hand", "right_hand", "head")
_COMPONENTS = ("x", "y", "z", "r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22")


def has_targets(log: dict) -> bool:
    return all(f"target_{e}.x" in log for e in EFFECTORS)


def has_truth(log: dict) -> bool:
    """The log holds the hands' undelayed reference (a run through the simulated impaired link)."""
    return all(f"teleop_truth.{h}.x" in log for h in HANDS)


def reach_checks(robot) -> dict[str, ChainReach] | None:
    """A :class:`~wbcbench.teleop.human.reachability.ChainReach` per effector (hands: pose, from the torso; head:
    position, from the base), or None where a chain has a joint with several configuration variables."""
    try:
        return {k: ChainReach(robot.model, frame, joints, robot.q0, rotation=k != "head")
                for k, (frame, joints) in effector_chains(robot).items()}
    except ValueError:
        return None


class _Reachability:
    """Every `stride`-th row of a log: per effector whether its reference was reachable, and per hand whether the
    speed-limited follower reached it (reachable in time); `at` is called with the row's forward kinematics done
    (the errors' pass over the rows)."""

    def __init__(self, checks: dict[str, ChainReach], Q: np.ndarray, ref: dict, t: np.ndarray, stride: int):
        self.checks, self.Q, self.ref, self.t, self.stride = checks, Q, ref, t, stride
        self.ticks = np.arange(0, len(Q), stride)
        self.reachable = np.zeros((len(EFFECTORS), len(self.ticks)), dtype=bool)
        self.in_time = np.zeros((len(HANDS), len(self.ticks)), dtype=bool)
        self._follower: dict[str, tuple[float, np.ndarray]] = {}  # hand -> (time, the follower's arm joints)

    def at(self, i: int, data) -> None:
        if i % self.stride:
            return
        col, ref = i // self.stride, self.ref
        for row, k in enumerate(EFFECTORS):
            check = self.checks[k]
            parent = data.oMi[check.parent]
            M = pin.SE3(ref[k][i, 3:].reshape(3, 3), ref[k][i, :3])
            self.reachable[row, col] = check.solve(self.Q[i], parent, M).reachable
            if k in HANDS:
                t_last, x = self._follower.get(k, (self.t[i], self.Q[i][check.q_index]))
                res = check.track(x, self.t[i] - t_last, parent, M)
                self.in_time[row, col] = res.reachable
                self._follower[k] = (self.t[i], res.q)

    def result(self) -> dict[str, np.ndarray]:
        return {"reach_ticks": self.ticks, "reachable": self.reachable, "reachable_in_time": self.in_time}


def teleop_errors_from_log(log: dict, robot, reach_stride: int | None = REACH_STRIDE) -> dict[str, np.ndarray]:
    """Per tick: position [m] and rotation (||I - R_ref R^T||_F) errors of both hands, whether each hand's
    reference lies inside the body (its protected point within r_rep + r of a repulsion point), the head's
    position error, and the time; every `reach_stride` ticks (None: not checked) whether each effector's
    reference was reachable and each hand's reachable in time (module docstring)."""
    n = len(log["t"])
    model = robot.model
    data = model.createData()
    names = ["x", "y", "z", "qx", "qy", "qz", "qw"] + robot.joint_names
    Q = np.column_stack([log[f"q.{c}"] for c in names])
    frames = {"left_hand": robot.profile.hands[Side.LEFT], "right_hand": robot.profile.hands[Side.RIGHT],
              "head": robot.profile.head_frame}
    fids = {k: model.getFrameId(f) for k, f in frames.items()}
    sides = {"left_hand": Side.LEFT, "right_hand": Side.RIGHT}
    reps = {h: robot.profile.repulsors.get(s) for h, s in sides.items()}
    rep_points = {h: [(model.getFrameId(p.frame), np.array(p.offset), p.radius + r.radius) for p in r.points]
                  for h, r in reps.items() if r is not None}
    shift = np.maximum(np.arange(n) - 1, 0)  # row i: the reference of tick i - 1
    ref = {k: np.column_stack([log[f"target_{k}.{c}"] for c in _COMPONENTS])[shift] for k in frames}
    pos = {k: np.empty((n, 3)) for k in frames}
    rot = {k: np.empty((n, 3, 3)) for k in frames}
    inside = {h: np.zeros(n, dtype=bool) for h in HANDS}
    t = np.asarray(log["t"]) - (log["t"][0] if n else 0.0)
    checks = reach_checks(robot) if reach_stride and n else None
    reach = _Reachability(checks, Q, ref, t, int(reach_stride)) if checks is not None else None
    for i in range(n):
        pin.framesForwardKinematics(model, data, Q[i])
        if reach is not None:
            reach.at(i, data)
        for k, fid in fids.items():
            M = data.oMf[fid]
            pos[k][i] = M.translation
            rot[k][i] = M.rotation
        for h, points in rep_points.items():
            R_ref = ref[h][i, 3:].reshape(3, 3)
            x = ref[h][i, :3] + R_ref @ np.asarray(reps[h].offset)
            inside[h][i] = any(np.linalg.norm(x - data.oMf[fid].act(off)) < a for fid, off, a in points)
    e_pos = {k: np.linalg.norm(ref[k][:, :3] - pos[k], axis=1) for k in frames}
    e_rot = {k: rotation_error(ref[k][:, 3:].reshape(-1, 3, 3), rot[k]) for k in frames}
    out = {"position": np.stack([e_pos[h] for h in HANDS]), "rotation": np.stack([e_rot[h] for h in HANDS]),
           "reference_inside_body": np.stack([inside[h] for h in HANDS]), "head_position": e_pos["head"],
           "t": t}
    if reach is not None:
        out.update(reach.result())
    if has_truth(log):
        true = {h: np.column_stack([log[f"teleop_truth.{h}.{c}"] for c in _COMPONENTS])[shift] for h in HANDS}
        out["position_true"] = np.stack([np.linalg.norm(true[h][:, :3] - pos[h], axis=1) for h in HANDS])
        out["rotation_true"] = np.stack([rotation_error(true[h][:, 3:].reshape(-1, 3, 3), rot[h]) for h in HANDS])
        out["reference_lag"] = np.stack([np.linalg.norm(true[h][:, :3] - ref[h][:, :3], axis=1) for h in HANDS])
    return out


def teleop_metrics_from_log(log: dict, robot, errors: dict | None = None) -> dict:
    """The Table II statistics ({mean, std, min, max}) of `teleop_errors_from_log`."""
    e = errors if errors is not None else teleop_errors_from_log(log, robot)
    outside = ~e["reference_inside_body"].reshape(-1)
    all_pos, all_rot = e["position"].reshape(-1), e["rotation"].reshape(-1)
    out = {
        "hand_position_error_m": stats(all_pos),
        "hand_rotation_error": stats(all_rot),
        "hand_errors": {h: {"position_m": stats(e["position"][i]), "rotation": stats(e["rotation"][i])}
                        for i, h in enumerate(HANDS)},
        "hand_position_error_outside_body_m": stats(all_pos[outside]),
        "hand_rotation_error_outside_body": stats(all_rot[outside]),
        "hand_reference_inside_body_fraction": float(1.0 - outside.mean()) if outside.size else None,
        "head_position_error_m": stats(e["head_position"]),
    }
    if "reachable" in e:
        out.update(_split_by_reach(e))
    if "position_true" in e:
        out["hand_position_error_true_m"] = stats(e["position_true"].reshape(-1))
        out["hand_rotation_error_true"] = stats(e["rotation_true"].reshape(-1))
        out["hand_reference_lag_m"] = stats(e["reference_lag"].reshape(-1))
    return out


def _split_by_reach(e: dict) -> dict:
    """The hand and head errors at the sampled ticks, split by reachability (module docstring)."""
    ticks, reach = e["reach_ticks"], e["reachable"]
    hands_reach = reach[:2] & ~e["reference_inside_body"][:, ticks]
    in_time = e["reachable_in_time"] & ~e["reference_inside_body"][:, ticks]
    pos = e["position"][:, ticks]
    head = e["head_position"][ticks]
    frac = (lambda mask: float(mask.mean()) if mask.size else None)
    return {
        "hand_position_error_reachable_m": stats(pos[hands_reach]),
        "hand_position_error_out_of_reach_m": stats(pos[~reach[:2]]),
        "hand_reachable_fraction": frac(hands_reach),
        "hand_position_error_reachable_in_time_m": stats(pos[in_time]),
        "hand_reachable_in_time_fraction": frac(in_time),
        "head_position_error_reachable_m": stats(head[reach[2]]),
        "head_position_error_out_of_reach_m": stats(head[~reach[2]]),
        "head_reachable_fraction": frac(reach[2]),
        "reach_check_period_ticks": int(ticks[1] - ticks[0]) if len(ticks) > 1 else 1,
    }
