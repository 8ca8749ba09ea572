"""
Parameters and the offline command: one validator, one-line errors, nothing left.

Physical bounds and memory, the disk estimate and progress, replay rejecting as the node does,
parameter-file sections, the exact output grid, the schedule time and unwritable output
directories.
"""
from __future__ import annotations

from pathlib import Path

from cli_helpers import assert_one_line_error, params_file, run_cli
import numpy as np
import pytest

from train_dynamics.cli import simulate as simulate_cmd
from train_dynamics.input_kinds import pressure_rejection as input_rejection
from train_dynamics.physics.brake_valve import BrakeValveModel, MAX_SCHEDULE_TIME
from train_dynamics.physics.config import (ConfigError, MAX_SIMULATOR_MEMORY, PARAMETERS,
                                           SimConfig, simulator_memory, validate_value)
from train_dynamics.physics.config.budgets import SIMULATOR_FIXED_BYTES
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.bags import BagRecorder, read_topics
from train_dynamics.recording.cdr import encode_fluid_pressure
from train_dynamics.recording.output_specs import output_disk
from train_dynamics.simulation import runner

REPO = Path(__file__).resolve().parents[2]
CFG = REPO / 'config' / 'paper_3coach.yaml'
ATM = 101325.0


# -- item 2: masses and sizes that crash or eat the memory ------------------------------------
@pytest.mark.parametrize('name, value', [('coach_mass', 1e-20), ('coach_mass', 1e-300),
                                         ('coach_mass', 499.0), ('masses', [45000.0, 1e-20]),
                                         ('brake_propagation_speed', 2e-4),
                                         ('brake_propagation_speed', 1e-5)])
def test_unphysical_masses_and_speeds_are_rejected_by_the_one_validator(name, value):
    with pytest.raises(ConfigError):
        validate_value(name, value)


