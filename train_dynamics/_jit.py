"""Compile the physics kernels with numba when it is installed.

The model code is written once, in numpy array style with explicit loops only where a
recurrence demands one (the tridiagonal solve). numba compiles it to machine code and caches
the result next to the sources (or in numba's user cache when that is read-only). Without
numba (or with ``NUMBA_DISABLE_JIT=1``) the very same functions run as plain Python: correct,
but far slower.
"""
from __future__ import annotations

try:  # pragma: no cover - exercised by the installed environment
    import numba as _numba
except ImportError:  # pragma: no cover
    _numba = None

HAVE_NUMBA = _numba is not None

#: LLVM fast-math flags that keep IEEE NaN and infinity semantics (the fault checks rely
#: on them): approximate functions, contraction (FMA), reciprocal and sign-of-zero freedom.
_FASTMATH = {'afn', 'contract', 'arcp', 'nsz'}


def jit(func):
    """``numba.njit(cache=True)`` when numba is available, else the function itself."""
    if _numba is None:
        return func
    return _numba.njit(cache=True, nogil=True, fastmath=_FASTMATH)(func)
