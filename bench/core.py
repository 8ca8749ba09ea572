"""
Benchmark of the physics core: speed, accuracy and memory at the default settings.

Scenario: the paper's emergency braking generalised to N coaches (config defaults: 45 t
coaches at 44.444 m/s, ``pipe_head``). The head brake-pipe pressure is set to 0 gauge at
t_e = 0 s (before the first step); 60 s of simulated time. The couplers are the paper's
idealisation, as the reference models them: the strokes are set out of reach
(:data:`PAPER_IDEALISATION`, 10 m, beyond ``max_coupler_displacement``: a coupler cannot
block without the run stopping with a fault), no slack, no resistance or track. With the
default strokes (105 mm buffers, 60 mm draw gear) trains of 100 coaches and more block, which
neither the reference nor the scipy baseline models.

Every case runs in a fresh Python process (``python bench/core.py --case JSON``), so that
warm-up, memory and timing of one case do not leak into the next. Every setting but the
integration step (and the law and u of the case) is SimConfig's default, so the cases
follow the default integration (e.g. ``multirate_tolerance``):

- warm-up (excluded from the timing, reported separately): one ``TrainSimulator`` and one
  ``advance(1)``, i.e. numba's cache load (or compilation when the cache is cold);
- memory and accuracy: an untimed run over [0, 60 s] (:func:`sampled_run`) under
  ``tracemalloc``: the peak of Python/numpy heap allocations [KiB] made by constructing the
  simulator and running it (numba's internal scratch arrays are not traced; they are a
  handful of N-element arrays per ``advance`` call). The process's peak RSS (VmHWM) is
  reported too, for context. The run samples every 10 ms the envelope max_j |F_j(t)| and,
  where the per-coupler reference is cached, max_j |F_j - F_ref,j| and max_j |y_j - y_ref,j|;
  these are compared with the tight-tolerance reference
  :func:`train_dynamics.physics.reference.reference_solution` (Radau, rtol 1e-9, atol 1e-11,
  analytical Jacobian) driven by the brake forces as a function of time,
  Fb_i(t) = mu_a m_i g fill(t - t_e - d_i) (d_i the pipe delay of coach i). The run checks
  that this formula is what the simulator applies (it applies the mean over the step,
  0.5 (Fb(t-h) + Fb(t))) and reports the largest mismatch. The reference ignores the brake
  holding a stopped coach, so the comparison covers [0, W], W = 0.5 s before the first
  coach stops (in our run or in the reference, whichever is first), at most 60 s. Sample
  accuracy (:func:`sample_errors`): max over the samples in [0, W] and the couplers of
  |F_j - F_ref,j| / max |F_ref| (and the same for the displacements y_j);
- timed runs: whole runs over [0, W] (:func:`timed_run`), the span in which every coach
  moves (a stopped train costs almost nothing and would flatter the figure):
  ``sim.advance_to`` in 10 ms chunks and after each chunk ``sim.coupler_force`` and its
  max |F|, as the node reads its outputs. The virtual machine's speed drifts by up to 2x
  within seconds, so the whole run is repeated (5 times, 3 for the slowest cases) and the
  figure is the fastest whole run; real-time factor = W / wall (the same from the least
  process CPU time is kept beside it: on a loaded host the wall time includes other work).

The target rows (``--targets``; :func:`target_case`, one fresh process per train) measure
the speed targets at the DEFAULT settings: 100 and 1000 of the paper's coaches (tanh
u = 1000, the configuration sets only the train and the paper's idealisation), with the
sample accuracy beside the speed, and the plain fixed step (``multirate_tolerance`` 0) the
same way for comparison. The settings are timed interleaved (A B A B ...) in whole runs over
the same moving span; ``--default-overrides JSON`` applies settings on top of the defaults
(to try a planned default; the rows name them). Where the reference's per-coupler samples
are cached, each row carries the accuracy contract's metrics too (:func:`robust_metrics`:
``physics/comparison.all_metrics`` on every coupler's 10 ms samples). ``--bdf`` adds two
scipy BDF rows timed in the same rounds (:func:`bdf_run`: rtol 1e-6 on the reference's
equations with its analytical sparse Jacobian, and on the paper's relative equations with
``jac_sparsity``); ``--floor`` the sensitivity floor (the reference of the same train with the
middle coach's mass x (1 + 1e-3), :func:`floor_inertia`; ``--refs --samples --floor``
computes and caches it like the other references); the markdown table
(:func:`contract_table`) goes to stderr after the JSON rows.

The baseline is what a user would write: ``scipy.integrate.solve_ivp`` (RK45, rtol 1e-6,
default atol 1e-6) on the paper's relative equations of motion (17)-(18) generalised to N
coaches (state y, ydot; tanh law u = 1000 with the paper's (1 -+ sgn y)/2 branch selection;
a plain vectorised numpy right-hand side, no Jacobian), same brake forces, 60 s.

Reference solutions (over 0-60 s, the envelope up to the first stop) are cached in
``bench/results/reference_cache.json``, keyed by everything they depend on, including a numerical
fingerprint of the force law and the reference solver's defaults, so they are recomputed
only when the physics changes (delete the file to force it). Their per-coupler samples
(F and y every 10 ms, float32: ~25 MB for 1000 coaches) are kept outside the repository, in
``~/.cache/train_dynamics/bench-reference/<key>.npz`` (same key;
``TRAIN_DYNAMICS_BENCH_REF_DIR`` overrides the folder). The reference never depends on
the strokes (it has none); :func:`check_idealisation` makes sure the simulated train is the
one the reference solves. ``python bench/core.py --refs [--samples]``
fills the cache; ``make bench`` computes missing ones up to ``--ref-max-n`` coaches (the
target rows' per-coupler ones up to ``--target-ref-max-n``, 1000 by default: ~2-4 min).

numpy, scipy and the package are imported inside the functions on purpose: each case runs
in a fresh process that times its own import and start-up, and the driver stays light.
"""
from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
if REPO not in sys.path:
    sys.path.insert(0, REPO)

CACHE_PATH = os.path.join(HERE, 'results', 'reference_cache.json')
T_END = 60.0            # simulated seconds per case
T_EMERGENCY = 0.0       # head pipe vented to 0 gauge at this time [s]
OUTPUT_DT = 0.01        # the node's 100 Hz output period [s]
STOP_MARGIN = 0.5       # the comparison window ends this long before the first coach stops [s]
SIZES = (3, 30, 100, 300, 1000)
MODELS = (('tanh', 100.0), ('tanh', 1000.0), ('tanh', 10000.0), ('sign', 1000.0))
STEP_CHOICES = (1.0e-3, 2.0e-3, 5.0e-3)   # integration steps of the accuracy/speed table
BASELINE_SIZES = (3, 30, 100)
BASELINE_EXTRAPOLATE = (300, 1000)


def _default_h() -> float:
    from train_dynamics.physics.config import PARAMETERS
    return float(PARAMETERS['integration_step'].default)


DEFAULT_H = _default_h()    # the package's default integration_step [s]
TIMED_REPEATS = 5           # timed whole runs per case (3 for the slowest cases)
SLOW_HOST = 0.8             # a case timed below this host speed is timed again ...
RETRIES = 2                 # ... at most this many times
STEP_VARIANTS = tuple((n, h) for n in (100, 1000) for h in STEP_CHOICES if h != DEFAULT_H)


def _py() -> str:
    return sys.executable


# --------------------------------------------------------------------------- helpers
def _rss_kib(field: str = 'VmRSS') -> int:
    with open('/proc/self/status') as fh:
        for line in fh:
            if line.startswith(field + ':'):
                return int(line.split()[1])
    return -1


#: the paper's couplers (no blocking), as the reference and the baseline model them: strokes
#: beyond max_coupler_displacement (5 m by default), which stops the run with a fault first
PAPER_IDEALISATION = {'buffer_stroke': 10.0, 'draw_gear_stroke': 10.0}


