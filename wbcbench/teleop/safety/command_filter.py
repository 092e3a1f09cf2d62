"""Unsafe-command filtering between the operator and the controller: what the teleoperation reference source
hands the robot passes through here last, so that nothing surprising reaches it.

Per effector (hands, head) and tick, on the pose reference M (position, rotation) with its feed-forward velocity
and acceleration (6,) each, in this order:

1. Garbage: a non-finite number anywhere, or a rotation that is not one (||R^T R - I|| > 1e-6), is not used: the
   last output is held (velocity and acceleration zero). Counted as `non_finite`.
2. Inside the body: the hand's protected point (the gripper centre of the profile's `repulsors`) closer than
   r_rep + `body_margin` to a repulsion point on a link that does not move with the arms (torso, pelvis, legs; at
   the reference posture, the robot standing) is pushed out radially, so a reference never asks the gripper
   into the hips or the chest. Counted as `body`. Off with the paper's `absolute` anchor, where such references
   are the repulsors' study (scenario param). The spheres are placed at the reference posture (the robot
   standing) and, when the filter is given the robot's measured configuration (`follow`: encoders and base
   estimate, what the controller gets), moved with it every `body_period` [s], so that they crouch with the
   robot. A re-join (3.) or a speed clamp (4.) moves the output along a straight line, through the body when the
   reference went round it: their output is pushed out again.
3. Jumps: a reference more than `jump_distance` [m] or `jump_angle` [rad] from the last one in one tick
   (a teleport: a stream that resumes after a loss, a recalibration, a corrupt frame) is re-joined with a min-jerk
   blend from the last output to the moving reference over max(`min_rejoin_time`, distance / `rejoin_speed`,
   angle / `rejoin_angular_speed`) s. Counted as `jump`.
4. Speed: the output moves at most `max_speed` [m/s] and `max_angular_speed` [rad/s] per tick (towards the
   reference, along the straight line / the geodesic); counted as `speed`. The feed-forward velocity and
   acceleration are clipped to `max_speed`, `max_angular_speed`, `max_acceleration` [m/s^2] and
   `max_angular_acceleration` [rad/s^2] (norms); counted as `acceleration` when the acceleration is clipped.
   A hand's angular speed can also be held to `hand_angular_speed` [rad/s], or to what the robot's wrist can do
   with "wrist" (`wrist_speed`: the norm of the velocity limits of the last three joints that carry the hand and
   not the other one, TALOS' 3.16 rad/s; a reference that turns the hand faster is followed with the shoulder and
   the elbow, swinging the gripper about its position reference); off by default (README, "Real recordings").

Every intervention is counted per kind and effector (`counts`), the first ones kept with their time
(`events`), and the tick's flags are logged (`teleop_filter` channel). The defaults let the shipped recordings
through untouched at up to twice their speed (their fastest hand: 3.5 m/s, 8 rad/s, 135 m/s^2, 470 rad/s^2 at
x2; a test checks it) and stop teleports and garbage.

The usual tick needs none of this: `_screen` decides it per effector in one compiled call, and `pass_rows` for all
the effectors of a recording's stacked rows at once (wbcbench/teleop/session/source.py), leaving the same state as
`__call__` would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ...jit import njit
from ...side import Side

__all__ = ["FILTER_KINDS", "CommandFilter", "SafetyConfig", "wrist_speed"]

#: The intervention kinds, in the order of the log channel's components.
FILTER_KINDS = ("non_finite", "body", "jump", "speed", "acceleration")
_MAX_EVENTS = 100
_HANDS = ("left_hand", "right_hand")
_EFFECTORS = ("left_hand", "right_hand", "head")


@dataclass(frozen=True)
class SafetyConfig:
    """Limits of the command filter (module docstring). `enabled`: False passes everything through."""

    enabled: bool = True
    max_speed: float = 4.0
    max_angular_speed: float = 10.0
    max_acceleration: float = 150.0
    max_angular_acceleration: float = 500.0
    jump_distance: float = 0.05
    jump_angle: float = 0.3
    rejoin_speed: float = 0.5
    rejoin_angular_speed: float = 1.5
    min_rejoin_time: float = 0.3
    body: bool = True
    body_margin: float = 0.03
    body_period: float = 0.005
    hand_angular_speed: float | str | None = None


@njit
def _screen(p, R, vel, acc, has_last, last_p, last_R, raw_p, raw_R, offset, centres, reach, lim):
    """True when the reference needs none of the filter's work (the common case, decided in one compiled call):
    finite, a rotation, outside the body spheres (``reach``: radius + margin, empty when off), no jump from the
    last raw reference and within the speed limits from the last output (when ``has_last``), feed-forward
    within its limits. ``lim``: [jump distance, jump angle, max step, max turn, max speed, max angular speed,
    max acceleration, max angular acceleration] (per tick where it says step / turn)."""
    for i in range(3):
        if not (np.isfinite(p[i]) and np.isfinite(vel[i]) and np.isfinite(vel[i + 3]) and np.isfinite(acc[i])
                and np.isfinite(acc[i + 3])):
            return False
        for j in range(3):
            if not np.isfinite(R[i, j]):
                return False
    for i in range(3):
        for j in range(3):
            g = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j]
            if abs(g - (1.0 if i == j else 0.0)) > 1e-6:
                return False
    x0 = p[0] + R[0, 0] * offset[0] + R[0, 1] * offset[1] + R[0, 2] * offset[2]
    x1 = p[1] + R[1, 0] * offset[0] + R[1, 1] * offset[1] + R[1, 2] * offset[2]
    x2 = p[2] + R[2, 0] * offset[0] + R[2, 1] * offset[1] + R[2, 2] * offset[2]
    for k in range(reach.shape[0]):
        d0, d1, d2 = x0 - centres[k, 0], x1 - centres[k, 1], x2 - centres[k, 2]
        if d0 * d0 + d1 * d1 + d2 * d2 < reach[k] * reach[k]:
            return False
    if has_last:
        if _dist(p, raw_p) > lim[0] or _angle(R, raw_R) > lim[1]:
            return False
        if _dist(p, last_p) > lim[2] or _angle(R, last_R) > lim[3]:
            return False
    if (_norm3(vel, 0) > lim[4] or _norm3(vel, 3) > lim[5] or _norm3(acc, 0) > lim[6]
            or _norm3(acc, 3) > lim[7]):
        return False
    return True


@njit
def _screen_rows(k, P, R, V, A, last_p, last_R, raw_p, raw_R, offsets, centres, reach, starts, angular, lim):
    """`_screen` of row k of every effector (P (n, e, 3), R (n, e, 3, 3), V, A (n, e, 6)) against its last
    output and raw reference (``last_p`` (e, 3), ...; every effector has them); the body spheres of effector i are
    ``centres[starts[i]:starts[i + 1]]``, its angular speed limit ``angular[i]`` (lim[3] and lim[5] are set from it,
    lim[8] being the tick's dt). True when all pass; their rows are then copied into the last states (what the
    filter keeps after a tick it passes untouched), which are left alone otherwise."""
    n = P.shape[1]
    for e in range(n):
        c0, c1 = starts[e], starts[e + 1]
        lim[3] = angular[e] * lim[8]
        lim[5] = angular[e]
        if not _screen(P[k, e], R[k, e], V[k, e], A[k, e], True, last_p[e], last_R[e], raw_p[e], raw_R[e],
                       offsets[e], centres[c0:c1], reach[c0:c1], lim):
            return False
    for e in range(n):
        for i in range(3):
            last_p[e, i] = P[k, e, i]
            raw_p[e, i] = P[k, e, i]
            for j in range(3):
                last_R[e, i, j] = R[k, e, i, j]
                raw_R[e, i, j] = R[k, e, i, j]
    return True


@njit
def _dist(a, b):
    return np.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


@njit
def _norm3(v, i):
    return np.sqrt(v[i] * v[i] + v[i + 1] * v[i + 1] + v[i + 2] * v[i + 2])


@njit
def _angle(A, B):
    """The angle [rad] of the rotation between A and B (from trace(A^T B))."""
    tr = 0.0
    for i in range(3):
        for j in range(3):
            tr += A[i, j] * B[i, j]
    c = min(1.0, max(-1.0, 0.5 * (tr - 1.0)))
    return np.arccos(c)


def _min_jerk(u: float) -> tuple[float, float]:
    """s(u) and ds/du of the min-jerk profile, u clipped to [0, 1]."""
    u = min(max(u, 0.0), 1.0)
    return 10 * u**3 - 15 * u**4 + 6 * u**5, 30 * u**2 - 60 * u**3 + 30 * u**4


def _clip_norm(x: np.ndarray, limit: float) -> tuple[np.ndarray, bool]:
    n = float(np.linalg.norm(x))
    if n > limit:
        return x * (limit / n), True
    return x, False


@dataclass
class _Rejoin:
    t0: float
    duration: float
    start: pin.SE3


class CommandFilter:
    """The filter for a robot's effector references (module docstring); `q_reference`: the posture the static
    body spheres are placed at; `dt`: the control period [s]."""

    def __init__(self, robot, q_reference: np.ndarray, config: SafetyConfig, dt: float):
        self.config = config
        self.dt = dt
        self.counts = {k: {} for k in FILTER_KINDS}
        self.events: list[dict] = []
        self._open: dict[tuple[str, str], dict] = {}  # each (effector, kind)'s latest event, extended while it lasts
        self.flags = np.zeros(len(FILTER_KINDS))
        self._last: dict[str, pin.SE3] = {}
        self._t_prev: float | None = None
        self._raw_last: dict[str, pin.SE3] = {}
        self._rejoin: dict[str, _Rejoin] = {}
        self._body, self._follow = self._body_spheres(robot, q_reference) if config.body else ({}, None)
        self._t_follow: float | None = None
        # the compiled screen's inputs: the spheres' reach (radius + margin), the limits, the last poses as arrays
        self._body_arrays = {e: (off, c, r + config.body_margin) for e, (off, c, r) in self._body.items()}
        self._no_body = (np.zeros(3), np.zeros((0, 3)), np.zeros(0))
        # the angular speed limit per effector: the hands' also held to the wrist's speed
        hand = config.hand_angular_speed
        hand = np.inf if hand is None else wrist_speed(robot) if hand == "wrist" else float(hand)
        self.angular_speed = {e: min(config.max_angular_speed, hand) if e in _HANDS else config.max_angular_speed
                              for e in _EFFECTORS}
        self._limits = np.zeros(9)
        self._limits[4:8] = (config.max_speed, config.max_angular_speed, config.max_acceleration,
                             config.max_angular_acceleration)
        self._arrays: dict[str, tuple] = {}
        # the row path (`bind_rows`, `pass_rows`): the last states of its effectors stacked, and whether they are
        # those of the dicts above (`_rows_ready`) or newer (`_dicts_stale`: the dicts are rebuilt before use)
        self._row_effectors: tuple[str, ...] | None = None
        self._rows_ready = False
        self._dicts_stale = False

    @staticmethod
    def _body_spheres(robot, q: np.ndarray) -> tuple[dict, _SphereKinematics | None]:
        """Per hand: (protected-point offset in the hand frame, centres (k, 3), radii (k,)) of the repulsion points
        on links that do not move with the arms, at configuration q; and their kinematics (`follow`)."""
        model = robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, q)
        kin = _SphereKinematics(robot)
        kin.place(q)
        out = {}
        for hand, side in (("left_hand", Side.LEFT), ("right_hand", Side.RIGHT)):
            spec = robot.profile.repulsors.get(side)
            if spec is None or hand not in kin.index:
                continue
            hand_frame = model.getFrameId(robot.profile.hands[side])
            gripper = model.getFrameId(spec.frame)
            # the protected point in the hand frame (the hand frame and the gripper frame are rigidly attached)
            point = data.oMf[gripper].act(np.asarray(spec.offset, float))
            offset = data.oMf[hand_frame].actInv(point)
            out[hand] = (offset, kin.centres[kin.index[hand]], kin.radii[hand])
        return out, (kin if out else None)

    def follow(self, t: float, q: np.ndarray) -> None:
        """The body spheres moved to the robot's configuration q (pinocchio's: the base estimate and the encoders,
        as measured) when `body_period` has passed since they last were (every call when it is 0). In place: the
        per-effector arrays and the row path's stacked ones see it."""
        if self._follow is None:
            return
        last = self._t_follow
        if last is not None and last <= t < last + self.config.body_period - 1e-9:
            return
        self._t_follow = t
        self._follow.place(q)
        for e, (_, c, _) in self._body.items():
            np.take(self._follow.centres, self._follow.index[e], axis=0, out=c)
        if self._row_effectors is not None:
            np.take(self._follow.centres, self._row_index, axis=0, out=self._row_body[1])

    def _push_out(self, effector: str, M: pin.SE3) -> tuple[pin.SE3, bool]:
        spheres = self._body.get(effector)
        if spheres is None:
            return M, False
        offset, centres, radii = spheres
        x = M.act(offset)
        moved = False
        for _ in range(3):  # overlapping spheres: a few passes
            d = x - centres
            dist = np.linalg.norm(d, axis=1)
            reach = radii + self.config.body_margin
            inside = np.flatnonzero(dist < reach)
            if inside.size == 0:
                break
            i = inside[np.argmax(reach[inside] - dist[inside])]
            direction = d[i] / dist[i] if dist[i] > 1e-9 else np.array([0.0, 0.0, 1.0])
            x = centres[i] + direction * reach[i]
            moved = True
        if not moved:
            return M, False
        return pin.SE3(M.rotation, M.translation + (x - M.act(offset))), True

    def _count(self, t: float, effector: str, kind: str) -> None:
        c = self.counts[kind]
        c[effector] = c.get(effector, 0) + 1
        self.flags[FILTER_KINDS.index(kind)] = 1.0
        # an event is a run of ticks with the same intervention on the same effector (gaps up to 2 ticks), whatever
        # else happens between them (a speed and an acceleration clamp alternate on a fast hand)
        ev = self._open.get((effector, kind))
        if ev is not None and t - ev["t_last"] < 2.5 * self.dt:
            ev["t_last"] = t
        elif len(self.events) < _MAX_EVENTS:
            ev = self._open[(effector, kind)] = {"t": t, "t_last": t, "effector": effector, "kind": kind}
            self.events.append(ev)

    def bind_rows(self, effectors) -> None:
        """Prepare `pass_rows` for references given as stacked rows of these effectors, in this order."""
        eff = tuple(effectors)
        n = len(eff)
        self._row_effectors = eff
        self._row_last = (np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3)))
        offsets, centres, reach, starts = np.zeros((n, 3)), [], [], [0]
        self._row_angular = np.array([self._angular(e) for e in eff])
        index = []  # the stacked spheres' rows of the followed centres (`follow`)
        for i, e in enumerate(eff):
            off, c, r = self._body_arrays.get(e, self._no_body)
            if self._follow is not None and e in self._follow.index:
                index.append(self._follow.index[e])
            offsets[i] = off
            centres.append(np.asarray(c, float).reshape(-1, 3))
            reach.append(np.asarray(r, float).reshape(-1))
            starts.append(starts[-1] + len(reach[-1]))
        self._row_body = (offsets, np.ascontiguousarray(np.concatenate(centres)), np.concatenate(reach),
                          np.array(starts, dtype=np.int64))
        self._row_index = np.concatenate(index) if index else np.zeros(0, dtype=np.int64)
        self._row_args = (*self._row_last, *self._row_body, self._row_angular, self._limits)
        # the kernel loaded now, not at the first tick it serves (a paced run's clock is running by then)
        _screen_rows(0, np.zeros((1, n, 3)), np.zeros((1, n, 3, 3)), np.zeros((1, n, 6)), np.zeros((1, n, 6)),
                     *(a.copy() for a in self._row_args))
        self._sync_rows()

    def pass_rows(self, t: float, k: int, P: np.ndarray, R: np.ndarray, V: np.ndarray, A: np.ndarray) -> bool:
        """The common tick in one compiled call: the references of `bind_rows`' effectors are row k of P (n, e, 3),
        R (n, e, 3, 3), V, A (n, e, 6). True when the filter lets every one through untouched (the tick is then
        done: its state and flags are what `__call__` would have left, and the output is the input); False when
        this cannot be decided here (a first tick, a re-join, an intervention): nothing changed, call `__call__`."""
        if not self.config.enabled:
            self.flags[:] = 0.0
            return True
        t_prev = self._t_prev
        if t_prev is None or not self._rows_ready or self._rejoin:
            return False
        dt = t - t_prev
        if dt <= 0.0:
            return False
        cfg = self.config
        scale = max(1.0, dt / self.dt)
        lim = self._limits
        lim[2], lim[8] = cfg.max_speed * dt, dt
        lim[0], lim[1] = cfg.jump_distance * scale, cfg.jump_angle * scale
        if not _screen_rows(k, P, R, V, A, *self._row_args):
            return False
        self.flags[:] = 0.0
        self._t_prev = t
        self._dicts_stale = True
        return True

    def _angular(self, effector: str) -> float:
        """The effector's angular speed limit [rad/s] (`angular_speed`; `max_angular_speed` for another name)."""
        return self.angular_speed.get(effector, self.config.max_angular_speed)

    def _sync_dicts(self) -> None:
        """After `pass_rows`: the last outputs as the poses `__call__` keeps (each the raw reference too)."""
        lp, lR = self._row_last[0], self._row_last[1]
        for i, e in enumerate(self._row_effectors):
            M = pin.SE3(lR[i].copy(), lp[i].copy())
            self._last[e] = self._raw_last[e] = M
            p, R = M.translation, M.rotation
            self._arrays[e] = (p, R, p, R)
        self._dicts_stale = False

    def _sync_rows(self) -> None:
        """After `__call__`: its last states into the stacked ones, when every row effector has them."""
        eff = self._row_effectors
        self._rows_ready = all(e in self._last and e in self._arrays for e in eff)
        if self._rows_ready:
            for i, e in enumerate(eff):
                for dst, src in zip(self._row_last, self._arrays[e]):
                    dst[i] = src

    def __call__(self, t: float, targets: dict) -> dict:
        """{effector: (SE3, velocity (6,), acceleration (6,))} -> the same, filtered (module docstring)."""
        if self._dicts_stale:
            self._sync_dicts()
        out = self._filter(t, targets)
        if self._row_effectors is not None:
            self._sync_rows()
        return out

    def _filter(self, t: float, targets: dict) -> dict:
        self.flags[:] = 0.0
        if not self.config.enabled:
            return targets
        cfg = self.config
        # the limits per elapsed time: a run calls every tick; a query at an earlier time starts afresh
        dt = None if self._t_prev is None else t - self._t_prev
        if dt is not None and dt <= 0.0:
            self._last.clear()
            self._raw_last.clear()
            self._rejoin.clear()
            dt = None
        self._t_prev = t
        scale = 1.0 if dt is None else max(1.0, dt / self.dt)
        lim = self._limits
        lim[2] = cfg.max_speed * (dt or 0.0)
        lim[0], lim[1] = cfg.jump_distance * scale, cfg.jump_angle * scale
        out = {}
        for e, (M, vel, acc) in targets.items():
            last = self._last.get(e) if dt is not None else None
            R = M.rotation
            w_max = self._angular(e)
            lim[3], lim[5] = w_max * (dt or 0.0), w_max
            if e not in self._rejoin:
                p = M.translation
                arrays = self._arrays.get(e)
                has_last = last is not None and arrays is not None
                lp, lR, rp, rR = arrays if has_last else (p, R, p, R)
                offset, centres, reach = self._body_arrays.get(e, self._no_body)
                if _screen(p, R, vel, acc, has_last, lp, lR, rp, rR, offset, centres, reach, lim):
                    self._last[e] = self._raw_last[e] = M
                    self._arrays[e] = (p, R, p, R)
                    out[e] = (M, vel, acc)
                    continue
            finite = (np.isfinite(M.translation).all() and np.isfinite(R).all() and np.isfinite(vel).all()
                      and np.isfinite(acc).all())
            if not finite or np.abs(R.T @ R - np.eye(3)).max() > 1e-6:
                self._count(t, e, "non_finite")
                if last is None:  # nothing safe to hold yet: drop the effector's reference this tick
                    continue
                M, vel, acc = last, np.zeros(6), np.zeros(6)
            M, pushed = self._push_out(e, M)
            if pushed:
                self._count(t, e, "body")
            previous = self._raw_last.get(e) if last is not None else None
            self._raw_last[e] = M
            if previous is not None:  # a jump is a discontinuity of the reference stream itself
                step = float(np.linalg.norm(M.translation - previous.translation))
                turn = float(np.linalg.norm(pin.log3(previous.rotation.T @ M.rotation)))
                if e not in self._rejoin and (step > cfg.jump_distance * scale or turn > cfg.jump_angle * scale):
                    dist = float(np.linalg.norm(M.translation - last.translation))
                    angle = float(np.linalg.norm(pin.log3(last.rotation.T @ M.rotation)))
                    T = max(cfg.min_rejoin_time, dist / cfg.rejoin_speed, angle / cfg.rejoin_angular_speed)
                    self._rejoin[e] = _Rejoin(t, T, pin.SE3(last))
                    self._count(t, e, "jump")
            rj = self._rejoin.get(e)
            if rj is not None:
                u = (t - rj.t0) / rj.duration
                if u >= 1.0:
                    del self._rejoin[e]
                else:
                    s, ds = _min_jerk(u)
                    ds /= rj.duration
                    dp = M.translation - rj.start.translation
                    dr = pin.log3(M.rotation @ rj.start.rotation.T)  # world axes
                    M = pin.SE3(pin.exp3(s * dr) @ rj.start.rotation, rj.start.translation + s * dp)
                    vel = s * vel
                    vel[:3] += ds * dp
                    vel[3:] += ds * dr
                    acc = s * acc
            fast = spin = False
            if last is not None:
                step = M.translation - last.translation
                step_c, fast = _clip_norm(step, cfg.max_speed * dt)
                rot = pin.log3(M.rotation @ last.rotation.T)
                rot_c, spin = _clip_norm(rot, w_max * dt)
                if fast or spin:
                    M = pin.SE3(pin.exp3(rot_c) @ last.rotation, last.translation + step_c)
                    self._count(t, e, "speed")
            v_lin, f1 = _clip_norm(vel[:3], cfg.max_speed)
            v_ang, f2 = _clip_norm(vel[3:], w_max)
            a_lin, f3 = _clip_norm(acc[:3], cfg.max_acceleration)
            a_ang, f4 = _clip_norm(acc[3:], cfg.max_angular_acceleration)
            if f1 or f2:
                self._count(t, e, "speed")
            if f3 or f4:
                self._count(t, e, "acceleration")
            vel, acc = np.concatenate([v_lin, v_ang]), np.concatenate([a_lin, a_ang])
            if pushed or rj is not None or fast or spin:
                # a re-join or a clamped step goes along a straight line from the last output, through the body
                # when the pushed reference went round it (a hand passing in front of the hips): out again
                M, again = self._push_out(e, M)
                if again and not pushed:
                    self._count(t, e, "body")
            self._last[e] = M
            self._arrays[e] = (M.translation, M.rotation, self._raw_last[e].translation, self._raw_last[e].rotation)
            out[e] = (M, vel, acc)
        return out

    def summary(self) -> dict:
        """Counts per kind and effector, their total, and the first events ({t, t_last, effector, kind})."""
        return {"counts": self.counts, "total": int(sum(sum(c.values()) for c in self.counts.values())),
                "events": self.events}


