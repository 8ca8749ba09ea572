"""Couplings as two vehicle ends in series: blocking, compliances, energies, mixed consists."""
import numpy as np
import pytest

from train_dynamics.physics import characteristics, couplers, equilibrium
from train_dynamics.physics.chain_reference import ChainLaw, solve_chain
from train_dynamics.physics.config import consist, SimConfig
from train_dynamics.physics.couplers import end_deflection, end_energy_to_blocking
from train_dynamics.physics.kernel.couplers import coupler_force_travel, MODEL_CODES
from train_dynamics.physics.kernel.layout import COUPLER, TABLE_ROWS
from train_dynamics.physics.train import TrainSimulator

S = 0.105      # UIC 526-1 buffer stroke [m]


def coupling_of(tmp_path, types, vehicles, extra=''):
    path = tmp_path / 'train.yaml'
    path.write_text(f'vehicle_types:\n{types}\nvehicles: {vehicles}\n{extra}')
    return SimConfig.from_dict({'consist_file': str(path)}).consist


def quasi_static_force(c, j, y):
    """F [N] of coupling j at deflections y [m], moving slowly into compression (loading)."""
    n = len(y)
    k = c.coupler_array()[:, j]
    row = dict(zip(consist.COUPLER_FIELDS, k))
    full = [np.full(n, row[f]) for f in ('buffer_stiffness', 'buffer_friction',
                                         'draw_gear_stiffness', 'draw_gear_friction',
                                         'draw_gear_slack', 'buffer_slack', 'draw_gear_stroke',
                                         'buffer_stroke', 'blocked_stiffness')]
    tables = np.repeat(c.tables[:, j:j + 1], n, axis=1)
    cpl = np.zeros((len(COUPLER), n))
    cpl[TABLE_ROWS] = tables
    return coupler_force_travel(np.asarray(y, float), np.full(n, -1e-3), *full,
                                MODEL_CODES['sign'], 1000.0, cpl)


BUFFER = ('  w: {buffer_stiffness: 4.0e6, buffer_friction: 2.0e6, buffer_stroke: 0.105,\n'
          '      blocked_stiffness: 2.0e8}')


def test_two_identical_buffers_block_at_twice_their_stroke(tmp_path):
    c = coupling_of(tmp_path, BUFFER, '[{type: w}, {type: w}]')
    y = -np.linspace(0.0, 3.0 * S, 3001)
    f = quasi_static_force(c, 0, y)
    slope = np.diff(f) / np.diff(y)
    # the buffers' springs (6e6 N/m per end in loading, 3e6 N/m the coupling) up to 2 S,
    # the blocked stiffness beyond: the kink is at y = -2 S
    kink = -y[1:][np.argmax(slope > 1.0e7)]
    assert kink == pytest.approx(2.0 * S, abs=2e-4)
    assert slope[0] == pytest.approx(3.0e6)


def test_a_stiff_and_a_soft_end_deflect_in_the_ratio_of_their_compliances(tmp_path):
    types = ('  stiff: {buffer_stiffness: 9.0e6, buffer_friction: 3.0e6, buffer_stroke: 0.2}\n'
             '  soft: {buffer_stiffness: 3.0e6, buffer_friction: 1.0e6, buffer_stroke: 0.2}')
    c = coupling_of(tmp_path, types, '[{type: stiff}, {type: soft}]')
    force = 2.0e5
    d_stiff = end_deflection(force, 9.0e6, 3.0e6, 0.0, 0.2, 1e8)
    d_soft = end_deflection(force, 3.0e6, 1.0e6, 0.0, 0.2, 1e8)
    assert d_soft / d_stiff == pytest.approx(12.0e6 / 4.0e6)    # compliances 1/4e6 : 1/12e6
    # the coupling's law carries that force at the sum of the two deflections
    y = -(d_stiff + d_soft)
    assert -quasi_static_force(c, 0, [y])[0] == pytest.approx(force, rel=1e-12)


