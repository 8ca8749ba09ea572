"""
Start-up of ``sim_node`` to its first output: cold, warm and first start after a colcon build.

Each start is a fresh process (300 coaches, 100 Hz, real time); timed from ``Popen`` to the
first ``couplers`` message arriving in this process (DDS discovery included), then stopped
with SIGINT. The compiled-kernel cache (``physics/kernel/compiler.py``) decides the cases:

- ``cold``: the venv's package with an empty user cache (``TRAIN_DYNAMICS_CACHE_DIR``):
  every kernel the start needs compiles (what a first start cost before kernels were built
  at install time, and what a start after a source edit costs);
- ``warm``: the venv's package with the user cache ``make venv`` filled;
- ``installed``: ``colcon build`` of the package into a fresh workspace (with the user
  cache the build finds), then the installed ``sim_node`` with an EMPTY user cache: it
  loads the kernels the build compiled into the install tree.

``python bench/startup.py [--repeats K] [--no-colcon] [--json]``; ``bench/run_all.py`` runs
it with the node benchmark.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import nodeutil as U  # noqa: E402

REPO = U.REPO
PARAMS = {'num_coaches': 300, 'publish_rate': 100.0}
#: the section's text in bench/RESULTS.md
DESCRIPTION = (
    'Fresh `sim_node` processes (300 coaches, 100 Hz, real time), timed from `Popen` to the '
    'first `couplers` message in the benchmark process (DDS discovery included); '
    '`bench/startup.py`. Cold: the venv with an empty kernel cache (`TRAIN_DYNAMICS_CACHE_DIR`): '
    'every kernel the start needs compiles, as after a source change. Warm: the user cache '
    '`make venv` filled. After `colcon build`: a fresh workspace built with colcon (which '
    'compiles the kernels into the install tree), then the installed `sim_node` with an '
    'empty user cache.')
PACKAGE_FILES = ['package.xml', 'setup.py', 'setup.cfg', 'resource', 'train_dynamics',
                 'config', 'launch', 'README.md']


def _args() -> list[str]:
    out = ['--ros-args']
    for key, value in PARAMS.items():
        out += ['-p', f'{key}:={value}']
    return out


def first_output(lst: U.Listener, cmd: list[str], env: dict, cwd: str,
                 timeout: float = 300.0, cpu: list | None = None) -> float | None:
    """
    Start ``cmd``; return the seconds to its first ``couplers`` message (None: none).

    ``cpu``: gets the process's CPU seconds (user + system) at that moment appended, a
    figure the other load on the machine barely changes.
    """
    lst.first_arrival = None
    with tempfile.TemporaryFile('w+') as log:
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
        while lst.first_arrival is None and time.monotonic() < t0 + timeout \
                and proc.poll() is None:
            time.sleep(0.001)
        first = lst.first_arrival - t0 if lst.first_arrival is not None else None
        if cpu is not None:
            cpu.append(U.proc_cpu_seconds(proc.pid))
        U.stop_node(proc)
    time.sleep(0.5)
    return first


def colcon_workspace(root: str, log=print) -> tuple[str, dict]:
    """Build the package with colcon in ``root``/ws; return (workspace, sourced env)."""
    ws = os.path.join(root, 'ws')
    src = os.path.join(ws, 'src', 'train_dynamics')
    os.makedirs(src)
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '_prebuilt', '*.egg-info')
    for name in PACKAGE_FILES:
        path = os.path.join(REPO, name)
        if os.path.isdir(path):
            shutil.copytree(path, os.path.join(src, name), ignore=ignore)
        elif os.path.exists(path):
            shutil.copy2(path, src)
    bindir = os.path.dirname(sys.executable)
    env = {k: v for k, v in U.ros_env().items()
           if k not in ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH',
                        'TRAIN_DYNAMICS_PREBUILD')}
    env['PATH'] = f'{bindir}{os.pathsep}{env.get("PATH", "")}'
    t0 = time.monotonic()
    subprocess.run([os.path.join(bindir, 'colcon'), 'build', '--base-paths', 'src'], cwd=ws,
                   env=env, check=True, capture_output=True, timeout=1800)
    log(f'startup: colcon build took {time.monotonic() - t0:.1f} s')
    out = subprocess.run(['bash', '-c', 'source install/setup.bash && env -0'], cwd=ws,
                         env=env, check=True, capture_output=True, timeout=60)
    sourced = dict(item.decode(errors='replace').split('=', 1)
                   for item in out.stdout.split(b'\0') if b'=' in item)
    return ws, sourced


def run(repeats: int = 3, cold_repeats: int = 1, colcon: bool = True, log=print) -> dict:
    """Time the starts of each case; return {case: [seconds or None, ...], 'load': ...}."""
    res: dict = {'params': PARAMS, 'load_before': os.getloadavg()[0]}
    lst = U.Listener('bench_startup_cold_warm', record=False)
    lst.start()
    module = [sys.executable, '-m', 'train_dynamics.ros.sim_node'] + _args()
    try:
        with tempfile.TemporaryDirectory(prefix='td_bench_startup_') as tmp:
            runs = []
            for k in range(cold_repeats):
                env = dict(U.ros_env(), TRAIN_DYNAMICS_CACHE_DIR=os.path.join(tmp, f'cold{k}'))
                runs.append(first_output(lst, module, env, REPO,
                                         cpu=res.setdefault('cold_cpu', [])))
                log(f'startup: venv, cold: {runs[-1]} s')
            res['cold'] = runs
            subprocess.run([sys.executable, '-m', 'train_dynamics.cli.prebuild'],
                           cwd=REPO, env=U.ros_env(), check=True, capture_output=True)
            res['warm'] = [first_output(lst, module, U.ros_env(), REPO,
                                        cpu=res.setdefault('warm_cpu', []))
                           for _ in range(repeats)]
            log(f'startup: venv, warm: {res["warm"]} s')
            if colcon:
                ws, env = colcon_workspace(tmp, log)
                exe = [os.path.join(ws, 'install', 'train_dynamics', 'lib', 'train_dynamics',
                                    'sim_node')] + _args()
                runs = []
                for k in range(repeats):
                    env['TRAIN_DYNAMICS_CACHE_DIR'] = os.path.join(tmp, f'installed{k}')
                    runs.append(first_output(lst, exe, env, ws,
                                             cpu=res.setdefault('installed_cpu', [])))
                    written = [n for _, _, files in os.walk(env['TRAIN_DYNAMICS_CACHE_DIR'])
                               for n in files]
                    res.setdefault('installed_compiled_files', []).append(len(written))
                res['installed'] = runs
                log(f'startup: colcon install, first start: {runs} s')
    finally:
        lst.close()
    res['load_after'] = os.getloadavg()[0]
    return res


def _fmt(values: list) -> str:
    ok = sorted(v for v in values if v is not None)
    if not ok:
        return 'n/a'
    if len(ok) == 1:
        return f'{ok[0]:.2f}'
    return f'{ok[0]:.2f} / {ok[len(ok) // 2]:.2f} / {ok[-1]:.2f}'


def table(res: dict) -> str:
    """Return the markdown table of :func:`run`'s result."""
    rows = ['| sim_node start | starts | first output [s] (min / median / max) | its CPU time '
            'until then [s] (min / median / max) |', '| --- | ---: | ---: | ---: |']
    labels = (('cold', 'venv, cold: empty kernel cache (every kernel compiles)'),
              ('warm', 'venv, warm: user cache filled by `make venv`'),
              ('installed', 'after `colcon build` in a fresh workspace, first start '
                            '(empty user cache: the kernels the build compiled)'))
    for key, label in labels:
        if key in res:
            rows.append(f'| {label} | {len(res[key])} | {_fmt(res[key])} | '
                        f"{_fmt(res.get(key + '_cpu', []))} |")
    rows.append('')
    rows.append(f"Load average (1 min) before / after: {res['load_before']:.2f} / "
                f"{res['load_after']:.2f} (2 cores).")
    if 'installed_compiled_files' in res:
        rows.append('Kernel cache files the installed node wrote (compiled) per start: '
                    f"{res['installed_compiled_files']}.")
    return '\n'.join(rows)


def main(argv=None) -> int:
    """Run the start-up cases and print the table (or the raw figures)."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--repeats', type=int, default=3, help='starts per warm case')
    ap.add_argument('--cold-repeats', type=int, default=1, help='cold starts (each compiles)')
    ap.add_argument('--no-colcon', action='store_true', help='skip the colcon workspace')
    ap.add_argument('--json', action='store_true', help='print the raw figures as JSON')
    args = ap.parse_args(argv)
    res = run(args.repeats, args.cold_repeats, not args.no_colcon,
              log=lambda m: print(m, file=sys.stderr, flush=True))
    print(json.dumps(res) if args.json else table(res))
    return 0


if __name__ == '__main__':
    sys.exit(main())
