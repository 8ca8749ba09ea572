"""
Benchmark of the physics core: speed, accuracy and memory of the fixed-step model.

Scenario: the paper's emergency braking generalised to N coaches (config defaults: 45 t
coaches at 44.444 m/s, ``pipe_head``). The head brake-pipe pressure is set to 0 gauge at
t_e = 0 s (before the first step); 60 s of simulated time. The couplers are the paper's
idealisation, as the reference models them: the strokes are set out of reach
(:data:`PAPER_IDEALISATION`, 10 m, beyond ``max_coupler_displacement``: a coupler cannot
block without the run stopping with a fault), no slack, no resistance or track. With the
default strokes (105 mm buffers, 60 mm draw gear) trains of 100 coaches and more block, which
neither the reference nor the scipy baseline models.

Every case runs in a fresh Python process (``python bench/core.py --case JSON``), so that
warm-up, memory and timing of one case do not leak into the next:

- warm-up (excluded from the timing, reported separately): one ``TrainSimulator`` and one
  ``advance(1)``, i.e. numba's cache load (or compilation when the cache is cold);
- timed run: ``sim.advance_to`` in 10 ms chunks (the node's 100 Hz output) and after each
  chunk ``sim.coupler_force`` and its max |F|, like the node reads its outputs. The virtual
  machine's speed drifts by up to 2x within seconds, so the run is repeated (5 times, 3 for
  the slowest cases) and the wall time is the sum over its six 10 s parts of each part's
  fastest time (the runs are deterministic: every run computes the same steps);
- memory: a second, untimed run of the same scenario (new simulator, same loop) under
  ``tracemalloc``: the peak of Python/numpy heap allocations [KiB] made by constructing the
  simulator and running it (numba's internal scratch arrays are not traced; they are a
  handful of N-element arrays per ``advance`` call). The process's peak RSS (VmHWM) is
  reported too, for context;
- accuracy (same untimed run): the envelope max_j |F_j(t)| on the 10 ms grid, compared with
  the tight-tolerance reference :func:`train_dynamics.physics.reference.reference_solution`
  (Radau, rtol 1e-9, atol 1e-11, analytical Jacobian) driven by the brake forces as a
  function of time, Fb_i(t) = mu_a m_i g fill(t - t_e - d_i) (d_i the pipe delay of coach
  i). The run checks that this formula is what the simulator applies (it applies the mean
  over the step, 0.5 (Fb(t-h) + Fb(t))) and reports the largest mismatch. The reference
  ignores the brake holding a stopped coach, so the comparison covers [0, W], W = 0.5 s
  before the first coach stops (in our run or in the reference, whichever is first), at most
  60 s.

The baseline is what a user would write: ``scipy.integrate.solve_ivp`` (RK45, rtol 1e-6,
default atol 1e-6) on the paper's relative equations of motion (17)-(18) generalised to N
coaches (state y, ydot; tanh law u = 1000 with the paper's (1 -+ sgn y)/2 branch selection;
a plain vectorised numpy right-hand side, no Jacobian), same brake forces, 60 s.

Reference solutions (over 0-60 s, the envelope up to the first stop) are cached in
``bench/reference_cache.json``, keyed by everything they depend on, including a numerical
fingerprint of the force law and the reference solver's defaults, so they are recomputed
only when the physics changes (delete the file to force it). The reference never depends on
the strokes (it has none); :func:`check_idealisation` makes sure the simulated train is the
one the reference solves. ``python bench/core.py --refs``
fills the cache; ``make bench`` computes missing ones up to ``--ref-max-n`` coaches.

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

CACHE_PATH = os.path.join(HERE, 'reference_cache.json')
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
TIMED_REPEATS = 5           # timed runs per case (3 for the slowest cases)
SEGMENTS = 6                # parts of a run timed separately (best of the runs per part)
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
    """(Fb(t) -> (N,) [N], delays (N,) [s]) for the pipe_head emergency at T_EMERGENCY."""
    import numpy as np
    from train_dynamics.physics.kernel.brakes import pipe_delays
    ft, ff = (np.asarray(a, float) for a in cfg.fill_table())
    delays = pipe_delays(cfg.n_coaches, cfg.coach_length, cfg.brake_propagation_speed)
    full = cfg.adhesion_coefficient * np.asarray(cfg.mass_array) * cfg.gravity

    def fb(t):
        return full * np.interp(t - T_EMERGENCY - delays, ft, ff, left=0.0)
    return fb, delays


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


def measure_case(n: int, model: str, u: float, h: float) -> dict:
    """Run in a fresh process: warm-up, timed run, untimed memory/accuracy run."""
    import numpy as np
    t0 = time.perf_counter()
    from train_dynamics.physics.train import TrainSimulator
    t_import = time.perf_counter() - t0
    cfg = make_config(n, model, u, h)
    out = {'n': n, 'model': model, 'u': u, 'h': h, 'import_s': t_import}

    # warm-up: numba cache load (or compile), excluded from the timing
    t0 = time.perf_counter()
    sim = TrainSimulator(cfg)
    sim.advance(1)
    _ = sim.coupler_force
    out['warmup_s'] = time.perf_counter() - t0

    cal_before = calibration_s()
    # timed runs. The machine is shared and virtual: its speed drifts by up to 2x within
    # seconds. Each run is split into SEGMENTS equal parts of simulated time; the figure is
    # the sum over the parts of their fastest time in TIMED_REPEATS runs (the runs are
    # deterministic, so every run computes the same steps). The fastest and the median
    # whole run are kept in the raw data.
    chunks = int(round(T_END / OUTPUT_DT))
    seg_len = chunks // SEGMENTS
    repeats = TIMED_REPEATS if n * (0.005 / h) < 2000 else 3
    walls = []
    seg_best = [float('inf')] * SEGMENTS
    for _ in range(repeats):
        sim = TrainSimulator(cfg)
        if T_EMERGENCY <= 0.0:
            sim.set_head_pipe_pressure(0.0)
        peak = 0.0
        t0 = t_seg = time.perf_counter()
        for k in range(1, chunks + 1):
            if T_EMERGENCY > 0.0 and abs((k - 1) * OUTPUT_DT - T_EMERGENCY) < 1e-9:
                sim.set_head_pipe_pressure(0.0)
            sim.advance_to(k * OUTPUT_DT)
            f = sim.coupler_force
            m = float(np.abs(f).max())
            if m > peak:
                peak = m
            if k % seg_len == 0:
                now = time.perf_counter()
                j = k // seg_len - 1
                seg_best[j] = min(seg_best[j], now - t_seg)
                t_seg = now
        walls.append(time.perf_counter() - t0)
    wall = sum(seg_best)
    out.update(wall_s=wall, wall_min_run_s=min(walls), segments_s=seg_best,
               wall_median_s=sorted(walls)[len(walls) // 2], walls_s=walls, repeats=repeats,
               rtf=T_END / wall, steps=int(sim.steps), peak_N=peak, fault=sim.fault)
    out['calibration_s'] = min(cal_before, calibration_s())

    # untimed: memory (tracemalloc) and accuracy data
    import tracemalloc
    env = np.zeros(chunks + 1)
    fb_of_t, _ = brake_formula(cfg)
    brake_mismatch = 0.0
    t_first_stop = None
    tracemalloc.start()
    sim = TrainSimulator(cfg)
    if T_EMERGENCY <= 0.0:
        sim.set_head_pipe_pressure(0.0)
    for k in range(1, chunks + 1):
        if T_EMERGENCY > 0.0 and abs((k - 1) * OUTPUT_DT - T_EMERGENCY) < 1e-9:
            sim.set_head_pipe_pressure(0.0)
        sim.advance_to(k * OUTPUT_DT)
        f = sim.coupler_force
        env[k] = float(np.abs(f).max())
        if t_first_stop is None:
            if np.any(sim.held) or np.any(sim.v <= 0.0):
                t_first_stop = sim.t
            else:   # brakes as the simulator applied them over the last step (all moving)
                t = sim.t
                expect = 0.5 * (fb_of_t(t - h) + fb_of_t(t))
                mism = float(np.max(np.abs(sim.brake_force - expect)) / np.max(
                    cfg.adhesion_coefficient * np.asarray(cfg.mass_array) * cfg.gravity))
                brake_mismatch = max(brake_mismatch, mism)
    _, tm_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out.update(tracemalloc_peak_kib=tm_peak / 1024.0, vmhwm_mib=_rss_kib('VmHWM') / 1024.0,
               t_first_stop=t_first_stop, brake_mismatch=brake_mismatch,
               envelope=env.tolist())
    return out


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


def reference_key(cfg) -> str:
    v = cfg.values
    parts = {k: v[k] for k in ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                               'draw_gear_friction', 'adhesion_coefficient', 'gravity',
                               'initial_speed', 'coach_length', 'brake_propagation_speed',
                               'scale_factor')}
    parts.update(n=cfg.n_coaches, masses=cfg.mass_array, fill=cfg.fill_table(),
                 t_e=T_EMERGENCY, t_end=T_END, dt=OUTPUT_DT,
                 physics=_physics_fingerprint(v['scale_factor']))
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


def compute_reference(n: int, u: float) -> dict:
    """
    Compute the reference over [0, T_END] on the 10 ms grid.

    Keeps the envelope max_j |F_j| (float32) up to the first sample at which a coach has
    stopped (v <= 0), where it stops being valid.
    """
    import numpy as np
    from train_dynamics.physics.kernel import couplers
    from train_dynamics.physics.reference import reference_solution
    cfg = make_config(n, 'tanh', u)
    fb_of_t, _ = brake_formula(cfg)
    grid = _grid(T_END)
    t0 = time.perf_counter()
    res = reference_solution(cfg.mass_array, cfg.buffer_stiffness, cfg.buffer_friction,
                             cfg.draw_gear_stiffness, cfg.draw_gear_friction, u,
                             cfg.initial_speed, fb_of_t, float(grid[-1]), t_eval=grid)
    wall = time.perf_counter() - t0
    if res.status != 0:
        raise RuntimeError(f'reference failed: {res.message}')
    x, v = res.y[:n], res.y[n:]
    stopped = np.nonzero(v.min(axis=0) <= 0.0)[0]
    k_valid = int(stopped[0]) if stopped.size else grid.size     # samples [0, k_valid)
    ones = np.ones(n - 1)
    env = np.empty(k_valid)
    for k in range(k_valid):
        F = couplers.coupler_force(x[:-1, k] - x[1:, k], v[:-1, k] - v[1:, k],
                                   cfg.buffer_stiffness * ones, cfg.buffer_friction * ones,
                                   cfg.draw_gear_stiffness * ones,
                                   cfg.draw_gear_friction * ones, couplers.TANH, float(u))
        env[k] = np.abs(F).max()
    return {'n': n, 'u': u, 't_end': T_END, 'wall_s': wall, 'nfev': int(res.nfev),
            'first_stop_s': float(grid[k_valid]) if k_valid < grid.size else None,
            'valid_samples': k_valid, 'peak_N': float(env.max()),
            't_peak_s': float(grid[int(env.argmax())]), 'envelope_f32_zlib_b64': _encode(env)}


def get_reference(n: int, u: float, allow_compute: bool) -> dict | None:
    """Return the cached reference (envelope decoded into 'envelope'), computed if allowed."""
    cfg = make_config(n, 'tanh', u)
    key = reference_key(cfg)
    cache = load_cache()
    entry = cache.get(key)
    if entry is None:
        if not allow_compute:
            return None
        entry = compute_reference(n, u)
        save_cache_entry(key, entry)
    entry = dict(entry)
    entry['envelope'] = _decode(entry['envelope_f32_zlib_b64'])
    return entry


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
def baseline_case(n: int, t_end: float = T_END, u: float = 1000.0) -> dict:
    """Run the user's script: solve_ivp RK45 on the paper's eqs. (17)-(18) for N coaches."""
    import numpy as np
    from scipy.integrate import solve_ivp
    cfg = make_config(n, 'tanh', u)
    fb_of_t, _ = brake_formula(cfg)
    m = np.asarray(cfg.mass_array, float)
    kt, ct = cfg.buffer_stiffness, cfg.buffer_friction        # compression (buffers)
    kc, cc = cfg.draw_gear_stiffness, cfg.draw_gear_friction  # extension (draw gear)
    nc = n - 1

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
    row = {key: res[key] for key in ('n', 'model', 'u', 'h', 'wall_s', 'wall_median_s',
                                     'wall_min_run_s', 'repeats', 'walls_s', 'segments_s',
                                     'calibration_s',
                                     'rtf', 'steps', 'peak_N',
                                     'fault', 'tracemalloc_peak_kib', 'vmhwm_mib',
                                     'warmup_s', 't_first_stop', 'brake_mismatch')}
    row['window'] = window
    row['peak_window_N'] = float(env.max())
    row['t_peak_window'] = float(np.argmax(env) * OUTPUT_DT)
    row['ref_note'] = note
    if ref is not None:
        renv = np.asarray(ref['envelope'][:k + 1])
        rpk = float(renv.max())
        row['ref_peak_N'] = rpk
        row['ref_t_peak'] = float(np.argmax(renv) * OUTPUT_DT)
        row['peak_err'] = (float(env.max()) - rpk) / rpk
        dev = np.abs(env - renv) / rpk
        row['env_err'] = float(dev.max())
        above = np.nonzero(dev > 0.01)[0]
        row['t_env_err_1pct'] = float(above[0] * OUTPUT_DT) if above.size else None
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


def run(ref_max_n: int = 100, sizes=SIZES, models=MODELS, steps=STEP_VARIANTS,
        baseline_sizes=BASELINE_SIZES, log=print) -> dict:
    """All core cases, the baseline and start-up; returns the raw results."""
    import numpy as np
    results = {'cases': [], 'steps': [], 'baseline': [], 'startup': None}
    log('core: start-up (cold and warm numba cache)')
    results['startup'] = measure_startup()

    def one(n, model, u, h):
        res = _run_sub(['--case', json.dumps([n, model, u, h])])
        ok, note = want_reference(n, model, u, ref_max_n)
        ref = None
        if model == 'tanh' and not (u >= 1.0e4 and n >= 300):
            ref = get_reference(n, u, allow_compute=ok)
            if ref is not None:
                note = ''
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
            row['speedup'] = b['wall_s'] / ours['wall_s']
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
                row['speedup'] = w / ours['wall_s']
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


def compute_references(sizes, us, max_n: int) -> None:
    """Fill the reference cache."""
    for n in sizes:
        for u in us:
            ok, note = want_reference(n, 'tanh', u, max_n)
            if not ok:
                print(f'N={n} u={u:g}: {note}', flush=True)
                continue
            t0 = time.perf_counter()
            ref = get_reference(n, u, allow_compute=True)
            print(f'N={n} u={u:g}: reference peak {ref["peak_N"]:.6g} N at {ref["t_peak_s"]:g} s, '
                  f'valid until {ref["first_stop_s"]} s ({ref["wall_s"]:.0f} s to compute; '
                  f'{time.perf_counter() - t0:.0f} s now)', flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--case', help='internal: JSON [n, model, u, h]; prints JSON')
    ap.add_argument('--baseline', type=int, help='internal: baseline for N coaches')
    ap.add_argument('--startup', action='store_true', help='internal: start-up probe')
    ap.add_argument('--adaptive', action='store_true',
                    help='error-controlled cases (ADAPTIVE_CASES): markdown table')
    ap.add_argument('--refs', action='store_true',
                    help='compute missing reference solutions into the cache')
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
    if args.adaptive:
        rows = []
        for n, tol in ADAPTIVE_CASES:
            rows.append(adaptive_case(n, tol))
            print(json.dumps(rows[-1]), flush=True)
        print(adaptive_table(rows))
        return 0
    if args.refs:
        compute_references([int(s) for s in args.ref_sizes.split(',')],
                           [float(s) for s in args.ref_us.split(',')], args.ref_max_n)
        return 0
    res = run()
    print(json.dumps(dict(res), indent=1, default=str)[:5000])
    return 0


if __name__ == '__main__':
    sys.exit(main())