def check_idealisation(cfg) -> None:
    """Raise ValueError unless ``cfg`` is a train the reference solves (the paper's law)."""
    v = cfg.values
    reach = v['max_coupler_displacement']
    if (v['buffer_stroke'] <= reach or v['draw_gear_stroke'] <= reach
            or v['buffer_slack'] or v['draw_gear_slack'] or cfg.external_forces
            or v['rotating_mass_factor']):
        raise ValueError("core bench: the configuration leaves the paper's idealisation "
                         '(strokes within reach, slack, rotating masses or external forces), '
                         'which the reference does not model')


def make_config(n: int, model: str, u: float, h: float = DEFAULT_H, **extra):
    """Return the bench's SimConfig: N paper coaches, the paper's idealisation (checked)."""
    from train_dynamics.physics.config import SimConfig
    cfg = SimConfig.from_dict({'num_coaches': int(n), 'model_type': model,
                               'scale_factor': float(u), 'integration_step': float(h),
                               **PAPER_IDEALISATION, **extra})
    check_idealisation(cfg)
    return cfg


def brake_formula(cfg):
    """Return Fb(t) -> (N,) [N] for the pipe_head emergency at T_EMERGENCY."""
    from train_dynamics.physics.reference import HeadVentBraking
    return HeadVentBraking(cfg, T_EMERGENCY)


def _grid(t_end: float):
    import numpy as np
    k = int(round(t_end / OUTPUT_DT))
    return np.arange(k + 1) * OUTPUT_DT


# --------------------------------------------------------------------------- one case
def calibration_s(reps: int = 5) -> float:
    """
    Return the wall time [s] of a fixed pure-Python workload (best of ``reps``).

    A yardstick of how fast the (shared, virtual) machine runs right now.
    """
    best = float('inf')
    for _ in range(reps):
        t0 = time.perf_counter()
        acc = 0
        for i in range(200000):
            acc += i * i % 7
        best = min(best, time.perf_counter() - t0)
    return best


def _start(cfg):
    """Return a new simulator of ``cfg`` with the emergency set up (head pipe vented)."""
    from train_dynamics.physics.train import TrainSimulator
    sim = TrainSimulator(cfg)
    if T_EMERGENCY <= 0.0:
        sim.set_head_pipe_pressure(0.0)
    else:
        sim.schedule(T_EMERGENCY, lambda: sim.set_head_pipe_pressure(0.0))
    return sim


def moving_span(t_first_stop: float | None, ref: dict | None = None) -> float:
    """
    Return the timed span [s]: the comparison window (:func:`comparison_window`).

    The train moves over all of it (it ends STOP_MARGIN before the first coach stops): a
    stopped train costs almost nothing and would flatter the real-time factor.
    """
    return comparison_window(t_first_stop, ref)


def timed_run(cfg, t_span: float) -> tuple[float, float]:
    """
    Return the wall and CPU time [s] of one whole run over [0, t_span], as a user meets it.

    A new simulator; ``sim.advance_to`` in 10 ms chunks and after each chunk
    ``sim.coupler_force`` and its max |F| (the node's 100 Hz read-out). The CPU time of the
    process (``time.process_time``) is kept beside the wall time: on a loaded host the wall
    time includes the time other processes ran.
    """
    import numpy as np
    sim = _start(cfg)
    chunks = int(round(t_span / OUTPUT_DT))
    peak = 0.0
    c0 = time.process_time()
    t0 = time.perf_counter()
    for k in range(1, chunks + 1):
        sim.advance_to(k * OUTPUT_DT)
        m = float(np.abs(sim.coupler_force).max())
        if m > peak:
            peak = m
    return time.perf_counter() - t0, time.process_time() - c0


def sampled_run(cfg, ref: dict | None, brakes: bool = True, keep: bool = False) -> dict:
    """
    Run [0, T_END] untimed and sample it every 10 ms.

    Returns the envelope max_j |F_j| per sample, the first instant a coach is at rest (or
    held), the largest mismatch of the applied brake forces with :func:`brake_formula`
    (``brakes``), and, when ``ref`` holds per-coupler samples ('F', 'y'), per sample k
    max_j |F_j - F_ref,j| and max_j |y_j - y_ref,j| (up to the reference's last valid
    sample), so that the caller takes the maximum over its comparison window. The sample
    arrays are allocated before the simulator (outside a caller's ``tracemalloc`` figure
    when the caller passes them in ``ref['_buffers']``) and returned as numpy arrays.
    ``keep``: every coupler's force on every sample as well ('F', float32, samples x
    couplers), for :func:`robust_metrics`.
    """
    import numpy as np
    chunks = int(round(T_END / OUTPUT_DT))
    bufs = (ref or {}).get('_buffers') or sample_buffers()
    forces = np.zeros((chunks + 1, cfg.n_coaches - 1), np.float32) if keep else None
    env, err_f, err_y = bufs['envelope'], bufs['sample_err_F'], bufs['sample_err_y']
    fb_of_t = brake_formula(cfg)
    fmax = np.max(cfg.adhesion_coefficient * np.asarray(cfg.mass_array) * cfg.gravity)
    h = float(cfg.integration_step)
    mismatch = 0.0
    t_first_stop = None
    ref_f = ref.get('F') if ref is not None else None
    ref_y = ref.get('y') if ref is not None else None
    k_ref = min(ref_f.shape[0], chunks + 1) if ref_f is not None else 0
    sim = _start(cfg)
    for k in range(1, chunks + 1):
        sim.advance_to(k * OUTPUT_DT)
        f = sim.coupler_force
        env[k] = np.abs(f).max()
        if keep:
            forces[k] = f
        if k < k_ref:
            err_f[k] = np.abs(f - ref_f[k]).max()
            err_y[k] = np.abs(sim.y - ref_y[k]).max()
        if t_first_stop is None:
            if np.any(sim.held) or np.any(sim.v <= 0.0):
                t_first_stop = sim.t
            elif brakes:    # brakes as the simulator applied them over the last step
                t = sim.t
                expect = 0.5 * (fb_of_t(t - h) + fb_of_t(t))
                mismatch = max(mismatch, float(np.max(np.abs(sim.brake_force - expect))) / fmax)
    out = {'envelope': env, 't_first_stop': t_first_stop, 'brake_mismatch': mismatch,
           'fault': sim.fault, 'steps': int(sim.steps),
           'peak_N': float(env.max()), 'integration': dict(sim.integration_stats)}
    if ref_f is not None:
        out.update(sample_err_F=err_f[:k_ref], sample_err_y=err_y[:k_ref])
    if keep:
        out['F'] = forces
    return out


def sample_buffers() -> dict:
    """Return zeroed per-sample arrays for :func:`sampled_run` (one per 10 ms sample)."""
    import numpy as np
    k = int(round(T_END / OUTPUT_DT)) + 1
    return {key: np.zeros(k) for key in ('envelope', 'sample_err_F', 'sample_err_y')}


def _lists(run: dict) -> dict:
    """Return ``run`` with its numpy arrays as lists (JSON)."""
    return {k: v.tolist() if hasattr(v, 'tolist') else v for k, v in run.items()}


