"""The parameter table and ROS 2 parameter files (shared by sim_node and the offline command)."""
import math
from pathlib import Path

import pytest

from train_dynamics.physics.config import (ConfigError, load_param_file, markdown_table,
                                           PARAMETERS, SimConfig, validate_value)
from train_dynamics.physics.train import TrainSimulator

REPO = Path(__file__).resolve().parents[1]


def test_contract_names_and_defaults(contract_defaults):
    for name, default in contract_defaults.items():
        assert PARAMETERS[name].default == default, name
    for name in ('scale_factor', 'adhesion_coefficient', 'integration_step'):
        assert name in PARAMETERS


def test_paper_parameter_file_loads_with_scientific_notation(tmp_path):
    cfg = load_param_file(str(REPO / 'config' / 'paper_3coach.yaml'))
    assert cfg.buffer_stiffness == 2.8e6 and isinstance(cfg.buffer_stiffness, float)
    assert cfg.n_coaches == 3 and cfg.initial_speed == pytest.approx(160 / 3.6, rel=1e-4)
    f = tmp_path / 'p.yaml'
    f.write_text('/**:\n  ros__parameters:\n    use_sim_time: false\n    coach_mass: 5e4\n'
                 'train_dynamics:\n  ros__parameters:\n    num_coaches: 7\n')
    cfg = load_param_file(str(f))
    assert cfg.coach_mass == 50000.0 and cfg.n_coaches == 7


@pytest.mark.parametrize('text, words', [
    ('train_dynamics:\n  ros__parameters:\n    no_such: 1\n', 'unknown parameter'),
    ('train_dynamics:\n  ros__parameters:\n    scale_factor: 0.0\n', 'must be > 0'),
    ('train_dynamics:\n  ros__parameters:\n    model_type: cubic\n', 'not one of'),
    ('train_dynamics:\n  ros__parameters:\n    num_coaches: 1\n', '>= 2'),
    ('train_dynamics:\n  ros__parameters:\n    masses: [45000.0, -1.0]\n', 'masses[1]'),
    ('train_dynamics:\n  ros__parameters:\n    coach_mass: .nan\n', 'finite'),
    ('train_dynamics:\n  ros__parameters:\n    buffer_friction: 3.0e6\n', 'k_f < k_e'),
    ('train_dynamics:\n  ros__parameters:\n    num_coaches: "3"\n', 'integer'),
    ('train_dynamics: [\n', 'cannot read'),
    ('- 1\n- 2\n', 'not a ROS 2 parameter file'),
])
def test_bad_parameter_files_give_one_line_reasons(tmp_path, text, words):
    f = tmp_path / 'bad.yaml'
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_param_file(str(f))
    assert words in str(err.value) and '\n' not in str(err.value)


def test_missing_file():
    with pytest.raises(ConfigError, match='not found'):
        load_param_file('/nonexistent/params.yaml')


@pytest.mark.parametrize('name, value', [
    ('scale_factor', -1.0), ('scale_factor', math.nan), ('scale_factor', math.inf),
    ('scale_factor', 'big'), ('num_coaches', 2.5), ('num_coaches', True),
    ('publish_clock', 1), ('masses', [1.0, 'x']), ('masses', 'heavy'),
    ('brake_input', 'magic'), ('integration_step', 0.0),
])
def test_validate_value_rejects(name, value):
    with pytest.raises(ConfigError):
        validate_value(name, value)


def test_cylinder_tables_checked():
    with pytest.raises(ConfigError, match='same length'):
        SimConfig.from_dict({'cylinder_fill_time': [0.0, 1.0], 'cylinder_fill_fraction': [0.0]})
    with pytest.raises(ConfigError, match='rise strictly'):
        SimConfig.from_dict({'cylinder_fill_time': [0.0, 1.0],
                             'cylinder_fill_fraction': [0.0, 0.5]})
    cfg = SimConfig.from_dict({'brake_regime': 'G'})
    assert cfg.fill_table()[0][-1] == pytest.approx(36.0)


def test_readme_parameter_table_is_current():
    """Check the README's table: python -m train_dynamics.physics.config.docs generates it."""
    readme = (REPO / 'README.md').read_text(encoding='utf-8')
    assert markdown_table() in readme, 'regenerate: python -m train_dynamics.physics.config.docs'


SCENARIOS = sorted(p.name for p in (REPO / 'config').glob('*.yaml')
                   if not p.name.startswith('consist_') and p.name != 'vehicles.yaml')


@pytest.mark.parametrize('name', SCENARIOS)
def test_every_shipped_scenario_loads_and_runs(name):
    """Each parameter file in config/ passes the validator and runs its first 0.1 s."""
    cfg = load_param_file(str(REPO / 'config' / name))
    sim = TrainSimulator(cfg)
    sim.advance_to(0.1)
    assert sim.fault is None and sim.t == pytest.approx(0.1)
    assert all(math.isfinite(v) for v in sim.v)
