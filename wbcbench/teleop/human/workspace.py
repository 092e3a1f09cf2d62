"""Reachable workspace of an end effector, as a spherical shell around the root of its kinematic chain.

For a hand, the chain root is the first joint after the torso frame's joint on the path to the hand (TALOS:
``arm_left_1_joint``); for the head, the first joint after the floating base (TALOS: ``torso_1_joint``). The shell
is centred on the root joint's origin in the robot's reference posture; its radii are the smallest and largest
distance from that origin to the effector frame over ``samples`` random configurations of the chain's joints
(uniform within the position limits, fixed seed), widened by ``margin``. Every reachable point lies in the shell
(up to sampling), but not every point of the shell is reachable: the shell is a cheap outer bound that removes
targets the arm could never reach (operator taller than the robot, arm stretched far away), and leaves the rest
to the controller. The head chain (torso and neck joints) barely changes the head's distance to the torso, so
its shell is thin: ``margin`` (default 0.10 m for the head) stands for what bending the legs adds. A sphere's
lower half is no place for a head, though: an operator who squats or bends down puts the head target below the
torso, the radial clamp keeps it there, and the head task pulled TALOS down into a crouch below the fall height
(a public motion-capture recording). So the head's shell is also a cone: the direction from the centre tilts from
the vertical at most ``max_tilt`` (the largest tilt of the samples plus ``tilt_margin``), and a target beyond it
is turned onto the cone about the centre, its distance kept (it leans instead of sinking). The samples move the
torso and neck with the base upright, and the teleoperation's head shell takes no tilt margin
(`robot_workspaces`): a head reference tilted further than the torso can lean made TALOS bow at the hips until its
base tilted past the fall limit (two public captures whose operators bow down after a stride).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ...errors import ConfigError

__all__ = ["ReachShell", "chain_joints", "reach_shell"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ReachShell:
    """Points ``p`` with ``r_min <= |p - center| <= r_max``.

    Attributes:
        center: (3,) world position of the chain root [m].
        r_min, r_max: radii [m], ``0 <= r_min <= r_max``.
        root_joint: name of the chain's root joint (informative).
    """

    center: FloatArray
    r_min: float
    r_max: float
    root_joint: str = ""
    max_tilt: float = np.pi

    def _tilt(self, delta: FloatArray, d: float) -> float:
        return float(np.arccos(np.clip(delta[2] / d, -1.0, 1.0))) if d > 1e-12 else 0.0

    def contains(self, p: npt.ArrayLike, tol: float = 1e-9) -> bool:
        """True when ``p`` is inside the shell (within ``tol``)."""
        delta = np.asarray(p, dtype=float) - self.center
        d = float(np.linalg.norm(delta))
        return self.r_min - tol <= d <= self.r_max + tol and self._tilt(delta, d) <= self.max_tilt + tol

    def clamp(self, p: npt.ArrayLike) -> tuple[FloatArray, bool]:
        """The point of the shell nearest ``p``: radial projection onto the radii, then (beyond ``max_tilt``) the
        direction turned onto the cone in its vertical plane (straight below: towards +x); and whether ``p`` was
        moved."""
        p = np.asarray(p, dtype=float)
        delta = p - self.center
        d = float(np.linalg.norm(delta))
        tilted = self._tilt(delta, d) > self.max_tilt
        if self.r_min <= d <= self.r_max and not tilted:
            return p.copy(), False
        if d < 1e-12:  # at the centre: push straight up
            return self.center + np.array([0.0, 0.0, self.r_min]), True
        r = min(max(d, self.r_min), self.r_max)
        u = delta / d
        if tilted:
            h = np.array([u[0], u[1], 0.0])
            n = float(np.linalg.norm(h))
            h = h / n if n > 1e-9 else np.array([1.0, 0.0, 0.0])
            u = np.cos(self.max_tilt) * np.array([0.0, 0.0, 1.0]) + np.sin(self.max_tilt) * h
        return self.center + u * r, True


def chain_joints(model: pin.Model, frame: str, after_joint: int) -> list[int]:
    """Joint ids from the first joint after ``after_joint`` down to the joint carrying ``frame``.

    If ``after_joint`` is not an ancestor of the frame, the chain starts after the floating base (joint 1).

    Raises:
        ConfigError: unknown frame.
    """
    if not model.existFrame(frame):
        raise ConfigError(f"unknown frame '{frame}'", key="frame")
    path = []
    j = model.frames[model.getFrameId(frame)].parentJoint
    while j > 0:
        path.append(j)
        j = model.parents[j]
    path.reverse()  # root first
    if after_joint in path:
        path = path[path.index(after_joint) + 1:]
    elif path and model.joints[path[0]].nq == 7:  # skip a free-flyer
        path = path[1:]
    if not path:
        raise ConfigError(f"frame '{frame}' has no joint below joint {after_joint}", key="frame")
    return path


def reach_shell(
    model: pin.Model,
    q_reference: npt.ArrayLike,
    frame: str,
    joints: list[int],
    *,
    samples: int = 2048,
    seed: int = 0,
    margin: float = 0.0,
    tilt_margin: float | None = None,
) -> ReachShell:
    """Sample the shell of ``frame`` around the origin of ``joints[0]`` (see the module docstring); with
    ``tilt_margin`` [rad] also its cone (``max_tilt``: the samples' largest tilt from the vertical plus it)."""
    q_reference = np.asarray(q_reference, dtype=float)
    data = model.createData()
    frame_id = model.getFrameId(frame)
    pin.forwardKinematics(model, data, q_reference)
    center = data.oMi[joints[0]].translation.copy()
    rng = np.random.default_rng(seed)
    lower = model.lowerPositionLimit
    upper = model.upperPositionLimit
    idx = [model.joints[j].idx_q for j in joints if model.joints[j].nq == 1]
    lo = np.clip(lower[idx], -np.pi, np.pi)
    hi = np.clip(upper[idx], -np.pi, np.pi)
    q = q_reference.copy()
    deltas = np.empty((samples + 1, 3))
    pin.updateFramePlacement(model, data, frame_id)
    deltas[0] = data.oMf[frame_id].translation - center
    draws = rng.uniform(lo, hi, size=(samples, len(idx)))
    for k in range(samples):
        q[idx] = draws[k]
        pin.forwardKinematics(model, data, q)
        deltas[k + 1] = pin.updateFramePlacement(model, data, frame_id).translation - center
    distances = np.linalg.norm(deltas, axis=1)
    r_min = max(float(distances.min()) - margin, 0.0)
    r_max = float(distances.max()) + margin
    max_tilt = np.pi
    if tilt_margin is not None:
        tilts = np.arccos(np.clip(deltas[:, 2] / np.maximum(distances, 1e-12), -1.0, 1.0))
        max_tilt = min(float(tilts.max()) + tilt_margin, np.pi)
    return ReachShell(center, r_min, r_max, model.names[joints[0]], max_tilt)
