"""
Speed of whole offline runs as a user meets them: in-process and ``train-dynamics simulate``.

Train: N of the paper's coaches (default 100; tanh, u = 1000 s/m, h = the default step, 100 Hz
output, the paper's couplers with strokes out of reach as in ``bench/core.py``), unstressed
at t = 0, emergency braking from 44.444 m/s with the brake valve at t = 0 (the head pipe
vented). The train decelerates at about mu g = 0.98 m/s^2 once braked and still runs at
11-12 m/s at :data:`T_LONG` = 40 s, so it is moving over the whole timed span (the run asserts
it: a stopped train costs almost nothing and would flatter the figure).

Measured, in one driver process after a warm-up (numba's cache load), repeated ``--repeats``
times with the modes INTERLEAVED in each round (the host's speed drifts; other processes may
load it), each figure the BEST of its repeats:

- ``kernel``: a whole run of :data:`T_LONG` s through
  :func:`train_dynamics.simulation.runner.run_simulation` (the offline command's loop and
  inputs) with a sink that does nothing: the model alone;
- ``encode``: the same run, the sink encoding every output topic in place, as ``BagSink``
  does (:class:`train_dynamics.recording.outputs.OutputRows`), into a block whose rows are
  dropped instead of written;
- ``bag``: the same run, the sink writing the bag (``BagSink`` into an atomic
  ``BagRecorder``, as ``simulate`` opens it): the offline command minus its start-up;
- ``simulate``: the offline command in a fresh process (``python -m train_dynamics.cli.offline
  simulate -q``) for :data:`T_SHORT` and :data:`T_LONG` s; its start-up (interpreter, imports,
  numba cache, parameter file, bag set-up) is removed by taking the difference of the two wall
  times: RTF = (T_LONG - T_SHORT) / (wall_long - wall_short), each wall the best of its repeats.

Each figure is given twice: from wall-clock time and from CPU time (user + system of this
process, or of the command's process from ``getrusage(RUSAGE_CHILDREN)``). On a host shared
with other work the wall times include waiting for a core; the CPU times do not (they still
include the slow-down of sharing caches and memory bandwidth), so with a load average above
the core count compare the CPU row.

The split per simulated second [ms]: kernel = kernel / T; encode = (encode - kernel) / T;
write = (bag - encode) / T. ``--baseline DIR`` times the command of another checkout (e.g.
``git archive`` of the commit before a change) in the same rounds: before and after under the
same load.
``python bench/offline_speed.py [--n 100] [--repeats 5] [--baseline DIR]``.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
#: the checkout whose package this process imports (a --child of --baseline: that one)
IMPORTED = os.environ.get('OFFLINE_SPEED_REPO', REPO)
if IMPORTED not in sys.path:
    sys.path.insert(0, IMPORTED)

T_SHORT = 2.0           # [s] simulated: the short run of the start-up difference
T_LONG = 40.0           # [s] simulated: the long run (the train still moves at its end)
U = 1000.0              # [s/m] tanh scale factor of the paper's bench (bench/core.py)
RESULTS_MD = os.path.join(HERE, 'results', 'offline_speed_results.md')

PARAMS = """\
/**/train_dynamics:
  ros__parameters:
    model_type: tanh
    scale_factor: {u!r}
    num_coaches: {n}
    initial_speed: 44.444
    initial_state: unstressed
    brake_input: pipe_head
    buffer_stroke: 10.0
    draw_gear_stroke: 10.0
    publish_rate: 100.0
/**/brake_valve:
  ros__parameters:
    schedule: ["0.0:emergency"]
"""


def write_params(path: str, n: int) -> str:
    """Write the bench's parameter file (N paper coaches, emergency at t = 0) to ``path``."""
    with open(path, 'w', encoding='utf-8') as fh:
        fh.write(PARAMS.format(n=int(n), u=U))
    return path


class _Null:
    """A sink that keeps nothing (the model alone)."""

    def sample(self, s) -> None:
        pass


