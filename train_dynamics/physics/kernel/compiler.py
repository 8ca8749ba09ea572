"""
Compile the physics kernels with numba when it is installed, cached by content.

The model code is written once, per coach or per coupler, with loops where numpy would
allocate temporaries; numba compiles it to machine code (10-60 s) and this module caches
that code on disk so that a new process loads it in well under a second. Without numba (or
with ``NUMBA_DISABLE_JIT=1``) the very same functions run as plain Python: correct, slow.

Cache key. numba's own cache files a function under the path of its source folder and
checks only that one file: a copy of the package elsewhere (a colcon ``build``/``install``
tree, a fresh clone) compiles again, and a kernel of ``fixed_step.py`` that inlines a
function of ``brakes.py`` or freezes a constant of ``layout.py`` would keep running OLD code
after that file changed. Here every kernel is filed under :func:`source_digest`: a hash of
all kernel sources (:func:`kernel_sources`: every ``.py`` of this folder) and of
the Python, numba, llvmlite and numpy versions, never of a path. One folder
``numba-<digest>`` per code version; inside it numba's index keys each entry by the
function, its argument types and the CPU (name and features), so a changed source, a new
numba or another CPU can never load old machine code: it compiles instead.

Where. Entries are read from (1) ``_prebuilt/numba-<digest>`` next to this file, written
by ``setup.py build`` (so by ``colcon build`` and ``pip install``; read-only at run time), then
(2) the user cache ``$TRAIN_DYNAMICS_CACHE_DIR`` or ``$XDG_CACHE_HOME/train_dynamics``
(default ``~/.cache/train_dynamics``), where what compiles at run time is written; a private
folder of the system's temporary directory when that is not writable, and nowhere (compiled
in memory each start) when none is. The user cache keeps the folders of the few most recently
used code versions and of all used in the last two weeks. ``NUMBA_CACHE_DIR`` does not apply
to these kernels (numba's own cache would file them by path).

Progress. Compiling takes minutes the first time a code version runs (numba: seconds per
kernel function). :func:`report_compilation` prints a line per compiled function (name,
seconds): on stderr when it is a terminal or ``TRAIN_DYNAMICS_COMPILE_PROGRESS=1`` (0: never),
and always at build time (``cli/prebuild.py``). Only what a run calls compiles (numba compiles
a function at its first call with new argument types), so a run of a configuration waits only
for its own kernels.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import re
import shutil
import sys
import tempfile
import time

try:  # pragma: no cover - exercised by the installed environment
    import llvmlite
    import numba as _numba
    from numba.core import caching as _caching
    from numba.core.dispatcher import Dispatcher as _Dispatcher
    import numpy
except ImportError:  # pragma: no cover
    _numba = None

HAVE_NUMBA = _numba is not None
#: numba's cache classes this module builds on (numba.core.caching, stable since 0.4x)
_CACHE_API = HAVE_NUMBA and all(hasattr(_caching, name) for name in (
    '_CacheLocator', 'CompileResultCacheImpl', 'FunctionCache', 'IndexDataCacheFile'))

#: LLVM fast-math flags that keep IEEE NaN and infinity semantics (the fault checks rely
#: on them): approximate functions, contraction (FMA), reciprocal and sign-of-zero freedom.
_FASTMATH = {'afn', 'contract', 'arcp', 'nsz'}

_HERE = os.path.dirname(os.path.abspath(__file__))
#: the parameter table, where the per-vehicle kernel rows are declared
_TABLE = os.path.join(os.path.dirname(_HERE), 'config', 'table.py')


def kernel_sources(folder: str | None = None) -> tuple[str, ...]:
    """
    Return the kernel's source files: every ``.py`` of ``folder`` (this folder), sorted.

    The compiled code of one kernel module depends on the others (numba inlines functions
    and freezes global constants), so the digest covers them all; a module that defines a
    jitted function lives here (``test_kernel_cache.py`` checks it).
    """
    folder = folder or _HERE
    try:
        return tuple(sorted(n for n in os.listdir(folder) if n.endswith('.py')))
    except OSError:
        return ()


#: the folder (next to this file) of the kernels compiled at build time
PREBUILT = '_prebuilt'

#: the user cache keeps the folders of the KEEP_VERSIONS most recently used code versions and
#: of all used within MAX_AGE_S
KEEP_VERSIONS = 4
MAX_AGE_S = 14 * 86400.0

_state: dict = {}
_dispatchers: list = []


def source_digest(folder: str = _HERE) -> str:
    """Return the hex digest of the kernel sources in ``folder`` and the compiler versions."""
    digest = hashlib.sha256()
    for name in kernel_sources(folder):
        digest.update(name.encode() + b'\0')
        try:
            with open(os.path.join(folder, name), 'rb') as fh:
                digest.update(fh.read())
        except OSError:
            digest.update(b'missing')
    versions = (sys.version_info[:2], sys.implementation.cache_tag,
                getattr(_numba, '__version__', ''),
                getattr(llvmlite, '__version__', '') if HAVE_NUMBA else '',
                getattr(numpy, '__version__', '') if HAVE_NUMBA else '')
    digest.update(repr(versions).encode())
    digest.update(repr(table_kernel_rows()).encode())
    return digest.hexdigest()


def table_kernel_rows(table: str = _TABLE) -> list[str]:
    """
    Return the kernel rows the parameter table declares (``row='...'``), in table order.

    The layout's per-vehicle rows come from the table, outside this folder, and numba freezes
    the row indices into the machine code, so the digest covers them. Read from the source,
    not imported: the digest is taken while the kernel modules are being imported.
    """
    try:
        with open(table, encoding='utf-8') as fh:
            return re.findall(r"\brow='(\w+)'", fh.read())
    except OSError:
        return ['missing']


def _digest() -> str:
    """Return :func:`source_digest` of this package (computed once per process)."""
    if 'digest' not in _state:
        _state['digest'] = source_digest()
    return _state['digest']


def _tag() -> str:
    return 'numba-' + _digest()[:20]


def user_cache_root() -> str:
    """Return the folder holding the user cache's ``numba-<digest>`` folders."""
    return os.environ.get('TRAIN_DYNAMICS_CACHE_DIR') or os.path.join(
        os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache'),
        'train_dynamics')


