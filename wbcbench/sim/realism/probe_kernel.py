"""`RealismProbe`'s per-tick values in one compiled call (see :mod:`wbcbench.jit`): as numpy calls (a fancy index,
two 3x3 products, the list) they cost about 5 us a tick."""

from __future__ import annotations

from ...jit import njit

__all__ = ["realism_probe_values"]


@njit(exact=True)
def realism_probe_values(qpos, adr, geom_xpos, geom_xmat, soles, offset, out):
    """Into ``out`` (len(adr) + 3 len(soles)): ``qpos[adr]`` (the hidden joints' deflections), then per sole geom
    ``g`` of ``soles`` the point ``geom_xpos[g] - R offset`` (R = ``geom_xmat[g]`` as 3x3, row-major)."""
    n = adr.shape[0]
    for i in range(n):
        out[i] = qpos[adr[i]]
    for k in range(soles.shape[0]):
        g = soles[k]
        for r in range(3):
            out[n + 3 * k + r] = geom_xpos[g, r] - (geom_xmat[g, 3 * r] * offset[0] + geom_xmat[g, 3 * r + 1] * offset[1]
                                                    + geom_xmat[g, 3 * r + 2] * offset[2])
