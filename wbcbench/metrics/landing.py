"""Landing errors at touch-down (paper 000 Section 7.2.2: on the real TALOS the hip flexibility put the feet up to
5 cm off where the controller believed them, landing early or late): for each planned touch-down of a walk, where
and when the foot actually landed.

A planned touch-down is a rise of `in_contact_ref_<side>`; the actual one is the first tick after it (or up to
`window` s before it) at which the sole's ground-truth normal force `contact_<side>.fz` rises above `threshold`
after having been below it. The foothold error is the foot frame's true (x, y) at the actual touch-down minus the
planned foot position `foot_ref_<side>` (its last value up to the planned touch-down: the swing's target); the timing error is actual minus planned
(negative: early). The true foot position comes from the caller: the simulator's own (`RealismProbe` logs it,
hidden deflections included) or forward kinematics of the logged q (exact on the ideal robot only).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..robots import Side


def foot_positions_from_q(log: dict, robot) -> dict[Side, np.ndarray]:
    """The foot frames' world positions (n, 3) from the logged q (the ideal robot's truth)."""
    names = ["x", "y", "z", "qx", "qy", "qz", "qw", *robot.joint_names]
    Q = np.stack([np.asarray(log[f"q.{n}"], dtype=float) for n in names], axis=1)
    data = robot.model.createData()
    out = {s: np.zeros((len(Q), 3)) for s in Side}
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(robot.model, data, q)
        for s in Side:
            out[s][k] = data.oMf[robot.sole_frame_id(s)].translation
    return out


def landing_errors(log: dict, feet: dict[Side, np.ndarray], threshold: float = 50.0, window: float = 0.5) -> dict:
    """Per touch-down errors and their summary (see the module docstring). `feet`: true foot positions (n, 3)."""
    t = np.asarray(log["t"], dtype=float)
    events = []
    for s in Side:
        ref_key = f"in_contact_ref_{s.value}"
        if ref_key not in log:
            continue
        planned = np.asarray(log[ref_key], dtype=float) > 0.5
        loaded = np.asarray(log[f"contact_{s.value}.fz"], dtype=float) > threshold
        rises_plan = np.flatnonzero(~planned[:-1] & planned[1:]) + 1
        rises_real = np.flatnonzero(~loaded[:-1] & loaded[1:]) + 1
        for k in rises_plan:
            near = rises_real[np.abs(t[rises_real] - t[k]) <= window] if len(rises_real) else rises_real
            if not len(near):
                events.append({"side": s.value, "t_planned": float(t[k]), "landed": False})
                continue
            j = int(near[np.argmin(np.abs(t[near] - t[k]))])
            ref_xy = np.stack([np.asarray(log[f"foot_ref_{s.value}.{a}"], dtype=float) for a in "xy"], axis=1)
            known = np.flatnonzero(np.isfinite(ref_xy[: k + 1, 0]))  # the swing's last target (none once landed)
            if not len(known):
                continue
            ref = ref_xy[known[-1]]
            dx, dy = feet[s][j, :2] - ref
            events.append({"side": s.value, "t_planned": float(t[k]), "landed": True, "dx_m": float(dx),
                           "dy_m": float(dy), "dt_s": float(t[j] - t[k])})
    landed = [e for e in events if e["landed"]]
    summary = {"touchdowns": len(events), "missed": len(events) - len(landed)}
    if landed:
        dx, dy, dt = (np.array([e[k] for e in landed]) for k in ("dx_m", "dy_m", "dt_s"))
        summary.update({"max_abs_dx_m": float(np.max(np.abs(dx))), "max_abs_dy_m": float(np.max(np.abs(dy))),
                        "max_xy_m": float(np.max(np.hypot(dx, dy))), "mean_dt_s": float(np.mean(dt)),
                        "earliest_dt_s": float(np.min(dt)), "latest_dt_s": float(np.max(dt))})
    return {"summary": summary, "events": events}
