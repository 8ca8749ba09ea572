"""Compile the physics kernels with numba when it is installed.

The model code is written once, per coach or per coupler, with loops where numpy would
allocate temporaries; numba compiles it to machine code and caches it on disk so a new
process starts in about a second instead of compiling for half a minute. Without numba (or
with ``NUMBA_DISABLE_JIT=1``) the very same functions run as plain Python: correct, slow.

Cache location. numba keys a cached function on its own file only: a kernel in
``integrators.py`` that inlines a function of ``brakes.py`` keeps running the OLD brakes code
after ``brakes.py`` changes. So the cache lives in a directory named after a hash of all
the kernel sources (and the numba and Python versions):
``$TRAIN_DYNAMICS_CACHE_DIR`` or ``$XDG_CACHE_HOME/train_dynamics`` (default
``~/.cache/train_dynamics``), one ``numba-<hash>`` folder per code version; the system's
temporary directory when that is not writable. ``NUMBA_CACHE_DIR``, when set, wins.
"""
from __future__ import annotations

import hashlib
import os
import sys
import tempfile

try:  # pragma: no cover - exercised by the installed environment
    import numba as _numba
except ImportError:  # pragma: no cover
    _numba = None

HAVE_NUMBA = _numba is not None

#: LLVM fast-math flags that keep IEEE NaN and infinity semantics (the fault checks rely
#: on them): approximate functions, contraction (FMA), reciprocal and sign-of-zero freedom.
_FASTMATH = {'afn', 'contract', 'arcp', 'nsz'}

#: the modules whose compiled code depends on each other
_KERNEL_SOURCES = ('_jit.py', 'couplers.py', 'brakes.py', 'integrators.py', 'train.py',
                   'pneumatic.py')

_cache_dir: str | None = None


def kernel_cache_dir() -> str:
    """Directory of the compiled-kernel cache for this exact version of the sources."""
    global _cache_dir
    if _cache_dir is not None:
        return _cache_dir
    digest = hashlib.sha256()
    here = os.path.dirname(os.path.abspath(__file__))
    for name in _KERNEL_SOURCES:
        try:
            with open(os.path.join(here, name), 'rb') as fh:
                digest.update(fh.read())
        except OSError:
            digest.update(name.encode())
    digest.update(f'{sys.version_info[:2]} {getattr(_numba, "__version__", "")}'.encode())
    tag = 'numba-' + digest.hexdigest()[:16]
    base = os.environ.get('TRAIN_DYNAMICS_CACHE_DIR') or os.path.join(
        os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache'),
        'train_dynamics')
    for root in (base, os.path.join(tempfile.gettempdir(), 'train_dynamics_cache')):
        path = os.path.join(root, tag)
        try:
            os.makedirs(path, exist_ok=True)
            if os.access(path, os.W_OK):
                _cache_dir = path
                return path
        except OSError:
            continue
    _cache_dir = ''
    return _cache_dir


def jit(func):
    """``numba.njit(cache=True)`` into :func:`kernel_cache_dir`, or the function itself."""
    if _numba is None:
        return func
    if os.environ.get('NUMBA_CACHE_DIR'):
        return _numba.njit(cache=True, nogil=True, fastmath=_FASTMATH)(func)
    path = kernel_cache_dir()
    if not path:       # nowhere to write: compile in memory
        return _numba.njit(cache=False, nogil=True, fastmath=_FASTMATH)(func)
    saved = _numba.config.CACHE_DIR
    _numba.config.CACHE_DIR = path     # read when the dispatcher sets up its cache
    try:
        return _numba.njit(cache=True, nogil=True, fastmath=_FASTMATH)(func)
    finally:
        _numba.config.CACHE_DIR = saved
