"""
Compile the numba kernels before the first start: ``python -m train_dynamics.cli.prebuild``.

``make venv`` runs it to fill the user cache; ``setup.py build`` (so ``colcon build`` and
``pip install``) runs it with ``--into <build>/train_dynamics/physics/kernel/_prebuilt`` so
the installed package carries the compiled kernels of its own code version (see
``physics/kernel/compiler.py``).
It runs :func:`train_dynamics.physics.train.warmup` (the simulator's kernel variants) and
the run metrics as ``sim_node`` and the offline command feed them (their compiled elastic
energy), which loads from or compiles into the user cache, then copies this version's folder.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time

from train_dynamics.physics.kernel import compiler
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.parameters import SimConfig
from train_dynamics.physics.train import TrainSimulator, warmup


def warm_metrics() -> None:
    """Feed the run metrics of the default train as the node does (``ros/outputs.py``)."""
    cfg = SimConfig.from_dict({})
    sim = TrainSimulator(cfg)
    metrics = RunMetrics.for_run(cfg, sim)
    for _ in range(3):
        sim.advance(5)
        metrics.add(sim.t, sim.y, sim.ydot, sim.coupler_force, sim.x, sim.v, sim.brake_force)
    metrics.diagnostic()
    metrics.flat()


def copy_version(dest_root: str) -> str:
    """Copy this code version's cache folder into ``dest_root``; drop other versions there."""
    src = compiler.kernel_cache_dir()
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
    if not compiler.HAVE_NUMBA:
        print('train_dynamics: numba is not installed: nothing to compile')
        return 0
    t0 = time.perf_counter()
    warmup()
    warm_metrics()
    stats = compiler.cache_stats()
    print(f'train_dynamics: kernels ready in {time.perf_counter() - t0:.1f} s '
          f'({stats["compiled"]} compiled, {stats["loaded"]} loaded from the cache '
          f'{compiler.kernel_cache_dir() or "(none: not writable)"})')
    if args.into:
        print(f'train_dynamics: compiled kernels copied to {copy_version(args.into)}')
    return 0


if __name__ == '__main__':    # pragma: no cover - the install step
    sys.exit(main())