def prebuilt_dir() -> str:
    """Return the build-time kernel folder of this code version (it may not exist)."""
    return os.path.join(_HERE, PREBUILT, _tag())


def _private_tmp_root() -> str | None:
    """Return a temporary folder only this user can write (cache files are pickles)."""
    uid = os.getuid() if hasattr(os, 'getuid') else 0
    root = os.path.join(tempfile.gettempdir(), f'train_dynamics_cache-{uid}')
    try:
        os.makedirs(root, mode=0o700, exist_ok=True)
        st = os.stat(root)
    except OSError:
        return None
    if st.st_uid != uid or st.st_mode & 0o022:
        return None
    return root


def kernel_cache_dir() -> str:
    """Return the writable cache folder of this code version; '' when there is none."""
    if 'dir' in _state:
        return _state['dir']
    _state['dir'] = ''
    for root in (user_cache_root(), _private_tmp_root()):
        if not root:
            continue
        path = os.path.join(root, _tag())
        try:
            os.makedirs(path, exist_ok=True)
            tempfile.TemporaryFile(dir=path).close()
        except OSError:
            continue
        _state['dir'] = path
        _prune(root, keep=path)
        break
    return _state['dir']


def _prune(root: str, keep: str) -> None:
    """Remove the code versions in ``root`` unused for MAX_AGE_S beyond KEEP_VERSIONS."""
    try:
        os.utime(keep)                       # mark this version as used now
        folders = [os.path.join(root, n) for n in os.listdir(root) if n.startswith('numba-')]
        folders.sort(key=lambda p: os.stat(p).st_mtime, reverse=True)
    except OSError:
        return
    for path in folders[KEEP_VERSIONS:]:
        try:
            if path != keep and time.time() - os.stat(path).st_mtime > MAX_AGE_S:
                shutil.rmtree(path, ignore_errors=True)
        except OSError:
            continue


def _file_stem(py_func) -> str:
    """Return the start of a kernel's cache file names: ``<module file>.<qualified name>``."""
    modname = os.path.splitext(os.path.basename(py_func.__code__.co_filename))[0]
    return f'{modname}.{py_func.__qualname__}'


def is_cached(function) -> bool:
    """Tell whether a :func:`jit` kernel of this code version has a file in the kernel cache."""
    py_func = getattr(function, 'py_func', None)
    if py_func is None:
        return False
    stem = _file_stem(py_func)
    for folder in (prebuilt_dir(), kernel_cache_dir()):
        try:
            if folder and any(name.startswith(stem) for name in os.listdir(folder)):
                return True
        except OSError:
            continue
    return False


