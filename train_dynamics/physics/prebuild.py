"""
Compile the numba kernels ahead of the first start (``python -m train_dynamics.physics.prebuild``).

``make venv`` runs it to fill the user cache; ``setup.py build`` (so ``colcon build`` and
``pip install``) runs it with ``--into <build>/train_dynamics/physics/_prebuilt`` so the
installed package carries the compiled kernels of its own code version (see ``_jit.py``).
It runs :func:`train_dynamics.physics.train.warmup` (every kernel variant a start can use),
which loads from or compiles into the user cache, then copies this version's folder of it.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time

from train_dynamics.physics import _jit
from train_dynamics.physics.train import warmup


def copy_version(dest_root: str) -> str:
    """Copy this code version's cache folder into ``dest_root``; drop other versions there."""
    src = _jit.kernel_cache_dir()
    if not src:
        raise OSError('no writable kernel cache: nothing compiled to copy')
    dest = os.path.join(dest_root, os.path.basename(src))
    if os.path.isdir(dest_root):
        for name in os.listdir(dest_root):
            if name.startswith('numba-') and name != os.path.basename(src):
                shutil.rmtree(os.path.join(dest_root, name), ignore_errors=True)
    shutil.copytree(src, dest, dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns('*.tmp.*'))
    return dest


def main(argv: list[str] | None = None) -> int:
    """Compile (or load) every kernel variant; with ``--into`` copy them there."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--into', metavar='DIR',
                        help='also copy the compiled kernels to DIR/numba-<code version>')
    args = parser.parse_args(argv)
    if not _jit.HAVE_NUMBA:
        print('train_dynamics: numba is not installed: nothing to compile')
        return 0
    t0 = time.perf_counter()
    warmup()
    stats = _jit.cache_stats()
    print(f'train_dynamics: kernels ready in {time.perf_counter() - t0:.1f} s '
          f'({stats["compiled"]} compiled, {stats["loaded"]} loaded from the cache '
          f'{_jit.kernel_cache_dir() or "(none: not writable)"})')
    if args.into:
        print(f'train_dynamics: compiled kernels copied to {copy_version(args.into)}')
    return 0


if __name__ == '__main__':    # pragma: no cover - the install step
    sys.exit(main())
