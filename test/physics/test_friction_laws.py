"""User-defined friction laws: tables and Karwatzki-type coefficients, library and consist."""
import pytest

from train_dynamics.physics import friction as fr
from train_dynamics.physics import friction_laws as fl
from train_dynamics.physics.config import ConfigError, consist, SimConfig

G = 9.81

TABLE = {'speeds': [0.0, 10.0, 20.0], 'forces': [10000.0, 30000.0],
         'mu': [[0.4, 0.3], [0.3, 0.2], [0.2, 0.1]]}


def test_table_law_is_bilinear_and_clamped_by_hand():
    law = fl.law_of_entry('t', TABLE, 'test')
    # v = 15 m/s, F = 15 kN: at 10 m/s 0.3 + 0.25 (0.2 - 0.3) = 0.275, at 20 m/s
    # 0.2 + 0.25 (0.1 - 0.2) = 0.175; halfway: 0.225
    assert law.mu(15.0, 15000.0) == pytest.approx(0.225, rel=1e-12)
    assert law.mu(-15.0, 15000.0) == pytest.approx(0.225, rel=1e-12)     # |v|
    assert law.mu(10.0, 30000.0) == pytest.approx(0.2, rel=1e-12)        # a knot
    assert law.mu(0.0, 5000.0) == pytest.approx(0.4, rel=1e-12)          # clamped below
    assert law.mu(35.0, 90000.0) == pytest.approx(0.1, rel=1e-12)        # clamped above
    assert law.mu(5.0, 50000.0) == pytest.approx(0.25, rel=1e-12)        # force clamped


def test_table_law_over_speed_only_and_in_kmh_and_kn():
    law = fl.law_of_entry('s', {'speed_unit': 'km/h', 'speeds': [0.0, 36.0, 72.0],
                                'mu': [0.3, 0.25, 0.15]}, 'test')
    # 54 km/h = 15 m/s, halfway between 36 and 72 km/h: (0.25 + 0.15) / 2
    assert law.mu(15.0, 1.0) == pytest.approx(0.2, rel=1e-12)
    assert law.mu(15.0, 1.0e5) == pytest.approx(0.2, rel=1e-12)     # no force dependence
    same = fl.law_of_entry('k', {**TABLE, 'speed_unit': 'km/h', 'force_unit': 'kN',
                                 'speeds': [0.0, 36.0, 72.0], 'forces': [10.0, 30.0]}, 'test')
    assert same.mu(15.0, 15000.0) == pytest.approx(0.225, rel=1e-12)


def test_coefficient_law_by_hand():
    law = fl.law_of_entry('c', {'coefficients': {'a': 0.5, 'b': 1000.0, 'c': 3000.0,
                                                 'd': 10.0, 'e': 20.0}}, 'test')
    # 0.5 (1000 + 1000) / (1000 + 3000) (10 + 10) / (10 + 20) = 0.5 * 0.5 * 2 / 3
    assert law.mu(10.0, 1000.0) == pytest.approx(1.0 / 6.0, rel=1e-12)
    kn = fl.law_of_entry('c', {'force_unit': 'kN', 'speed_unit': 'km/h', 'coefficients': {
        'a': 0.5, 'b': 1.0, 'c': 3.0, 'd': 36.0, 'e': 72.0}}, 'test')
    assert kn.mu(10.0, 1000.0) == pytest.approx(1.0 / 6.0, rel=1e-12)


@pytest.mark.parametrize('kmh, tonnes', [(0.0, 0.5), (10.0, 1.5), (60.0, 1.5096),
                                         (100.0, 3.0), (160.0, 0.8)])
def test_shipped_cast_iron_is_karwatzkis_formula(kmh, tonnes):
    k = tonnes
    expected = 0.6 * (16 * k + 100) / (80 * k + 100) * (kmh + 100) / (5 * kmh + 100)
    assert fr.material_friction('cast_iron', kmh / 3.6, k * 1000 * G) == pytest.approx(
        expected, rel=1e-12)
    assert fr.material_friction(fr.CAST_IRON, kmh / 3.6, k * 1000 * G) == pytest.approx(
        expected, rel=1e-12)


