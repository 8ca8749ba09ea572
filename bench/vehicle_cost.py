"""
Cost per vehicle-step of the fixed-step kernel: the freight train against uniform trains.

Each case runs in a fresh process (``--case NAME`` prints one figure: process CPU time of
the integration [ns] per vehicle-step); :func:`main` interleaves the cases (A B C A B C ...)
and reports best and spread of each, because this host's speed drifts within minutes.

Cases (120 s each, the freight scenario's inputs: emergency at t = 5 s; the cost is split
into the moving part and the part with every vehicle at rest at an output period's start):

- ``freight``: ``config/freight_750m.yaml`` (47 vehicles, every force of the real-train model);
- ``uniformN``: N of the paper's coaches, ``SimConfig.from_dict({'num_coaches': N})``,
  flat, default step (the strokes as the defaults set them: long trains block);
- ``paperN``: the same with the strokes out of reach (the paper's idealisation, as a
  kernel without strokes computed it);
- ``<case>+w``: the case with rotating wheelsets (``wheelsets: true``: the creep-law sub-step
  per vehicle and step, dry rail), against the case without; ``<case>+b``: two per vehicle
  (``bogie_wheelsets: true``: one per bogie).
- ``CASE+mrTOL``, ``CASE+tolTOL``: any of these with ``multirate_tolerance`` or
  ``integration_tolerance`` TOL (e.g. ``uniform100+mr1e-3``).

``--python PY --path DIR`` (repeatable, pairwise) adds a kernel version: the case runs with
``PY`` and ``PYTHONPATH=DIR`` (e.g. a worktree of an older commit); the uniform and paper
cases use only the simulator's oldest interface, so they also run on kernels without strokes.

    .venv/bin/python bench/vehicle_cost.py --cases freight,paper47 --repeats 5 \
        --python .venv/bin/python --path /path/to/other/worktree
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
T_END = 120.0
T_EMERGENCY = 5.0
SAMPLE = 0.01       # [s] advance() is called once per output period, as freight.py does


def drive(sim, events, t: float) -> None:
    """
    Set the freight scenario's inputs at output instant ``t`` [s]; the caller advances.

    ``events``: the traction schedule (``runner.schedule_events``) or none; the head pipe
    at 5 bar gauge until T_EMERGENCY, then vented (emergency).
    """
    from train_dynamics.simulation.runner import apply_event
    for e in events:
        if abs(e.t_ns * 1e-9 - t) < 1e-9:
            apply_event(sim, e)
    sim.set_head_pipe_pressure(0.0 if t >= T_EMERGENCY - 1e-9 else 500000.0)


def _config(case: str):
    """Return the SimConfig of a case (see the module docstring)."""
    from train_dynamics.param_files import load_param_file
    from train_dynamics.physics.config import SimConfig
    if case.endswith('+w'):
        return _config(case[:-2]).replace(wheelsets=True)
    if case.endswith('+b'):     # two wheelsets per vehicle, one per bogie
        return _config(case[:-2]).replace(bogie_wheelsets=True)
    if '+rw' in case:       # ``uniform100+mr1e-3+rw0.3``: multirate_reversal_weight 0.3
        case, w = case.split('+rw')
        return _config(case).replace(multirate_reversal_weight=float(w))
    for suffix, name in (('+mr', 'multirate_tolerance'), ('+tol', 'integration_tolerance')):
        if suffix in case:       # ``uniform100+mr1e-3``, ``uniform100+tol1e-3``
            case, tol = case.split(suffix)
            return _config(case).replace(**{name: float(tol)})
    if case == 'freight':
        return load_param_file(os.path.join(ROOT, 'config', 'freight_750m.yaml'))
    if case.startswith('uniform'):
        return SimConfig.from_dict({'num_coaches': int(case[len('uniform'):])})
    if case.startswith('paper'):
        n = int(case[len('paper'):])
        try:
            return SimConfig.from_dict({'num_coaches': n, 'buffer_stroke': 10.0,
                                        'draw_gear_stroke': 10.0})
        except (KeyError, ValueError):      # a kernel without strokes
            return SimConfig.from_dict({'num_coaches': n})
    raise ValueError(f'unknown case {case!r}')


def measure(case: str) -> dict:
    """Run one case (after a warm-up step); return its CPU ns per vehicle-step."""
    # imported here: the case runs in the process of the kernel version under test
    from train_dynamics.physics.train import TrainSimulator
    cfg = _config(case)
    TrainSimulator(cfg).advance(1)       # load the compiled kernels (not timed)
    sim = TrainSimulator(cfg)
    events = []
    if case == 'freight':
        from train_dynamics.simulation.runner import schedule_events
        events = sorted(schedule_events(cfg), key=lambda e: e.step)
    per = int(round(SAMPLE / sim.h))
    cpu = [0.0, 0.0]        # moving, stopped (every vehicle at rest at the period's start)
    steps = [0, 0]
    for k in range(int(round(T_END / SAMPLE))):
        drive(sim, events, k * SAMPLE)
        phase = int(not sim.v.any())
        t0 = time.process_time()
        sim.advance(per)
        cpu[phase] += time.process_time() - t0
        steps[phase] += per
    import train_dynamics
    scale = 1e9 / sim.n
    return {'case': case, 'ns': sum(cpu) * scale / sum(steps),
            'ns_moving': cpu[0] * scale / max(steps[0], 1),
            'ns_stopped': cpu[1] * scale / steps[1] if steps[1] else None, 'n': sim.n,
            'x0': float(sim.x[0]), 'fault': sim.fault,
            'module': os.path.dirname(train_dynamics.__file__)}


def _run_case(python: str, path: str | None, case: str) -> dict:
    env = dict(os.environ)
    if path:
        env['PYTHONPATH'] = path
    out = subprocess.run([python, os.path.abspath(__file__), '--case', case], env=env,
                         capture_output=True, text=True, check=True, cwd=ROOT).stdout
    return json.loads(out.strip().splitlines()[-1])


def interleave(versions, cases, repeats: int = 5, log=print) -> dict:
    """
    Run every (version, case) ``repeats`` times, interleaved, each in a fresh process.

    ``versions``: [(label, python, PYTHONPATH or None)]. Returns {'label case': summary}
    with the sorted totals 'ns' [ns per vehicle-step] and the best 'moving' and 'stopped'
    figures; a case a version cannot run (freight on a kernel without its forces) is left out.
    """
    combos = [(label, py, path, case) for label, py, path in versions for case in cases]
    for combo in list(combos):       # warm-up: load or compile the kernels
        label, py, path, case = combo
        try:
            r = _run_case(py, path, case)
        except subprocess.CalledProcessError:      # e.g. freight on a kernel before it
            log(f'# {label} {case}: cannot run, left out')
            combos.remove(combo)
            continue
        log(f'# {label} {case}: kernel from {r["module"]}')
    runs = {c[0] + ' ' + c[3]: [] for c in combos}
    for _ in range(repeats):
        for label, py, path, case in combos:
            runs[label + ' ' + case].append(_run_case(py, path, case))
    return {key: {'ns': sorted(r['ns'] for r in rs), 'n': rs[0]['n'],
                  'moving': min(r['ns_moving'] for r in rs),
                  'stopped': min((r['ns_stopped'] for r in rs if r['ns_stopped'] is not None),
                                 default=None)} for key, rs in runs.items()}


#: ``make bench``'s wheelset section: each train with and without rotating wheelsets
WHEELSET_PAIRS = (('paper47', 'paper47+w'), ('freight', 'freight+w'))
#: the target of the wheel-slide model's cost: at most this times the same train without
WHEELSET_TARGET = 1.5
WHEELSET_MD = os.path.join(HERE, 'results', 'wheelset_cost_results.md')


def wheelset_section(repeats: int = 3, log=print, write: bool = True) -> str:
    """
    Measure the cost of rotating wheelsets (``+w``) against the same train without them.

    Interleaved fresh processes, best moving vehicle-step of ``repeats``; returns (and
    writes to ``bench/results/wheelset_cost_results.md``) a markdown table with the ratio.
    """
    cases = [c for pair in WHEELSET_PAIRS for c in pair]
    load = os.getloadavg()[0]
    res = interleave([('this', sys.executable, None)], cases, repeats, log=log)
    lines = ['### Cost of rotating wheelsets (ns per moving vehicle-step)', '',
             f'Best of {repeats} interleaved runs, each in a fresh process '
             f'(bench/vehicle_cost.py), load average {load:.1f} at the start; target at '
             f'most {WHEELSET_TARGET}x the same train without wheelsets.', '',
             '| train | without | with wheelsets | ratio | target met |',
             '| --- | --- | --- | --- | --- |']
    for plain, wheels in WHEELSET_PAIRS:
        a, b = res[f'this {plain}']['moving'], res[f'this {wheels}']['moving']
        lines.append(f'| {plain} | {a:.1f} | {b:.1f} | {b / a:.2f}x | '
                     f'{"yes" if b / a <= WHEELSET_TARGET else "no"} |')
    text = '\n'.join(lines) + '\n'
    if write:
        with open(WHEELSET_MD, 'w', encoding='utf-8') as fh:
            fh.write(text)
    return text


def main(argv=None) -> None:
    """Interleave the cases over the kernel versions; print best, median and spread."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--case', help='run one case in this process and print it (JSON)')
    ap.add_argument('--cases', default='freight,paper47,uniform47')
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--python', action='append', default=[])
    ap.add_argument('--path', action='append', default=[])
    ap.add_argument('--label', action='append', default=[])
    args = ap.parse_args(argv)
    if args.case:
        print(json.dumps(measure(args.case)))
        return
    versions = list(zip(args.python, args.path)) or [(sys.executable, None)]
    labels = args.label or [p or 'this' for _, p in versions]
    res = interleave([(label, py, path) for label, (py, path) in zip(labels, versions)],
                     args.cases.split(','), args.repeats, log=lambda s: print(s, flush=True))
    print(f'{"":28s} ns per vehicle-step: best / median / max of {args.repeats} '
          '(best moving, best stopped)')
    for key, r in res.items():
        ts = r['ns']
        stopped = '     -' if r['stopped'] is None else f'{r["stopped"]:6.1f}'
        print(f'{key:28s} {ts[0]:6.1f} / {ts[len(ts) // 2]:6.1f} / {ts[-1]:6.1f}   '
              f'({r["moving"]:6.1f}, {stopped})')


if __name__ == '__main__':
    main()
