"""
Compile the physics kernels with numba when it is installed.

The model code is written once, per coach or per coupler, with loops where numpy would
allocate temporaries; numba compiles it to machine code and caches it on disk so a new
process starts in about a second instead of compiling for half a minute. Without numba (or
with ``NUMBA_DISABLE_JIT=1``) the very same functions run as plain Python: correct, slow.

Cache location. numba keys a cached function on its own file only: a kernel in
``integrators.py`` that inlines a function of ``brakes.py``, or freezes a constant of
``layout.py``, keeps running the OLD code after that file changes. So the cache lives in a
directory named after a hash of all the kernel sources (:data:`KERNEL_SOURCES`: every
physics module with compiled functions and every module they take code or constants from;
``test_integrators.py`` checks the list) and the numba and Python versions:
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

#: the modules (of this folder) whose compiled code depends on each other
KERNEL_SOURCES = ('_jit.py', 'brakes.py', 'couplers.py', 'integrators.py', 'layout.py',
                  'pneumatic.py', 'resistance.py', 'standstill.py', 'track.py', 'traction.py')

_cache_dir: str | None = None


def kernel_cache_dir() -> str:
    """Return the directory of the compiled-kernel cache for this version of the sources."""
    global _cache_dir
    if _cache_dir is not None:
        return _cache_dir
    digest = hashlib.sha256()
    here = os.path.dirname(os.path.abspath(__file__))
    for name in KERNEL_SOURCES:
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


def jit(func=None, *, inline: bool = False):
    """
    Compile ``func`` with numba, cached in :func:`kernel_cache_dir`; without numba keep it.

    ``@jit(inline=True)``: numba inlines the function into its compiled callers (at its IR
    level), for the named steps of a kernel that run once per step: a call costs the
    reference counting of every array argument, which a 3-coach step would notice.
    """
    if func is None:
        return lambda f: jit(f, inline=inline)
    if _numba is None:
        return func
    options = {'nogil': True, 'fastmath': _FASTMATH, 'inline': 'always' if inline else 'never'}
    if os.environ.get('NUMBA_CACHE_DIR'):
        return _numba.njit(cache=True, **options)(func)
    path = kernel_cache_dir()
    if not path:       # nowhere to write: compile in memory
        return _numba.njit(cache=False, **options)(func)
    saved = _numba.config.CACHE_DIR
    _numba.config.CACHE_DIR = path     # read when the dispatcher sets up its cache
    try:
        return _numba.njit(cache=True, **options)(func)
    finally:
        _numba.config.CACHE_DIR = saved
