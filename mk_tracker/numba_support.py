"""Whether the compiled (numba) paths of the detector and the tracker can be used.

The sparse kernel covariance detector (:mod:`mk_tracker.detection.kernel_covariance`) and
the multiple-kernel tracker's histograms (:mod:`mk_tracker.tracking.search_region`) run
their inner loops as numba functions when numba can be imported, and fall back to numpy
otherwise (or when the environment variable ``MK_TRACKER_NO_NUMBA`` is set).  They all ask
:func:`import_numba`, so the nodes can say at start-up which path they will run
(:func:`fallback_warning`).  The numpy paths are slower: on the 2-core development machine
the detector took 4-8x as long per frame and a tracked target 1.3-2.8x as long per refine,
over five runs at different loads (benchmarks/numba_fallback.py, docs/numba_fallback.md).
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Callable

DISABLE_VARIABLE = "MK_TRACKER_NO_NUMBA"
#: Measured slow-down of the numpy fallback (module docstring), for the start-up warning.
FALLBACK_SLOWDOWN = "measured 4-8x per detector frame, 1.3-2.8x per tracked target"


def import_numba() -> ModuleType:
    """The numba module; ImportError (with the reason) when the compiled paths are off."""
    if os.environ.get(DISABLE_VARIABLE):
        raise ImportError(f"disabled by {DISABLE_VARIABLE}")
    import numba
    return numba


def unavailable_reason() -> str | None:
    """Why the compiled paths are not used (None: they are)."""
    try:
        import_numba()
    except ImportError as exc:
        return str(exc) or type(exc).__name__
    return None


def fallback_warning() -> str | None:
    """The one start-up warning line of a node when numba is unavailable, else None."""
    reason = unavailable_reason()
    if reason is None:
        return None
    return (f"compiled (numba) kernels unavailable ({reason}): using the numpy fallback, "
            f"slower ({FALLBACK_SLOWDOWN}); install python3-numba or pip install numba")


_BIT_CASTS: list = []


def register_bit_casts(float_bits: Callable, bits_float: Callable) -> None:
    """Compile the plain-Python bit casts ``float_bits`` (a float64's bit pattern as an
    int64) and ``bits_float`` (the reverse) to an LLVM ``bitcast`` (no arithmetic) in numba
    code, for compiled functions that read a double's exponent bits
    (:func:`mk_tracker.detection.sparse_factorization._cube_root`); the Python functions
    stay what Python calls.  Once per process; needs numba."""
    if _BIT_CASTS:
        return
    numba = import_numba()
    from llvmlite import ir
    from numba.extending import intrinsic, overload

    @intrinsic
    def to_bits(typingctx, x):
        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], ir.IntType(64))
        return numba.types.int64(numba.types.float64), codegen

    @intrinsic
    def from_bits(typingctx, i):
        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], ir.DoubleType())
        return numba.types.float64(numba.types.int64), codegen

    @overload(float_bits)
    def _float_bits_impl(x):
        return lambda x: to_bits(x)

    @overload(bits_float)
    def _bits_float_impl(i):
        return lambda i: from_bits(i)

    _BIT_CASTS.append(True)