@pytest.mark.parametrize('ends', [
    [(4.0e6, 2.0e6, S)] * 2,
    # ends of different stiffness and stroke reaching the same final force (as a datasheet pair)
    [(8.0e6, 2.0e6, 0.075), (4.0e6, 1.0e6, 0.15)],
])
def test_energy_to_blocking_is_the_sum_of_the_ends_datasheet_energies(tmp_path, ends):
    types = '\n'.join(f'  e{i}: {{buffer_stiffness: {k!r}, buffer_friction: {f!r}, '
                      f'buffer_stroke: {s!r}}}' for i, (k, f, s) in enumerate(ends))
    c = coupling_of(tmp_path, types, '[{type: e0}, {type: e1}]')
    datasheet = sum(end_energy_to_blocking(k, f, s) for k, f, s in ends)
    closed = c.coupler('buffer_stroke')[0] + c.coupler('buffer_slack')[0]
    y = -np.linspace(0.0, closed, 20001)
    f = -quasi_static_force(c, 0, y)
    absorbed = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(-y)))
    assert absorbed == pytest.approx(datasheet, rel=0.02)


def test_a_mixed_consist_couples_its_ends_not_their_averages(tmp_path):
    c = SimConfig.from_dict({'consist_file': 'consist_passenger_12.yaml'}).consist
    lib = consist.library_types()
    loco, coach = lib['electric_passenger_locomotive'], lib['passenger_coach']
    k = consist.series(loco['buffer_stiffness'] + loco['buffer_friction'],
                       coach['buffer_stiffness'] + coach['buffer_friction'])
    assert c.coupler('buffer_stiffness')[0] + c.coupler('buffer_friction')[0] == pytest.approx(k)
    assert c.coupler('buffer_stroke')[0] == pytest.approx(
        loco['buffer_stroke'] + coach['buffer_stroke'])           # 2 x 105 mm, not 105 mm
    c = SimConfig.from_dict({'consist_file': 'consist_freight_750m.yaml'}).consist
    wag, loco = lib['freight_wagon_loaded'], lib['electric_freight_locomotive']
    assert c.coupler('buffer_stroke')[0] == pytest.approx(2 * S)
    assert c.coupler('blocked_stiffness')[1] == pytest.approx(
        consist.series(loco['blocked_stiffness'], lib['freight_wagon_empty']['blocked_stiffness']))
    assert wag['buffer_stroke'] == S


def test_front_and_rear_ends_and_whole_coupling_constants(tmp_path):
    types = ('  w: {buffer_stiffness: 4.0e6, buffer_friction: 2.0e6,\n'
             '      rear: {buffer_stroke: 0.15}, front: {buffer_stroke: 0.05}}')
    c = coupling_of(tmp_path, types, '[{type: w, count: 3}]')
    assert list(c.coupler('buffer_stroke')) == pytest.approx([0.2, 0.2])   # rear + front
    c = coupling_of(tmp_path, types, '[{type: w, count: 3}]',
                    'couplings: {buffer_stiffness: 1.0e6, buffer_friction: 0.5e6}\n')
    assert list(c.coupler('buffer_stiffness')) == [1.0e6, 1.0e6]        # as given
    assert list(c.coupler('buffer_friction')) == [0.5e6, 0.5e6]


def test_the_uniform_train_keeps_the_parameters_as_whole_coupling_constants():
    cfg = SimConfig.from_dict({'num_coaches': 3, 'buffer_stiffness': 2.8e6,
                               'buffer_stroke': 0.105})
    c = cfg.consist
    assert list(c.coupler('buffer_stiffness')) == [2.8e6, 2.8e6]     # bit for bit
    assert list(c.coupler('buffer_stroke')) == [0.105, 0.105]
    assert list(c['buffer_stiffness']) == [5.6e6] * 3                   # each end


def test_two_paper_coaches_are_coupled_as_in_the_paper(tmp_path):
    path = tmp_path / 't.yaml'
    path.write_text('vehicles: [{type: paper_coach, count: 3}]\n')
    c = SimConfig.from_dict({'consist_file': str(path)}).consist
    assert list(c.coupler('buffer_stiffness')) == [2.8e6, 2.8e6]
    assert list(c.coupler('buffer_friction')) == [1.4e6, 1.4e6]
    assert list(c.coupler('draw_gear_stiffness')) == [5.46e6, 5.46e6]
    assert list(c.coupler('draw_gear_friction')) == [2.43e6, 2.43e6]
    assert list(c.coupler('buffer_stroke')) == [0.105, 0.105]


