"""
Where the error-controlled steps go: cases run through the traced copy of the chain driver.

The traced driver (:mod:`train_dynamics.physics.kernel.adaptive_trace`) is the error-controlled
driver with every attempted step logged and the controller's constants and the error norm's
variant taken from an array; ``test/kernel/test_adaptive_trace.py`` checks that with the
driver's constants it leaves the driver's state bit for bit. Norm variants (``--mode``):

0. the kernel's: the embedded estimate weighted into coupler forces (stage-matrix slopes);
   with the kernel's constants (no ``--set``) the run is the driver's to the last bit;
1. the estimate filtered through the stage matrix, (I - g h J)^-1 e (Shampine), then 0;
2. filtered, then the force difference F(y, ydot) - F(y - e_y, ydot - e_ydot) (the law);
3. unfiltered force difference.

``python bench/adaptive_trace.py CASE TOL [--mode M ...]`` runs a case of bench/adaptive.py
through it and prints the step statistics and the errors against the cached reference.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
if REPO not in sys.path:
    sys.path.insert(0, REPO)

import numpy as np  # noqa: E402

# the ctl slots (MODE, SAFETY, ...) by name for --set, the log's columns (ACC, BAND, ...)
from train_dynamics.physics.kernel.adaptive_trace import (  # noqa: E402,F401
    ACC, BAND, default_ctl, EPOS, EVEL, EXACT, FAC_MAX, FAC_MIN, H, KI, KP, MODE, SAFETY,
    traced)


def run(case: str, tol: float, ctl: np.ndarray, budget: int, cache: str):
    """Run ``case`` traced; return (row with errors and step statistics, log)."""
    import adaptive
    from train_dynamics.physics import train
    from train_dynamics.simulation import runner
    cfg, inputs, duration = adaptive.case_setup(case, tol, budget)
    k_out = int(round(duration / adaptive.OUTPUT_DT)) + 1
    F = np.zeros((k_out, cfg.n_coaches - 1))
    moving = np.ones(k_out, dtype=bool)
    pos = [0]
    holder = {}
    real_init = train.TrainSimulator.__init__

    def init(self, *a, **k):
        real_init(self, *a, **k)
        holder['log'] = traced(self, ctl)
    train.TrainSimulator.__init__ = init
    runner.TrainSimulator.__init__ = init

    def on_sample(s):
        F[pos[0]] = s.sim.coupler_force
        moving[pos[0]] = not (np.any(s.sim.held) or np.any(s.sim.v <= 0.0))
        pos[0] += 1
    t0 = time.process_time()
    sim = runner.run_simulation(cfg, duration, inputs, on_sample=on_sample)
    cpu = time.process_time() - t0
    train.TrainSimulator.__init__ = real_init
    path = os.path.join(cache, f'trace_{os.getpid()}.npz')
    np.savez(path, F=F[:pos[0]], moving=moving[:pos[0]])
    row = adaptive.compare(path, adaptive.reference(case, cache, REPO))
    log = holder['log']()
    acc = log[log[:, ACC] == 1.0]
    rej = log[log[:, ACC] == 0.0]
    row.update(case=case, tol=tol, mode=int(ctl[MODE]), cpu_s=cpu, fault=sim.fault,
               steps=int(acc.shape[0]), rejected=int(rej.shape[0]),
               band_limited=float((acc[:, BAND] < 1.0).mean()) if acc.size else 0.0,
               near_band=float((acc[:, BAND] < 10.0).mean()) if acc.size else 0.0,
               vel_dominated=float((acc[:, EVEL] > acc[:, EPOS]).mean()) if acc.size else 0.0,
               h_median_ms=1e3 * float(np.median(acc[:, H])) if acc.size else 0.0)
    return row, log


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('case')
    ap.add_argument('tol', type=float)
    ap.add_argument('--mode', type=int, default=0)
    ap.add_argument('--budget', type=int, default=1000000)
    ap.add_argument('--set', action='append', default=[],
                    help='controller constant NAME=VALUE (SAFETY, FAC_MIN, FAC_MAX, KI, KP)')
    ap.add_argument('--cache', default='/tmp/td_adaptive_cache')
    ap.add_argument('--save-log', help='write the step log (.npy)')
    args = ap.parse_args(argv)
    sys.path.insert(0, HERE)
    ctl = default_ctl(args.mode)
    for item in args.set:
        name, value = item.split('=')
        ctl[globals()[name]] = float(value)
        ctl[EXACT] = 0.0        # the constants come from ctl
    row, log = run(args.case, args.tol, ctl, args.budget, args.cache)
    if args.save_log:
        np.save(args.save_log, log)
    print(json.dumps(row))
    return 0


if __name__ == '__main__':
    sys.exit(main())