class _Discard:
    """A recorder that takes the rows of a block and writes nothing (the encoding alone)."""

    def attach(self, block) -> None:
        self.block = block

    def row(self, t_ns: int) -> int:
        if self.block.full:
            self.block.count = 0
        return self.block.next_row(t_ns)


class _Encode:
    """Encode every output topic of each sample in place (OutputRows, as BagSink), no bag."""

    def __init__(self, cfg) -> None:
        from train_dynamics.recording.outputs import OutputEncoder, OutputRows
        self.atm = float(cfg.atmospheric_pressure)
        self.rows = OutputRows(OutputEncoder(cfg), True)
        self.rec = _Discard()

    def sample(self, s) -> None:
        from train_dynamics.recording.outputs import time_ns
        self.rows.write(self.rec, time_ns(s.t), s.sim, s.head_gauge + self.atm)


def run_inprocess(params: str, mode: str, duration: float, tmp: str) -> tuple[float, float]:
    """Return the wall and CPU times [s] of one whole run of ``duration`` [s] here."""
    from train_dynamics.cli.scenario import brake_inputs, load_config
    from train_dynamics.simulation.runner import run_simulation
    cfg = load_config(params)
    inputs = brake_inputs(argparse.Namespace(input=None, namespace='', params=params), cfg)
    rec = None
    if mode == 'kernel':
        sink = _Null()
    elif mode == 'encode':
        sink = _Encode(cfg)
    else:
        from train_dynamics import topics
        from train_dynamics.recording.bags import BagRecorder
        from train_dynamics.recording.sinks import BagSink
        out = os.path.join(tmp, f'bag_{time.monotonic_ns()}')
        rec = BagRecorder(out, atomic=True, file_stem='bag')
        sink = BagSink(rec, cfg)
        rec.add_topic(topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE)
    t0, c0 = time.perf_counter(), time.process_time()
    sim = run_simulation(cfg, duration, inputs, on_sample=sink.sample,
                         on_input=getattr(sink, 'input', None))
    if rec is not None:
        rec.close()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    assert sim.fault is None, sim.fault
    assert float(sim.v.min()) > 1.0, 'the train must be moving over the whole timed span'
    return wall, cpu


def run_command(params: str, duration: float, tmp: str, repo: str = REPO
                ) -> tuple[float, float]:
    """Return wall and CPU times [s] of ``train-dynamics simulate`` of ``repo`` (a new process)."""
    out = os.path.join(tmp, f'cli_{time.monotonic_ns()}')
    env = dict(os.environ, PYTHONPATH=repo)
    cmd = [sys.executable, '-m', 'train_dynamics.cli.offline', 'simulate', '-q',
           '--params', params, '--duration', repr(duration), '--output', out]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, cwd=tmp)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)


def run_child(params: str, mode: str, tmp: str, repo: str) -> tuple[float, float]:
    """Return wall and CPU times [s] of an in-process ``mode`` run of ``repo``'s package."""
    env = dict(os.environ, PYTHONPATH=repo, OFFLINE_SPEED_REPO=repo)
    out = subprocess.run([sys.executable, os.path.abspath(__file__), '--child', mode,
                          '--params', params, '--tmp', tmp], check=True, env=env, cwd=tmp,
                         capture_output=True, text=True).stdout.split()
    return float(out[-2]), float(out[-1])


def write_speed(tmp: str, mib: int = 32) -> float:
    """Return the speed [MB/s] of writing ``mib`` MiB of new file data (1 MiB writes)."""
    buf = bytes(range(256)) * 4096
    path = os.path.join(tmp, f'probe_{time.monotonic_ns()}')
    t0 = time.perf_counter()
    with open(path, 'wb') as fh:
        for _ in range(mib):
            fh.write(buf)
    return mib * len(buf) / (time.perf_counter() - t0) / 1e6


def _size(path: str) -> int:
    return sum(os.path.getsize(os.path.join(path, f)) for f in os.listdir(path))


