"""
`make bench`: the physics-core benchmark, the solve_ivp baseline and the node benchmark.

Prints the tables (markdown) and writes ``bench/RESULTS.md`` (machine, load, tables, targets,
and the soak figures of the last ``make soak`` from ``bench/results/soak_results.md``), plus
the raw figures to ``bench/results/last_run.json``. See bench/core.py and bench/node.py for
what is measured. Every script's own tables and raw figures are in ``bench/results/``.

Options: ``--no-node``, ``--no-core``, ``--no-sweep`` (bench/sweep.py: cases/min on 1 and 2 Dask
workers), ``--no-lockstep`` (bench/lockstep.py: closed-loop periods/s over DDS),
``--ref-max-n N`` (compute missing reference solutions only up to N coaches; cached ones are
always used), ``--target-ref-max-n N`` (the same for the per-coupler references of the target
rows, default 1000), ``--default-overrides JSON`` (settings applied on top of the defaults in
the target rows, to try a planned default; the rows name them), ``--core-sizes N,N`` and
``--core-max-u U`` (a smaller core table: the target rows still run), ``--no-write`` (print
only).

The targets table gives the speed at DEFAULT settings of the paper's coaches (100 and 1000)
and of the 750 m freight, in whole runs of a moving train, each with its sample accuracy
beside it, and the plain fixed step for comparison (bench/core.py ``target_case``,
bench/freight.py ``target``).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(1, os.path.dirname(HERE))

import core  # noqa: E402
import freight  # noqa: E402  (the real-train case: 750 m freight)
import lockstep as lockstepbench  # noqa: E402  (lockstep.py owns its section)
from memory import MEMORY_BEGIN, MEMORY_END, MEMORY_MD  # noqa: E402  (memory.py's section)
from results_md import saved_section  # noqa: E402
from soak import SOAK_BEGIN, SOAK_END, SOAK_MD as SOAK  # noqa: E402  (soak.py owns its section)
import sweep as sweepbench  # noqa: E402  (sweep.py owns its section)

RESULTS = os.path.join(HERE, 'RESULTS.md')
RAW = os.path.join(HERE, 'results', 'last_run.json')


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


class CpuMeter:
    """
    CPU time used on the machine by other processes, averaged over the wall time [cores].

    Other processes: all but this one and its children (/proc/stat minus our own os.times()).
    """

    def __init__(self):
        self.t0, self.busy0, self.own0 = time.monotonic(), self._busy(), self._own()

    @staticmethod
    def _busy() -> float:
        with open('/proc/stat') as fh:
            f = [int(x) for x in fh.readline().split()[1:]]
        idle = f[3] + (f[4] if len(f) > 4 else 0)
        return (sum(f[:8]) - idle) / os.sysconf('SC_CLK_TCK')

    @staticmethod
    def _own() -> float:
        t = os.times()
        return t.user + t.system + t.children_user + t.children_system

    def others_cores(self) -> float:
        wall = time.monotonic() - self.t0
        other = (self._busy() - self.busy0) - (self._own() - self.own0)
        return max(other, 0.0) / wall if wall > 0 else 0.0


def machine() -> dict:
    import numpy
    import scipy
    try:
        import numba
        nb = numba.__version__
    except ImportError:
        nb = 'not installed'
    cpu = 'unknown'
    try:
        with open('/proc/cpuinfo') as fh:
            for line in fh:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    mem = ''
    try:
        with open('/proc/meminfo') as fh:
            mem = f'{int(fh.readline().split()[1]) / 1048576:.1f} GiB'
    except OSError:
        pass
    return {'cpu': cpu, 'cores': os.cpu_count(), 'memory': mem,
            'python': platform.python_version(), 'numpy': numpy.__version__,
            'scipy': scipy.__version__, 'numba': nb, 'platform': platform.platform(),
            'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}


def _fmt_err(x) -> str:
    return f'{100 * x:+.3f} %' if x is not None else ''


def _runs(r: dict) -> str:
    w = r.get('walls_s') or []
    return f'{max(w):.3f} / {min(w):.3f}' if w else ''


def _t1(r: dict) -> str:
    if 'env_err' not in r:
        return ''
    t = r.get('t_env_err_1pct')
    return f'{t:.2f}' if t is not None else 'never'


def core_table(rows: list[dict]) -> str:
    out = ['| N | model | u [s/m] | h [ms] | multirate tolerance | timed span [s] | wall [s] | '
           'real-time factor | slowest / fastest whole run [s] | steps | '
           'peak abs(F) 0-60 s [kN] | W [s] | peak 0-W [kN] (t [s]) | reference peak 0-W [kN] '
           '(t [s]) | peak error | envelope error | envelope error > 1 % from t [s] | '
           'force samples (0-W) | displacement samples (0-W) | '
           'tracemalloc peak [KiB] | process VmHWM [MiB] | host speed | note |',
           '| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | '
           '---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |']
    for r in rows:
        u = f"{r['u']:g}" if r['model'] == 'tanh' else '-'
        note = r.get('ref_note', '')
        if r.get('fault'):
            note = (note + '; ' if note else '') + f"FAULT: {r['fault']}"
        ref = (f"{r['ref_peak_N'] / 1e3:.2f} ({r['ref_t_peak']:.2f})" if 'ref_peak_N' in r
               else 'n/a')
        fs = (f"{_pct(r['force_err'])} | {_pct(r['disp_err'])}" if 'force_err' in r
              else ' | ')
        out.append(
            f"| {r['n']} | {r['model']} | {u} | {r['h'] * 1e3:g} | {r.get('multirate', 0):g} | "
            f"{r.get('span_s', float('nan')):g} | {r['wall_s']:.3f} | "
            f"{r['rtf']:.0f}x | {_runs(r)} | {r['steps']} | {r['peak_N'] / 1e3:.2f} | "
            f"{r['window']:.1f} | "
            f"{r['peak_window_N'] / 1e3:.2f} ({r['t_peak_window']:.2f}) | {ref} | "
            f"{_fmt_err(r.get('peak_err'))} | "
            f"{_fmt_err(r.get('env_err')).lstrip('+')} | {_t1(r)} | {fs} | "
            f"{r['tracemalloc_peak_kib']:.0f} | "
            f"{r['vmhwm_mib']:.0f} | {r.get('host_speed', float('nan')):.2f} | {note} |")
    return '\n'.join(out)


def baseline_table(rows: list[dict]) -> str:
    out = ['| N | solve_ivp RK45 wall for 60 s [s] | its real-time factor | f-evaluations | '
           'its peak error (0-W) | its envelope error (0-W) | our real-time factor / its '
           f'(default settings, h = {core.DEFAULT_H * 1e3:g} ms) |',
           '| ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
    for r in rows:
        ex = ' (extrapolated)' if r['extrapolated'] else ''
        sp = f"{r['speedup']:.0f}x" if 'speedup' in r else ''
        out.append(f"| {r['n']} | {r['wall_s']:.2f}{ex} | {r['rtf']:.1f}x | "
                   f"{r.get('nfev', '')} | {_fmt_err(r.get('peak_err'))} | "
                   f"{_fmt_err(r.get('env_err')).lstrip('+')} | {sp}{ex} |")
    return '\n'.join(out)


def startup_table(st: dict) -> str:
    out = ['| numba cache | import train_dynamics.physics.train [s] | first TrainSimulator '
           '+ first output (10 ms) [s] | total [s] |', '| --- | ---: | ---: | ---: |']
    for k, label in (('cold', 'cold (empty TRAIN_DYNAMICS_CACHE_DIR: compiles)'),
                     ('warm', 'warm (cache loaded)'), ('warm2', 'warm, again')):
        s = st[k]
        out.append(f"| {label} | {s['import_s']:.2f} | {s['first_output_s']:.2f} | "
                   f"{s['total_s']:.2f} |")
    return '\n'.join(out)


def _pct(x) -> str:
    return f'{100 * x:.2f} %'


def _judge(speed_ok: bool, acc_ok: bool | None) -> str:
    """Return PASS, or FAIL with what failed (accuracy None: not measured, speed only)."""
    failed = [w for w, ok in (('speed', speed_ok), ('accuracy', acc_ok)) if ok is False]
    return 'PASS' if not failed else 'FAIL: ' + ' and '.join(failed)


def core_targets(rows: list[dict]) -> list[tuple[str, str, str]]:
    """
    Judge the speed targets of the paper's coaches: (target, result, figures) per row.

    ``rows``: :func:`core.target_case` rows: whole runs of the moving train at the default
    settings (and the plain fixed step, judged by the same criteria for comparison), with
    the sample accuracy against the Radau reference beside the speed.
    """
    goal = dict(core.SPEED_TARGETS)
    lim = core.SAMPLE_TARGET
    out = []
    for r in rows:
        n = r['n']
        if n not in goal:
            continue
        what = ('' if r['label'].startswith('default') else 'comparison: ')
        name = (f"{what}{n} paper coaches, tanh u = {r['u']:g}, {r['label']}: >= "
                f'{goal[n]:g}x real time, every coupler-force and displacement sample '
                f'within {100 * lim:g} % of the reference peak')
        speed = (f"{r['rtf']:.0f}x (fastest of {r['repeats']} whole runs, interleaved, "
                 f"0-{r['span_s']:g} s, train moving; by CPU time {r['rtf_cpu']:.0f}x)")
        if 'force_err' in r:
            acc_ok = r['force_err'] <= lim and r['disp_err'] <= lim
            acc = (f"force samples {_pct(r['force_err'])}, displacements "
                   f"{_pct(r['disp_err'])} of the reference peak (10 ms samples, every "
                   f"coupler, 0-{r['span_s']:g} s); peak {100 * r['peak_err']:+.3f} %")
        else:
            acc_ok = None
            acc = ('sample accuracy not measured: no per-coupler reference cached for '
                   f'{n} coaches (`python bench/core.py --refs --samples --ref-sizes {n} '
                   f'--ref-max-n {n}`)'
                   + (f"; peak {100 * r['peak_err']:+.3f} %" if 'peak_err' in r else ''))
        if r.get('fault'):
            acc += f"; FAULT: {r['fault']}"
        out.append((name, _judge(r['rtf'] >= goal[n] and not r.get('fault'), acc_ok),
                    f'{speed}; {acc}'))
    return out


def freight_targets(rows: list[dict]) -> list[tuple[str, str, str]]:
    """Judge the freight's speed target: (target, result, figures) per setting."""
    import freight
    out = []
    for r in rows:
        what = ('' if r['label'].startswith('default') else 'comparison: ')
        name = (f"{what}750 m freight (config/freight_750m.yaml, {r['n']} vehicles), "
                f"{r['label']}: >= {freight.SPEED_TARGET:g}x real time")
        val = (f"{r['rtf']:.0f}x (fastest of {r['repeats']} whole runs, interleaved, "
               f"0-{r['span_s']:g} s, train moving; by CPU time {r['rtf_cpu']:.0f}x); "
               'sample accuracy against an independent '
               'reference: not measured (the Radau reference has no pneumatic brake, '
               'traction, gradients, curves, running resistance or strokes); against the '
               'same model at a fixed 0.1 ms step: force samples '
               f"{_pct(r['conv_force_err'])}, displacements {_pct(r['conv_disp_err'])} of "
               'its peak')
        if r.get('fault'):
            val += f"; FAULT: {r['fault']}"
        out.append((name, _judge(r['rtf'] >= freight.SPEED_TARGET and not r.get('fault'),
                                 None), val))
    return out


