"""
``train-dynamics report`` on a bag of the offline command and on one recorded by sim_node.

The report's metrics equal those computed live during the run (the same accumulator fed by
the run loop), and the node's recording gives the same metrics as its offline replay.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from train_dynamics import topics
from train_dynamics.cli.offline import main
from train_dynamics.cli.scenario import valve_from_param_file
from train_dynamics.param_files import load_param_file
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.recording.plots import png_size
from train_dynamics.simulation.runner import InputSchedule, run_simulation, schedule_events
import yaml

PAPER = os.path.join(
    os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
    'config', 'paper_3coach.yaml')
FIGURES = ('force_envelope.png', 'worst_force.png', 'vehicles.png', 'coupler_force.png',
           'coaches.png')


def same_numbers(a: dict, b: dict, rel: float = 1e-9) -> None:
    """Assert the train-level metrics of two reports agree (times to 1 us)."""
    assert set(a) == set(b)
    for k in a:
        if isinstance(a[k], float) and isinstance(b[k], float):
            assert a[k] == pytest.approx(b[k], rel=rel, abs=1e-6), k
        else:
            assert a[k] == b[k], k


def test_report_of_an_offline_bag_equals_the_live_metrics(tmp_path):
    bag, out = tmp_path / 'run', tmp_path / 'report'
    assert main(['simulate', '--params', PAPER, '--duration', '12', '--output', str(bag),
                 '-q']) == 0
    assert main(['report', str(bag), '--output', str(out), '--params', PAPER,
                 '--coupler-force-limit', '4000', '-q']) == 0
    doc = json.loads((out / 'summary.json').read_text())
    cfg = load_param_file(PAPER)
    live = RunMetrics.for_run(cfg, coupler_force_limit=4000.0)
    inputs = InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(PAPER, cfg), 'valve')
    run_simulation(cfg, 12.0, inputs, on_sample=live.sample)
    expected = live.result()
    for k in ('max_tension_every_step', 'max_compression_every_step'):
        # the simulator's every-step envelope; a bag has its samples only
        assert doc['train'][k] is None
        assert expected['train'][k] >= expected['train'][k.replace('_every_step', '')] > 0.0
        doc['train'][k] = expected['train'][k]
    same_numbers(doc['train'], expected['train'])
    assert doc['source']['parameters'] == PAPER
    assert [c['name'] for c in doc['couplers']] == ['coupler_1', 'coupler_2']
    # the paper's emergency braking: a compression of ~4.6 kN crosses the 4 kN limit once,
    # in the rear coupler, shortly after the brake application at 1 s
    assert [(e['name'], e['kind']) for e in doc['crossings']] == [('coupler_2',
                                                                   'coupler_force')]
    assert 1.0 < doc['crossings'][0]['t'] < 2.0 and doc['crossings'][0]['value'] < -4000.0
    md = (out / 'summary.md').read_text()
    assert 'Worst coupler force: compression' in md and 'WARN coupler_2' in md
    for name in FIGURES:
        assert png_size(out / name)[0] > 100, name


def test_report_without_parameters_has_no_limits(tmp_path, capsys):
    bag, out = tmp_path / 'run', tmp_path / 'report'
    assert main(['simulate', '--params', PAPER, '--duration', '3', '--output', str(bag),
                 '-q']) == 0
    assert main(['report', str(bag), '--output', str(out)]) == 0
    doc = json.loads((out / 'summary.json').read_text())
    assert doc['settings']['coupler_force_limit'] == 0.0
    assert doc['train']['coupler_dissipated'] is None and doc['crossings'] == []
    assert 'max compression' in capsys.readouterr().out
    assert main(['report', str(tmp_path / 'missing'), '--output', str(out)]) == 2


def test_report_of_a_bag_recorded_by_sim_node(tmp_path):
    """
    sim_node (subprocess, loopback DDS) brakes on a stale input and records its run.

    The report takes the parameters the node recorded; the node's recorded inputs replayed
    by ``simulate --input`` give the very same metrics.
    """
    bag = tmp_path / 'node_bag'
    cmd = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args',
           '--params-file', PAPER, '-p', f'record_bag:={bag}', '-p', 'duration:=6.0',
           '-p', 'real_time_factor:=4.0', '-p', 'input_timeout:=0.2',
           '-p', 'on_input_timeout:=emergency', '-p', 'coupler_force_limit:=2000.0']
    proc = subprocess.run(cmd, cwd=str(tmp_path), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = tmp_path / 'report'
    assert main(['report', str(bag), '--output', str(out), '-q']) == 0
    doc = json.loads((out / 'summary.json').read_text())
    tr = doc['train']
    assert doc['source']['parameters'] == 'bag custom_data'
    assert doc['settings']['coupler_force_limit'] == 2000.0     # as the node ran
    assert len(doc['vehicles']) == 3 and tr['t_end'] == pytest.approx(6.0)
    assert 0.0 < tr['brake_onset_time'] < 5.0 and tr['max_compression'] > 2000.0
    assert tr['limit_crossings'] >= 1
    for name in FIGURES[:3]:
        assert png_size(out / name)[0] > 100
    # replay the node's recorded inputs offline: the same run, the same metrics
    params = tmp_path / 'node_params.yaml'
    recorded = json.loads(yaml.safe_load((bag / 'metadata.yaml').read_text())
                          ['rosbag2_bagfile_information']['custom_data']['parameters'])
    recorded['record_bag'] = ''
    params.write_text(yaml.safe_dump({'train_dynamics': {'ros__parameters': recorded}}))
    replay, out2 = tmp_path / 'replay', tmp_path / 'report2'
    assert main(['simulate', '--params', str(params), '--input', str(bag), '--duration',
                 '6', '--output', str(replay), '-q']) == 0
    assert main(['report', str(replay), '--output', str(out2), '--params', str(params),
                 '-q']) == 0
    same_numbers(json.loads((out2 / 'summary.json').read_text())['train'], tr, rel=1e-6)


def test_report_reads_slack_and_strokes_from_the_consist_as_the_simulator_does(tmp_path):
    """The slack run-in scenario: the report counts the simulator's own free-play impacts."""
    from train_dynamics.physics.train import TrainSimulator

    params = os.path.join(os.path.dirname(PAPER), 'slack_runin.yaml')
    bag, out = tmp_path / 'run', tmp_path / 'report'
    assert main(['simulate', '--params', params, '--duration', '25', '--output', str(bag),
                 '-q']) == 0
    assert main(['report', str(bag), '--output', str(out), '--params', params, '-q']) == 0
    doc = json.loads((out / 'summary.json').read_text())
    cfg = load_param_file(params)
    live = RunMetrics.for_run(cfg, TrainSimulator(cfg))
    inputs = InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(params, cfg), 'valve')
    inputs.commands = schedule_events(cfg)
    run_simulation(cfg, 25.0, inputs, on_sample=live.sample)
    expected = live.result()['train']
    assert expected['impact_count'] > 0
    assert doc['train']['impact_count'] == expected['impact_count']
    assert doc['train']['blocking_count'] == expected['blocking_count']