def test_library_locomotives_match_their_sources():
    lib = consist.library_types()
    db101 = lib['electric_passenger_locomotive']
    # DB 101: its 300 kN starting effort within its adhesion at standstill
    assert db101['traction_adhesion'] * db101['mass'] * 9.81 >= db101['max_tractive_force']
    # the UK Class 66 has no dynamic brake
    class66 = lib['heavy_freight_locomotive']
    assert class66.get('max_dynamic_brake_force', 0.0) == 0.0
    db185 = lib['electric_freight_locomotive']
    assert db185['traction_adhesion'] * db185['mass'] * 9.81 >= db185['max_tractive_force']


# ----------------------------------------------------------- preloaded and progressive ends
CATEGORY_C = ('  cat_c: {buffer_stroke: 0.105, buffer_final_force: 1.0e6,\n'
              '          buffer_energy: 70000.0,\n'
              '          buffer_preload: 30000.0, buffer_stiffness: 7.0e6, '
              'buffer_friction: 4.2e6, brake_regime: G}')


def _energy_to_blocking(c, j=0):
    """Energy [J] coupling j absorbs compressed quasi-statically from 0 to blocking."""
    closed = c.coupler('buffer_stroke')[j] + c.coupler('buffer_slack')[j]
    y = -np.linspace(0.0, closed, 40001)
    f = -quasi_static_force(c, j, y)
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(-y)))


def test_two_category_buffers_absorb_the_sum_of_their_datasheet_energies(tmp_path):
    """
    UIC 526-1 category A ends (two side buffers) + A ends, and one-buffer A + C ends.

    The library's category A wagon has two buffers per end in parallel: each end absorbs
    2 x 30 kJ to its 105 mm and carries 2 x 1 MN at the stroke; a coupling of two such ends
    120 kJ to 2 x 105 mm. One-buffer ends (buffers_per_end 1): 30 + 70 kJ and 1 MN.
    """
    lib = consist.library_types()['freight_wagon_loaded_category_a']
    assert lib['buffers_per_end'] == 2
    one_a = CATEGORY_C.replace('cat_c', 'cat_a').replace('70000.0', '30000.0')
    c = coupling_of(tmp_path, CATEGORY_C + '\n' + one_a,
                    '[{type: freight_wagon_loaded_category_a, count: 2}, {type: cat_a}, '
                    '{type: cat_c}]')
    assert c.coupler('buffer_stroke')[0] == pytest.approx(2 * 0.105)
    assert _energy_to_blocking(c, 0) == pytest.approx(2 * 2 * lib['buffer_energy'], rel=0.02)
    assert _energy_to_blocking(c, 2) == pytest.approx(30000.0 + 70000.0, rel=0.02)
    # at the end of the stroke the buffers carry their final force, before blocking
    f_two = -quasi_static_force(c, 0, [-(2 * 0.105 - 1e-9)])[0]
    assert f_two == pytest.approx(2 * 1.0e6, rel=1e-6)
    f_one = -quasi_static_force(c, 2, [-(2 * 0.105 - 1e-9)])[0]
    assert f_one == pytest.approx(1.0e6, rel=1e-6)


def test_preloaded_ends_stay_closed_below_the_preload_then_take_the_springs(tmp_path):
    """P = 30 kN per end, K_b 2e8 N/m, k + k_f = 11.2e6 N/m per end: a hand-computed law."""
    types = ('  w: {buffer_stiffness: 7.0e6, buffer_friction: 4.2e6, buffer_preload: 30000.0,\n'
             '      blocked_stiffness: 2.0e8}')
    c = coupling_of(tmp_path, types, '[{type: w}, {type: w}]')
    ramp = 2 * 30000.0 / 2.0e8                 # each end's structure up to the preload [m]
    f = -quasi_static_force(c, 0, [-0.5 * ramp, -ramp, -(ramp + 0.01)])
    assert f[0] == pytest.approx(15000.0, rel=1e-9)         # half the preload: 0.15 mm
    assert f[1] == pytest.approx(30000.0, rel=1e-9)
    assert f[2] == pytest.approx(30000.0 + 5.6e6 * 0.01, rel=1e-9)   # springs in series


