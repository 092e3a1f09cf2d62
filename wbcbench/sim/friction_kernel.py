"""The realism preset's Coulomb friction with stiction, one compiled call per physics step (see :mod:`wbcbench.jit`).

A per-joint switch between two phases (after Karnopp's stick-slip model), decided before each physics step from
the joint's velocity ``v`` (and the last step's):

- damper (sticking, stopping): the friction is a saturated damper, ``-min(stick |v|, coulomb) sign(v)``, put into
  MuJoCo's joint damping as its secant, ``min(stick, coulomb / |v|)`` (MuJoCo's implicitfast integrator treats
  damping implicitly: any value is stable). At rest under a net torque ``tau`` below break-away the joint creeps
  at ``tau / stick`` rad/s; a joint coming to a stop loses its velocity without overshooting through zero.
- sliding (+1 / -1): the constant ``-coulomb sign(v)`` (MuJoCo's ``qfrc_applied``), the joint's own (viscous)
  damping only. Entered from the damper phase when the joint breaks away (``stick |v| > coulomb`` and ``|v|``
  growing in the same direction), left when the velocity changes sign.

The friction force that MuJoCo's constraint solver sees (the explicit part) is therefore never above the break-away
torque: a heavy damper on a joint moving at a finite speed would otherwise enter the contact solution as a huge
torque for that step (MuJoCo solves the constraints with the explicit forces and applies implicit damping after).

MuJoCo's own `frictionloss` (a constraint of its solver) does the same job solved jointly with the contacts, but
with a stiction hard enough to hold a joint (creep of micro-radians per second) its Newton solver needs three to
four iterations a step instead of one (docs/results/real-robot.md, "Cost").
"""

from __future__ import annotations

from ..jit import njit
from .torque_loop_kernel import torque_loop_step

__all__ = ["joint_friction_step", "torque_loop_and_friction_step"]


@njit(exact=True)
def joint_friction_step(qvel, dof, coulomb, damping, stick, state, vprev, base, dof_damping, qfrc_applied):
    """One physics step's friction of the joints at MuJoCo degrees of freedom ``dof`` (n,): ``state`` (n, int:
    0 damper, +1 / -1 sliding in the positive / negative direction) and ``vprev`` (n,: the velocity at the last
    call) are updated from ``qvel``, and the damping (``damping`` (n,), the joint's own, plus the damper phase's)
    and the applied generalized force (``base`` (n,), the command's, minus ``coulomb`` (n,) in the sliding
    direction) written into MuJoCo's ``dof_damping`` and ``qfrc_applied``."""
    for i in range(dof.shape[0]):
        d = dof[i]
        v = qvel[d]
        vp = vprev[i]
        vprev[i] = v
        s = state[i]
        av = abs(v)
        fc = coulomb[i]
        if s == 0:
            if stick * av > fc and v * vp > 0.0 and av > abs(vp):  # breaks away
                s = 1 if v > 0.0 else -1
        elif v * s <= 0.0:  # the sliding joint stopped or turned: the damper stops it
            s = 0
        state[i] = s
        if s == 0:
            dof_damping[d] = damping[i] + (stick if stick * av <= fc else fc / av)
            qfrc_applied[d] = base[i]
        else:
            dof_damping[d] = damping[i]
            qfrc_applied[d] = base[i] - fc * s


@njit(exact=True)
def torque_loop_and_friction_step(buf, k, target, out, alpha, noise, limit, dst, idx, qvel, dof, coulomb, damping,
                                  stick, state, vprev, base, dof_damping, qfrc_applied):
    """`torque_loop_step` then `joint_friction_step` (their arguments in that order) in one call: each compiled
    call from Python costs about a microsecond of argument checks. Returns the torque loop's next row."""
    k = torque_loop_step(buf, k, target, out, alpha, noise, limit, dst, idx)
    joint_friction_step(qvel, dof, coulomb, damping, stick, state, vprev, base, dof_damping, qfrc_applied)
    return k
