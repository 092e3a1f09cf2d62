"""Ground-truth contact wrenches on the soles in one compiled call (see :mod:`wbcbench.jit`).

MuJoCo stores each contact's force as constraint forces (``efc_force``): with a pyramidal friction cone, ``2 (dim -
1)`` non-negative edge forces whose sum is the normal force and whose pairwise differences times the friction
coefficients are the tangential ones (``mju_decodePyramid``); with an elliptic cone, the contact-frame force itself.
``mj_contactForce`` decodes one contact per Python call; this kernel decodes them all, rotates them to the world
(the contact frame's rows are its axes, normal first) and sums force and moment about the world origin per sole.
A test checks it against ``mj_contactForce``.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit

__all__ = ["sole_wrenches"]


@njit
def sole_wrenches(efc_force, efc_address, dim, friction, frame, pos, geom, soles, pyramidal, out):
    """Fill ``out`` (len(soles), 6) with the wrench (force, moment about the world origin) that contacts exert on
    each sole geom, world axes [N, N m]. Contact arrays as MuJoCo's ``data.contact`` fields for the ``n`` current
    contacts: ``efc_address`` (n,), ``dim`` (n,), ``friction`` (n, 5), ``frame`` (n, 9), ``pos`` (n, 3), ``geom``
    (n, 2); the force acts from ``geom[0]`` on ``geom[1]``. ``pyramidal``: the model's cone type. Contacts with
    ``efc_address < 0`` (excluded) carry no force."""
    out[:] = 0.0
    n = efc_address.shape[0]
    local = np.zeros(3)
    sgn = np.zeros(soles.shape[0])
    for i in range(n):
        sgn[:] = 0.0
        hit = False
        for k in range(soles.shape[0]):
            if geom[i, 0] == soles[k]:
                sgn[k] = -1.0
                hit = True
            elif geom[i, 1] == soles[k]:
                sgn[k] = 1.0
                hit = True
        adr = efc_address[i]
        if not hit or adr < 0:
            continue
        d = dim[i]
        local[:] = 0.0
        if pyramidal:
            if d == 1:
                local[0] = efc_force[adr]
            else:
                s = 0.0
                for j in range(2 * (d - 1)):
                    s += efc_force[adr + j]
                local[0] = s
                for j in range(min(d - 1, 2)):
                    local[j + 1] = (efc_force[adr + 2 * j] - efc_force[adr + 2 * j + 1]) * friction[i, j]
        else:
            for j in range(min(d, 3)):
                local[j] = efc_force[adr + j]
        f0 = frame[i, 0] * local[0] + frame[i, 3] * local[1] + frame[i, 6] * local[2]
        f1 = frame[i, 1] * local[0] + frame[i, 4] * local[1] + frame[i, 7] * local[2]
        f2 = frame[i, 2] * local[0] + frame[i, 5] * local[1] + frame[i, 8] * local[2]
        p0, p1, p2 = pos[i, 0], pos[i, 1], pos[i, 2]
        for k in range(soles.shape[0]):
            if sgn[k] == 0.0:
                continue
            g0, g1, g2 = sgn[k] * f0, sgn[k] * f1, sgn[k] * f2
            out[k, 0] += g0
            out[k, 1] += g1
            out[k, 2] += g2
            out[k, 3] += p1 * g2 - p2 * g1
            out[k, 4] += p2 * g0 - p0 * g2
            out[k, 5] += p0 * g1 - p1 * g0
