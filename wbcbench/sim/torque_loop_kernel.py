"""The realism torque loop's physics step in one compiled call (see :mod:`wbcbench.jit`).

In Python the loop's step (ring buffer, first-order lag, noise, clip, the write into MuJoCo's ``ctrl``) was a
dozen numpy calls, about 10 us per physics step; compiled it is one call. It is an `exact` kernel: the same IEEE
operations in the same order as that numpy code, so the delivered torques do not change (a test checks them
against it).
"""

from __future__ import annotations

from ..jit import njit

__all__ = ["torque_loop_step"]


@njit(exact=True)
def torque_loop_step(buf, k, target, out, alpha, noise, limit, dst, idx):
    """One physics step of the loop: ``target`` (n,) into the delay line ``buf`` (delay + 1, n) at row ``k``, the
    lag ``out`` (n,) moves by ``alpha`` towards the command of ``delay`` steps ago, the sensor's ``noise`` (n,, or
    empty: none) is subtracted and the torque, clipped to +-``limit``, written to ``dst[idx[i]]``. Returns the next
    row ``k``."""
    n = out.shape[0]
    for i in range(n):
        buf[k, i] = target[i]
    k = (k + 1) % buf.shape[0]
    for i in range(n):
        out[i] += alpha * (buf[k, i] - out[i])
        tau = out[i] - noise[i] if noise.shape[0] else out[i]
        dst[idx[i]] = min(max(tau, -limit[i]), limit[i])
    return k