if _CACHE_API:
    class _KernelLocator(_caching._CacheLocator):
        """File a kernel under the code version (:func:`source_digest`), not its path."""

        def __init__(self, py_func, py_file: str):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno

        def ensure_cache_path(self):
            """Create the writable folder; raise OSError when there is none."""
            if not kernel_cache_dir():
                raise OSError('no writable kernel cache folder')

        def get_cache_path(self) -> str:
            """Return the writable folder ('' when there is none)."""
            return kernel_cache_dir()

        def get_source_stamp(self) -> str:
            """Return the digest of all kernel sources (the folder name has its prefix)."""
            return _digest()

        def get_disambiguator(self) -> str:
            """Return the function's first line (two functions of one name in one file)."""
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file: str):
            """Return the locator of ``py_func``."""
            return cls(py_func, py_file)

    class _KernelCacheImpl(_caching.CompileResultCacheImpl):
        """numba's compile-result cache with :class:`_KernelLocator` as the only locator."""

        def __init__(self, py_func):  # numba's __init__ less its locator search
            self._lineno = py_func.__code__.co_firstlineno
            self._locator = _KernelLocator(py_func, py_func.__code__.co_filename)
            self._filename_base = self.get_filename_base(_file_stem(py_func),
                                                         getattr(sys, 'abiflags', ''))

    class KernelCache(_caching.FunctionCache):
        """
        Load a kernel from the build-time folder, then the user cache; save to the latter.

        A file that cannot be read (truncated, from a foreign numba) is a miss, a cache that
        cannot be written leaves the compiled code in memory: neither stops the simulation.
        """

        _impl_class = _KernelCacheImpl

        def __init__(self, py_func):
            super().__init__(py_func)
            base, stamp = self._impl.filename_base, _digest()
            self._files = [_caching.IndexDataCacheFile(d, base, stamp)
                           for d in (prebuilt_dir(), kernel_cache_dir()) if d]

        def _load_overload(self, sig, target_context):
            if not self._enabled:
                return None
            key = self._index_key(sig, target_context.codegen())
            for cache_file in self._files:
                try:
                    data = cache_file.load(key)
                    if data is not None:
                        return self._impl.rebuild(target_context, data)
                except (OSError, EOFError, pickle.UnpicklingError, AttributeError,
                        ImportError, IndexError, KeyError, TypeError, ValueError):
                    continue
            return None

        def _save_overload(self, sig, data):
            if not kernel_cache_dir():
                return
            try:
                super()._save_overload(sig, data)
            except OSError:
                pass


def cache_stats() -> dict:
    """Return the kernel signatures loaded from the cache and compiled in this process."""
    hits = sum(sum(getattr(d, '_cache_hits', {}).values()) for d in _dispatchers)
    misses = sum(sum(getattr(d, '_cache_misses', {}).values()) for d in _dispatchers)
    return {'loaded': hits, 'compiled': misses}


if HAVE_NUMBA:
    from numba.core import event as _event

    class CompileProgress(_event.Listener):
        """
        Report each kernel compilation as it ends: one line, the function and its seconds.

        numba broadcasts ``numba:compile`` around every compilation that the cache could not
        serve (numba.core.event, numba >= 0.53); a kernel's callees compile inside it.
        """

        def __init__(self, write) -> None:
            self._write = write
            self._started: list[float] = []
            self._announced = False
            self.count = 0

        def on_start(self, event) -> None:
            """Note the start (and announce the first compilation)."""
            if not self._announced:
                self._announced = True
                self._write('train_dynamics: compiling the numba kernels this run needs (once '
                            f'per code version; cached in {kernel_cache_dir() or "memory"})')
            self._started.append(time.perf_counter())

        def on_end(self, event) -> None:
            """Report the kernel function compiled and how long it took (numba's own: not)."""
            seconds = time.perf_counter() - self._started.pop()
            func = event.data['dispatcher'].py_func
            if not func.__module__.startswith('train_dynamics.'):
                return          # numba's implementation of a numpy function: in its caller
            self.count += 1
            module = func.__module__.rsplit('.', 1)[-1]
            self._write(f'train_dynamics: compiled {module}.{func.__qualname__} '
                        f'({seconds:.1f} s; {self.count} so far)')


