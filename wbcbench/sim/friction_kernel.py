"""The realism preset's Coulomb friction with stiction, one compiled call per physics step (see :mod:`wbcbench.jit`).

A stick-slip switch per joint (Karnopp's model) whose stick phase is a heavy viscous damper that MuJoCo integrates
implicitly: sticking, the joint's damping is raised by ``stick`` [N m s/rad] (MuJoCo's ``dof_damping``, implicit in
velocity under the implicitfast integrator, so any value is stable), which holds it within ``tau / stick`` rad/s
of rest under a net torque ``tau``; the damper's force is the friction force. When that force would exceed the
break-away torque ``coulomb`` the joint slides: the friction becomes the constant ``-coulomb sign(v)`` (through
MuJoCo's ``qfrc_applied``) and the damping the joint's own (viscous) again, until the velocity changes sign, when
it sticks again. The switch is decided once per physics step from the velocity the step ended with.

MuJoCo's own `frictionloss` (a constraint of its solver) does the same job solved jointly with the contacts, but
with a stiction hard enough to hold a joint (creep of micro-radians per second) its Newton solver needs three to
four iterations a step instead of one (docs/results/real-robot.md, "Cost").
"""

from __future__ import annotations

from ..jit import njit

__all__ = ["joint_friction_step"]


@njit(exact=True)
def joint_friction_step(qvel, dof, coulomb, damping, stick, state, base, dof_damping, qfrc_applied):
    """One physics step's friction of the joints at MuJoCo degrees of freedom ``dof`` (n,): ``state`` (n, int:
    0 sticking, +1 / -1 sliding in the positive / negative direction) is updated from ``qvel`` and the damping
    (``damping`` (n,), the joint's own, plus ``stick`` while sticking) and the applied generalized force
    (``base`` (n,), the command's, minus ``coulomb`` (n,) in the sliding direction) written into MuJoCo's
    ``dof_damping`` and ``qfrc_applied``."""
    for i in range(dof.shape[0]):
        d = dof[i]
        v = qvel[d]
        s = state[i]
        if s == 0:  # stuck through the last step: its friction was the damper's force
            if abs(stick * v) > coulomb[i]:
                s = 1 if v > 0.0 else -1
        elif v * s <= 0.0:  # the sliding joint stopped or turned: it sticks
            s = 0
        state[i] = s
        if s == 0:
            dof_damping[d] = damping[i] + stick
            qfrc_applied[d] = base[i]
        else:
            dof_damping[d] = damping[i]
            qfrc_applied[d] = base[i] - coulomb[i] * s
