"""Consist files: the vehicle library, defaults from parameters, connection rule, errors."""
import numpy as np
import pytest

from train_dynamics.physics.config import ConfigError, consist, files, SimConfig


def write(tmp_path, text, name='train.yaml'):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def values(**over):
    return SimConfig.from_dict(over).values


def test_library_holds_the_required_types_and_the_papers_coach_exactly():
    lib = consist.library_types()
    for name in ('paper_coach', 'electric_passenger_locomotive', 'heavy_freight_locomotive',
                 'freight_wagon_loaded', 'freight_wagon_empty'):
        assert name in lib
    assert lib['paper_coach'] == {
        'mass': 45000.0, 'length': 25.0, 'buffer_stiffness': 5.6e6, 'buffer_friction': 2.8e6,
        'draw_gear_stiffness': 10.92e6, 'draw_gear_friction': 4.86e6,
        'adhesion_coefficient': 0.1, 'max_cylinder_pressure': 380000.0, 'brake_regime': 'P'}


def test_coupling_rule_for_a_mixed_pair_of_ends(tmp_path):
    path = write(tmp_path, """
vehicle_types:
  a: {buffer_stiffness: 2.0e6, buffer_friction: 1.0e6, draw_gear_stiffness: 6.0e6,
      draw_gear_friction: 0.0, blocked_stiffness: 1.0e8, buffer_stroke: 0.10,
      draw_gear_stroke: 0.05, buffer_slack: 0.0, draw_gear_slack: 0.02}
  b: {buffer_stiffness: 3.0e6, buffer_friction: 1.0e6, draw_gear_stiffness: 3.0e6,
      draw_gear_friction: 0.0, blocked_stiffness: 3.0e8, buffer_stroke: 0.12,
      draw_gear_stroke: 0.07, buffer_slack: 0.01, draw_gear_slack: 0.0}
vehicles: [{type: a}, {type: b}, {type: b}]
""")
    c = consist.load_consist(path, values())
    # loading branches 3e6 and 4e6 in series: 12/7e6; unloading 1e6 and 2e6: 2/3e6
    load, unload = 12.0e6 / 7.0, 2.0e6 / 3.0
    assert c.coupler('buffer_stiffness')[0] == pytest.approx(0.5 * (load + unload))
    assert c.coupler('buffer_friction')[0] == pytest.approx(0.5 * (load - unload))
    assert c.coupler('draw_gear_stiffness')[0] == pytest.approx(2.0e6)      # 6e6 + 3e6 in series
    assert c.coupler('draw_gear_friction')[0] == 0.0
    assert c.coupler('blocked_stiffness')[0] == pytest.approx(0.75e8)
    # travels add
    assert c.coupler('buffer_stroke')[0] == pytest.approx(0.22)
    assert c.coupler('draw_gear_stroke')[0] == pytest.approx(0.12)
    assert c.coupler('buffer_slack')[0] == pytest.approx(0.01)
    assert c.coupler('draw_gear_slack')[0] == pytest.approx(0.02)
    # two identical ends: half their stiffness and friction, twice their travel, exactly
    for f in consist.COUPLER_FIELDS:
        factor = 0.5 if f in consist.SERIES else 2.0
        assert c.coupler(f)[1] == factor * c[f][2]
    assert c.coupler_array().shape == (9, 2)


def test_fields_left_out_take_the_parameters_and_overrides_win(tmp_path):
    path = write(tmp_path, """
vehicles:
  - {type: paper_coach, count: 2}
  - {type: paper_coach, mass: 50000.0, davis_a: 700.0}
""")
    c = consist.load_consist(path, values(davis_a=123.0, rotating_mass_factor=0.05))
    assert c.n == 3
    assert list(c['mass']) == [45000.0, 45000.0, 50000.0]
    assert list(c['davis_a']) == [123.0, 123.0, 700.0]
    assert list(c['rotating_mass_factor']) == [0.05] * 3
    assert c.regimes == ['P'] * 3
    assert c.locomotives == []


def test_types_in_the_file_add_to_the_library(tmp_path):
    path = write(tmp_path, """
vehicle_types:
  shunter: {mass: 60000.0, length: 10.0, max_tractive_force: 200000.0, max_power: 5.0e5}
vehicles: [{type: shunter}, {type: freight_wagon_empty, count: 3}]
""")
    c = consist.load_consist(path, values())
    assert c.types == ['shunter'] + ['freight_wagon_empty'] * 3
    assert c.locomotives == [0]
    assert c.regimes[1] == 'G'


