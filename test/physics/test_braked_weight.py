"""Braked weight (UIC 544-1): G and P from one label, a G label of its own, load fields."""
import numpy as np
import pytest
from scipy.integrate import trapezoid

from train_dynamics.physics import friction as fr
from train_dynamics.physics.config import ConfigError, SimConfig, table
from train_dynamics.physics.kernel.layout import VEHICLE

V0 = 100.0 / 3.6

CONSIST = """
friction_materials:
  flat: {{speeds: [0.0], mu: [0.3]}}          # a constant mu: the response-time rule is exact
vehicle_types:
  wagon: {{mass: 50000.0, friction_material: flat, braked_mass_p: 40000.0, brake_regime: {regime},
          brake_blocks: 8.0 {extra}}}
vehicles:
  - {{type: wagon, count: 3}}
"""


def _config(tmp_path, regime, extra='', **values):
    path = tmp_path / f'train_{regime}.yaml'
    path.write_text(CONSIST.format(regime=regime, extra=extra))
    return SimConfig.from_dict({'consist_file': str(path), 'initial_speed': V0,
                                'brake_input': 'pipe_head', 'brake_model': 'empirical',
                                **values})


def _stop(cfg):
    from train_dynamics.physics.train import TrainSimulator
    sim = TrainSimulator(cfg)
    sim.set_head_pipe_pressure(0.0)                     # emergency at t = 0
    while np.any(sim.v > 0.0) and sim.t < 300.0:
        sim.advance_to(sim.t + 5.0)
    assert np.all(sim.v == 0.0)
    return sim


def _spread(times, fractions):
    """Return M1 - t_e^2 / 2 [s^2] of a filling: M1 = int t (1 - f) dt, t_e = int (1 - f) dt."""
    t = np.linspace(0.0, times[-1], 200001)
    rest = 1.0 - np.interp(t, times, fractions)
    t_e = trapezoid(rest, t)                # scipy's: np.trapezoid is numpy >= 2.0 only
    return trapezoid(t * rest, t) - 0.5 * t_e * t_e


def test_g_and_p_from_one_braked_weight_g_stops_longer_by_its_response_time(tmp_path):
    """
    Same braked weight: the same normal force; G fills slower and stops later.

    A constant force F f(t) (f the filling, 1 once filled, before the stop) and a constant
    mu stop a mass m from v0 in s = v0 t_e + v0^2 / (2 a) - a (M1 - t_e^2 / 2), a = F / m,
    t_e = int (1 - f) dt, M1 = int t (1 - f) dt: G - P = v0 (t_e,G - t_e,P), about 225 m
    from 100 km/h, less a times the difference of the fillings' spread (UIC 544-1: equal
    braked weights in G and P, the same cylinder pressure).
    """
    p, g = _stop(_config(tmp_path, 'P')), _stop(_config(tmp_path, 'G'))
    assert np.array_equal(p.coach[VEHICLE.BRAKE_GAIN], g.coach[VEHICLE.BRAKE_GAIN])
    t_p = fr.response_time(table.P_FILL_TIME, table.P_FILL_FRACTION)
    t_g = fr.response_time(table.G_FILL_TIME, table.P_FILL_FRACTION)
    assert t_g - t_p == pytest.approx(5.0 * t_p, rel=1e-9)          # the G table: 6 times
    a = 0.3 * p.coach[VEHICLE.BRAKE_GAIN][0] * 380000.0 / 50000.0
    spread = (_spread(table.G_FILL_TIME, table.P_FILL_FRACTION)
              - _spread(table.P_FILL_TIME, table.P_FILL_FRACTION))
    extra = V0 * (t_g - t_p) - a * spread                            # 225 m - 17 m
    assert V0 * (t_g - t_p) == pytest.approx(225.3, abs=0.1)
    assert g.x[0] - p.x[0] == pytest.approx(extra, rel=0.01)
    assert g.x[0] > p.x[0] + 200.0


def test_braked_weight_force_is_calibrated_on_the_p_fill_whatever_the_train_fill(tmp_path):
    """The label's force does not depend on the train's filling tables or the regime."""
    base = _config(tmp_path, 'G')
    slow = _config(tmp_path, 'G', cylinder_fill_time=[0.0, 60.0],
                   cylinder_fill_fraction=[0.0, 1.0])
    from train_dynamics.physics.train import TrainSimulator
    gains = [TrainSimulator(c).coach[VEHICLE.BRAKE_GAIN] for c in (base, slow)]
    assert np.array_equal(gains[0], gains[1])
    law = base.consist.materials[1]
    expected = fr.braked_mass_normal_force(40000.0, 50000.0, law, 8, fr.P_RESPONSE_TIME,
                                           inertia=0.0) / 380000.0
    assert gains[0][0] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize('regime, label', [('G', 30000.0), ('P', 40000.0)])
