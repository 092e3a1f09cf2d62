"""Whether an effector's reference is reachable by the effector's own chain from where the robot was.

The reach shells of :mod:`wbcbench.teleop.human.workspace` are an outer bound: a sphere around the chain's root
holds every reachable point and many that are not (TALOS' gripper frame sits up to 0.80 m from its shoulder with
the wrist bent outwards, 0.62 m with the wrist straight; a hand's reference 0.7 m below the shoulder is inside the
shell and out of reach). For the metrics a reference is *reachable* at a tick when the chain alone (a hand: the
joints after the torso's, TALOS' seven arm joints; the head: the joints after the floating base), within its
joints' position limits and with every other joint where the robot had it at that tick, can put the effector
frame at the reference: position within ``position_tolerance`` and, for a pose, rotation within
``rotation_tolerance`` (the angle of ``R_ref^T R``). The search is a damped least-squares (Levenberg-Marquardt)
descent on ``[p - p_ref; w log3(R_ref^T R)]`` with the joints clipped to their limits, from up to three starts
(the previous solution, the robot's own chain configuration of that tick, the reference posture's); the
first start that meets the tolerances ends it. A local minimum can only call a reachable reference out of reach.

Reachable *in time* (:meth:`ChainReach.track`): a moving reference can be reachable at every instant and still
move faster than the arm's joints turn (a serve, a jump's arm swing: the hand at 2 to 11 m/s), and after such a
swing the arm needs time to come back. A speed-limited follower answers both: a kinematic copy of the chain that
starts where the robot's arm was and, every sampled tick, moves as close to the reference as it can, each joint
by at most its velocity limit times the time since the last sample (within its position limits; no acceleration
limit, no dynamics: quicker than the real arm, though not an optimal plan, as it does not know where the
reference goes next). Where it is at the reference (the tolerances above), a controller could have been there too.

The teleoperation metrics split the effectors' errors by them: a reference out of reach is where the operator's
hand was and the robot's arm cannot be (a retargeting limit, whatever the controller); one the follower reaches
and the robot misses is the controller's (or the command filter's) doing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

__all__ = ["ChainReach", "ReachResult"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ReachResult:
    """One reference's reachability: whether the tolerances were met, the best residuals [m, rad], the chain's
    joint positions found."""

    reachable: bool
    position_residual: float
    rotation_residual: float
    q: FloatArray


class ChainReach:
    """Reachability of ``frame`` by the revolute/prismatic joints ``joints`` (a chain, root first) of ``model``.

    Args:
        model: the robot's pinocchio model.
        frame: the effector frame.
        joints: the chain's joint ids, root first (:func:`~wbcbench.teleop.human.workspace.chain_joints`).
        q_reference: the robot's reference configuration (the third start; the other joints' placements of the
            reduced model, which :meth:`solve` moves to the tick's).
        rotation: whether a reference's rotation counts (a hand's pose) or only its position (the head).
        position_tolerance [m], rotation_tolerance [rad]: what "at the reference" means.
        rotation_weight [m/rad]: the rotation residual's weight in the search.
        iterations: per start.

    Raises:
        ValueError: a chain joint with more than one configuration variable.
    """

    def __init__(self, model: pin.Model, frame: str, joints: list[int], q_reference: npt.ArrayLike, *,
                 rotation: bool = True, position_tolerance: float = 0.01, rotation_tolerance: float = 0.1,
                 rotation_weight: float = 0.1, iterations: int = 40):
        bad = [model.names[j] for j in joints if model.joints[j].nq != 1 or model.joints[j].nv != 1]
        if bad:
            raise ValueError(f"reachability needs one-variable joints; {bad} are not")
        q_reference = np.asarray(q_reference, dtype=float)
        keep = set(joints)
        locked = [j for j in range(1, model.njoints) if j not in keep]
        self.model = pin.buildReducedModel(model, locked, q_reference)
        self.data = self.model.createData()
        self.frame_id = self.model.getFrameId(frame)
        self.parent = int(model.parents[joints[0]])
        full = model.createData()
        pin.forwardKinematics(model, full, q_reference)
        self._parent_reference = full.oMi[self.parent].copy()
        self.q_index = np.array([model.joints[j].idx_q for j in joints])
        self.lower = np.clip(self.model.lowerPositionLimit, -np.pi, np.pi)
        self.upper = np.clip(self.model.upperPositionLimit, -np.pi, np.pi)
        self.q_rest = np.clip(q_reference[self.q_index], self.lower, self.upper)
        self._eye = np.eye(len(joints))
        self.rotation = rotation
        self.position_tolerance = float(position_tolerance)
        self.rotation_tolerance = float(rotation_tolerance)
        self.weight = float(rotation_weight)
        self.iterations = int(iterations)
        self.velocity_limit = np.array([model.velocityLimit[model.joints[j].idx_v] for j in joints], dtype=float)
        self._last: FloatArray | None = None

    def target(self, parent_placement: pin.SE3, reference: pin.SE3) -> pin.SE3:
        """A world reference, with the chain's parent joint at ``parent_placement`` -> the reduced model's frame."""
        return self._parent_reference * parent_placement.actInv(reference)

    def _residual(self, x: FloatArray, M: pin.SE3) -> tuple[FloatArray, FloatArray, pin.SE3]:
        pin.forwardKinematics(self.model, self.data, x)
        F = pin.updateFramePlacement(self.model, self.data, self.frame_id)
        e_p = F.translation - M.translation
        e_r = pin.log3(M.rotation.T @ F.rotation) if self.rotation else np.zeros(3)
        return e_p, e_r, F

    def _descend(self, x0: FloatArray, M: pin.SE3, lower: FloatArray | None = None,
                 upper: FloatArray | None = None) -> tuple[FloatArray, float, float]:
        """The search from ``x0`` within [lower, upper] (default: the joints' position limits)."""
        lower = self.lower if lower is None else lower
        upper = self.upper if upper is None else upper
        x = np.clip(x0, lower, upper)
        e_p, e_r, F = self._residual(x, M)
        cost = float(e_p @ e_p + self.weight**2 * (e_r @ e_r))
        lam = 1e-3
        eye = self._eye
        for _ in range(self.iterations):
            if np.sqrt(e_p @ e_p) <= 0.1 * self.position_tolerance and (
                    not self.rotation or np.sqrt(e_r @ e_r) <= 0.1 * self.rotation_tolerance):
                break
            J = pin.computeFrameJacobian(self.model, self.data, x, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
            if self.rotation:
                Jr = self.weight * pin.Jlog3(M.rotation.T @ F.rotation) @ F.rotation.T @ J[3:]
                A, e = np.vstack((J[:3], Jr)), np.concatenate((e_p, self.weight * e_r))
            else:
                A, e = J[:3], e_p
            g = A.T @ e
            H = A.T @ A
            improved = False
            while lam < 1e6:
                dx = np.linalg.solve(H + lam * eye, -g)
                x_new = np.clip(x + dx, lower, upper)
                p_new, r_new, F_new = self._residual(x_new, M)
                c_new = float(p_new @ p_new + self.weight**2 * (r_new @ r_new))
                if c_new < cost:
                    x, e_p, e_r, F, cost = x_new, p_new, r_new, F_new, c_new
                    lam = max(lam * 0.3, 1e-6)
                    improved = True
                    break
                lam *= 10.0
            if not improved or np.linalg.norm(dx) < 1e-7:
                break
        return x, float(np.linalg.norm(e_p)), float(np.linalg.norm(e_r))

    def solve(self, q: FloatArray, parent_placement: pin.SE3, reference: pin.SE3) -> ReachResult:
        """Whether ``reference`` (world) is reachable with the robot at ``q`` (its chain's parent joint at
        ``parent_placement``, the world placement at ``q``)."""
        M = self.target(parent_placement, reference)
        starts = [s for s in (self._last, np.asarray(q, dtype=float)[self.q_index], self.q_rest) if s is not None]
        best = None
        for x0 in starts:
            res = self._result(*self._descend(x0, M))
            score = res.position_residual + self.weight * res.rotation_residual
            if best is None or res.reachable or score < best[0]:
                best = (score, res)
            if res.reachable:
                break
        self._last = best[1].q.copy()
        return best[1]

    def track(self, q_chain: FloatArray, dt: float, parent_placement: pin.SE3, reference: pin.SE3) -> ReachResult:
        """One step of the speed-limited follower (module docstring): from the chain's joint positions ``q_chain``
        (the follower's last ones), the closest the chain comes to ``reference`` (world; the chain's parent joint
        at ``parent_placement``) with each joint moved by at most its velocity limit times ``dt`` [s] (a joint
        without a limit, 0 in the model, moves freely), within its position limits. The result's ``q`` is the
        follower's next state."""
        if dt < 0:
            raise ValueError(f"track: dt must be >= 0 s, got {dt!r}")
        x = np.clip(np.asarray(q_chain, dtype=float), self.lower, self.upper)
        step = np.where(self.velocity_limit > 0, self.velocity_limit * dt, np.inf)
        lower, upper = np.maximum(self.lower, x - step), np.minimum(self.upper, x + step)
        return self._result(*self._descend(x, self.target(parent_placement, reference), lower, upper))

    def _result(self, x: FloatArray, rp: float, rr: float) -> ReachResult:
        """A search's end ``x`` with its residuals as a result: reachable within the tolerances (the rotation only
        where it counts, and then 0 in the result)."""
        if not self.rotation:
            rr = 0.0
        return ReachResult(rp <= self.position_tolerance and rr <= self.rotation_tolerance, rp, rr, x)