def test_shipped_tables_keep_their_curves():
    # the composite and disc curves: their knots [km/h] and the mean of two knots
    for name, mus in (('composite_k', (0.270, 0.255, 0.245)), ('disc', (0.370, 0.360, 0.350)),
                      ('composite_ll', (0.200, 0.175, 0.160))):
        for kmh, mu in zip((0.0, 50.0, 100.0), mus):
            assert fr.material_friction(name, kmh / 3.6, 1.0e4) == pytest.approx(mu, rel=1e-12)
        assert fr.material_friction(name, 75.0 / 3.6, 1.0e4) == pytest.approx(
            0.5 * (mus[1] + mus[2]), rel=1e-12)


@pytest.mark.parametrize('entry, message', [
    ({'speeds': [0.0, 10.0], 'mu': [0.3, 1.2]}, r'\(0, 1\]'),
    ({'speeds': [10.0, 0.0], 'mu': [0.3, 0.2]}, 'ascending'),
    ({'speeds': [0.0, 10.0], 'mu': [0.3]}, 'one value per speed'),
    ({'speeds': [0.0, 10.0], 'forces': [1.0, 2.0], 'mu': [[0.3, 0.2], [0.2]]},
     'one value per force'),
    ({'speeds': list(range(13)), 'mu': [0.3] * 13}, 'at most'),
    ({'coefficients': {'a': 0.024, 'b': 1.0, 'c': 0.0, 'd': 1.0, 'e': 1.0}}, 'c > 0'),
    ({'coefficients': {'a': 2.0, 'b': 1.0, 'c': 1.0, 'd': 1.0, 'e': 1.0}}, '> 1'),
    ({'coefficients': {'a': 0.1}}, 'a, b, c, d, e'),
    ({'speeds': [0.0], 'mu': [0.3], 'coefficients': {}}, 'not both'),
    ({'speeds': [0.0], 'mu': [0.3], 'speed_unit': 'mph'}, 'speed_unit'),
    ({'speed': [0.0], 'mu': [0.3]}, 'unknown key'),
])
def test_bad_friction_law_is_refused_with_its_name(entry, message):
    with pytest.raises(ConfigError, match=message) as err:
        fl.laws_of({'my_block': entry}, 'file.yaml')
    assert 'my_block' in str(err.value)


def test_paper_cannot_be_redefined():
    with pytest.raises(ConfigError, match='built in'):
        fl.laws_of({'paper': {'speeds': [0.0], 'mu': [0.3]}}, 'file.yaml')


CONSIST = """
friction_materials:
  flat_block: {speeds: [0.0, 50.0], mu: [0.3, 0.3]}
  fast_block: {speeds: [0.0, 50.0], mu: [0.2, 0.2]}
vehicle_types:
  wagon: {mass: 40000.0, friction_material: flat_block, brake_cylinder_area: 0.0507,
          rigging_ratio: 8.0, brake_blocks: 8.0}
vehicles:
  - {type: wagon, count: 2}
  - {type: wagon, friction_material: fast_block}
  - {type: wagon, friction_material: cast_iron}
"""