def sample_errors(run: dict, ref: dict | None, window: float) -> dict:
    """
    Return the sample accuracy of ``run`` (:func:`sampled_run`) over [0, window].

    'force_err': max over the 10 ms samples and couplers of |F - F_ref| / max |F_ref|;
    'disp_err': the same for the coupler displacements y; 'peak_err': (our peak - reference
    peak) / reference peak; 'env_err' = max over samples of |max_j |F_j| - the reference's|
    / reference peak. Empty without a reference (no 'F' samples: only peak and envelope).
    """
    import numpy as np
    if ref is None:
        return {}
    k = int(round(window / OUTPUT_DT))
    env = np.asarray(run['envelope'][:k + 1])
    renv = np.asarray(ref['envelope'][:k + 1])
    rpk = float(renv.max())
    out = {'ref_peak_N': rpk, 'ref_t_peak': float(np.argmax(renv) * OUTPUT_DT),
           'peak_err': (float(env.max()) - rpk) / rpk,
           'env_err': float(np.max(np.abs(env - renv))) / rpk}
    dev = np.abs(env - renv) / rpk
    above = np.nonzero(dev > 0.01)[0]
    out['t_env_err_1pct'] = float(above[0] * OUTPUT_DT) if above.size else None
    if 'sample_err_F' in run and 'F' in ref:
        out['force_err'] = float(np.max(run['sample_err_F'][:k + 1])
                                 / np.abs(ref['F'][:k + 1]).max())
        out['disp_err'] = float(np.max(run['sample_err_y'][:k + 1])
                                / np.abs(ref['y'][:k + 1]).max())
    return out


