"""
Compile the numba kernels before the first start: ``python -m train_dynamics.cli.prebuild``.

A kernel variant is one compiled signature of a kernel function (the drivers and the
functions they call). Variants are grouped by what runs them (:data:`VARIANTS`):

- ``paper``: the fixed-step chain with the brake pipe (every scenario without the options
  below: the paper's, freight, passenger) and the run metrics as ``sim_node`` and the offline
  command feed them: what ``make run`` needs;
- ``adaptive``: the error-controlled driver (``integration_tolerance`` > 0);
- ``pneumatic``: the pneumatic brake (``brake_model: pneumatic``).

``make venv`` compiles ``paper`` now and the rest in a detached background process
(``--rest-in-background``), so that the first ``make run`` waits only for what it runs; a
variant not yet compiled compiles at its first use. ``setup.py build`` (so ``colcon build``
and ``pip install``) compiles the groups :func:`build_groups` names (``paper`` unless
``TRAIN_DYNAMICS_PREBUILD`` says otherwise) with ``--into
<build>/train_dynamics/physics/kernel/_prebuilt``, so that the installed package carries the
compiled kernels of its own code version (see ``physics/kernel/compiler.py``). Kernels are
loaded from or compiled into the user cache, then this version's folder is copied. Each
compiled function is reported on stdout as it ends (name, seconds).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import compiler
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.metrics_report import run_metrics

#: variant group -> the configurations (parameter overrides) whose runs compile it
VARIANTS = {
    'paper': ({},),
    'adaptive': ({'integration_tolerance': 1e-3},),
    'pneumatic': ({'brake_model': 'pneumatic'},),
}


#: ``TRAIN_DYNAMICS_PREBUILD`` (build time): what ``setup.py build`` / ``develop`` compile
PREBUILD_ENV = 'TRAIN_DYNAMICS_PREBUILD'
#: compiled at build time unless the variable says otherwise: what every scenario without
#: ``integration_tolerance`` or the pneumatic brake runs (cold: ~70 s of one core)
BUILD_DEFAULT = 'paper'


def build_groups(value: str | None) -> str:
    """
    Return the ``--variants`` a build compiles for ``$TRAIN_DYNAMICS_PREBUILD`` = ``value``.

    Unset, ``1`` or ``paper``: ``paper``; ``all``: every group; a comma-separated list: those;
    ``0`` (or ``none``, empty): '' (nothing: the first start compiles what it runs).
    """
    value = (value if value is not None else BUILD_DEFAULT).strip().lower()
    if value in ('0', 'none', '', 'no', 'false'):
        return ''
    if value in ('1', 'yes', 'true'):
        return BUILD_DEFAULT
    return ','.join(_groups(value))


def warm(groups) -> None:
    """Run a small train of each configuration of ``groups`` (and the metrics with ``paper``)."""
    for group in groups:
        for overrides in VARIANTS[group]:
            sim = TrainSimulator(SimConfig.from_dict(dict(overrides)))
            sim.advance(10)
            _ = sim.coupler_force
        if group == 'paper':
            warm_metrics()


def warm_metrics() -> None:
    """Feed the run metrics of the default train as the node does (``ros/publishers.py``)."""
    cfg = SimConfig.from_dict({})
    sim = TrainSimulator(cfg)
    metrics = run_metrics(cfg, sim)
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


def start_in_background(groups) -> str:
    """
    Compile ``groups`` in a detached process (its output: prebuild.log in the cache).

    At the lowest CPU priority (nice 19): on a 2-core machine the demo's two nodes keep real
    time while it compiles (at the default priority the simulator fell ~0.1 s behind).
    """
    log_path = os.path.join(compiler.kernel_cache_dir() or os.devnull, 'prebuild.log')
    if not compiler.kernel_cache_dir():
        log_path = os.devnull
    with open(log_path, 'ab') as log:
        subprocess.Popen([sys.executable, '-m', 'train_dynamics.cli.prebuild',
                          '--variants', ','.join(groups)],
                         stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                         start_new_session=True, close_fds=True,
                         preexec_fn=lambda: os.nice(19))
    return log_path


def _groups(text: str) -> list[str]:
    names = list(VARIANTS) if text == 'all' else [g for g in text.split(',') if g]
    unknown = [g for g in names if g not in VARIANTS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f'unknown variant group(s) {", ".join(unknown)}; one of: all, {", ".join(VARIANTS)}')
    return names


def main(argv: list[str] | None = None) -> int:
    """Compile (or load) the kernel variants asked for; with ``--into`` copy them there."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--variants', type=_groups, default=list(VARIANTS), metavar='GROUPS',
                        help='all (default) or a comma-separated list of: '
                             + ', '.join(VARIANTS))
    parser.add_argument('--rest-in-background', action='store_true',
                        help='then compile the other groups in a detached background process')
    parser.add_argument('--build', action='store_true',
                        help=f'the groups ${PREBUILD_ENV} names (setup.py build and develop): '
                             f'unset {BUILD_DEFAULT}, all, a list, or 0 for none')
    parser.add_argument('--into', metavar='DIR',
                        help='also copy the compiled kernels to DIR/numba-<code version>')
    args = parser.parse_args(argv)
    if args.build:
        try:
            args.variants = [g for g in build_groups(os.environ.get(PREBUILD_ENV)).split(',')
                             if g]
        except argparse.ArgumentTypeError as exc:
            parser.error(f'{PREBUILD_ENV}: {exc}')
        if not args.variants:
            print(f'train_dynamics: {PREBUILD_ENV}={os.environ.get(PREBUILD_ENV)}: no kernels '
                  'compiled now; the first start compiles what it runs', flush=True)
            return 0
        print(f'train_dynamics: compiling the numba kernels ({", ".join(args.variants)}) '
              f'into {args.into or "the user cache"}: ~70 s of one core per group when nothing '
              f'is cached ({PREBUILD_ENV}=0 skips, =all compiles every group; the others '
              'compile at their first use)', flush=True)
    if not compiler.HAVE_NUMBA:
        print('train_dynamics: numba is not installed: nothing to compile')
        return 0
    compiler.report_compilation(lambda line: print(line, flush=True))
    t0 = time.perf_counter()
    warm(args.variants)
    stats = compiler.cache_stats()
    print(f'train_dynamics: kernels ({", ".join(args.variants)}) ready in '
          f'{time.perf_counter() - t0:.1f} s ({stats["compiled"]} compiled, '
          f'{stats["loaded"]} loaded from the cache '
          f'{compiler.kernel_cache_dir() or "(none: not writable)"})', flush=True)
    if args.into:
        print(f'train_dynamics: compiled kernels copied to {copy_version(args.into)}')
    rest = [g for g in VARIANTS if g not in args.variants]
    if args.rest_in_background and rest:
        log_path = start_in_background(rest)
        print(f'train_dynamics: compiling {", ".join(rest)} in the background '
              f'(log: {log_path}); until then they compile at their first use')
    return 0


if __name__ == '__main__':    # pragma: no cover - the install step
    sys.exit(main())