class _SphereKinematics:
    """The body spheres of `CommandFilter._body_spheres`: each distinct (parent joint, point in the joint's frame)
    once, their centres at the configuration last `place`d ((k, 3)), per hand the rows of its spheres (`index`)
    and their radii (`radii`)."""

    def __init__(self, robot):
        model = robot.model
        self.model, self.data = model, model.createData()
        arm_joints = robot.arm_joint_ids()
        self.joints: list[int] = []
        self.points: list[np.ndarray] = []
        self.index: dict[str, np.ndarray] = {}
        self.radii: dict[str, np.ndarray] = {}
        keys: dict = {}
        for hand, side in (("left_hand", Side.LEFT), ("right_hand", Side.RIGHT)):
            spec = robot.profile.repulsors.get(side)
            if spec is None:
                continue
            rows, radii = [], []
            for p in spec.points:
                frame = model.frames[model.getFrameId(p.frame)]
                if _moves_with_arms(model, frame.parentJoint, arm_joints):
                    continue
                point = frame.placement.act(np.asarray(p.offset, float))
                key = (frame.parentJoint, *point.tolist())
                if key not in keys:
                    keys[key] = len(self.joints)
                    self.joints.append(frame.parentJoint)
                    self.points.append(point)
                rows.append(keys[key])
                radii.append(p.radius)
            if rows:
                self.index[hand] = np.array(rows, dtype=np.int64)
                self.radii[hand] = np.array(radii)
        self.centres = np.zeros((len(self.joints), 3))
        self._distinct = sorted(set(self.joints))
        self._which = np.array([self._distinct.index(j) for j in self.joints], dtype=np.int64)
        self._points = np.array(self.points, dtype=float).reshape(-1, 3)

    def place(self, q: np.ndarray) -> None:
        """The centres at configuration q (the joints' placements only: one forward kinematics pass)."""
        pin.forwardKinematics(self.model, self.data, q)
        oMi = self.data.oMi
        _place(np.array([oMi[j].homogeneous for j in self._distinct]), self._which, self._points, self.centres)