def test_consist_vehicles_brake_on_their_own_law(tmp_path):
    """A consist's own laws and a library law, each vehicle at mu N (N by the chain, by hand)."""
    from train_dynamics.physics.train import TrainSimulator
    path = tmp_path / 'train.yaml'
    path.write_text(CONSIST)
    cfg = SimConfig.from_dict({'consist_file': str(path), 'initial_speed': 10.0,
                               'brake_input': 'cylinder_per_coach'})
    assert cfg.consist.choices('friction_material') == ['flat_block', 'flat_block',
                                                        'fast_block', 'cast_iron']
    sim = TrainSimulator(cfg)
    sim.set_cylinder_pressure(3.8e5)
    sim.advance_to(0.01)
    normal = 3.8e5 * 0.0507 * 0.95 * 8.0 * 0.83        # 121 543 N on 8 blocks
    assert sim.brake_force[0] == pytest.approx(0.3 * normal, rel=1e-9)
    assert sim.brake_force[1] == pytest.approx(0.3 * normal, rel=1e-9)
    assert sim.brake_force[2] == pytest.approx(0.2 * normal, rel=1e-9)
    iron = fr.material_friction('cast_iron', sim.v[3], normal / 8.0)
    assert sim.brake_force[3] == pytest.approx(iron * normal, rel=2e-3)


def test_unknown_friction_material_is_a_config_error_naming_the_known_ones(tmp_path):
    path = tmp_path / 'train.yaml'
    path.write_text(CONSIST.replace('friction_material: fast_block',
                                    'friction_material: fast_blok'))
    with pytest.raises(ConfigError, match=r'fast_blok.*not a friction law.*cast_iron.*'
                                          r'fast_block.*flat_block'):
        SimConfig.from_dict({'consist_file': str(path)}).consist
    with pytest.raises(ConfigError, match='not a friction law'):
        SimConfig.from_dict({'friction_material': 'granite'}).consist


def test_uniform_train_takes_a_library_law():
    cfg = SimConfig.from_dict({'friction_material': 'disc', 'braked_mass_p': 40000.0})
    assert cfg.consist.choices('friction_material') == ['disc'] * 3
    assert fl.library_laws()['disc'].mu(0.0, 1.0) == pytest.approx(0.37)


def test_library_types_brake_on_real_materials_with_a_braked_weight():
    """Every library type but the paper's coach: a friction law, a label, wagons load-weighed."""
    from train_dynamics.physics.train import TrainSimulator
    from train_dynamics.physics.kernel.layout import VEHICLE
    laws = fl.library_laws()
    for name, fields in consist.library_types().items():
        material = fields.get('friction_material', 'paper')
        if name == 'paper_coach':
            assert material == 'paper'
            continue
        assert material in laws, name
        lam = 100.0 * fields['braked_mass_p'] / fields['mass']
        if fields.get('load_empty_mass', 0.0) > 0.0:       # the label is the loaded one
            lam = 100.0 * fields['braked_mass_p'] / fields['load_full_mass']
            assert 'wagon' in name
        assert 60.0 <= lam <= 150.0, (name, lam)
        if 'wagon' in name:
            assert fields['load_empty_mass'] > 0.0 and fields['load_empty_ratio'] < 1.0
    # an empty and a loaded wagon of one label: the valve's empty setting below 40 t
    path_values = {'initial_speed': 10.0, 'brake_input': 'cylinder_per_coach'}
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'train.yaml'
        path.write_text('vehicles: [{type: freight_wagon_loaded}, {type: freight_wagon_empty}]\n')
        sim = TrainSimulator(SimConfig.from_dict({'consist_file': str(path), **path_values}))
    gain = sim.coach[VEHICLE.BRAKE_GAIN]
    # the label's force at 90 t, the empty wagon with its own rotating masses (2.2 t, not
    # 3.6 t: the allowance of the stop the label is fitted on), then the valve's 0.365
    law = sim.consist.materials[1]
    loaded = fr.braked_mass_normal_force(61000.0, 90000.0, law, 16, fr.P_RESPONSE_TIME,
                                         inertia=0.04 * 90000.0)
    empty = fr.braked_mass_normal_force(61000.0, 90000.0, law, 16, fr.P_RESPONSE_TIME,
                                        inertia=0.10 * 22000.0)
    assert gain[0] * 380000.0 == pytest.approx(loaded, rel=1e-9)
    assert gain[1] * 380000.0 == pytest.approx(0.365 * empty, rel=1e-9)