def test_uniform_train_of_the_parameters():
    c = consist.consist_of(values(num_coaches=4))
    assert c.n == 4 and list(c['mass']) == [45000.0] * 4
    assert list(c.coupler('buffer_stiffness')) == [2.8e6] * 3
    c = consist.consist_of(values(masses=[40000.0, 50000.0]))
    assert list(c['mass']) == [40000.0, 50000.0]


def test_relative_path_resolves_against_base_dir_then_config(tmp_path, monkeypatch):
    write(tmp_path, 'vehicles: [{type: paper_coach, count: 2}]\n', 'mine.yaml')
    assert files.resolve_path('mine.yaml', str(tmp_path)) == tmp_path / 'mine.yaml'
    monkeypatch.chdir(tmp_path)             # without a base folder: the working directory
    assert consist.consist_of(values(consist_file='mine.yaml')).n == 2
    # the library itself is found in config/ from anywhere
    assert files.resolve_path('vehicles.yaml', str(tmp_path)).name == 'vehicles.yaml'


@pytest.mark.parametrize('text, words', [
    ('vehicles: [{type: paper_coach}, {type: nope}]', ['vehicles[2]', "'nope'"]),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, mas: 1.0}]',
     ['vehicles[2]', 'paper_coach', "'mas'"]),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, mass: -5.0}]',
     ['vehicles[2]', 'mass', 'must be >= 500']),
    ('vehicles: [{type: paper_coach, count: 0}, {type: paper_coach}]', ['vehicles[1]', 'count']),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, brake_regime: X}]',
     ['vehicles[2]', 'brake_regime']),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, buffer_friction: 6.0e6}]',
     ['vehicle 2', 'buffer_friction']),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, rear: {buffer_friction: 6.0e6}}]',
     ['vehicle 2', 'rear end', 'buffer_friction']),
    ('vehicles: [{type: paper_coach}, {type: paper_coach, front: {mass: 1.0}}]',
     ['vehicles[2]', 'front', 'mass']),
    ('couplings: {davis_a: 1.0}\nvehicles: [{type: paper_coach}, {type: paper_coach}]',
     ['couplings', 'davis_a']),
    ('vehicle_types: {w: {length: 0.0}}\nvehicles: [{type: w}, {type: w}]',
     ["vehicle type 'w'", 'length']),
    ('vehicles: [{type: paper_coach}]', ['at least 2']),
    ('vehicles: []', ['non-empty']),
    ('trains: []', ['unknown key']),
])
def test_errors_name_the_vehicle_and_the_field(tmp_path, text, words):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        consist.load_consist(path, values())
    msg = str(err.value)
    assert '\n' not in msg
    for w in words:
        assert w in msg


def test_missing_consist_file_is_a_clear_error(tmp_path):
    with pytest.raises(ConfigError, match='not found'):
        consist.consist_of({'consist_file': 'nowhere.yaml'}, str(tmp_path))
    with pytest.raises(ConfigError, match='not found'):
        SimConfig.from_dict({'consist_file': 'nowhere.yaml'})


def test_series_of_springs_with_zero_stiffness():
    out = consist.series(np.array([0.0, 2.0, 2.0]), np.array([1.0, 2.0, 6.0]))
    assert list(out) == [0.0, 1.0, 1.5]


def test_the_per_vehicle_declarations_elsewhere_name_fields_of_the_table():
    """The table holds each vehicle field once; the kernel's row maps only refer to it."""
    from train_dynamics.physics.config import VEHICLE_PARAMETERS
    from train_dynamics.physics.train import TrainSimulator

    assert consist.VEHICLE_FIELDS == tuple(VEHICLE_PARAMETERS)
    assert consist.PARAM_OF == {'mass': 'coach_mass', 'length': 'coach_length'}
    connections = {f for f, s in VEHICLE_PARAMETERS.items() if s.connection}
    assert set(consist.END_FIELDS) == connections
    # the kernel's constants are joined by the linear rules; the characteristics' figures
    # (preload, final force: equal force; energy: added) make the coupling's tables
    equal_force = {f for f, s in VEHICLE_PARAMETERS.items() if s.connection == 'equal force'}
    assert set(consist.COUPLER_FIELDS) == {*consist.SERIES, *consist.ADDED} - set(
        consist.CHARACTERISTIC_FIELDS)
    assert set(consist.CHARACTERISTIC_FIELDS) - equal_force == {'buffer_energy',
                                                                'draw_gear_energy'}
    assert set(TrainSimulator._VEHICLE_ROWS) <= set(VEHICLE_PARAMETERS)
    assert {*TrainSimulator._TRAVEL_ROWS, *TrainSimulator._COUPLER_ROWS} == set(
        consist.COUPLER_FIELDS)


#: parameters a field's consist needs to be valid (remote brake valves: the pneumatic brake)
_CONTEXT = {'remote': {'brake_model': 'pneumatic'}}