def test_own_g_label_wins_in_g_only(tmp_path, regime, label):
    from train_dynamics.physics.train import TrainSimulator
    cfg = _config(tmp_path, regime, extra=', braked_mass_g: 30000.0')
    gain = TrainSimulator(cfg).coach[VEHICLE.BRAKE_GAIN][0]
    law = cfg.consist.materials[1]
    expected = fr.braked_mass_normal_force(label, 50000.0, law, 8, fr.P_RESPONSE_TIME)
    assert gain == pytest.approx(expected / 380000.0, rel=1e-12)


def test_braked_mass_of_picks_the_label():
    assert fr.braked_mass_of('G', 40e3, 0.0) == 40e3
    assert fr.braked_mass_of('G', 40e3, 30e3) == 30e3
    assert fr.braked_mass_of('P', 40e3, 30e3) == 40e3
    assert fr.braked_mass_of('P', 0.0, 30e3) == 30e3
    assert fr.braked_mass_of('P', 0.0, 0.0) == 0.0


@pytest.mark.parametrize('field, value', [('load_empty_ratio', 0.4),
                                          ('load_empty_mass', 20000.0),
                                          ('load_changeover_mass', 50000.0)])
def test_load_fields_on_paper_are_refused(field, value):
    with pytest.raises(ConfigError, match=rf'parameters: vehicle 1 \(coach\): {field} set with '
                                          r'friction_material paper'):
        SimConfig.from_dict({field: value}).consist


def test_load_fields_on_a_paper_wagon_of_a_consist_are_refused(tmp_path):
    path = tmp_path / 'train.yaml'
    path.write_text('vehicles:\n  - {type: paper_coach}\n'
                    '  - {type: paper_coach, load_empty_ratio: 0.5}\n')
    with pytest.raises(ConfigError, match=r'vehicle 2 \(paper_coach\): load_empty_ratio set '
                                          r'with friction_material paper'):
        SimConfig.from_dict({'consist_file': str(path)}).consist


def test_load_ratio_without_empty_mass_is_refused():
    with pytest.raises(ConfigError, match='load_empty_ratio set without load_empty_mass'):
        SimConfig.from_dict({'friction_material': 'disc', 'braked_mass_p': 40000.0,
                             'load_empty_ratio': 0.5}).consist


def test_load_ratio_acts_on_a_friction_material(tmp_path):
    from train_dynamics.physics.train import TrainSimulator
    values = {'friction_material': 'disc', 'braked_mass_p': 40000.0, 'coach_mass': 30000.0,
              'load_empty_mass': 25000.0, 'load_full_mass': 90000.0,
              'load_changeover_mass': 50000.0}
    empty = TrainSimulator(SimConfig.from_dict({**values, 'load_empty_ratio': 0.5}))
    loaded = TrainSimulator(SimConfig.from_dict(values))
    assert empty.coach[VEHICLE.BRAKE_GAIN][0] == pytest.approx(
        0.5 * loaded.coach[VEHICLE.BRAKE_GAIN][0], rel=1e-12)


@pytest.mark.parametrize('fields, message', [
    ({'braked_mass_p': 0.0}, 'needs its force level'),
    ({'braked_mass_p': 1.0e6}, r'braked weight 1e\+06 kg of a 46000 kg vehicle \(lambda 2174 %\)'),
    ({'mass': 1000.0}, r'braked weight 59000 kg of a 1000 kg vehicle')])
def test_unreachable_force_level_is_refused_with_the_configuration(tmp_path, fields, message):
    """Refused when the file is read (exit 2 everywhere), not when the simulator starts."""
    path = tmp_path / 'train.yaml'
    entry = ', '.join(f'{k}: {v!r}' for k, v in fields.items())
    path.write_text(f'vehicles:\n  - {{type: passenger_coach, {entry}}}\n'
                    '  - {type: passenger_coach}\n')
    with pytest.raises(ConfigError, match=r'vehicle 1 \(passenger_coach\): .*' + message):
        SimConfig.from_dict({'consist_file': str(path)})
