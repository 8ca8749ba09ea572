"""
Run metrics (train_dynamics.physics.metrics) against hand-computed values.

Constructed histories with known forces, speeds and displacements; the energies of a real
run against the integrator's own per-step integrals and the kinetic energy lost.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.cli.scenario import valve_from_param_file
from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.metrics import FLAT_KEYS, RunMetrics
from train_dynamics.simulation.runner import InputSchedule, run_simulation

PAPER = 'config/paper_3coach.yaml'


def feed(metrics, t, y, ydot, f, x, v, fb, one_by_one=False):
    """Feed arrays (K, ...) sample by sample or as one block; return metrics.result()."""
    if one_by_one:
        for k in range(len(t)):
            metrics.add(t[k], y[k], ydot[k], f[k], x[k], v[k], fb[k])
    else:
        metrics.add_block(t, y, ydot, f, x, v, fb)
    return metrics.result()


def braking_history(dt=0.01, t_end=14.0):
    """
    Two vehicles at 10 m/s; from t = 1 s both brake at 1 m/s^2 (Fb = 1000 N each, 1 t).

    They stop at t = 11 s after x = 10 + 50 = 60 m. The coupler is idle (y = F = 0).
    """
    t = np.round(np.arange(0.0, t_end + dt / 2, dt), 10)
    tb = np.clip(t - 1.0, 0.0, 10.0)
    v1 = 10.0 - tb
    x1 = 10.0 * np.minimum(t, 1.0) + 10.0 * tb - 0.5 * tb ** 2
    x = np.column_stack((x1, x1))
    v = np.column_stack((v1, v1))
    fb = np.where((t >= 1.0) & (v1 > 0.0), 1000.0, 0.0)[:, None].repeat(2, axis=1)
    z = np.zeros((len(t), 1))
    return t, z, z, z, x, v, fb


def test_stopping_deceleration_jerk_and_brake_energy_by_hand():
    r = feed(RunMetrics(2, stop_speed=1e-9), *braking_history())
    tr = r['train']
    assert tr['stopped']
    assert tr['stopping_time'] == pytest.approx(11.0)
    assert tr['stopping_distance'] == pytest.approx(60.0)
    assert tr['brake_onset_time'] == pytest.approx(1.0)
    assert tr['stopping_time_from_brake'] == pytest.approx(10.0)
    assert tr['stopping_distance_from_brake'] == pytest.approx(50.0)
    # 1 s mean deceleration: 1 m/s^2 once the window lies inside the ramp (t in [2, 11])
    assert tr['max_deceleration'] == pytest.approx(1.0)
    assert tr['peak_deceleration'] == pytest.approx(1.0)
    # jerk over 1 s windows: a_W goes 0 -> -1 m/s^2 between t = 1 and 2 s: |j| = 1 m/s^3 at
    # t = 2 s (and again at the stop, t = 12 s; the earlier one is reported)
    assert tr['max_jerk'] == pytest.approx(1.0)
    assert tr['max_jerk_time'] == pytest.approx(2.0)
    # brake energy: 1000 N * 50 m per vehicle = kinetic energy 0.5 * 1000 kg * 10^2 m^2/s^2
    assert tr['brake_energy'] == pytest.approx(2 * 1000.0 * 50.0, rel=1e-3)
    for row in r['vehicles']:
        assert row['max_deceleration_time'] >= 2.0 - 1e-9
        assert row['brake_energy'] == pytest.approx(50000.0, rel=1e-3)
    assert tr['max_tension'] == 0.0 and tr['max_compression'] == 0.0
    assert tr['max_tension_time'] is None


def test_brake_at_t0_shows_its_jerk():
    """Before the first sample the train cruises (a = 0): braking from t = 0 has jerk 1."""
    t, y, yd, f, x, v, fb = braking_history()
    k = int(round(1.0 / 0.01))
    r = feed(RunMetrics(2), t[k:] - 1.0, y[k:], yd[k:], f[k:], x[k:] - x[k], v[k:], fb[k:])
    assert r['train']['max_jerk'] == pytest.approx(1.0)
    assert r['train']['max_jerk_time'] == pytest.approx(1.0)


def test_not_stopped():
    t, y, yd, f, x, v, fb = braking_history(t_end=5.0)
    tr = feed(RunMetrics(2), t, y, yd, f, x, v, fb)['train']
    assert not tr['stopped'] and tr['stopping_time'] is None
    assert tr['final_speed'] == pytest.approx(6.0)


def coupler_history():
    """One coupler, dt = 0.1 s: a known force and displacement history."""
    t = np.round(np.arange(0.0, 2.0, 0.1), 10)
    f = np.array([0, 100, 400, 250, -50, -300, -900, -700, 0, 50,
                  600, 120, 0, -100, -820, -600, 0, 0, 0, 0], dtype=float)
    y = np.array([0, .005, .03, .06, .04, .0, -.02, -.07, -.08, -.03,
                  .0, .02, .08, .0, -.01, 0, 0, 0, 0, 0])
    yd = np.gradient(y, t)
    x = np.column_stack((np.zeros_like(t), -y))      # y = x1 - x2
    v = np.column_stack((np.zeros_like(t), -yd))
    return t, y[:, None], yd[:, None], f[:, None], x, v, np.zeros_like(x)


def test_coupler_extremes_blocking_impacts_and_crossings_by_hand():
    t, y, yd, f, x, v, fb = coupler_history()
    m = RunMetrics(2, coupler_force_limit=500.0, draw_gear_slack=0.01, buffer_slack=0.01,
                   draw_gear_stroke=0.04, buffer_stroke=0.05)
    r = feed(m, t, y, yd, f, x, v, fb)
    c = r['couplers'][0]
    assert (c['max_tension'], c['max_tension_time']) == (600.0, pytest.approx(1.0))
    assert (c['max_compression'], c['max_compression_time']) == (900.0, pytest.approx(0.6))
    # blocked while y > 0.01 + 0.04 (t = 0.3, 1.2) or y < -(0.01 + 0.05) (t = 0.7-0.8):
    # three blockings, worst overrun 0.08 - 0.06 = 0.02 m at t = 0.8 (0.08 - 0.05 = 0.03 at
    # t = 1.2 is larger: draw gear)
    assert c['blocking_count'] == 3
    assert c['max_blocking_overrun'] == pytest.approx(0.03)
    assert c['max_blocking_overrun_time'] == pytest.approx(1.2)
    # contacts leave the free play [-0.01, 0.01]: t = 0.2 (y .03), 0.6 (-.02), 1.1 (.02),
    # 1.4 (-.01 is inside: no), so three impacts; closing speeds |ydot| at those samples
    assert c['impact_count'] == 3
    hits = [2, 6, 11]
    assert c['max_impact_speed'] == pytest.approx(max(abs(yd[k, 0]) for k in hits))
    # |F| > 500 N: t = 0.6-0.7 (peak -900 at 0.6), 1.0 (600), 1.4-1.5 (-820 at 1.4)
    cross = r['crossings']
    assert [(e['coupler'], e['value'], e['t'], e['t_start'], e['t_end']) for e in cross] == [
        (1, -900.0, pytest.approx(0.6), pytest.approx(0.6), pytest.approx(0.8)),
        (1, 600.0, pytest.approx(1.0), pytest.approx(1.0), pytest.approx(1.1)),
        (1, -820.0, pytest.approx(1.4), pytest.approx(1.4), pytest.approx(1.6))]
    assert r['train']['limit_crossings'] == 3
    level, message, values = m.diagnostic()
    assert level == 'WARN' and 'coupler_1' in message and '-900' in message
    assert dict(values)['limit_crossings'] == '3'


def test_a_limit_set_live_acts_from_the_next_sample_on():
    t, y, yd, f, x, v, fb = coupler_history()
    m = RunMetrics(2)
    m.add_block(t[:10], y[:10], yd[:10], f[:10], x[:10], v[:10], fb[:10])
    m.set_limits(coupler_force_limit=500.0)
    m.add_block(t[10:], y[10:], yd[10:], f[10:], x[10:], v[10:], fb[10:])
    assert [e['value'] for e in m.crossings()] == [600.0, -820.0]   # not the -900 at 0.6 s


def test_no_strokes_never_block_and_no_slack_no_impacts():
    r = feed(RunMetrics(2), *coupler_history())
    c = r['couplers'][0]
    assert c['blocking_count'] == 0 and c['impact_count'] == 0
    assert r['crossings'] == [] and RunMetrics(2).diagnostic()[0] == 'OK'


def test_coupler_work_by_hand():
    """F = 1000 t N, ydot = 0.01 m/s for 2 s: work = int 10 t dt = 20 J (trapezoid exact)."""
    t = np.linspace(0.0, 2.0, 201)
    f = (1000.0 * t)[:, None]
    yd = np.full((len(t), 1), 0.01)
    y = 0.01 * t[:, None]
    x = np.column_stack((y[:, 0], np.zeros_like(t)))
    v = np.column_stack((yd[:, 0], np.zeros_like(t)))
    m = RunMetrics(2, elastic_energy=lambda yy: 0.5 * 5.0e4 * yy ** 2)
    tr = feed(m, t, y, yd, f, x, v, np.zeros_like(x))['train']
    assert tr['coupler_work'] == pytest.approx(20.0)
    assert tr['coupler_dissipated'] == pytest.approx(20.0 - 0.5 * 5.0e4 * 0.02 ** 2)


@pytest.mark.parametrize('block', [1, 3, 7, 256])
def test_result_does_not_depend_on_the_block_size(block):
    """Streaming (any block size, across block boundaries) = one block of all samples."""
    hist = coupler_history()
    kw = {'coupler_force_limit': 500.0, 'jerk_limit': 0.5, 'draw_gear_slack': 0.01,
          'draw_gear_stroke': 0.04, 'buffer_slack': 0.01, 'buffer_stroke': 0.05}
    ref = feed(RunMetrics(2, **kw), *hist)
    got = feed(RunMetrics(2, block=block, **kw), *hist, one_by_one=True)
    assert_same(got, ref)
    ref = feed(RunMetrics(2, jerk_limit=0.5), *braking_history())
    got = feed(RunMetrics(2, jerk_limit=0.5, block=block), *braking_history(), one_by_one=True)
    assert got['crossings']
    assert_same(got, ref)


def assert_same(a, b, path='result'):
    """Assert equal nested results; floats to 1e-12 (sums over other block splits)."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            assert_same(a[k], b[k], f'{path}.{k}')
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f'{path}[{k}]')
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-12, abs=1e-9), path
    else:
        assert a == b, path