def test_a_progressive_and_a_degressive_end_in_series_carry_one_force(tmp_path):
    """Equal force through both ends, strokes add: y(F) = d_A(F) + d_C(F), each inverted."""
    c = coupling_of(tmp_path, CATEGORY_C, '[{type: freight_wagon_loaded_category_a}, '
                    '{type: cat_c}]')
    d = np.linspace(0.0, 0.105, 200001)
    kw = {'k': 7.0e6, 'k_friction': 4.2e6, 'stroke': 0.105, 'preload': 30000.0,
          'final_force': 1.0e6, 'kb': 2.0e8}
    load_a = characteristics.end_loading(d, energy=30000.0, **kw)
    load_c = characteristics.end_loading(d, energy=70000.0, **kw)
    for force in (2.0e5, 5.0e5, 8.0e5):     # the category A end: two buffers in parallel
        y = -(np.interp(force / 2, load_a, d) + np.interp(force, load_c, d))
        assert -quasi_static_force(c, 0, [y])[0] == pytest.approx(force, rel=0.01)


def test_kernel_follows_the_reference_with_preloaded_progressive_ends():
    """
    Four coaches, preloaded progressive buffers and preloaded draw gear, front braked first.

    The kernel (error control 1e-4) against the independent reference (numpy tables, Radau
    restarted at every knot of the tables): every 10 ms sample within 0.5 % of the peak force
    (0.05 % when written).
    """
    masses = [45000.0, 30000.0, 60000.0, 25000.0]
    cfg = SimConfig.from_dict({
        'masses': masses, 'brake_input': 'cylinder_per_coach', 'scale_factor': 700.0,
        'initial_speed': 20.0, 'integration_tolerance': 1e-4, 'buffer_preload': 5000.0,
        'buffer_final_force': 2.0e5, 'buffer_energy': 4000.0, 'buffer_stroke': 0.04,
        'draw_gear_preload': 5000.0})
    sim = TrainSimulator(cfg)
    assert np.all(sim.cpl[COUPLER.TAB] == 1.0)
    full = cfg.adhesion_coefficient * np.array(masses) * cfg.gravity
    on = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]])
    times = np.array([0.1, 0.5])
    for t, p in zip(times, on * cfg.max_cylinder_pressure):
        sim.schedule(t, lambda p=p: sim.set_cylinder_pressure(p))
    t_eval = np.round(np.arange(1, 101) * 0.01, 10)
    ref = solve_chain(sim.inertia, ChainLaw.of_simulator(sim), 20.0, (times, on * full), t_eval)
    assert ref.segments > 10                        # knots of the tables crossed
    assert ref.y.min() < -0.01 and ref.y.max() > 0.005     # both sides well into the tables
    F = []
    for t in t_eval:
        sim.advance_to(t)
        F.append(sim.coupler_force)
    F = np.array(F)
    peak = np.abs(ref.F).max()
    assert peak > 5 * 5000.0                        # beyond the preloads
    assert np.abs(F - ref.F).max() < 0.005 * peak


def test_tabled_couplings_at_rest_static_deflection_and_stored_energy():
    """The static solve inverts the tables (F(y, 0) = T) and the stored energy is int E dy."""
    cfg = SimConfig.from_dict({'num_coaches': 3, 'buffer_preload': 3.0e4,
                               'buffer_final_force': 1.0e6, 'buffer_energy': 3.0e4,
                               'draw_gear_preload': 2.0e4})
    sim = TrainSimulator(cfg)
    c = sim.cpl
    rows = [c[getattr(COUPLER, r)] for r in ('KE', 'KF', 'KEC', 'KFC', 'GT', 'GC', 'ST', 'SC',
                                             'KB')]
    force = np.array([1.5e5, -4.0e5])
    y = equilibrium.static_deflection(force, rows[0], rows[2], *rows[4:], c[TABLE_ROWS])
    assert -0.105 < y[1] < -0.01 and 0.01 < y[0] < 0.06       # within the strokes
    at_rest = coupler_force_travel(y, np.zeros(2), *rows, MODEL_CODES['tanh'], 1000.0, c)
    assert at_rest == pytest.approx(force, rel=1e-9)
    path = np.linspace(0.0, 1.0, 20001)[:, None] * y
    f = np.array([coupler_force_travel(p, np.zeros(2), *rows, MODEL_CODES['tanh'], 1000.0, c)
                  for p in path])
    work = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(path, axis=0), axis=0)
    stored = couplers.elastic_energy_travel(y, rows[0], rows[2], *rows[4:], c[TABLE_ROWS])
    assert stored == pytest.approx(work, rel=1e-6)