def test_unphysical_mass_is_one_line_and_exit_2_offline_not_a_traceback(tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', '    coach_mass: 1.0e-20\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert_one_line_error(code, err)
    assert 'coach_mass' in err[0] and not (tmp_path / 'out').exists()


def test_every_bound_is_justified_in_the_description():
    for name in ('coach_mass', 'masses', 'coach_length', 'buffer_stiffness', 'gravity',
                 'brake_propagation_speed', 'max_cylinder_pressure'):
        assert 'bounds' in PARAMETERS[name].description.lower(), name


def test_delay_line_memory_is_estimated_and_refused_past_the_limit():
    ok = {'num_coaches': 1000, 'brake_propagation_speed': 50.0, 'integration_step': 1e-4}
    assert simulator_memory(1000, 25.0, 50.0, 1e-4) < MAX_SIMULATOR_MEMORY
    SimConfig.from_dict(ok)
    big = {'num_coaches': 100000, 'coach_length': 100.0, 'brake_propagation_speed': 50.0,
           'integration_step': 1e-5}
    with pytest.raises(ConfigError, match='delay line') as exc:
        SimConfig.from_dict(big)
    assert 'limit' in str(exc.value) and '\n' not in str(exc.value)


@pytest.mark.parametrize('overrides', [{}, {'num_coaches': 40, 'brake_propagation_speed': 50.0,
                                            'integration_step': 1e-4}])
def test_memory_estimate_bounds_the_simulators_real_arrays(overrides):
    cfg = SimConfig.from_dict(overrides)
    sim = TrainSimulator(cfg)
    real = sum(a.nbytes for a in vars(sim).values() if isinstance(a, np.ndarray))
    estimate = simulator_memory(cfg.n_coaches, cfg.coach_length, cfg.brake_propagation_speed,
                                cfg.integration_step)
    assert real <= estimate <= 4 * real + 2 * SIMULATOR_FIXED_BYTES


# -- item 8: outputs on an exact grid ---------------------------------------------------------
@pytest.mark.parametrize('h, rate, hint', [(0.05, 100.0, '20 Hz'), (0.003, 100.0, '0.0025 s'),
                                           (0.002, 10000.0, '500 Hz')])
def test_publish_rate_off_the_step_grid_is_rejected_with_the_nearest_valid_values(h, rate, hint):
    with pytest.raises(ConfigError, match='whole number of integration steps') as exc:
        SimConfig.from_dict({'integration_step': h, 'publish_rate': rate})
    assert hint in str(exc.value)


def test_default_grid_is_valid_and_outputs_land_exactly_on_it():
    cfg = SimConfig.from_dict({})
    assert (cfg.integration_step, cfg.publish_rate) == (0.002, 100.0)
    steps = runner.output_steps(2.0, cfg.publish_rate, cfg.integration_step)
    assert steps == list(range(0, 1001, 5))
    for h, rate in ((0.001, 250.0), (0.0025, 100.0), (1e-4, 1000.0), (0.05, 20.0)):
        cfg = SimConfig.from_dict({'integration_step': h, 'publish_rate': rate})
        k = runner.output_steps(1.0, rate, h)
        assert np.allclose(np.asarray(k) * h, np.arange(len(k)) / rate, atol=1e-12)


def test_off_grid_rate_is_one_line_exit_2_offline(tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', '    integration_step: 0.05\n    publish_rate: 100.0\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert_one_line_error(code, err)
    assert 'publish_rate' in err[0]


# -- item 9: schedule time, unwritable output ---------------------------------------------------
def test_schedule_time_beyond_the_longest_run_is_rejected_by_the_valve_validator():
    with pytest.raises(ValueError, match='<= 1e\\+09'):
        BrakeValveModel(schedule=['1e300:emergency'])
    BrakeValveModel(schedule=[f'{MAX_SCHEDULE_TIME!r}:emergency'])


def test_schedule_time_1e300_is_one_line_exit_2_offline(tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', valve='    schedule: ["1e300:emergency"]\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert_one_line_error(code, err)
    assert 'schedule[0]' in err[0]


@pytest.mark.parametrize('where', ['/proc/train_dynamics_test_out', 'file/sub'])
def test_plot_and_compare_into_an_unwritable_directory_are_one_line_exit_2(
        tmp_path, capsys, where):
    (tmp_path / 'file').write_text('x')
    out = where if where.startswith('/') else tmp_path / where
    code, err = run_cli(capsys, 'plot', '/work/baseline/paper60' if Path(
        '/work/baseline/paper60').exists() else tmp_path, '--output', out)
    assert_one_line_error(code, err)
    code, err = run_cli(capsys, 'compare', '--params', CFG, '--duration', 0.5, '--output', out,
                        '-q')
    assert_one_line_error(code, err)
    assert 'cannot write figures' in err[0]


def test_compare_removes_the_directory_it_created_when_it_fails(tmp_path, capsys, monkeypatch):
    from train_dynamics.cli import compare

    def boom(*args, **kwargs):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(compare, 'plot_comparison', boom)
    code, err = run_cli(capsys, 'compare', '--params', CFG, '--duration', 0.2, '--output',
                        tmp_path / 'a' / 'b', '--steps', '0.002', '--scale-factors', '1000', '-q')
    assert_one_line_error(code, err)
    assert not (tmp_path / 'a').exists()


# -- item 4: disk estimate, confirmation, progress ---------------------------------------------
def test_simulate_duration_1e9_is_refused_up_front_with_the_disk_estimate(tmp_path, capsys):
    code, err = run_cli(capsys, 'simulate', '--params', CFG, '--duration', 1e9, '--output',
                        tmp_path / 'out')
    assert_one_line_error(code, err)
    assert 'TB' in err[0] and not (tmp_path / 'out').exists()
    assert list(tmp_path.iterdir()) == []


def test_a_large_bag_needs_allow_large(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(simulate_cmd, 'LARGE_BAG', 10_000)
    code, err = run_cli(capsys, 'simulate', '--params', CFG, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert_one_line_error(code, err)
    assert '--allow-large' in err[0] and not (tmp_path / 'out').exists()
    code, err = run_cli(capsys, 'simulate', '--params', CFG, '--duration', 1, '--output',
                        tmp_path / 'out', '-q', '--allow-large')
    assert code == 0 and (tmp_path / 'out' / 'metadata.yaml').is_file()


def test_disk_estimate_is_close_to_the_real_bag(tmp_path, capsys):
    for n in (3, 60):
        p = params_file(tmp_path / f'p{n}.yaml', raw=(
            f'train_dynamics:\n  ros__parameters:\n    num_coaches: {n}\n'))
        out = tmp_path / f'b{n}'
        assert run_cli(capsys, 'simulate', '--params', p, '--duration', 2, '--output', out,
                       '-q')[0] == 0
        real = sum(f.stat().st_size for f in out.iterdir())
        estimate = output_disk(SimConfig.from_dict({'num_coaches': n}), 2.0)
        assert 0.8 * real <= estimate <= 1.3 * real, (n, estimate, real)


def test_progress_is_paced_by_wall_time_not_by_the_fraction_of_the_run(monkeypatch):
    cfg = SimConfig.from_dict({})
    inputs = runner.InputSchedule('pipe_head', [], BrakeValveModel(schedule=['0.5:emergency']))
    calls: list[float] = []
    monkeypatch.setattr(runner, 'PROGRESS_PERIOD', 1e9)      # never within a short run
    runner.run_simulation(cfg, 2.0, inputs, on_sample=lambda s: None, progress=calls.append)
    assert calls == [1.0]
    calls.clear()
    monkeypatch.setattr(runner, 'PROGRESS_PERIOD', 0.0)      # at every chunk
    runner.run_simulation(cfg, 2.0, inputs, on_sample=lambda s: None, progress=calls.append)
    assert len(calls) > 100 and calls == sorted(calls) and calls[-1] == 1.0


# -- item 5: the replay rejects what the node rejects -------------------------------------------
@pytest.mark.parametrize('absolute, reason', [(float('nan'), 'non_finite'), (-1.0, 'negative'),
                                              (1e12, 'too_high'), (2.0e6 + 1, 'too_high')])
def test_one_rejection_rule(absolute, reason):
    assert input_rejection(absolute)[0] == reason
    assert input_rejection(2.0e6) is None and input_rejection(ATM) is None


def test_offline_replay_rejects_a_pressure_the_node_rejects_as_too_high(tmp_path, capsys):
    bag = tmp_path / 'in'
    with BagRecorder(bag) as rec:
        rec.add_topic('brake_pipe/pressure', 'sensor_msgs/msg/FluidPressure')
        for k, p in enumerate([500000.0 + ATM, 1e12, 0.0 + ATM]):
            t_ns = k * 200_000_000
            rec.write('brake_pipe/pressure', t_ns, encode_fluid_pressure(t_ns, p))
    p = params_file(tmp_path / 'p.yaml', '    brake_input: pipe_head\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--input', bag, '--duration', 1,
                        '--output', tmp_path / 'out', '-q')
    assert code == 0
    assert any('1 message(s)' in line and 'too_high' in line for line in err), err
    used = [m.fluid_pressure for _, _, m in read_topics(tmp_path / 'out',
                                                        ['brake_pipe/pressure'])]
    assert 1e12 not in used and len(used) == 2
    cyl = [max(m.position) for _, _, m in read_topics(tmp_path / 'out', ['brake_cylinders'])]
    assert max(cyl) <= PARAMETERS['max_cylinder_pressure'].default


# -- item 6: parameter-file sections ---------------------------------------------------------
def test_a_typo_in_the_only_section_is_an_error_offline(tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', raw='train_dynamic:\n  ros__parameters:\n'
                    '    num_coaches: 4\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert_one_line_error(code, err)
    assert "'train_dynamic'" in err[0] and 'train_dynamics' in err[0]


def test_an_unknown_section_beside_the_nodes_is_a_warning_naming_the_known_ones(
        tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', raw=CFG.read_text()
                    + 'train_dynamic:\n  ros__parameters:\n    num_coaches: 4\n')
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 0.2, '--output',
                        tmp_path / 'out', '-q')
    assert code == 0
    assert len(err) == 1 and 'warning' in err[0] and "'train_dynamic'" in err[0]
    assert 'train_dynamics, brake_valve, /**' in err[0]


def test_wildcard_section_applies_to_both_nodes_and_other_nodes_keys_are_ignored(
        tmp_path, capsys):
    p = params_file(tmp_path / 'p.yaml', raw=(
        '/**:\n  ros__parameters:\n    use_sim_time: false\n    num_coaches: 4\n'
        '    schedule: ["0.3:emergency"]\n    publish_clock: false\n'))
    code, err = run_cli(capsys, 'simulate', '--params', p, '--duration', 1, '--output',
                        tmp_path / 'out', '-q')
    assert (code, err) == (0, [])
    msgs = [m for _, _, m in read_topics(tmp_path / 'out', ['couplers'])]
    assert len(msgs[0].name) == 3                                # num_coaches 4
    head = [(m.header.stamp.nanosec, m.fluid_pressure)
            for _, _, m in read_topics(tmp_path / 'out', ['brake_pipe/pressure'])]
    assert min(p for _, p in head) < 500000.0    # vented from 0.3 s: the /** schedule is used
