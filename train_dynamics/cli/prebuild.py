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

Two processes. numba compiles in one thread. The fixed-step driver's large parts are
compiled functions of their own (``physics/kernel/fixed_step.py``, :func:`fixed_step.parts`);
when the driver of this code version is not in the cache yet, ``paper`` first compiles them
in ``--jobs`` processes (default: 2 where there are 2 CPUs; a helper process ``--parts``
takes its share), then the driver, which loads them. Measured, empty cache, this 2-core
machine: the ``paper`` group in 31 s of wall time with two processes when idle (first
``colcon build``); with about one core busy elsewhere (load 1.7-3.2) 58 s with two processes
(56 s of CPU), 111 s with one (73 s of CPU). The parts make two shares of ~24 s of CPU
(:func:`share_parts`), the driver then 7 s.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import compiler, fixed_step
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.metrics_report import run_metrics

#: variant group -> the configurations (parameter overrides) whose runs compile it
VARIANTS = {
    'paper': ({},),
    'adaptive': ({'integration_tolerance': 1e-3},),
    'pneumatic': ({'brake_model': 'pneumatic'},),
}


#: processes compiling the fixed-step driver's parts at most (``fixed_step.parts``: two shares
#: of ~23 s each, measured; more would wait on the largest part)
JOBS_MAX = 2

#: ``TRAIN_DYNAMICS_PREBUILD`` (build time): what ``setup.py build`` / ``develop`` compile
PREBUILD_ENV = 'TRAIN_DYNAMICS_PREBUILD'
#: compiled at build time unless the variable says otherwise: what every scenario without
#: ``integration_tolerance`` or the pneumatic brake runs (cold: ~57 s of CPU, two processes)
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


def part_calls(names=None) -> list:
    """
    Return the fixed-step driver's parts (``fixed_step.parts``) of the default train.

    (name, seconds, function, arguments) of those in ``names`` (None: all), for the
    ``paper`` group (the default configuration runs that driver).
    """
    sim = TrainSimulator(SimConfig.from_dict({}))
    found = fixed_step.parts(sim.coach, sim.cpl, sim.sc, sim.iv, sim.ws, sim.gprof, sim.cprof)
    return [p for p in found if names is None or p[0] in names]


def compile_parts(names) -> None:
    """Compile the driver's parts ``names`` for their arguments' types (or load them)."""
    for _, _, function, args in part_calls(names):
        compiler.compile_for(function, args)


def share_parts(jobs: int) -> list[list[str]]:
    """
    Share the driver's parts out to ``jobs`` processes: the largest first, to the least loaded.

    Returns the names per process (the first: this process's), by their measured seconds.
    """
    shares: list[list] = [[0.0, []] for _ in range(max(1, jobs))]
    for name, seconds, _, _ in part_calls():
        least = min(shares, key=lambda share: share[0])
        least[0] += seconds
        least[1].append(name)
    return [names for _, names in shares]


def compile_in_parallel(jobs: int) -> None:
    """
    Compile the driver's parts in ``jobs`` processes (this one and helpers); wait for them.

    Each process compiles its share into the kernel cache; the driver's compilation (in
    :func:`warm`) then loads them. A helper that fails only costs time: what it left out
    compiles in :func:`warm`.
    """
    shares = share_parts(jobs)
    helpers = [subprocess.Popen([sys.executable, '-m', 'train_dynamics.cli.prebuild',
                                 '--parts', ','.join(names)], stdin=subprocess.DEVNULL)
               for names in shares[1:] if names]
    print(f'train_dynamics: compiling the parts of the fixed-step driver in {len(helpers) + 1} '
          'processes', flush=True)
    try:
        compile_parts(shares[0])
    except BaseException:       # interrupted (Ctrl-C) or failed: the helpers stop too
        for helper in helpers:
            helper.terminate()
        raise
    finally:
        for helper in helpers:
            helper.wait()


def driver_cached() -> bool:
    """Tell whether this code version's fixed-step driver was compiled (a cache entry exists)."""
    return compiler.is_cached(fixed_step.advance_chain)


def default_jobs() -> int:
    """Return the processes that compile in parallel: 2 where there are 2 CPUs or more."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    return max(1, min(JOBS_MAX, cpus))


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
    parser.add_argument('--jobs', type=int, default=None, metavar='N',
                        help='processes compiling in parallel (default: 2 with 2 CPUs or more)')
    parser.add_argument('--parts', help=argparse.SUPPRESS)    # a helper of --jobs
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
              f'into {args.into or "the user cache"}: ~1 min of CPU per group when nothing '
              f'is cached ({PREBUILD_ENV}=0 skips, =all compiles every group; the others '
              'compile at their first use)', flush=True)
    if not compiler.HAVE_NUMBA:
        print('train_dynamics: numba is not installed: nothing to compile')
        return 0
    compiler.report_compilation(lambda line: print(line, flush=True))
    if args.parts is not None:
        compile_parts(args.parts.split(','))
        return 0
    t0 = time.perf_counter()
    jobs = args.jobs if args.jobs is not None else default_jobs()
    # in parallel only through the cache (a helper's kernels reach this process there)
    if ('paper' in args.variants and jobs > 1 and compiler.kernel_cache_dir()
            and not driver_cached()):
        compile_in_parallel(jobs)
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
