"""
Benchmark of the error-controlled stepping: accuracy and speed per tolerance.

Cases (all tanh u = 1000, the package's default parameters unless said):

- ``paper``: ``config/paper_3coach.yaml`` with its brake valve (emergency at 1 s), 60 s,
  through the stop (the run the paper bag records);
- ``unequal4``: ``config/unequal_4coach.yaml``, four coaches of 60, 25, 80 and 40 t whose
  cylinder pressures are replayed (:func:`unequal4_schedule`, 100 Hz, zero-order hold):
  staggered fillings, a partial release and re-application of coach 2, a release of
  coach 4; 30 s;
- ``n100``, ``n1000``: the paper's coaches, 100 and 1000 of them, head pipe vented at
  t = 0 (bench/core.py's scenario), 60 s; ``n100p``, ``n1000p``: the same with the strokes
  out of reach (the paper's law without blocking, as bench/core.py's error-controlled
  section and its Radau reference).

Every run goes through the offline run loop (:func:`train_dynamics.simulation.runner.
run_simulation`) and reads ``coupler_force`` at every 10 ms output. The reference of a case
is the same model, fed the same inputs, at a tight tolerance (``REF_TOL``, step budget out
of reach): the brake system runs on the same 2 ms tick in both, so the difference is the
chain's integration error alone. Figures:

- sample error: max over the samples and couplers of |F - F_ref| / max |F_ref|;
- envelope error (bench/core.py): max over the samples of |max_j |F_j| - max_j |F_ref,j||
  / max |F_ref|, up to 0.5 s before the first coach stops (``window``) and over the whole
  run (``all``);
- in-train envelope error: max over the couplers of the difference of their largest
  tension and of their largest compression over every integration step
  (``TrainSimulator.coupler_force_envelope``) up to the end of the window, / max |F_ref|: the
  railway engineer's force envelope along the train, free of the 10 ms sampling (a blocking
  impact's peak lasts ~20 ms: samples taken 1-2 ms apart in the run and in the reference
  differ by 10 % and more there, which dominates the two errors above in n100);
- speed: process CPU time, best of ``--repeats`` fresh runs (after a warm-up run), as a
  real-time factor;
- where the steps go: chain steps per output period (median, 99th percentile, max),
  rejected steps, smallest step, periods that ran out of ``integration_max_steps``.

Each case runs in a fresh process (``--case JSON``); the references are cached under
``--cache`` (default /tmp/td_adaptive_cache), keyed by the case and the tolerance.
``--repo PATH`` imports the package from another source tree (A/B comparisons of kernel
versions: alternate the two trees' runs); ``--write-bag DIR`` writes the ``unequal4`` input bag
for ``train-dynamics simulate --input``.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

OUTPUT_DT = 0.01
REF_TOL = 1e-6            # the reference runs' tolerance
REF_BUDGET = 10 ** 6      # no fallback in the reference
STOP_MARGIN = 0.5         # [s] the envelope window ends this long before the first stop
CASES = {'paper': 60.0, 'unequal4': 30.0, 'n100': 60.0, 'n1000': 60.0, 'n100p': 60.0,
         'n1000p': 60.0}
UNEQUAL_MASSES = [60000.0, 25000.0, 80000.0, 40000.0]
TOLERANCES = (1e-2, 3e-3, 1e-3, 3e-4)


def _import_path(repo: str) -> None:
    if repo not in sys.path:
        sys.path.insert(0, repo)


# ----------------------------------------------------------------------------- scenarios
def unequal4_schedule(t: float):
    """
    Return the four cylinder pressures [Pa gauge] at t [s] of the ``unequal4`` case.

    Staggered fillings (0.15 s apart, 2-4 s long); coach 2 released to 40 % from 10 s to
    11 s and re-applied from 15 s over 1.5 s; coach 4 released over 2 s from 20 s.
    """
    import numpy as np
    pmax = 380000.0
    idx = np.arange(4)
    fill = np.clip((t - 0.5 - 0.15 * idx) / np.array([2.0, 3.0, 4.0, 2.5]), 0.0, 1.0)
    p = pmax * fill
    cut = 1.0 - 0.6 * np.clip(t - 10.0, 0.0, 1.0) + 0.6 * np.clip((t - 15.0) / 1.5, 0.0, 1.0)
    p[1] *= cut
    p[3] *= 1.0 - np.clip((t - 20.0) / 2.0, 0.0, 1.0)
    return p


def _events_unequal4(h: float, duration: float):
    from train_dynamics import topics
    from train_dynamics.simulation.runner import CommandEvent, step_of
    events = []
    for k in range(int(round(duration / OUTPUT_DT)) + 1):
        t_ns = int(round(k * OUTPUT_DT * 1e9))
        for i, p in enumerate(unequal4_schedule(k * OUTPUT_DT)):
            events.append(CommandEvent(topics.CYLINDER_PER_COACH, i, float(p), t_ns,
                                       step_of(t_ns, h),
                                       topics.input_topic(topics.CYLINDER_PER_COACH, i + 1)))
    return events


def write_unequal4_bag(path: str, duration: float = CASES['unequal4']) -> None:
    """
    Write the ``unequal4`` cylinder pressures as an input bag (absolute Pa, 100 Hz).

    For ``train-dynamics simulate --params config/unequal_4coach.yaml --input BAG``: the
    offline command replays it exactly as this bench does (zero-order hold from each
    message's time, bag start = t 0).
    """
    from train_dynamics import topics
    from train_dynamics.recording import messages
    from train_dynamics.recording.bags import BagRecorder
    atm = 101325.0
    epoch = 1_700_000_000_000_000_000
    with BagRecorder(path) as rec:
        for k in range(int(round(duration / OUTPUT_DT)) + 1):
            t = k * OUTPUT_DT
            for i, p in enumerate(unequal4_schedule(t)):
                rec.write_msg('/' + topics.input_topic(topics.CYLINDER_PER_COACH, i + 1),
                              epoch + int(round(t * 1e9)), messages.fluid_pressure(t, p + atm))


def case_setup(case: str, tol: float, budget: int, extra: dict | None = None):
    """Return (config, InputSchedule, duration [s]) of a case at tolerance ``tol``."""
    from train_dynamics import topics
    from train_dynamics.cli.scenario import load_config, valve_from_param_file
    from train_dynamics.physics.config import SimConfig
    from train_dynamics.simulation.runner import CommandEvent, InputSchedule
    over = {'integration_tolerance': tol, 'integration_max_steps': budget, **(extra or {})}
    duration = CASES[case]
    if case == 'paper':
        path = os.path.join(REPO, 'config', 'paper_3coach.yaml')
        cfg = SimConfig.from_dict({**load_config(path).values, **over})
        return cfg, InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(path, cfg)), duration
    if case == 'unequal4':
        path = os.path.join(REPO, 'config', 'unequal_4coach.yaml')
        cfg = SimConfig.from_dict({**load_config(path).values, **over})
        events = _events_unequal4(float(cfg.integration_step), duration)
        return cfg, InputSchedule(topics.CYLINDER_PER_COACH, events), duration
    n = int(case[1:].rstrip('p'))
    if case.endswith('p'):      # the paper's law: strokes out of reach (bench/core.py)
        over.update(buffer_stroke=10.0, draw_gear_stroke=10.0)
    cfg = SimConfig.from_dict({'num_coaches': n, **over})
    vent = CommandEvent(topics.PIPE_HEAD, None, 0.0, 0, 0, topics.HEAD_PIPE_TOPIC)
    return cfg, InputSchedule(topics.PIPE_HEAD, [vent]), duration


def run_case(case: str, tol: float, budget: int, repeats: int, save: str | None,
             extra: dict | None = None) -> dict:
    """In a fresh process: a warm-up run, ``repeats`` timed runs; the samples to ``save``."""
    import numpy as np
    from train_dynamics.simulation.runner import run_simulation
    cfg, inputs, duration = case_setup(case, tol, budget, extra)
    k_out = int(round(duration / OUTPUT_DT)) + 1
    n = cfg.n_coaches
    F = np.zeros((k_out, n - 1))
    steps = np.zeros(k_out, dtype=np.int64)
    moving = np.ones(k_out, dtype=bool)
    env = np.zeros((k_out, 2, n - 1))
    pos = [0]

    def on_sample(s):
        j = pos[0]
        F[j] = s.sim.coupler_force
        steps[j] = s.sim.integration_stats['steps_last_period']
        moving[j] = not (np.any(s.sim.held) or np.any(s.sim.v <= 0.0))
        env[j] = s.sim.coupler_force_envelope
        pos[0] += 1

    short, _, _ = case_setup(case, tol, budget, extra)
    run_simulation(short, 0.05, inputs, on_sample=lambda s: None)    # numba warm-up
    cpu = []
    for _ in range(max(1, repeats)):
        pos[0] = 0
        t0 = time.process_time()
        sim = run_simulation(cfg, duration, inputs, on_sample=on_sample)
        cpu.append(time.process_time() - t0)
    if save:
        np.savez(save, F=F[:pos[0]], moving=moving[:pos[0]], env=env[:pos[0]])
    st = sim.integration_stats
    per = steps[1:pos[0]]
    return {'case': case, 'tol': tol, 'budget': budget, 'n': n, 'duration': duration,
            'extra': extra or {},
            'cpu_s': cpu, 'rtf': duration / min(cpu), 'fault': sim.fault,
            'steps': st['steps'], 'rejected': st['rejected'], 'h_min': st['h_min'],
            'fallback_periods': st['fallback_periods'], 'steps_max_period': int(per.max()),
            'steps_p50': float(np.percentile(per, 50)),
            'steps_p99': float(np.percentile(per, 99)), 'steps_mean': float(per.mean()),
            'fixed_steps': int(sim.steps)}


# ----------------------------------------------------------------------------- driver
def _sub(args: list[str], repo: str) -> dict:
    cmd = [sys.executable, os.path.abspath(__file__), '--repo', repo] + args
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
    if proc.returncode != 0:
        raise RuntimeError(f'{args}: exit {proc.returncode}\n{proc.stderr[-3000:]}')
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _ref_path(cache: str, case: str, tol: float) -> str:
    with open(os.path.join(REPO, 'config', 'unequal_4coach.yaml'), 'rb') as fh:
        key = hashlib.sha256(fh.read() + repr((case, tol, CASES[case], 'env')).encode()
                             ).hexdigest()
    return os.path.join(cache, f'{case}_{tol:g}_{key[:10]}.npz')


def reference(case: str, cache: str, repo: str, tol: float = REF_TOL, log=print) -> str:
    """Return the path of the cached reference samples of ``case`` (computed if missing)."""
    os.makedirs(cache, exist_ok=True)
    path = _ref_path(cache, case, tol)
    if not os.path.exists(path):
        t0 = time.perf_counter()
        res = _sub(['--case', json.dumps([case, tol, REF_BUDGET, 1, path])], repo)
        log(f'  reference {case} tol {tol:g}: {res["steps"]} steps, '
            f'{time.perf_counter() - t0:.0f} s')
    return path


def compare(path: str, ref_path: str) -> dict:
    """Return the sample and envelope errors of the samples at ``path`` against the reference."""
    import numpy as np
    a, r = np.load(path), np.load(ref_path)
    F, Fr = a['F'], r['F']
    k = min(len(F), len(Fr))
    F, Fr = F[:k], Fr[:k]
    peak = float(np.abs(Fr).max())
    dev = np.abs(F - Fr) / peak
    j = np.unravel_index(int(np.argmax(dev)), dev.shape)
    env, renv = np.abs(F).max(axis=1), np.abs(Fr).max(axis=1)
    still = np.nonzero(~(a['moving'][:k] & r['moving'][:k]))[0]
    kw = max(1, int(still[0]) - int(round(STOP_MARGIN / OUTPUT_DT))) if still.size else k
    return {'sample_err': float(dev.max()), 't_sample_err': float(j[0] * OUTPUT_DT),
            'coupler_sample_err': int(j[1]) + 1,
            'sample_err_window': float(dev[:kw].max()),
            'env_err_window': float(np.abs(env[:kw] - renv[:kw]).max() / peak),
            'env_err_all': float(np.abs(env - renv).max() / peak),
            'train_env_err': float(np.abs(a['env'][kw - 1] - r['env'][kw - 1]).max() / peak),
            'window_s': kw * OUTPUT_DT, 'peak_ref_N': peak}


def measure(case: str, tol: float, budget: int, repeats: int, cache: str, repo: str,
            ref_repo: str, extra: dict | None = None, accuracy: bool = True) -> dict:
    """Run one case in a fresh process and compare it with its reference (``accuracy``)."""
    os.makedirs(cache, exist_ok=True)
    path = os.path.join(cache, f'run_{os.getpid()}_{case}.npz') if accuracy else None
    row = _sub(['--case', json.dumps([case, tol, budget, repeats, path, extra or {}])], repo)
    if accuracy:
        row.update(compare(path, reference(case, cache, ref_repo)))
        os.remove(path)
    return row


def _extra(r) -> str:
    return ''.join(f'{k}={v:g} ' for k, v in r.get('extra', {}).items())


def table(rows) -> str:
    """Return the markdown table of :func:`measure` rows."""
    def err(r):
        if 'sample_err' not in r:
            return 'n/a | n/a | n/a'
        return (f"{100 * r['sample_err']:.2f} % (t {r['t_sample_err']:.2f} s, "
                f"c{r['coupler_sample_err']}) | {100 * r['env_err_window']:.2f} / "
                f"{100 * r['env_err_all']:.2f} % | {100 * r['train_env_err']:.2f} %")
    lines = ['| case | tolerance | real-time factor | CPU [s] best (spread) | sample error | '
             'envelope error window / all | in-train envelope error | steps | '
             'steps / 10 ms p50 / p99 / max | rejected | smallest step [ms] | fallback periods |',
             '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: '
             '| ---: |']
    for r in rows:
        cpu = r['cpu_s']
        spread = (max(cpu) - min(cpu)) / min(cpu)
        lines.append(
            f"| {r['case']} {_extra(r)}| {r['tol']:g} | {r['rtf']:.0f}x | {min(cpu):.3f} "
            f"(+{100 * spread:.0f} %) | {err(r)} | {r['steps']} | "
            f"{r['steps_p50']:g} / {r['steps_p99']:g} / {r['steps_max_period']} | "
            f"{r['rejected']} | {1e3 * r['h_min']:.4f} | {r['fallback_periods']} |")
    return '\n'.join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--case', help='internal: JSON [case, tol, budget, repeats, save]')
    ap.add_argument('--repo', default=REPO, help='import train_dynamics from this tree')
    ap.add_argument('--ref-repo', default=REPO, help='tree that computes the references')
    ap.add_argument('--cases', default='paper,unequal4,n100,n1000')
    ap.add_argument('--tols', default=','.join(f'{t:g}' for t in TOLERANCES))
    ap.add_argument('--budget', type=int, default=100, help='integration_max_steps')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--cache', default='/tmp/td_adaptive_cache')
    ap.add_argument('--json', help='append the rows to this JSON-lines file')
    ap.add_argument('--write-bag', metavar='DIR',
                    help='write the unequal4 input bag (cylinder pressures) and exit')
    ap.add_argument('--extra', default='{}', help='JSON: more parameters of every run')
    ap.add_argument('--speed-only', default='n1000,n1000p',
                    help='cases timed without a reference (too slow to compute here)')
    args = ap.parse_args(argv)
    _import_path(args.repo)
    if args.write_bag:
        write_unequal4_bag(args.write_bag)
        return 0
    if args.case:
        case, tol, budget, repeats, save, *extra = json.loads(args.case)
        print(json.dumps(run_case(case, float(tol), int(budget), int(repeats), save,
                                  *extra)))
        return 0
    rows = []
    for case in args.cases.split(','):
        for tol in (float(s) for s in args.tols.split(',')):
            row = measure(case, tol, args.budget, args.repeats, args.cache, args.repo,
                          args.ref_repo, json.loads(args.extra),
                          case not in args.speed_only.split(','))
            rows.append(row)
            print(table([row]).splitlines()[-1], flush=True)
            if args.json:
                with open(args.json, 'a') as fh:
                    fh.write(json.dumps(row) + '\n')
    print(table(rows))
    return 0


if __name__ == '__main__':
    sys.exit(main())