def measure_case(n: int, model: str, u: float, h: float) -> dict:
    """Run in a fresh process: warm-up, untimed memory/accuracy run, timed whole runs."""
    import tracemalloc
    t0 = time.perf_counter()
    from train_dynamics.physics.train import TrainSimulator
    t_import = time.perf_counter() - t0
    cfg = make_config(n, model, u, h)
    out = {'n': n, 'model': model, 'u': u, 'h': h, 'import_s': t_import,
           'multirate': float(cfg.values['multirate_tolerance'])}

    # warm-up: numba cache load (or compile), excluded from the timing
    t0 = time.perf_counter()
    sim = TrainSimulator(cfg)
    sim.advance(1)
    _ = sim.coupler_force
    out['warmup_s'] = time.perf_counter() - t0

    # the reference (cached only; the driver fills the cache) with its per-coupler samples
    ref = cached_reference(n, u) if model == 'tanh' else None
    # untimed: memory (tracemalloc) and accuracy data; the sample arrays allocated before
    if ref is not None:
        ref['_buffers'] = sample_buffers()
    tracemalloc.start()
    run = sampled_run(cfg, ref)
    _, tm_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out.update(_lists(run), tracemalloc_peak_kib=tm_peak / 1024.0,
               vmhwm_mib=_rss_kib('VmHWM') / 1024.0)
    out['ref_samples'] = ref is not None and 'F' in ref
    cal_before = calibration_s()
    # timed: whole runs of the moving train (the span ends before the first coach stops:
    # a stopped train costs almost nothing). The machine is shared and virtual (its speed
    # drifts by up to 2x within seconds): best of TIMED_REPEATS whole runs.
    span = moving_span(out['t_first_stop'], ref)
    repeats = TIMED_REPEATS if n * (0.005 / h) < 2000 else 3
    times = [timed_run(cfg, span) for _ in range(repeats)]
    walls = [w for w, _ in times]
    wall = min(walls)
    cpu = min(c for _, c in times)
    out.update(wall_s=wall, walls_s=walls, wall_median_s=sorted(walls)[len(walls) // 2],
               repeats=repeats, span_s=span, rtf=span / wall, cpu_s=cpu, rtf_cpu=span / cpu)
    out['calibration_s'] = min(cal_before, calibration_s())
    return out


#: the speed targets at default settings: N paper coaches (tanh u = 1000), real-time factor
SPEED_TARGETS = ((100, 200.0), (1000, 20.0))
#: the sample-accuracy target: every coupler-force and displacement sample within this
#: fraction of the reference's peak
SAMPLE_TARGET = 0.02
#: the plain fixed step (every coupler at integration_step), for comparison
FIXED_STEP = {'multirate_tolerance': 0.0, 'integration_tolerance': 0.0}


def default_config(n: int, **overrides):
    """
    Return N paper coaches at the package's DEFAULT settings (plus ``overrides``).

    Only num_coaches and the paper's idealisation (strokes out of reach, checked) are set:
    the integration settings are SimConfig's defaults, so the target rows follow them.
    """
    from train_dynamics.physics.config import SimConfig
    cfg = SimConfig.from_dict({'num_coaches': int(n), **PAPER_IDEALISATION, **overrides})
    check_idealisation(cfg)
    if cfg.values['model_type'] != 'tanh':
        raise ValueError('core bench: the reference solves the tanh law only')
    return cfg


#: the scipy rows of the target table: what a user with a stiff solver would write, at a
#: user's tolerance (solve_ivp's default atol), in two formulations (:func:`bdf_run`)
BDF_RTOL = 1e-6
BDF_ATOL = 1e-6
BDF_LABELS = {
    'reference': f'scipy BDF, reference equations (x, v), analytical sparse Jacobian, '
                 f'rtol {BDF_RTOL:g}',
    'relative': f'scipy BDF, relative equations (y, ydot), jac_sparsity, rtol {BDF_RTOL:g}'}


def bdf_run(cfg, t_span: float, formulation: str = 'reference') -> dict:
    """
    Return one timed scipy BDF run of ``cfg`` over [0, t_span], sampled every 10 ms.

    ``scipy.integrate.solve_ivp`` (method 'BDF', rtol BDF_RTOL, atol BDF_ATOL) with the
    reference's brake forces (:func:`brake_formula`), on

    - 'reference': the reference's equations
      (:func:`train_dynamics.physics.reference.reference_solution`: eqs. 5-7 with the tanh
      law, state [x, v] of the coaches, its analytical sparse Jacobian): the tolerance
      scales with the distance travelled (hundreds of m), not with the coupler
      displacements (tens of mm);
    - 'relative': the paper's relative equations (17)-(18) (:func:`relative_equations`,
      state [y, ydot] of the couplers), the Jacobian by finite differences on its sparsity
      pattern (``jac_sparsity``).

    Every coupler's force and displacement on the 10 ms samples are part of the timed run,
    as the simulator's read-out is. Returns wall and CPU time [s], the solver's counters and
    'F' [N], 'y' [m] (samples x couplers, float32).
    """
    import numpy as np
    from scipy.integrate import solve_ivp
    from train_dynamics.physics.reference import reference_solution
    grid = _grid(t_span)
    n = cfg.n_coaches
    c0 = time.process_time()
    t0 = time.perf_counter()
    if formulation == 'reference':
        res = reference_solution(cfg.mass_array, cfg.buffer_stiffness, cfg.buffer_friction,
                                 cfg.draw_gear_stiffness, cfg.draw_gear_friction,
                                 float(cfg.values['scale_factor']), cfg.initial_speed,
                                 brake_formula(cfg), float(grid[-1]), t_eval=grid,
                                 rtol=BDF_RTOL, atol=BDF_ATOL, method='BDF')
        F, Y = coupler_samples(cfg, res.y[:n], res.y[n:], grid.size)
    else:
        rhs, force, sparsity = relative_equations(cfg)
        res = solve_ivp(rhs, (0.0, float(grid[-1])), np.zeros(2 * (n - 1)), method='BDF',
                        rtol=BDF_RTOL, atol=BDF_ATOL, jac_sparsity=sparsity, t_eval=grid)
        Y = res.y[:n - 1].T.astype(np.float32)
        F = force(res.y[:n - 1], res.y[n - 1:]).T.astype(np.float32)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if res.status != 0:
        raise RuntimeError(f'scipy BDF ({formulation}) failed: {res.message}')
    return {'wall_s': wall, 'cpu_s': cpu, 'nfev': int(res.nfev), 'njev': int(res.njev),
            'nlu': int(res.nlu), 'F': F, 'y': Y}


def samples_run(F, Y, ref: dict) -> dict:
    """
    Return what :func:`sample_errors` reads of a run given as per-coupler samples.

    ``F`` [N], ``Y`` [m]: samples x couplers on the 10 ms grid from t = 0 (a scipy run's, or
    the floor's reference); ``ref``: the reference with its per-coupler samples.
    """
    import numpy as np
    k = min(len(F), len(ref['F']))
    return {'envelope': np.abs(F).max(axis=1),
            'sample_err_F': np.abs(F[:k] - ref['F'][:k]).max(axis=1),
            'sample_err_y': np.abs(Y[:k] - ref['y'][:k]).max(axis=1)}


def robust_metrics(F, ref: dict, window: float) -> dict:
    """
    Return the accuracy contract's metrics of the forces ``F`` over [0, window].

    :func:`train_dynamics.physics.comparison.all_metrics` (fractions of the reference's
    peak; the cycle count's a fraction of the reference's count, signed) on the 10 ms
    samples 0.01 s .. ``window`` of every coupler; ``F`` [N] samples x couplers from t = 0,
    against the reference's per-coupler samples.
    """
    import numpy as np
    from train_dynamics.physics.comparison import all_metrics
    k = int(round(window / OUTPUT_DT))
    t = np.arange(1, k + 1) * OUTPUT_DT
    return all_metrics(t, np.asarray(F[1:k + 1], float), np.asarray(ref['F'][1:k + 1], float))


def target_case(n: int, settings: list, repeats: int, bdf: bool = False,
                floor: bool = False) -> list[dict]:
    """
    Run in a fresh process: speed and sample accuracy of N coaches for each setting.

    ``settings``: [(label, overrides of the defaults)]. Each setting: warm-up, then an
    untimed run sampled every 10 ms against the cached reference (:func:`sampled_run`,
    :func:`sample_errors`); the timed span is the comparison window of the settings (the
    earliest, so every setting is timed over the same moving span); then ``repeats`` whole
    runs of each setting, interleaved (A B A B ...: the host's drift meets every setting
    alike); the figure is the fastest whole run. Where the reference's per-coupler samples
    are cached, the accuracy contract's metrics too (:func:`robust_metrics`). ``bdf``: a
    scipy BDF row (:func:`bdf_run`), timed in the same rounds; ``floor``: the sensitivity
    floor's row (its cached reference, :func:`floor_inertia`, against the reference).
    """
    from train_dynamics.physics.train import TrainSimulator
    cfgs = [default_config(n, **over) for _, over in settings]
    u = float(cfgs[0].values['scale_factor'])
    ref = cached_reference(n, u)
    keep = ref is not None and 'F' in ref
    rows = []
    for (label, over), cfg in zip(settings, cfgs):
        TrainSimulator(cfg).advance(1)          # numba warm-up, not timed
        run = sampled_run(cfg, ref, keep=keep)
        rows.append({'n': n, 'u': u, 'label': label, 'overrides': over,
                     'h': float(cfg.integration_step),
                     'multirate': float(cfg.values['multirate_tolerance']),
                     'reversal_weight': float(cfg.values['multirate_reversal_weight']),
                     'integration_tolerance': float(cfg.values['integration_tolerance']),
                     't_first_stop': run['t_first_stop'], 'fault': run['fault'],
                     'steps': run['steps'], 'integration': run['integration'],
                     'brake_mismatch': run['brake_mismatch'], '_run': run})
    span = min(moving_span(r['t_first_stop'], ref) for r in rows)
    times = [[] for _ in rows]
    bdf_runs = {key: [] for key in (BDF_LABELS if bdf else ())}
    cal = calibration_s()
    for _ in range(repeats):
        for k, cfg in enumerate(cfgs):
            times[k].append(timed_run(cfg, span))
        for key, runs in bdf_runs.items():
            for earlier in runs:        # the samples of the last run only (deterministic)
                earlier.pop('F', None)
                earlier.pop('y', None)
            runs.append(bdf_run(default_config(n), span, key))
    cal = min(cal, calibration_s())
    for r, t in zip(rows, times):
        run = r.pop('_run')
        w = [a for a, _ in t]
        cpu = min(c for _, c in t)
        r.update(sample_errors(run, ref, span), span_s=span, walls_s=w, wall_s=min(w),
                 rtf=span / min(w), cpu_s=cpu, rtf_cpu=span / cpu, calibration_s=cal,
                 repeats=repeats, cpus_s=[c for _, c in t],
                 ref_samples=keep,
                 ref_note='' if ref is not None else 'no cached reference')
        if keep:
            r['robust'] = robust_metrics(run['F'], ref, span)
    for key, runs in bdf_runs.items():
        last = runs[-1]
        w = [b['wall_s'] for b in runs]
        c = [b['cpu_s'] for b in runs]
        row = {'n': n, 'u': u, 'label': BDF_LABELS[key], 'bdf': key, 'nfev': last['nfev'],
               'njev': last['njev'], 'nlu': last['nlu'], 'span_s': span, 'walls_s': w,
               'wall_s': min(w), 'rtf': span / min(w), 'cpus_s': c, 'cpu_s': min(c),
               'rtf_cpu': span / min(c), 'calibration_s': cal, 'repeats': len(runs),
               'ref_samples': keep}
        if keep:
            row.update(sample_errors(samples_run(last['F'], last['y'], ref), ref, span),
                       robust=robust_metrics(last['F'], ref, span))
        rows.append(row)
    if floor and keep:
        fref = get_reference(n, u, allow_compute=False, samples=True, floor=True)
        if fref is None:
            rows.append({'n': n, 'label': floor_label(n), 'floor': True,
                         'ref_note': 'floor reference not cached (core.py --refs --floor)'})
        else:
            rows.append({'n': n, 'u': u, 'label': floor_label(n), 'floor': True,
                         'span_s': span, 'ref_wall_s': fref['wall_s'],
                         **sample_errors(samples_run(fref['F'], fref['y'], ref), ref, span),
                         'robust': robust_metrics(fref['F'], ref, span)})
    return rows


# --------------------------------------------------------------------------- reference
def _physics_fingerprint(u: float) -> str:
    """
    Return a hash of what the reference depends on besides the configuration.

    That is the force law (evaluated on a grid of states, so cosmetic source edits keep the
    cache) and the reference solver's default tolerances and method.
    """
    import numpy as np
    from train_dynamics.physics import reference
    from train_dynamics.physics.kernel import couplers
    y, yd = np.meshgrid(np.linspace(-0.3, 0.3, 13), np.linspace(-0.02, 0.02, 17))
    y, yd = y.ravel(), yd.ravel()
    one = np.ones(y.size)
    F = couplers.coupler_force(y, yd, 2.8e6 * one, 1.4e6 * one, 5.46e6 * one, 2.43e6 * one,
                               couplers.TANH, float(u))
    sig = inspect.signature(reference.reference_solution)
    defaults = {k: p.default for k, p in sig.parameters.items()
                if p.default is not inspect.Parameter.empty}
    text = ' '.join(f'{f:.9e}' for f in F) + json.dumps(defaults, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def floor_inertia(cfg):
    """
    Return the masses [kg] of the sensitivity floor's train: coach N // 2 + 1 heavier.

    The middle coach's mass x (1 + ``FLOOR_PERTURBATION`` of bench/accuracy.py), its brake
    force unchanged: the floor of bench/accuracy.py (``--robust``) on the target case.
    """
    import numpy as np
    from accuracy import FLOOR_PERTURBATION
    m = np.array(cfg.mass_array, float)
    m[cfg.n_coaches // 2] *= 1.0 + FLOOR_PERTURBATION
    return m


def floor_label(n: int) -> str:
    """Return the floor row's label for N coaches."""
    from accuracy import FLOOR_PERTURBATION
    return f'floor: reference, coach {n // 2 + 1} mass x (1 + {FLOOR_PERTURBATION:g})'


def reference_key(cfg, inertia=None) -> str:
    """
    Return the cache key of the reference of ``cfg``.

    ``inertia``: the masses [kg] the reference integrates when they are not the
    configuration's (the sensitivity floor, :func:`floor_inertia`; the brake forces stay
    the configuration's).
    """
    v = cfg.values
    parts = {k: v[k] for k in ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                               'draw_gear_friction', 'adhesion_coefficient', 'gravity',
                               'initial_speed', 'coach_length', 'brake_propagation_speed',
                               'scale_factor')}
    parts.update(n=cfg.n_coaches, masses=cfg.mass_array, fill=cfg.fill_table(),
                 t_e=T_EMERGENCY, t_end=T_END, dt=OUTPUT_DT,
                 physics=_physics_fingerprint(v['scale_factor']))
    if inertia is not None:
        parts['inertia'] = [float(m) for m in inertia]
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:24]


def _encode(values) -> str:
    import base64
    import zlib
    import numpy as np
    return base64.b64encode(zlib.compress(np.asarray(values, '<f4').tobytes(), 9)).decode()


def _decode(text: str):
    import base64
    import zlib
    import numpy as np
    return np.frombuffer(zlib.decompress(base64.b64decode(text)), '<f4').astype(float)


def load_cache() -> dict:
    try:
        with open(CACHE_PATH) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return {}


def save_cache_entry(key: str, entry: dict) -> None:
    cache = load_cache()        # re-read: another process may have added entries
    cache[key] = entry
    tmp = CACHE_PATH + f'.{os.getpid()}.tmp'
    with open(tmp, 'w') as fh:
        json.dump(cache, fh, indent=1, sort_keys=True)
    os.replace(tmp, CACHE_PATH)


#: per-coupler reference samples (too big for the repository: ~25 MB for 1000 coaches),
#: one ``<reference_key>.npz`` each; TRAIN_DYNAMICS_BENCH_REF_DIR overrides the folder
SAMPLES_DIR = os.environ.get('TRAIN_DYNAMICS_BENCH_REF_DIR', os.path.join(
    os.path.expanduser('~'), '.cache', 'train_dynamics', 'bench-reference'))


def samples_path(key: str) -> str:
    """Return the file of the per-coupler reference samples of ``reference_key`` ``key``."""
    return os.path.join(SAMPLES_DIR, key + '.npz')


def coupler_samples(cfg, x, v, k_valid: int) -> tuple:
    """
    Return every coupler's force F [N] and displacement y [m] on the first ``k_valid`` samples.

    ``x``, ``v``: coach positions [m] and speeds [m/s], (N, samples), as ``solve_ivp``
    returns them; float32 arrays, samples x couplers (the force law of the kernel, as the
    reference's right-hand side evaluates it).
    """
    import numpy as np
    from train_dynamics.physics.kernel import couplers
    n = cfg.n_coaches
    ones = np.ones(n - 1)
    law = (cfg.buffer_stiffness * ones, cfg.buffer_friction * ones,
           cfg.draw_gear_stiffness * ones, cfg.draw_gear_friction * ones, couplers.TANH,
           float(cfg.values['scale_factor']))
    F = np.empty((k_valid, n - 1), np.float32)
    Y = np.empty((k_valid, n - 1), np.float32)
    for k in range(k_valid):
        y = x[:-1, k] - x[1:, k]
        Y[k] = y
        F[k] = couplers.coupler_force(y, v[:-1, k] - v[1:, k], *law)
    return F, Y


def compute_reference(n: int, u: float, floor: bool = False) -> tuple[dict, dict]:
    """
    Compute the reference over [0, T_END] on the 10 ms grid.

    Returns (cache entry, samples). The entry keeps the envelope max_j |F_j| (float32) up to
    the first sample at which a coach has stopped (v <= 0), where it stops being valid; the
    samples are every coupler's force F [N] and displacement y [m] on the same samples
    (float32 arrays, samples x couplers). ``floor``: the sensitivity floor's train
    (:func:`floor_inertia`: one coach heavier, the same brake forces).
    """
    import numpy as np
    from train_dynamics.physics.reference import reference_solution
    cfg = make_config(n, 'tanh', u)
    fb_of_t = brake_formula(cfg)
    masses = floor_inertia(cfg) if floor else cfg.mass_array
    grid = _grid(T_END)
    t0 = time.perf_counter()
    res = reference_solution(masses, cfg.buffer_stiffness, cfg.buffer_friction,
                             cfg.draw_gear_stiffness, cfg.draw_gear_friction, u,
                             cfg.initial_speed, fb_of_t, float(grid[-1]), t_eval=grid)
    wall = time.perf_counter() - t0
    if res.status != 0:
        raise RuntimeError(f'reference failed: {res.message}')
    x, v = res.y[:n], res.y[n:]
    stopped = np.nonzero(v.min(axis=0) <= 0.0)[0]
    k_valid = int(stopped[0]) if stopped.size else grid.size     # samples [0, k_valid)
    F, Y = coupler_samples(cfg, x, v, k_valid)
    env = np.abs(F.astype(float)).max(axis=1)
    entry = {'n': n, 'u': u, 't_end': T_END, 'wall_s': wall, 'nfev': int(res.nfev),
             'first_stop_s': float(grid[k_valid]) if k_valid < grid.size else None,
             'valid_samples': k_valid, 'peak_N': float(env.max()),
             't_peak_s': float(grid[int(env.argmax())]), 'envelope_f32_zlib_b64': _encode(env)}
    if floor:
        entry['floor'] = floor_label(n)
    return entry, {'F': F, 'y': Y}


def save_samples(key: str, samples: dict) -> None:
    """Write the per-coupler reference samples (outside the repository: SAMPLES_DIR)."""
    import numpy as np
    os.makedirs(SAMPLES_DIR, exist_ok=True)
    tmp = samples_path(key) + f'.{os.getpid()}.tmp.npz'
    np.savez_compressed(tmp, **samples)
    os.replace(tmp, samples_path(key))


def get_reference(n: int, u: float, allow_compute: bool,
                  samples: bool = False, floor: bool = False) -> dict | None:
    """
    Return the cached reference (envelope decoded into 'envelope'), computed if allowed.

    ``samples``: also the per-coupler samples 'F' and 'y' (:func:`compute_reference`); None
    when they are not cached and computing is not allowed. ``floor``: the reference of the
    sensitivity floor's train (:func:`floor_inertia`), cached the same way.
    """
    import numpy as np
    cfg = make_config(n, 'tanh', u)
    key = reference_key(cfg, floor_inertia(cfg) if floor else None)
    entry = load_cache().get(key)
    arrays = None
    if samples and os.path.exists(samples_path(key)):
        with np.load(samples_path(key)) as z:
            arrays = {'F': z['F'], 'y': z['y']}        # float32
    if entry is None or (samples and arrays is None):
        if not allow_compute:
            return None
        new, arrays = compute_reference(n, u, floor)
        save_samples(key, arrays)
        if entry is None:       # the committed cache keeps its first computation
            entry = new
            save_cache_entry(key, entry)
    entry = dict(entry)
    entry['envelope'] = _decode(entry['envelope_f32_zlib_b64'])
    if samples:
        entry.update(arrays)
    return entry


def cached_reference(n: int, u: float) -> dict | None:
    """Return the cached reference with its per-coupler samples, or without, or None."""
    ref = get_reference(n, u, allow_compute=False, samples=True)
    return ref if ref is not None else get_reference(n, u, allow_compute=False)


def comparison_window(t_first_stop_sim: float | None, ref: dict | None) -> float:
    """
    Return the end of the comparison [s], on the 10 ms grid.

    STOP_MARGIN before the first coach stops (in our run or in the reference, whichever is
    first), at most T_END.
    """
    t = T_END + STOP_MARGIN
    if t_first_stop_sim is not None:
        t = min(t, t_first_stop_sim)
    if ref is not None and ref.get('first_stop_s') is not None:
        t = min(t, ref['first_stop_s'])
    return OUTPUT_DT * int(round((t - STOP_MARGIN) / OUTPUT_DT))


# --------------------------------------------------------------------------- baseline
def relative_equations(cfg):
    """
    Return the paper's relative equations of motion (17)-(18) of ``cfg``'s train.

    (rhs(t, z), force(y, ydot), sparsity): state z = [y, ydot] (N-1 coupler displacements
    [m] and rates [m/s]); the tanh law (u the configuration's scale factor) with the paper's
    (1 -+ sgn y)/2 branch selection, a plain vectorised numpy right-hand side; the braking
    forces of :func:`brake_formula`; ``sparsity`` the pattern of its Jacobian (ydd_i depends
    on couplers i-1 .. i+1), for ``solve_ivp``'s ``jac_sparsity``.
    """
    import numpy as np
    import scipy.sparse as sp
    fb_of_t = brake_formula(cfg)
    u = float(cfg.values['scale_factor'])
    m = np.asarray(cfg.mass_array, float)
    kt, ct = cfg.buffer_stiffness, cfg.buffer_friction        # compression (buffers)
    kc, cc = cfg.draw_gear_stiffness, cfg.draw_gear_friction  # extension (draw gear)
    nc = cfg.n_coaches - 1

    def force(y, yd):
        th = np.tanh(u * yd)
        sg = np.sign(y)
        return 0.5 * (1.0 - sg) * (kt - ct * th) * y + 0.5 * (1.0 + sg) * (kc + cc * th) * y

    def rhs(t, z):
        y, yd = z[:nc], z[nc:]
        F = force(y, yd)
        Fb = fb_of_t(t)
        Fp = np.concatenate(([0.0], F, [0.0]))
        a = (Fp[:-1] - Fp[1:] - Fb) / m              # eqs. (5)-(7)
        return np.concatenate((yd, a[:-1] - a[1:]))  # eqs. (17)-(18): ydd_i = a_i - a_{i+1}

    band = sp.diags([np.ones(nc - 1), np.ones(nc), np.ones(nc - 1)], [-1, 0, 1])
    sparsity = sp.bmat([[None, sp.identity(nc)], [band, band]], format='csc')
    return rhs, force, sparsity


def baseline_case(n: int, t_end: float = T_END, u: float = 1000.0) -> dict:
    """Run the user's script: solve_ivp RK45 on the paper's eqs. (17)-(18) for N coaches."""
    import numpy as np
    from scipy.integrate import solve_ivp
    cfg = make_config(n, 'tanh', u)
    rhs, force, _ = relative_equations(cfg)
    nc = n - 1
    grid = _grid(t_end)
    t0 = time.perf_counter()
    res = solve_ivp(rhs, (0.0, float(grid[-1])), np.zeros(2 * nc), method='RK45', rtol=1e-6,
                    t_eval=grid)
    wall = time.perf_counter() - t0
    y, yd = res.y[:nc], res.y[nc:]
    env = np.abs(force(y, yd)).max(axis=0)
    return {'n': n, 'wall_s': wall, 'rtf': t_end / wall, 'nfev': int(res.nfev),
            'status': int(res.status), 'envelope': env.tolist()}


# --------------------------------------------------------------------------- start-up
def startup_probe() -> dict:
    """In a fresh process: import, construct, first advance (cold or warm numba cache)."""
    t0 = time.perf_counter()
    from train_dynamics.physics.train import TrainSimulator
    t1 = time.perf_counter()
    sim = TrainSimulator(make_config(30, 'tanh', 1000.0))
    sim.set_head_pipe_pressure(0.0)
    sim.advance_to(OUTPUT_DT)
    _ = sim.coupler_force
    t2 = time.perf_counter()
    return {'import_s': t1 - t0, 'first_output_s': t2 - t1, 'total_s': t2 - t0}


def measure_startup() -> dict:
    out = {}
    with tempfile.TemporaryDirectory(prefix='td_numba_cold_') as tmp:
        # an empty kernel cache (physics/kernel/compiler.py): every kernel the start needs compiles
        env = dict(os.environ, TRAIN_DYNAMICS_CACHE_DIR=tmp)
        out['cold'] = _run_sub(['--startup'], env=env)
    out['warm'] = _run_sub(['--startup'])
    out['warm2'] = _run_sub(['--startup'])
    return out


# --------------------------------------------------------------------------- driver
def _run_sub(args: list[str], env: dict | None = None, timeout: float = 3600.0) -> dict:
    proc = subprocess.run([_py(), os.path.abspath(__file__)] + args, capture_output=True,
                          text=True, env=env, timeout=timeout, cwd=REPO)
    if proc.returncode != 0:
        raise RuntimeError(f'{args}: exit {proc.returncode}\n{proc.stderr[-2000:]}')
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _summarise_case(res: dict, ref: dict | None, note: str) -> dict:
    import numpy as np
    window = comparison_window(res['t_first_stop'], ref)
    k = int(round(window / OUTPUT_DT))
    env = np.asarray(res['envelope'][:k + 1])
    row = {key: res[key] for key in ('n', 'model', 'u', 'h', 'multirate', 'wall_s',
                                     'wall_median_s', 'repeats', 'walls_s', 'span_s',
                                     'calibration_s', 'rtf', 'steps', 'peak_N',
                                     'fault', 'tracemalloc_peak_kib', 'vmhwm_mib',
                                     'warmup_s', 't_first_stop', 'brake_mismatch')}
    row['window'] = window
    row['peak_window_N'] = float(env.max())
    row['t_peak_window'] = float(np.argmax(env) * OUTPUT_DT)
    row['ref_note'] = note
    if ref is not None:
        row.update(sample_errors(res, ref, window))
        row['ref_wall_s'] = ref['wall_s']
        row['ref_first_stop'] = ref.get('first_stop_s')
    return row


def want_reference(n: int, model: str, u: float, max_n: int) -> tuple[bool, str]:
    if model != 'tanh':
        return False, 'sign: no smooth reference'
    if u >= 1.0e4 and n >= 300:
        return False, 'skipped: reference too slow (u=1e4, N>=300)'
    if n > max_n:
        return False, f'skipped: reference not cached and N > {max_n} (too slow to compute here)'
    return True, ''


def target_settings(default_overrides: dict | None = None) -> list:
    """
    Return the settings of the target rows: [(label, overrides)].

    The package's defaults (``default_overrides`` on top of them, e.g. to try a planned
    default before it is one: the label says so), and the plain fixed step for comparison.
    """
    over = dict(default_overrides or {})
    label = 'default settings'
    if over:
        label += ' + ' + ', '.join(f'{k} {v:g}' if isinstance(v, float) else f'{k} {v}'
                                   for k, v in sorted(over.items()))
    return [(label, over),
            (f'fixed {DEFAULT_H * 1e3:g} ms step (multirate off)', dict(FIXED_STEP))]


def run_targets(ref_max_n: int, default_overrides: dict | None = None, sizes=None,
                log=print, bdf: bool = False, floor: bool = False) -> list[dict]:
    """
    Measure the target rows (:func:`target_case`, fresh process per train).

    References with per-coupler samples are computed first for trains up to ``ref_max_n``
    coaches (cached outside the repository, SAMPLES_DIR); larger trains use what is cached.
    ``bdf``: with the scipy BDF row; ``floor``: with the sensitivity floor's row (its
    reference computed first on the same terms).
    """
    settings = target_settings(default_overrides)
    rows = []
    for n, _ in SPEED_TARGETS if sizes is None else [(m, None) for m in sizes]:
        if n <= ref_max_n:
            log(f'core targets: reference with per-coupler samples, N={n}')
            get_reference(n, 1000.0, allow_compute=True, samples=True)
            if floor:
                log(f'core targets: the floor reference, N={n}')
                get_reference(n, 1000.0, allow_compute=True, samples=True, floor=True)
        repeats = TIMED_REPEATS if n <= 300 else 3
        res = _run_sub(['--target', json.dumps([n, settings, repeats, bdf, floor])])
        for r in res:
            acc = (f", force samples {100 * r['force_err']:.3f} %, displacements "
                   f"{100 * r['disp_err']:.3f} %" if 'force_err' in r else
                   ' (no per-coupler reference samples)')
            if 'robust' in r:
                acc += ', ' + ', '.join(f'{k} {100 * v:.3f} %' for k, v in r['robust'].items())
            speed = (f"{r['rtf_cpu']:.1f}x real time (CPU) over 0-{r['span_s']:g} s"
                     if 'rtf_cpu' in r else '')
            log(f"  N={n} {r['label']}: {speed}" + acc)
        rows += res
    return rows


#: the accuracy contract's metrics in the target table: (all_metrics key, heading)
CONTRACT_COLUMNS = (('worst_sample', 'worst sample'), ('tube_10ms', 'tube +-10 ms (2 %)'),
                    ('window_envelope_1s', '1 s windows (2 %)'),
                    ('coupler_envelope', 'per-coupler envelope (1 %)'),
                    ('del_m4', 'DEL m = 4 (1 %)'), ('cycles_above_10pct', 'cycles > 10 % (2 %)'))


def contract_table(rows: list[dict]) -> str:
    """
    Return the target rows of one train as a markdown table: speed beside the contract.

    Real-time factor from the least CPU time of the whole runs (span / CPU), CPU time per
    vehicle and 2 ms of simulated time [ns] (the plain step's vehicle-step), the contract's
    metrics [% of the reference's peak; the cycle count in % of the reference's count] and
    the peak's error.
    """
    n, span = rows[0]['n'], rows[0].get('span_s')
    head = ' | '.join(label for _, label in CONTRACT_COLUMNS)
    out = [f'| {n} paper coaches, 0-{span:g} s | real-time factor (CPU) | CPU [s] | '
           f'ns per vehicle-step | {head} | peak |',
           '|---|' + '---:|' * (len(CONTRACT_COLUMNS) + 4)]
    for r in rows:
        if 'cpu_s' in r:
            ns = 1e9 * r['cpu_s'] / (n * r['span_s'] / DEFAULT_H)
            speed = f"{r['rtf_cpu']:.1f}x | {r['cpu_s']:.2f} | {ns:.0f}"
        else:
            speed = ' | | '
        m = r.get('robust', {})
        cells = ' | '.join(
            (f'{100 * m[key]:+.2f}' if key == 'cycles_above_10pct' else f'{100 * m[key]:.3f}')
            if key in m else '' for key, _ in CONTRACT_COLUMNS)
        peak = f"{100 * r['peak_err']:+.3f} %" if 'peak_err' in r else ''
        out.append(f"| {r['label']} | {speed} | {cells} | {peak} |")
    return '\n'.join(out)


def run(ref_max_n: int = 100, sizes=SIZES, models=MODELS, steps=STEP_VARIANTS,
        baseline_sizes=BASELINE_SIZES, log=print, default_overrides: dict | None = None,
        target_ref_max_n: int = 1000) -> dict:
    """
    All core cases, the targets, the baseline and start-up; returns the raw results.

    ``ref_max_n``: references of the case table computed when missing up to this many
    coaches; ``target_ref_max_n``: the same for the target rows' per-coupler references.
    """
    import numpy as np
    results = {'cases': [], 'steps': [], 'baseline': [], 'startup': None}
    log('core: start-up (cold and warm numba cache)')
    results['startup'] = measure_startup()
    log('core: targets at default settings (whole runs of the moving train)')
    results['targets'] = run_targets(target_ref_max_n, default_overrides, log=log)

    def one(n, model, u, h):
        ok, note = want_reference(n, model, u, ref_max_n)
        ref = None
        if model == 'tanh' and not (u >= 1.0e4 and n >= 300):
            ref = get_reference(n, u, allow_compute=ok)     # before the case, which reads it
            if ref is not None:
                note = ''
        res = _run_sub(['--case', json.dumps([n, model, u, h])])
        row = _summarise_case(res, ref, note)
        log(f'  N={n:5d} {model} u={u:g} h={h:g}: wall {row["wall_s"]:.3f} s, '
            f"{row['rtf']:.1f}x real time, peak {row['peak_N']:.4g} N"
            + (f", peak err {100 * row['peak_err']:+.3f} %" if 'peak_err' in row else
               f' ({note})'))
        return row

    log('core: fixed-step cases')
    for n in sizes:
        for model, u in models:
            results['cases'].append(one(n, model, u, DEFAULT_H))
    log('core: integration step variants')
    for n, h in steps:
        results['steps'].append(one(n, 'tanh', 1000.0, h))

    # The host's speed drifts (see calibration_s): cases timed while it ran below
    # SLOW_HOST of its best speed seen in this run are run again (up to RETRIES times);
    # the run timed at the higher host speed is kept.
    for attempt in range(RETRIES + 1):
        rows = results['cases'] + results['steps']
        cal_best = min(r['calibration_s'] for r in rows)
        for r in rows:
            r['host_speed'] = cal_best / r['calibration_s']
        slow = [(key, k, r) for key in ('cases', 'steps') for k, r in enumerate(results[key])
                if r['host_speed'] < SLOW_HOST]
        if not slow or attempt == RETRIES:
            break
        log(f'core: {len(slow)} case(s) ran while the host was slow: timing them again')
        for key, k, r in slow:
            new = one(r['n'], r['model'], r['u'], r['h'])
            new['retries'] = r.get('retries', 0) + 1
            if new['calibration_s'] < r['calibration_s']:
                results[key][k] = new
            else:
                r['retries'] = new['retries']
    log('baseline: solve_ivp RK45 rtol 1e-6, tanh u=1000')
    for n in baseline_sizes:
        b = _run_sub(['--baseline', str(n)])
        ours = next((r for r in results['cases'] if r['n'] == n and r['model'] == 'tanh'
                     and r['u'] == 1000.0), None)
        row = {'n': n, 'wall_s': b['wall_s'], 'rtf': b['rtf'], 'nfev': b['nfev'],
               'status': b['status'], 'extrapolated': False}
        if ours is not None:
            row['speedup'] = ours['rtf'] / b['rtf']      # real-time factors
            k = int(round(ours['window'] / OUTPUT_DT))
            env = np.asarray(b['envelope'][:k + 1])
            row['peak_window_N'] = float(env.max())
            row['window'] = ours['window']
            ref = get_reference(n, 1000.0, allow_compute=False)
            if ref is not None:
                renv = np.asarray(ref['envelope'][:k + 1])
                rpk = float(renv.max())
                row['peak_err'] = (float(env.max()) - rpk) / rpk
                row['env_err'] = float(np.max(np.abs(env - renv))) / rpk
        results['baseline'].append(row)
        log(f"  N={n}: wall {b['wall_s']:.2f} s ({b['rtf']:.1f}x real time)"
            + (f", ours is {row['speedup']:.0f}x faster" if 'speedup' in row else ''))
    # extrapolate the larger trains from the two largest measured (power law in N)
    meas = [r for r in results['baseline'] if not r['extrapolated']]
    if len(meas) >= 2:
        (n1, w1), (n2, w2) = [(r['n'], r['wall_s']) for r in meas[-2:]]
        p = np.log(w2 / w1) / np.log(n2 / n1)
        for n in BASELINE_EXTRAPOLATE:
            w = w2 * (n / n2) ** p
            row = {'n': n, 'wall_s': float(w), 'rtf': T_END / w, 'extrapolated': True,
                   'exponent': float(p)}
            ours = next((r for r in results['cases'] if r['n'] == n and r['model'] == 'tanh'
                         and r['u'] == 1000.0), None)
            if ours is not None:
                row['speedup'] = ours['rtf'] / (T_END / w)
            results['baseline'].append(row)
    return results


#: error-controlled cases: N, integration_tolerance; the paper's law (strokes
#: out of reach, as in the reference), tanh u = 1000, 100 Hz outputs
ADAPTIVE_CASES = ((3, 1e-3), (100, 1e-2), (100, 1e-3), (1000, 1e-2), (1000, 1e-3))


def adaptive_case(n: int, tol: float, budget: int = 100, repeats: int = 2) -> dict:
    """
    Time one error-controlled run (best of ``repeats``) and compare it with the reference.

    Returns wall [s], real-time factor, the integration counters, the peak and envelope
    errors over the comparison window (cached reference, None when missing) and the time
    from the first coach at rest to every coach held (standstill).
    """
    import numpy as np
    from train_dynamics.physics.train import TrainSimulator
    cfg = make_config(n, 'tanh', 1000.0, integration_tolerance=tol,
                      integration_max_steps=budget)
    TrainSimulator(cfg).advance(10)            # numba warm-up
    chunks = int(round(T_END / OUTPUT_DT))
    best = float('inf')
    for _ in range(repeats):
        sim = TrainSimulator(cfg)
        sim.set_head_pipe_pressure(0.0)
        env = np.zeros(chunks + 1)
        t_stop = t_held = None
        t0 = time.perf_counter()
        for k in range(1, chunks + 1):
            sim.advance_to(k * OUTPUT_DT)
            env[k] = np.abs(sim.coupler_force).max()
            if t_stop is None and (np.any(sim.held) or np.any(sim.v <= 0.0)):
                t_stop = sim.t
            all_held = bool(np.all(sim.held))
            t_held = (t_held or sim.t) if all_held else None
        best = min(best, time.perf_counter() - t0)
    row = {'n': n, 'tol': tol, 'budget': budget, 'wall_s': best, 'rtf': T_END / best,
           't_first_stop': t_stop, 't_all_held': t_held, **sim.integration_stats}
    ref = get_reference(n, 1000.0, allow_compute=False)
    if ref is not None:
        k = int(round(comparison_window(t_stop, ref) / OUTPUT_DT))
        renv = np.asarray(ref['envelope'][:k + 1])
        rpk = float(renv.max())
        row['peak_err'] = (float(env[:k + 1].max()) - rpk) / rpk
        row['env_err'] = float(np.max(np.abs(env[:k + 1] - renv)) / rpk)
    return row


def adaptive_table(rows) -> str:
    """Return the markdown table of :func:`adaptive_case` rows."""
    def pct(r, key):
        return f'{100 * r[key]:.2f} %' if key in r else 'n/a'
    lines = ['| N | tolerance | wall [s] | real-time factor | chain steps | rejected | '
             'smallest step [ms] | max steps / 10 ms | fallback periods | peak error | '
             'envelope error | all held [s] after first stop |',
             '| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: '
             '| ---: |']
    for r in rows:
        held = (f"{r['t_all_held'] - r['t_first_stop']:.2f}"
                if r['t_all_held'] is not None and r['t_first_stop'] is not None else 'never')
        lines.append(f"| {r['n']} | {r['tol']:g} | {r['wall_s']:.3f} | {r['rtf']:.0f}x | "
                     f"{r['steps']} | {r['rejected']} | {1e3 * r['h_min']:.4f} | "
                     f"{r['steps_max_period']} | {r['fallback_periods']} | "
                     f"{pct(r, 'peak_err')} | {pct(r, 'env_err')} | {held} |")
    return '\n'.join(lines)


def compute_references(sizes, us, max_n: int, samples: bool = False,
                       floor: bool = False) -> None:
    """
    Fill the reference cache (``samples``: the per-coupler samples as well).

    ``floor``: the references of the sensitivity floor's trains (:func:`floor_inertia`).
    """
    for n in sizes:
        for u in us:
            ok, note = want_reference(n, 'tanh', u, max_n)
            if not ok:
                print(f'N={n} u={u:g}: {note}', flush=True)
                continue
            t0 = time.perf_counter()
            ref = get_reference(n, u, allow_compute=True, samples=samples, floor=floor)
            print(f'N={n} u={u:g}: reference peak {ref["peak_N"]:.6g} N at {ref["t_peak_s"]:g} s, '
                  f'valid until {ref["first_stop_s"]} s ({ref["wall_s"]:.0f} s to compute; '
                  f'{time.perf_counter() - t0:.0f} s now)', flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--case', help='internal: JSON [n, model, u, h]; prints JSON')
    ap.add_argument('--baseline', type=int, help='internal: baseline for N coaches')
    ap.add_argument('--startup', action='store_true', help='internal: start-up probe')
    ap.add_argument('--target', help='internal: JSON [n, settings, repeats]; prints JSON')
    ap.add_argument('--targets', action='store_true',
                    help='only the target rows (speed at default settings, sample accuracy)')
    ap.add_argument('--sizes', help='with --targets: these trains (comma-separated N)')
    ap.add_argument('--default-overrides', type=json.loads, default=None,
                    help='JSON object of settings applied on top of the defaults in the '
                         'target rows (to try a planned default; the rows say so)')
    ap.add_argument('--adaptive', action='store_true',
                    help='error-controlled cases (ADAPTIVE_CASES): markdown table')
    ap.add_argument('--refs', action='store_true',
                    help='compute missing reference solutions into the cache')
    ap.add_argument('--samples', action='store_true',
                    help='with --refs: the per-coupler samples too (SAMPLES_DIR)')
    ap.add_argument('--bdf', action='store_true',
                    help='with --targets: the scipy BDF rows (timed in the same rounds)')
    ap.add_argument('--floor', action='store_true',
                    help='with --refs: the sensitivity floor (one coach heavier); with '
                         '--targets: its row')
    ap.add_argument('--ref-sizes', default='3,30,100,300')
    ap.add_argument('--ref-us', default='100,1000,10000')
    ap.add_argument('--ref-max-n', type=int, default=300)
    args = ap.parse_args(argv)
    if args.case:
        n, model, u, h = json.loads(args.case)
        print(json.dumps(measure_case(int(n), model, float(u), float(h))))
        return 0
    if args.baseline:
        print(json.dumps(baseline_case(args.baseline)))
        return 0
    if args.startup:
        print(json.dumps(startup_probe()))
        return 0
    if args.target:
        n, settings, repeats, *extra = json.loads(args.target)
        print(json.dumps(target_case(int(n), settings, int(repeats), *extra)))
        return 0
    if args.targets:
        sizes = [int(m) for m in args.sizes.split(',')] if args.sizes else None
        rows = run_targets(args.ref_max_n, args.default_overrides, sizes,
                           log=lambda m: print(m, file=sys.stderr, flush=True),
                           bdf=args.bdf, floor=args.floor)
        print(json.dumps(rows, indent=1))
        for n in sorted({r['n'] for r in rows}):
            print(contract_table([r for r in rows if r['n'] == n]) + '\n', file=sys.stderr)
        return 0
    if args.adaptive:
        rows = []
        for n, tol in ADAPTIVE_CASES:
            rows.append(adaptive_case(n, tol))
            print(json.dumps(rows[-1]), flush=True)
        print(adaptive_table(rows))
        return 0
    if args.refs:
        compute_references([int(s) for s in args.ref_sizes.split(',')],
                           [float(s) for s in args.ref_us.split(',')], args.ref_max_n,
                           args.samples, args.floor)
        return 0
    res = run(default_overrides=args.default_overrides)
    print(json.dumps(dict(res), indent=1, default=str)[:5000])
    return 0


if __name__ == '__main__':
    sys.exit(main())