@njit
def _place(H, which, points, out):
    """out[i] = the point points[i] placed by the homogeneous transform H[which[i]]."""
    for i in range(points.shape[0]):
        h = H[which[i]]
        for r in range(3):
            out[i, r] = h[r, 0] * points[i, 0] + h[r, 1] * points[i, 1] + h[r, 2] * points[i, 2] + h[r, 3]


def wrist_speed(robot) -> float:
    """The fastest a robot's wrist turns its hand [rad/s]: the norm of the velocity limits of the last three joints
    that carry a hand and not the other one (the wrist's joints at their limits about orthogonal axes; the smaller
    over the two hands)."""
    model = robot.model
    limit = dict(zip(robot.joint_names, robot.velocity_limit))
    chains = {side: list(model.supports[model.frames[model.getFrameId(frame)].parentJoint])
              for side, frame in robot.profile.hands.items()}
    speeds = []
    for side, chain in chains.items():
        others = set().union(*(set(c) for s, c in chains.items() if s != side))
        own = [model.names[j] for j in chain if j not in others and model.names[j] in limit]
        v = [float(limit[name]) for name in own[-3:]]
        speeds.append(float(np.linalg.norm(v)) if v else np.inf)
    return float(min(speeds)) if speeds else np.inf


def _moves_with_arms(model, joint: int, arm_joints: set) -> bool:
    j = joint
    while j > 0:
        if j in arm_joints:
            return True
        j = model.parents[j]
    return False