#: the tabulated curve a field naming one names (stored as its number in the consist)
_CURVE = ('characteristics: {c: {stroke: [0.0, 0.1], loading: [0.0, 1.0e5], '
          'unloading: [0.0, 5.0e4]}}\n')


def _distinctive(spec):
    """Return a valid value of the field ``spec`` declares that is not its default."""
    if spec.name == 'friction_material':      # a friction law of the vehicle library
        return 'disc'
    if spec.choices:
        return next(c for c in spec.choices if c != spec.default)
    if isinstance(spec.default, bool):
        return not spec.default
    if spec.kind == 'integer':
        return spec.default + 1
    if spec.kind == 'string':             # a tabulated curve's name (_CURVE defines it)
        return 'c'
    value = spec.default * 1.1 + 0.01
    return value if spec.high is None or value <= spec.high else (spec.default + spec.high) / 2


def _vehicle_fields():
    from train_dynamics.physics.config import VEHICLE_PARAMETERS
    return list(VEHICLE_PARAMETERS.items())


@pytest.mark.parametrize('field, spec', _vehicle_fields(), ids=[f for f, _ in _vehicle_fields()])
def test_one_declaration_per_vehicle_field(tmp_path, field, spec):
    """
    Check that a per-vehicle field is its ParamSpec alone.

    The consist takes it, the docs list it, its kernel row exists and a simulator carries a
    consist's value of it there.
    """
    from pathlib import Path

    from train_dynamics.physics.kernel import compiler, layout
    from train_dynamics.physics.train import TrainSimulator

    page = (Path(__file__).resolve().parents[2] / 'docs' / 'parameters.md').read_text()
    assert f'| `{field}` | `{spec.name}` |' in page, 'the per-vehicle table of the docs'
    value = _distinctive(spec)
    # a force limit needs its power limit (consist.check_traction_power)
    power = dict(consist._POWER_PAIRS).get(field)
    extra = f', {power}: 1.0e6' if power else ''
    if field == 'friction_material':      # a material other than paper needs a force level
        extra += ', braked_mass_p: 40000.0'
    if field.startswith('load_'):         # a load valve acts on a friction material
        extra += (', friction_material: disc, brake_cylinder_area: 0.05, rigging_ratio: 5.0'
                  ', load_changeover_mass: 3e4')
        extra += ', load_empty_mass: 20000.0' if field != 'load_empty_mass' else ''
        extra = extra.replace(', load_changeover_mass: 3e4', '') \
            if field == 'load_changeover_mass' else extra
    if field == 'piston_stroke':          # a stroke needs the pistons' area
        extra += ', brake_cylinder_area: 0.0507'
    curve = _CURVE if field in consist.CURVE_FIELDS else ''
    path = write(tmp_path, f'{curve}vehicle_types: {{w: {{{field}: {value!r}{extra}}}}}\n'
                           'vehicles: [{type: w, count: 3}]\n')
    cfg = SimConfig.from_dict({'consist_file': path, **_CONTEXT.get(field, {})})
    kernel_value = value
    if field == 'friction_material':    # a law's code: its index in the consist's laws
        assert cfg.consist.choices(field) == [value] * 3
        kernel_value = 1.0              # paper is 0, the first law used 1
    elif spec.choices:          # a choice reaches the kernel as its index in the choices
        assert cfg.consist.choices(field) == [value] * 3
        kernel_value = float(spec.choices.index(value))
    elif field in consist.CURVE_FIELDS:     # the curve's number: the first of the consist
        assert list(cfg.consist[field]) == [1.0] * 3
    else:
        assert list(cfg.consist[field]) == [value] * 3
    if spec.row:
        assert spec.row in layout.VEHICLE._fields
        assert spec.row in compiler.table_kernel_rows()      # the kernel cache's key
        sim = TrainSimulator(cfg)
        assert list(sim.coach[getattr(layout.VEHICLE, spec.row)]) == [kernel_value] * 3
        sim.reset()
        assert list(sim.coach[getattr(layout.VEHICLE, spec.row)]) == [kernel_value] * 3


def test_the_kernel_layout_has_a_row_for_each_field_that_declares_one_and_no_other():
    """VEHICLE = the derived rows, then the rows of the table in table order, nothing else."""
    from train_dynamics.physics.config.table import KERNEL_ROWS
    from train_dynamics.physics.kernel import compiler, layout

    assert layout.VEHICLE._fields == (*layout.DERIVED_VEHICLE_ROWS, *KERNEL_ROWS.values())
    assert compiler.table_kernel_rows() == list(KERNEL_ROWS.values())
    assert not set(layout.DERIVED_VEHICLE_ROWS) & set(KERNEL_ROWS.values())