def report_compilation(write=None) -> bool:
    """
    Report every kernel compilation of this process with ``write`` (a line each).

    ``write`` None: on stderr, when it is a terminal or ``TRAIN_DYNAMICS_COMPILE_PROGRESS`` is
    1 (a user waiting at the first start of a code version; tests and logs stay quiet).
    Returns True if installed; a later call with a ``write`` replaces the reporter.
    """
    if not HAVE_NUMBA or ('progress' in _state and write is None):
        return False
    if write is None:
        wanted = os.environ.get('TRAIN_DYNAMICS_COMPILE_PROGRESS')
        if wanted == '0' or (wanted != '1' and not _isatty(sys.stderr)):
            return False

        def write(line: str) -> None:
            print(line, file=sys.stderr, flush=True)
    if 'progress' in _state:
        _event.unregister('numba:compile', _state.pop('progress'))
    _state['progress'] = CompileProgress(write)
    _event.register('numba:compile', _state['progress'])
    return True


def _isatty(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def jit(func=None, *, inline: bool = False):
    """
    Compile ``func`` with numba, cached by content (see the module); without numba keep it.

    ``@jit(inline=True)``: numba inlines the function into its compiled callers (at its IR
    level), for the small named pieces of a kernel: a call costs the reference counting of
    every array argument, which a 3-coach step would notice for many small calls. Not for
    large pieces: an inlined function is compiled again inside each caller, and numba's
    compilation of one large function grows faster than its code (the fixed-step driver with
    everything inlined: 85-90 % of the default kernels' compilation; see ``fixed_step.py``).
    """
    if func is None:
        return lambda f: jit(f, inline=inline)
    if _numba is None:
        return func
    options = {'nogil': True, 'fastmath': _FASTMATH, 'inline': 'always' if inline else 'never'}
    if not _CACHE_API:     # pragma: no cover - another numba: its own cache, in our folder
        saved, _numba.config.CACHE_DIR = _numba.config.CACHE_DIR, kernel_cache_dir()
        try:
            return _numba.njit(cache=bool(kernel_cache_dir()), **options)(func)
        finally:
            _numba.config.CACHE_DIR = saved
    dispatcher = _numba.njit(cache=False, **options)(func)
    if isinstance(dispatcher, _Dispatcher):   # not NUMBA_DISABLE_JIT
        dispatcher._cache = KernelCache(func)       # what Dispatcher.enable_caching sets
        _dispatchers.append(dispatcher)
    return dispatcher


def compile_for(function, args) -> bool:
    """
    Compile ``function`` (a :func:`jit` kernel) for the types of ``args``, or load it; say if.

    What its first call with ``args`` would compile, without the call (``cli/prebuild.py``
    compiles the fixed-step driver's parts so, in parallel processes). False without numba.
    """
    if not HAVE_NUMBA or not isinstance(function, _Dispatcher):
        return False
    function.compile(tuple(_numba.typeof(a) for a in args))
    return True


def _skip_blas_probe() -> bool:
    """
    Import numba's array functions without their probe for scipy's BLAS; return True if done.

    ``numba.np.arraymath`` calls ``numba.np.linalg.ensure_blas`` when it is imported (when
    the first kernel is loaded or compiled), which imports ``scipy.linalg``: 0.10-0.12 s of
    CPU time, an eighth of the offline command's start-up (measured: 0.25 s -> 0.14 s for the
    first kernel call). The probe only decides how ``np.convolve`` and ``np.correlate`` are
    compiled (with or without BLAS); the kernels use neither, nor ``np.dot`` or ``np.linalg``.
    The probe is made to fail while the module is imported, then restored, so that
    ``np.dot``/``np.linalg`` in other jitted code still find scipy's BLAS at their compilation.
    Nothing is done when the module is already imported or numba's names differ.
    """
    if not HAVE_NUMBA or 'numba.np.arraymath' in sys.modules:
        return False
    try:
        from numba.np import linalg as _linalg
    except ImportError:     # pragma: no cover - another numba
        return False
    saved = getattr(_linalg, 'ensure_blas', None)
    if saved is None:       # pragma: no cover - another numba
        return False

    def _not_probed():
        raise ImportError('train_dynamics: BLAS probe skipped (the kernels use no BLAS)')

    _linalg.ensure_blas = _not_probed
    try:
        import numba.np.arraymath  # noqa: F401
    except ImportError:     # pragma: no cover
        return False
    finally:
        _linalg.ensure_blas = saved
    return True


_skip_blas_probe()
report_compilation()      # a user at a terminal sees what the first start compiles