def test_report_fatigue_counts_every_sample_of_the_bag(tmp_path):
    """Check report --fatigue: each coupler's DEL and cycle count equal the whole history's."""
    import numpy as np

    from train_dynamics.physics.fatigue import cycle_count, damage_equivalent_load, rainflow
    from train_dynamics.recording.bags import read_topics
    bag, out = tmp_path / 'run', tmp_path / 'report'
    assert main(['simulate', '--params', PAPER, '--duration', '12', '--output', str(bag),
                 '-q']) == 0
    assert main(['report', str(bag), '--output', str(out), '--fatigue', '-q']) == 0
    found = json.loads((out / 'summary.json').read_text())['fatigue']
    forces = np.array([list(m.effort) for _, _, m in read_topics(bag, ['couplers'])])
    above = 0.1 * np.abs(forces).max()
    assert found['threshold_N'] == pytest.approx(above)
    for j, name in enumerate(('coupler_1', 'coupler_2')):
        whole = rainflow(forces[:, j])
        assert found['couplers'][name]['del'] == pytest.approx(
            damage_equivalent_load(whole, 4.0), rel=1e-12)
        assert found['couplers'][name]['cycles'] == cycle_count(whole, above)
        assert found['couplers'][name]['cycles'] > 0          # the run-in oscillates
    assert main(['report', str(bag), '--output', str(tmp_path / 'plain'), '-q']) == 0
    assert 'fatigue' not in json.loads((tmp_path / 'plain' / 'summary.json').read_text())