def test_jerk_crossings_per_vehicle():
    r = feed(RunMetrics(2, jerk_limit=0.5), *braking_history())
    cross = [e for e in r['crossings'] if e['kind'] == 'jerk']
    # each vehicle: the brake application (jerk -1 at t = 2) and the stop (+1 at t = 12)
    signs = [(e['vehicle'], np.sign(e['value'])) for e in cross]
    assert signs == [(1, -1), (2, -1), (1, 1), (2, 1)]
    assert cross[0]['t'] == pytest.approx(2.0) and cross[2]['t'] == pytest.approx(12.0)
    assert cross[0]['t_start'] == pytest.approx(1.5 + 0.01) and cross[0]['t_end'] > 2.0


def test_run_energies_match_the_integrator_and_the_kinetic_energy():
    """
    The paper's run, 60 s: the trapezoid over the 100 Hz samples against the integrator.

    Brake energy within 0.05 %, coupler work within 1 % of the per-step integrals; brake +
    coupler energy = kinetic energy lost (the train stops).
    """
    cfg = load_param_file(PAPER)
    metrics = RunMetrics.for_run(cfg)
    inputs = InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(PAPER, cfg), 'valve')
    sim = run_simulation(cfg, 60.0, inputs, on_sample=metrics.sample)
    tr = metrics.result()['train']
    assert tr['brake_energy'] == pytest.approx(sim.work_brake, rel=5e-4)
    assert tr['coupler_work'] == pytest.approx(sim.work_coupler, rel=1e-2)
    ke0 = 0.5 * np.sum(sim.masses) * cfg.initial_speed ** 2
    assert tr['brake_energy'] + tr['coupler_work'] == pytest.approx(ke0, rel=5e-4)
    assert tr['stopped'] and 40.0 < tr['stopping_time'] < 55.0
    # the paper's fig. 11: the largest force is a compression of a few kN, soon after the
    # brake application at t = 1 s, in the rear coupler
    assert 3e3 < tr['max_compression'] < 6e3 and 1.0 < tr['max_compression_time'] < 2.0
    assert tr['max_compression_coupler'] == 2
    assert tr['coupler_dissipated'] == pytest.approx(tr['coupler_work'], rel=1e-3)
    assert set(tr) == set(FLAT_KEYS)


def test_for_run_takes_limits_and_strokes_from_the_parameters():
    cfg = SimConfig.from_dict({'coupler_force_limit': 1e5, 'jerk_limit': 2.0})
    m = RunMetrics.for_run(cfg)
    assert m.force_crossings.limit == 1e5 and m.jerk_crossings.limit == 2.0
    # the default strokes of the parameters: 60 mm draw gear, 105 mm buffers
    assert list(m.block_t) == [0.06, 0.06] and list(m.block_c) == [0.105, 0.105]
    assert not m.has_slack.any()

    class Sim:
        buffer_stroke = np.array([0.1, 0.2])
        draw_gear_slack = 0.02
        ke = np.array([2e6, 2e6])
        kec = np.array([4e6, 4e6])

    m = RunMetrics.for_run(SimConfig.from_dict({'num_coaches': 3}), Sim())
    assert list(m.block_c) == [0.1, 0.2] and list(m.gt) == [0.02, 0.02]
    assert m.elastic_energy(np.array([-0.01, 0.01])) == pytest.approx([100.0, 200.0])
