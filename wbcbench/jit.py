"""The switch of the compiled kernels and the decorator they use (numba).

A control tick of a Python whole-body controller is a hundred or so small array operations; on TALOS-sized
problems (50 variables) each numpy or LAPACK call costs 1-8 us of interpreter and wrapper overhead, more than its
arithmetic. The kernels (wbcbench/qp/kernels.py, wbcbench/controllers/_kernels.py, wbcbench/stabilizers/_kernels.py,
wbcbench/tasks/placements.py, the self-collision task's) fuse such sequences into one call each. Each has one implementation: with ``WBCBENCH_JIT=0`` in the environment (or
numba missing) `njit` returns the function unchanged and the same code runs as plain Python (slow; for
debugging). The tests check every kernel against plain numpy/LAPACK references written in the tests.

Kernels are compiled on first use and cached on disk next to their sources (``__pycache__``, numba's
``cache=True``): the first process pays about 5-10 s, later ones load them in well under a second.
"""

from __future__ import annotations

import os

__all__ = ["JIT_ENABLED", "njit"]


def _enabled() -> bool:
    if os.environ.get("WBCBENCH_JIT", "1").strip().lower() in ("0", "false", "no", "off"):
        return False
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - numba is a dependency; kept for exotic platforms
        return False
    return True


JIT_ENABLED = _enabled()

if JIT_ENABLED:
    from numba import njit as _numba_njit

    # Reassociation lets LLVM vectorise the dot-product loops (sums in another order, as BLAS does); no
    # flag that assumes finite values: NaN must still fail the tests
    _FASTMATH = {"reassoc", "contract"}

    def njit(fn=None, *, exact: bool = False):
        """numba.njit with the options every kernel uses (cached on disk, vectorised sums). `exact=True`: no
        reassociation or fused multiply-add, i.e. the same IEEE arithmetic, operation by operation, as the
        numpy code the kernel replaces (for kernels whose results are logged bit for bit)."""
        if fn is None:
            return lambda f: njit(f, exact=exact)
        return _numba_njit(cache=True, nogil=True, fastmath=set() if exact else _FASTMATH,
                           error_model="numpy")(fn)
else:
    def njit(fn=None, *, exact: bool = False):
        """JIT off: the kernel runs as plain Python."""
        if fn is None:
            return lambda f: f
        return fn