def node_targets(res: dict) -> list[tuple[str, str, str]]:
    def pf(ok):
        return 'PASS' if ok else 'FAIL'
    return [
        ('node 300 coaches, 100 Hz: achieved real-time factor >= 0.99 over 60 s',
         pf(res['targets']['rtf']), f"{res['rtf']:.4f}"),
        ('node: p99 output period jitter <= 2 ms', pf(res['targets']['jitter_p99']),
         f"{res['jitter_p99_ms']:.3f} ms"),
        ('node: first output within 3 s of start (median of the starts)',
         pf(res['targets']['startup']),
         res.get('startup_summary', f"{res['startup_s']:.2f} s")),
    ]


def targets_table(items) -> str:
    out = ['| target | measured | result |', '| --- | ---: | --- |']
    for name, result, val in items:
        out.append(f'| {name} | {val} | {result} |')
    return '\n'.join(out)


def soak_section() -> str:
    """Return the soak section (bench/soak.py owns it; ``make soak`` runs it)."""
    return saved_section(SOAK, SOAK_BEGIN, SOAK_END, '## Soak (make soak)')


def memory_section() -> str:
    """Return the memory section (bench/memory.py owns it; run by main unless --no-memory)."""
    return saved_section(MEMORY_MD, MEMORY_BEGIN, MEMORY_END,
                         '## Memory of the offline commands (bench/memory.py)')


