"""The parameter table and ROS 2 parameter files (shared by sim_node and the offline command)."""
import dataclasses
import math
from pathlib import Path

import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig, validate_value
from train_dynamics.physics.config.docs import markdown_table
from train_dynamics.physics.train import TrainSimulator

REPO = Path(__file__).resolve().parents[2]


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


def test_docs_parameter_table_is_current():
    """Check docs/parameters.md's table: python -m train_dynamics.physics.config.docs makes it."""
    page = (REPO / 'docs' / 'parameters.md').read_text(encoding='utf-8')
    assert markdown_table() in page, 'regenerate: python -m train_dynamics.physics.config.docs'


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


# -- the typed configuration -------------------------------------------------------------------
_ANNOTATION = {'double': 'float', 'integer': 'int', 'string': 'str', 'bool': 'bool',
               'double_array': 'list[float]'}


def test_simconfig_declares_every_parameter_with_the_tables_type_and_default():
    declared = dataclasses.fields(SimConfig)
    assert [f.name for f in declared] == list(PARAMETERS)       # same set, table order
    for f in declared:
        spec = PARAMETERS[f.name]
        default = f.default_factory() if f.default is dataclasses.MISSING else f.default
        assert default == spec.default and type(default) is type(spec.default), f.name
        assert f.type == _ANNOTATION[spec.kind], f.name
    cfg = SimConfig.from_dict({'scale_factor': 5})
    assert cfg.scale_factor == 5.0 and isinstance(cfg.scale_factor, float)
    assert cfg.values['scale_factor'] == 5.0 and list(cfg.values) == list(PARAMETERS)


def test_a_configuration_never_changes_a_live_value_makes_a_new_one():
    cfg = SimConfig.from_dict({})
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.num_coaches = 5
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.scale_factor = 20.0                        # live or not: never in place
    live = cfg.replace(scale_factor=20)
    assert live.scale_factor == 20.0 and cfg.scale_factor == 1000.0
    assert live.consist is cfg.consist                 # a live change reads no file
    assert cfg.replace(num_coaches=5).n_coaches == 5 and cfg.n_coaches == 3
    with pytest.raises(ConfigError, match='unknown parameter'):
        cfg.replace(no_such=1)
    with pytest.raises(ConfigError, match='k_f < k_e'):
        cfg.replace(scale_factor=20, buffer_friction=3.0e6)    # checked as a whole


CONSIST = 'vehicles: [{type: paper_coach, count: %d}]\n'


def test_replace_keeps_the_parsed_consist_unless_a_consist_value_changes(tmp_path):
    """A deleted consist file does not affect a built configuration nor its replace()."""
    path = tmp_path / 'train.yaml'
    path.write_text(CONSIST % 4)
    cfg = SimConfig.from_dict({'consist_file': str(path)})
    assert cfg.n_coaches == 4
    path.unlink()
    other = cfg.replace(scale_factor=20.0, real_time_factor=0.0, initial_speed=10.0)
    assert other.consist is cfg.consist and other.n_coaches == 4
    assert TrainSimulator(other).n == 4
    with pytest.raises(ConfigError, match='not found'):      # a consist value: read again
        cfg.replace(davis_a=100.0)
    path.write_text(CONSIST % 5)
    assert cfg.replace(coach_mass=50000.0).n_coaches == 5
    assert cfg.replace(consist_file='').consist is not cfg.consist
    uniform = SimConfig.from_dict({'num_coaches': 6})
    assert uniform.replace(gravity=9.8).consist is uniform.consist
    assert uniform.replace(num_coaches=7).consist.n == 7


def test_relative_consist_file_one_rule_for_node_and_offline(tmp_path, monkeypatch):
    """From a parameter file: its folder, never the cwd's same-named file; else the cwd."""
    folder, cwd = tmp_path / 'params', tmp_path / 'cwd'
    folder.mkdir()
    cwd.mkdir()
    (folder / 'mine.yaml').write_text(CONSIST % 2)
    (cwd / 'mine.yaml').write_text(CONSIST % 3)
    params = folder / 'p.yaml'
    params.write_text('train_dynamics:\n  ros__parameters:\n    consist_file: mine.yaml\n')
    monkeypatch.chdir(cwd)
    cfg = load_param_file(str(params))
    assert cfg.n_coaches == 2 and cfg.consist_file == str(folder / 'mine.yaml')
    assert SimConfig.from_dict({'consist_file': 'mine.yaml'}).n_coaches == 3     # set: cwd
    # the node: the same absolute path given after the file, so later arguments still win
    from train_dynamics.ros.executor import file_input_args
    from train_dynamics.ros.sim_node import SPECS
    args = ['sim_node', '--ros-args', '--params-file', str(params), '-p', 'duration:=1.0']
    assert file_input_args(args, 'train_dynamics', SPECS) == [
        *args[:4], '-p', f"consist_file:='{folder / 'mine.yaml'}'", *args[4:]]
    (folder / 'mine.yaml').unlink()          # not next to the file: config/, never the cwd
    with pytest.raises(ConfigError, match="p.yaml: consist_file: 'mine.yaml' not found"):
        load_param_file(str(params))
    with pytest.raises(ConfigError, match="p.yaml: consist_file: 'mine.yaml' not found"):
        file_input_args(args, 'train_dynamics', SPECS)