def measure(n: int, repeats: int, baseline: str | None = None, log=print) -> dict:
    """Return the best wall time [s] of each mode over ``repeats`` interleaved rounds."""
    with tempfile.TemporaryDirectory(prefix='offline_speed_') as tmp:
        params = write_params(os.path.join(tmp, 'params.yaml'), n)
        run_inprocess(params, 'kernel', 0.1, tmp)                  # warm-up: numba cache
        run_command(params, 0.1, tmp)                              # warm-up: file cache
        best: dict[str, float] = {}
        plan = [('kernel', None, REPO), ('encode', None, REPO), ('bag', None, REPO),
                ('simulate_short', T_SHORT, REPO), ('simulate_long', T_LONG, REPO)]
        if baseline:
            run_command(params, 0.1, tmp, baseline)
            plan += [('baseline_short', T_SHORT, baseline), ('baseline_long', T_LONG, baseline),
                     ('baseline_kernel', 'child', baseline), ('baseline_bag', 'child', baseline)]
        best['load_before'] = os.getloadavg()[0]
        for r in range(repeats):
            for mode, t, repo in plan:
                if t == 'child':
                    wall, cpu = run_child(params, mode.split('_')[1], tmp, repo)
                elif t is not None:
                    wall, cpu = run_command(params, t, tmp, repo)
                else:
                    wall, cpu = run_inprocess(params, mode, T_LONG, tmp)
                best[mode] = min(best.get(mode, float('inf')), wall)
                best['cpu_' + mode] = min(best.get('cpu_' + mode, float('inf')), cpu)
                best.setdefault('rounds', {}).setdefault(mode, []).append((wall, cpu))
                log(f'  round {r + 1}/{repeats} {mode:15s} {wall:7.3f} s wall {cpu:7.3f} s CPU')
            mb = write_speed(tmp)
            best['new_file_mb_s'] = max(best.get('new_file_mb_s', 0.0), mb)
            bags = sorted((e for e in os.listdir(tmp) if e.startswith('cli_')),
                          key=lambda e: int(e[4:]))
            best['bag_mb_per_s'] = (_size(os.path.join(tmp, bags[-1])) - _size(
                os.path.join(tmp, bags[-2]))) / (T_LONG - T_SHORT) / 1e6 if not baseline \
                else (_size(os.path.join(tmp, bags[-3])) - _size(
                    os.path.join(tmp, bags[-4]))) / (T_LONG - T_SHORT) / 1e6
            for entry in os.listdir(tmp):                          # keep the disk free
                if entry.startswith(('bag_', 'cli_', 'probe_')):
                    subprocess.run(['rm', '-rf', os.path.join(tmp, entry)], check=False)
        best['load_after'] = os.getloadavg()[0]
    return best


def _row(n: int, best: dict, what: str, pre: str) -> str:
    k, e, b = best[pre + 'kernel'], best[pre + 'encode'], best[pre + 'bag']
    span = T_LONG - T_SHORT
    cli = best[pre + 'simulate_long'] - best[pre + 'simulate_short']
    startup = best[pre + 'simulate_short'] - T_SHORT / span * cli
    row = (f'| {n} | {what} | {T_LONG / k:.0f}x | {T_LONG / e:.0f}x | {T_LONG / b:.0f}x | '
           f'{span / cli:.0f}x ({1e3 * cli / span:.1f} ms/s) | {startup:.2f} | '
           f'{1e3 * k / T_LONG:.1f} / {1e3 * (e - k) / T_LONG:.1f} / '
           f'{1e3 * (b - e) / T_LONG:.1f} |')
    if pre + 'baseline_long' in best:
        base = best[pre + 'baseline_long'] - best[pre + 'baseline_short']
        row += f' {span / base:.0f}x ({1e3 * base / span:.1f} ms/s) |'
    return row