#: the error-controlled stepping's accuracy/speed tables: ``python bench/adaptive.py``
#: measures them (references at tolerance 1e-6 take ~15 min of CPU, so not on every run)
ADAPTIVE_MD = os.path.join(HERE, 'results', 'adaptive_results.md')


def adaptive_section() -> str:
    """Return the error-controlled stepping section, as bench/adaptive.py last measured it."""
    return saved_section(ADAPTIVE_MD, '<!-- adaptive: begin -->', '<!-- adaptive: end -->',
                         '## Error-controlled stepping (bench/adaptive.py)')


#: the speed targets beside the accuracy contract's metrics (hand-run: the references and the
#: settings' runs take tens of minutes)
CONTRACT_MD = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'contract_results.md')


def contract_section() -> str:
    """Return the speed-and-contract section, as last measured (bench/contract_results.md)."""
    return saved_section(CONTRACT_MD, '<!-- contract: begin -->', '<!-- contract: end -->',
                         '## Speed and the accuracy contract side by side')


def render(mach: dict, load: dict, core_res: dict | None, node_res: dict | None,
           freight_rows: list[dict] | None = None) -> str:
    import node as nodebench
    parts = ['# Benchmark results (`make bench`)', '',
             'Written by `bench/run_all.py`; the soak section by `bench/soak.py` (`make soak`). '
             'Numbers are from one run on the machine below; timings are wall-clock, single '
             'process, one core for the model. Speeds are measured the way a user meets them: '
             "whole runs (the fastest of 5, 3 for the slowest cases; the host's speed drifts "
             'by up to 2x within seconds), of a train that moves over the whole timed span '
             '(it ends 0.5 s before the first vehicle stops: a stopped train costs almost '
             'nothing), real-time factor = timed span / wall time; settings compared in one '
             "row set (default against fixed step) are timed interleaved. Each script's "
             'own tables and raw figures are in [results/](results/).', '',
             '## Machine', '',
             f"- CPU: {mach['cpu']}, {mach['cores']} cores, {mach['memory']} RAM",
             f"- {mach['platform']}; Python {mach['python']}, numpy {mach['numpy']}, "
             f"scipy {mach['scipy']}, numba {mach['numba']}",
             f"- date: {mach['date']}",
             f"- load average (1 min) before the run: {load['before']:.2f}; CPU used by OTHER "
             f"processes during the run: {load['others_cores']:.2f} cores on average"
             + (' -- the machine was LOADED by other work: timings are pessimistic'
                if load['others_cores'] > 0.15 else ' (no other work on this VM)'), '']
    items = []
    if core_res and core_res.get('targets'):
        items += core_targets(core_res['targets'])
    if freight_rows:
        items += freight_targets(freight_rows)
    if node_res:
        items += node_targets(node_res)
    if items:
        parts += ['## Targets', '',
                  'The speed targets at the DEFAULT settings (the configuration sets only the '
                  "train; the integration settings are SimConfig's defaults unless the row "
                  'names an override), each with its sample accuracy: max over the 10 ms '
                  'samples and couplers of abs(F - F_ref) / max abs(F_ref), and the same for '
                  'the coupler displacements, against the independent reference '
                  '(`reference.reference_solution`: Radau, rtol 1e-9, analytical Jacobian; '
                  'per-coupler samples cached outside the repository, '
                  '`~/.cache/train_dynamics/bench-reference/`). The plain fixed step is '
                  'judged by the same criteria for comparison. A FAIL says which criterion '
                  'failed.', '', targets_table(items), '']
    parts += [contract_section(), '']
    if core_res:
        parts += [
            '## Physics core (ROS2 integrator at the default settings, numba kernel)', '',
            f'Scenario: paper defaults (45 t coaches, 44.444 m/s, `pipe_head`, P brake; the '
            "paper's couplers: strokes set out of reach, as the reference models them, "
            'where the default 105/60 mm strokes would block from about 100 coaches on), head '
            f'brake pipe vented to 0 gauge at t = {core.T_EMERGENCY:g} s, {core.T_END:g} s '
            'simulated; every setting but the step h (and, where shown, the model and u) is '
            "SimConfig's default (multirate tolerance: the column). Timed: whole runs over the "
            'timed span (0-W, the train moving throughout), `sim.advance_to` in 10 ms chunks '
            "and `sim.coupler_force` after each (the node's 100 Hz read-out), the fastest of "
            '5 (3 for the slowest cases); real-time factor = timed span / wall; numba warm-up '
            'excluded (see start-up). '
            '"peak abs(F)" = max over couplers and 10 ms samples. Reference: '
            '`reference.reference_solution` (Radau, rtol 1e-9, atol 1e-11) with the brake '
            'forces Fb_i(t) = mu_a m_i g fill(t - t_e - d_i) (checked against '
            '`sim.brake_force`: largest mismatch '
            f"{max(r['brake_mismatch'] for r in core_res['cases'] + core_res['steps']):.1e} "
            'of mu_a m g), over 0-W with W = 0.5 s before the first coach stops in our run '
            'or in the reference (the reference does not model the brake holding a stopped '
            'coach), at most 60 s. '
            'peak error = (our peak - reference peak) / reference peak over 0-W s; envelope '
            "error = max over the 10 ms samples of abs(our max_j abs(F_j) - the reference's), / "
            'reference peak; force samples = max over the 10 ms samples and couplers of '
            'abs(F_j - F_ref,j) / reference peak, displacement samples the same for y_j '
            '(where the per-coupler reference is cached: `python bench/core.py --refs '
            '--samples`). Memory: tracemalloc peak of Python/numpy allocations while '
            'building the simulator and running the 60 s (numba-internal scratch arrays are '
            'not traced), and the peak RSS of the whole benchmark process (interpreter, numpy, '
            'scipy, numba, LLVM) for context. Host speed: a fixed pure-Python workload timed '
            'next to each case, relative to its fastest time in this run (1.00 = the machine '
            "ran at its best; this virtual machine's speed drifts by up to 2x over minutes "
            'even with nothing else running on it, and every timing drifts with it); cases '
            f'timed below {core.SLOW_HOST:g} of it were timed again, up to {core.RETRIES} '
            'times, keeping the run at the higher host speed (retries: '
            f"{sum(r.get('retries', 0) for r in core_res['cases'] + core_res['steps'])}).",
            '',
            core_table(core_res['cases']), '',
            '### Integration step: accuracy against speed (tanh u = 1000)', '',
            core_table([r for r in core_res['cases'] if r['model'] == 'tanh'
                        and r['u'] == 1000.0 and r['n'] in {s[0] for s in core.STEP_VARIANTS}]
                       + core_res['steps']), '',
            '### Baseline: what a user would write', '',
            '`scipy.integrate.solve_ivp(method="RK45", rtol=1e-6)` on the paper\'s relative '
            'equations (17)-(18) generalised to N coaches (tanh u = 1000, plain vectorised '
            'numpy right-hand side, no Jacobian), same brake forces, 60 s, dense output at '
            '10 ms. Larger trains are extrapolated with the power law in N fitted to the two '
            'largest measured.', '',
            baseline_table(core_res['baseline']), '',
            '### Start-up of the core (numba)', '',
            'Fresh process each: `import train_dynamics.physics.train`, then a 30-coach simulator '
            'and its first 10 ms. Cold = empty kernel cache (a source change, or an install '
            'without the build-time kernels: every kernel compiles); warm = kernels loaded from '
            'the cache (`~/.cache/train_dynamics/numba-<code version>`, see '
            '`physics/kernel/compiler.py`).',
            '', startup_table(core_res['startup']), '']
    if node_res:
        p = node_res['params']
        parts += [
            '## Node (`sim_node`, separate process, DDS on loopback)', '',
            '`python -m train_dynamics.ros.sim_node --ros-args '
            + ' '.join(f'-p {k}:={v}' for k, v in p.items()) + '`; '
            'the benchmark process subscribes to `couplers` (reliable, depth 10, raw CDR) '
            'and timestamps arrivals with `time.monotonic()`; it vents the head brake pipe '
            '(emergency) as soon as the first output arrives. Jitter = abs(arrival period - '
            '10 ms). CPU share from `/proc/<pid>/stat` (utime + stime) over the 60 s window.',
            '', nodebench.table(node_res), '']
        if core_res and 'calibration_s' in node_res:
            best = min(r['calibration_s'] for r in core_res['cases'] + core_res['steps'])
            a, b = node_res['calibration_s']
            parts[-1:-1] = ['', f'Host speed (see the core section) just before / after the '
                            f'60 s run: {best / a:.2f} / {best / b:.2f} (run '
                            f"{node_res.get('attempt', 1)}; a run below {core.SLOW_HOST:g} is "
                            'done once more, keeping the run at the higher host speed).']
        if node_res.get('startup_cases'):
            import startup as startupbench
            parts += ['### Node start-up to first output: cold, warm, after a colcon build', '',
                      startupbench.DESCRIPTION, '',
                      startupbench.table(node_res['startup_cases']), '']
    parts += [adaptive_section(), '', soak_section(), '', sweepbench.sweep_section(), '',
              lockstepbench.lockstep_section(), '', memory_section(), '']
    return '\n'.join(parts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--no-core', action='store_true')
    ap.add_argument('--no-node', action='store_true')
    ap.add_argument('--no-sweep', action='store_true', help='skip bench/sweep.py')
    ap.add_argument('--no-lockstep', action='store_true', help='skip bench/lockstep.py')
    ap.add_argument('--no-memory', action='store_true')
    ap.add_argument('--no-freight', action='store_true')
    ap.add_argument('--ref-max-n', type=int, default=100)
    ap.add_argument('--target-ref-max-n', type=int, default=1000,
                    help='compute missing per-coupler references for the target rows only '
                         'up to N coaches (1000: ~2-4 min on this host)')
    ap.add_argument('--default-overrides', type=json.loads, default=None,
                    help='JSON object of settings applied on top of the defaults in the '
                         'target rows, to try a planned default (the rows say so)')
    ap.add_argument('--core-sizes', metavar='N,N,...',
                    help='trains of the core table and its step variants (default: '
                         'core.SIZES); the target rows always run 100 and 1000')
    ap.add_argument('--core-max-u', type=float, metavar='U',
                    help='only the core laws with u <= U (the tanh u = 1e4 cases of long '
                         'trains take minutes each at the default multirate setting)')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--no-pneumatic', action='store_true', help='skip bench/pneumatic.py')
    ap.add_argument('--no-wheelsets', action='store_true',
                    help="skip the wheelsets' cost (bench/vehicle_cost.py)")
    ap.add_argument('--from-json', metavar='RAW',
                    help='only re-render RESULTS.md from a raw file (bench/results/last_run.json)')
    args = ap.parse_args(argv)
    if args.from_json:
        with open(args.from_json) as fh:
            raw = json.load(fh)
        raw['load'].setdefault('others_cores', 0.0)
        text = render(raw['machine'], raw['load'], raw['core'], raw['node'],
                      raw.get('freight_targets'))
        print(text)
        if not args.no_write:
            with open(RESULTS, 'w') as fh:
                fh.write(text)
        return 0
    load = {'before': os.getloadavg()[0]}
    meter = CpuMeter()
    mach = machine()
    t0 = time.monotonic()
    core_res = node_res = None
    if not args.no_core:
        sizes = (tuple(int(n) for n in args.core_sizes.split(',')) if args.core_sizes
                 else core.SIZES)
        models = (core.MODELS if args.core_max_u is None
                  else tuple(m for m in core.MODELS if m[1] <= args.core_max_u))
        core_res = core.run(ref_max_n=args.ref_max_n, log=log, sizes=sizes, models=models,
                            steps=tuple(s for s in core.STEP_VARIANTS if s[0] in sizes),
                            target_ref_max_n=args.target_ref_max_n,
                            default_overrides=args.default_overrides)
    if not args.no_node:
        import node as nodebench
        log('node: 300 coaches, 100 Hz, real time, 60 s')
        try:
            best = min((r['calibration_s'] for r in core_res['cases'] + core_res['steps']),
                       default=None) if core_res else None
            for attempt in range(2):
                cal0 = core.calibration_s()
                res = nodebench.run(log=log)
                res['calibration_s'] = (cal0, core.calibration_s())
                res['attempt'] = attempt + 1
                speed = best / max(res['calibration_s']) if best else 1.0
                res['host_speed'] = speed
                if node_res is None or speed > node_res['host_speed']:
                    node_res = res
                if speed >= core.SLOW_HOST:
                    break
                log(f'node: the host ran at {speed:.2f} of its best speed: timing it again')
            log('node: start-up spread (4 more starts)')
            node_res['startup_trials'] = nodebench.startup_trials(log=log)
            nodebench.apply_startup_target(node_res)
            log('node: start-up cold, warm and after a colcon build (bench/startup.py)')
            import startup as startupbench
            node_res['startup_cases'] = startupbench.run(log=log)
        except Exception as exc:  # noqa: BLE001 - report and keep the core results
            log(f'node benchmark failed: {exc}')
    pneu_md = ''
    if not args.no_pneumatic:       # bench/pneumatic.py owns its section
        import pneumatic
        rows = pneumatic.run_offline(log=log)
        pneu_md = pneumatic.render(rows, None if args.no_node else pneumatic.run_node(log=log))
        with open(pneumatic.RESULTS_MD, 'w') as fh:
            fh.write(pneu_md)
    wheel_md = ''
    if not args.no_wheelsets:       # bench/vehicle_cost.py owns its section
        import vehicle_cost
        log('wheelsets: cost per vehicle-step with and without (paper47, freight)')
        wheel_md = vehicle_cost.wheelset_section(log=log, write=not args.no_write)
        if not args.no_node:
            import node as nodebench
            n, params = nodebench.CASES['wheelsets300']
            log(f'node: {n} vehicles with wheelsets, 100 Hz, real time, 60 s')
            try:
                res = nodebench.run(n=n, rate=100.0, duration=60.0, log=log, extra_params=params)
                wheel_md += ('\n#### The node with 300 vehicles and wheelsets (100 Hz, 60 s)\n\n'
                             + nodebench.table(res) + '\n')
            except Exception as exc:  # noqa: BLE001 - report and keep the other results
                log(f'wheelsets node benchmark failed: {exc}')
    if not args.no_sweep:
        try:
            sweepbench.run_and_write(log=log, write=not args.no_write)
        except Exception as exc:  # noqa: BLE001 - report and keep the other results
            log(f'sweep benchmark failed: {exc}')
        try:
            import sweep_plan_cost       # printed only: planning the largest sweep allowed
            sweep_plan_cost.run(log=log)
        except Exception as exc:  # noqa: BLE001 - one benchmark must not stop the others
            log(f'sweep plan benchmark failed: {exc}')
    if not args.no_lockstep:
        try:
            lockstepbench.run_and_write(log=log, write=not args.no_write)
        except Exception as exc:  # noqa: BLE001 - report and keep the other results
            log(f'lockstep benchmark failed: {exc}')
    if not args.no_memory:
        import memory
        text = memory.section(memory.run([60.0, 600.0], log=log))
        memory.MEMORY_MD.write_text(f'{MEMORY_BEGIN}\n{text}\n{MEMORY_END}\n')
    load['after'] = os.getloadavg()[0]
    load['others_cores'] = meter.others_cores()
    freight_res = freight_rows = None
    if not args.no_freight:
        try:
            freight_rows = freight.target(core.target_settings(args.default_overrides),
                                          log=log)
        except Exception as exc:  # noqa: BLE001 - report and keep the other results
            log(f'freight target failed: {exc}')
        try:
            freight_res = freight.run(log=log)
        except Exception as exc:  # noqa: BLE001 - report and keep the other results
            log(f'freight benchmark failed: {exc}')
    text = render(mach, load, core_res, node_res, freight_rows)
    if pneu_md:
        text = text.rstrip('\n') + '\n\n' + pneu_md
    if wheel_md:
        text = text.rstrip('\n') + '\n\n' + wheel_md
    if freight_res is not None:
        text = text.rstrip('\n') + '\n\n' + freight.render(freight_res) + '\n'
    print(text)
    log(f'bench: {time.monotonic() - t0:.0f} s')
    if not args.no_write:
        with open(RESULTS, 'w') as fh:
            fh.write(text)
        raw = {'machine': mach, 'load': load, 'core': core_res, 'node': node_res,
               'freight': freight_res, 'freight_targets': freight_rows}
        with open(RAW, 'w') as fh:
            json.dump(raw, fh, indent=1, default=str)
        log(f'wrote {RESULTS} and {RAW}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
