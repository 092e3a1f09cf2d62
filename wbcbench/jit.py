"""The switch of the compiled kernels and the decorator they use (numba).

A control tick of a Python whole-body controller is a hundred or so small array operations; on TALOS-sized
problems (50 variables) each numpy or LAPACK call costs 1-8 us of interpreter and wrapper overhead, more than its
arithmetic. The kernels (wbcbench/qp/kernels.py, wbcbench/controllers/_kernels.py, wbcbench/stabilizers/_kernels.py,
wbcbench/tasks/placements.py, the self-collision task's) fuse such sequences into one call each. Each has one implementation: with ``WBCBENCH_JIT=0`` in the environment (or
numba missing) `njit` returns the function unchanged and the same code runs as plain Python (slow; for
debugging). The tests check every kernel against plain numpy/LAPACK references written in the tests.

`c_view(a, shape)` views a slice of a flat buffer with a shape inside a kernel, as ``a.reshape(shape)`` but
without its checks (numba's reshape costs ~30 ns, an argument of a compiled call ~40 ns): the kernels that take a few
flat buffers instead of many arrays (estimation/_memo.py) view them with it.

Kernels are compiled on first use and cached on disk next to their sources (``__pycache__``, numba's
``cache=True``): the first process pays about 5-10 s, later ones load them in well under a second.
"""

from __future__ import annotations

import os

__all__ = ["JIT_ENABLED", "c_view", "njit"]


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

    def njit(fn=None, *, exact: bool = False, inline: bool = False):
        """numba.njit with the options every kernel uses (cached on disk, vectorised sums). `exact=True`: no
        reassociation or fused multiply-add, i.e. the same IEEE arithmetic, operation by operation, as the
        numpy code the kernel replaces (for kernels whose results are logged bit for bit). `inline=True`: a
        helper inlined into the kernels that call it (numba's ``inline="always"``), which saves a call that passes
        many arrays (~10 ns an array). The inlined code takes its caller's `exact`: only for helpers without
        floating-point arithmetic (views, comparisons, copies), or whose compiled callers all have the helper's
        `exact` (their docstrings say so). And only for small helpers: each caller compiles the body again (the
        forward kinematics inlined into the four kernels that place joints took a first IK run's compile time
        from 19 to 37 s, for less than a microsecond a tick)."""
        if fn is None:
            return lambda f: njit(f, exact=exact, inline=inline)
        return _numba_njit(cache=True, nogil=True, fastmath=set() if exact else _FASTMATH,
                           error_model="numpy", inline="always" if inline else "never")(fn)

    from numba import types as _types
    from numba.core import cgutils as _cgutils
    from numba.core.imputils import impl_ret_borrowed as _borrowed
    from numba.extending import intrinsic as _intrinsic
    from numba.np.arrayobj import make_array as _make_array, populate_array as _populate_array

    @_intrinsic
    def c_view(typingctx, a, shape):
        """Inside a kernel: the C-contiguous array ``a`` (e.g. a slice ``buf[o:o + 9 * n]`` of a flat buffer) as
        an array of ``shape`` (a tuple of integers), a view. Unchecked: ``a`` must hold exactly that many items
        (as ``a.reshape(shape)`` without the size check and the stride computation of numba's reshape)."""
        if not (isinstance(a, _types.Array) and a.layout == "C" and isinstance(shape, _types.BaseTuple)
                and len(shape) > 0 and all(isinstance(d, _types.Integer) for d in shape)):
            return None
        ret = a.copy(ndim=len(shape), layout="C")

        def codegen(context, builder, sig, args):
            src = _make_array(sig.args[0])(context, builder, args[0])
            out = _make_array(sig.return_type)(context, builder)
            dims = [context.cast(builder, d, t, _types.intp)
                    for d, t in zip(_cgutils.unpack_tuple(builder, args[1]), sig.args[1])]
            strides, step = [], src.itemsize
            for d in reversed(dims):  # C order: each stride the item size times the later dimensions
                strides.insert(0, step)
                step = builder.mul(step, d)
            _populate_array(out, data=src.data, shape=dims, strides=strides, itemsize=src.itemsize,
                            meminfo=src.meminfo)
            return _borrowed(context, builder, sig.return_type, out._getvalue())

        return ret(a, shape), codegen
else:
    def njit(fn=None, *, exact: bool = False, inline: bool = False):
        """JIT off: the kernel runs as plain Python."""
        if fn is None:
            return lambda f: f
        return fn

    def c_view(a, shape):
        """JIT off: ``a.reshape(shape)``."""
        return a.reshape(shape)