def _baseline_line(best: dict) -> str:
    if 'baseline_bag' not in best:
        return ''
    parts = []
    for what, pre in (('wall', ''), ('CPU', 'cpu_')):
        k, b = best[pre + 'baseline_kernel'], best[pre + 'baseline_bag']
        here = best[pre + 'bag'] - best[pre + 'kernel']
        parts.append(f'{what}: model only {T_LONG / k:.0f}x, with the bag {T_LONG / b:.0f}x '
                     f'(encode + write {1e3 * (b - k) / T_LONG:.1f} ms per simulated s; this '
                     f'checkout {1e3 * here / T_LONG:.1f})')
    return ('\nBaseline checkout in-process (a child process per run, its start-up outside the '
            'timing): ' + '; '.join(parts) + '.\n')


def _median_line(best: dict) -> str:
    """Return the command's figures from the median of each round's long - short difference."""
    rounds, span = best['rounds'], T_LONG - T_SHORT
    parts = []
    for name, pre in (('this checkout', 'simulate'), ('baseline', 'baseline')):
        if pre + '_long' not in rounds:
            continue
        diffs = [[lo[i] - sh[i] for lo, sh in zip(rounds[pre + '_long'], rounds[pre + '_short'])]
                 for i in (0, 1)]
        wall, cpu = (sorted(d)[len(d) // 2] for d in diffs)
        parts.append(f'{name} {span / wall:.0f}x wall ({1e3 * wall / span:.1f} ms/s), '
                     f'{span / cpu:.0f}x CPU ({1e3 * cpu / span:.1f} ms/s)')
    return ('\nThe command from the median of the per-round differences (long - short of the '
            'same round): ' + '; '.join(parts) + '.\n')


def table(n: int, best: dict, repeats: int) -> str:
    """Return the results as a markdown table: wall-clock and CPU time."""
    base = 'baseline_long' in best
    rows = [
        '| N | time | in-process model only | in-process with encoding | in-process with the bag '
        '| `train-dynamics simulate`, start-up removed | start-up [s] | kernel / encode / write '
        '[ms per simulated s] |' + (' baseline checkout: simulate |' if base else ''),
        '| ---: | --- | ---: | ---: | ---: | ---: | ---: | --- |' + (' ---: |' if base else ''),
        _row(n, best, 'wall', ''), _row(n, best, 'CPU', 'cpu_')]
    return '\n'.join(rows) + (
        f'\n\nBest of {repeats} interleaved rounds; whole runs of {T_LONG:g} s (command: '
        f'{T_LONG:g} s minus {T_SHORT:g} s). The bag: {best["bag_mb_per_s"]:.2f} MB per '
        f'simulated second; this host writes new file data at {best["new_file_mb_s"]:.0f} MB/s '
        f'(best of the rounds). Load average (1 min) {best["load_before"]:.1f} before, '
        f'{best["load_after"]:.1f} after.\n' + _median_line(best) + _baseline_line(best))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--n', type=int, default=100, help='coaches (default 100)')
    ap.add_argument('--repeats', type=int, default=5, help='interleaved rounds (default 5)')
    ap.add_argument('--baseline', metavar='DIR',
                    help='another checkout of the package: its simulate timed in the same rounds')
    ap.add_argument('--write', action='store_true',
                    help=f'append the table to {os.path.relpath(RESULTS_MD, REPO)}')
    ap.add_argument('--child', metavar='MODE', help=argparse.SUPPRESS)
    ap.add_argument('--params', help=argparse.SUPPRESS)
    ap.add_argument('--tmp', help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:                        # one timed in-process run (after a warm-up)
        run_inprocess(args.params, 'kernel', 0.1, args.tmp)
        print(*run_inprocess(args.params, args.child, T_LONG, args.tmp))
        return 0
    best = measure(args.n, args.repeats, args.baseline)
    text = table(args.n, best, args.repeats)
    print(text)
    if args.write:
        stamp = time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())
        with open(RESULTS_MD, 'a', encoding='utf-8') as fh:
            fh.write(f'\n### {stamp}\n\n{text}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
