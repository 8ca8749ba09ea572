"""
The controller-test harness (train_dynamics.testing) against hostile input: what is refused.

Read as a list:

- A scenario file is checked whole when it is read, before anything runs: unknown keys,
  misspelled or harness-owned sim_node parameters (the table the offline command uses), bad
  values, a configuration the offline command refuses, a missing consist file (looked for
  next to the scenario file), controller parameters a ROS parameter file cannot carry, and
  criteria that cannot be meant (``equals: null``, a NaN bound, ``min > max``, ``equals``
  mixed with bounds, an unknown metric). Each: one :class:`ConfigError` line naming the file
  and the key; ``python -m train_dynamics.testing`` exits 2 with it; no process is started
  and no output folder created.
- An output folder that already holds files (an earlier run) is refused the same way.
- A controller that dies ends the run at once, reported as the controller's failure (not as
  a timeout of the node).
- Every process a controller command starts (a shell wrapper's child too) is gone when the
  harness returns: after a pass, after a timeout, after a Ctrl-C.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

from train_dynamics.physics.config import ConfigError
from train_dynamics.testing import harness, run_scenario, Scenario
from train_dynamics.testing.processes import group_members

ROOT = Path(__file__).resolve().parents[2]
ECHO = [sys.executable, str(ROOT / 'test' / 'echo_controller.py')]
#: a short run of the paper's train with the brake released: the loop itself is quick
SHORT = 'parameters: {num_coaches: 3, initial_speed: 10.0}\nduration: 1.0\n'


def _scenario(tmp_path: Path, text: str, name: str = 'scenario.yaml') -> Path:
    path = tmp_path / name
    path.write_text(text, encoding='utf-8')
    return path


# -- scenario files refused when read ---------------------------------------------------------

REFUSED_SCENARIOS = {
    # sim_node parameters: the offline command's table, with a hint
    'num_coachs': ('parameters: {num_coachs: 4}',
                   "unknown parameter 'num_coachs' (did you mean num_coaches?)"),
    'inital_speed': ('parameters: {inital_speed: 10.0}',
                     "unknown parameter 'inital_speed' (did you mean initial_speed?)"),
    'friction_materal': ('parameters: {friction_materal: disc}',
                         "unknown parameter 'friction_materal' (did you mean "
                         'friction_material?)'),
    'value out of range': ('parameters: {num_coaches: 1}', 'num_coaches: must be >= 2'),
    'wrong type': ('parameters: {initial_speed: fast}', 'initial_speed: expected a number'),
    'unknown choice': ('parameters: {friction_material: cheese}', 'friction_material'),
    'harness-owned parameter': ('parameters: {sync_mode: free}',
                                'sync_mode is set by the harness'),
    'duration as a parameter': ('parameters: {duration: 5.0}',
                                'duration is set by the harness'),
    'consist file not next to the scenario': ('parameters: {consist_file: nowhere.yaml}',
                                              "consist_file: 'nowhere.yaml' not found"),
    'parameters not a mapping': ('parameters: [num_coaches, 4]', 'parameters: expected a '
                                 'mapping'),
    # the scenario's own keys
    'misspelled key': ('criterion: {}', "unknown key(s) 'criterion' (did you mean criteria?)"),
    'figures not a bool': ('figures: maybe', 'figures: expected true or false'),
    'parameters_file missing': ('parameters_file: missing.yaml', 'parameters_file: file not '
                                'found'),
    # controller parameters: what a ROS 2 parameter file can carry
    'controller parameter null': ('controller_parameters: {kp: null}',
                                  'controller_parameters: kp: None is no ROS parameter value'),
    'controller parameter mixed list': ('controller_parameters: {gains: [1, x]}',
                                        'gains: a list of mixed types'),
    'controller parameter empty list': ('controller_parameters: {gains: []}',
                                        'gains: an empty list has no ROS parameter type'),
    'controller parameter bad name': ('controller_parameters: {"k p": 1}',
                                      "'k p' is not a ROS parameter name"),
    'controller parameter NaN': ('controller_parameters: {kp: .nan}',
                                 'kp: nan is not a finite number'),
    # criteria: refused when read, naming the criterion
    'equals null': ('criteria: {stopped: {equals: null}}',
                    'criterion stopped: equals: null is no value'),
    'NaN bound': ('criteria: {max_jerk: {max: .nan}}',
                  'criterion max_jerk: max nan is not a finite number'),
    'infinite bound': ('criteria: {max_jerk: {min: -.inf}}',
                       'criterion max_jerk: min -inf is not a finite number'),
    'min above max': ('criteria: {max_jerk: {min: 5, max: 1}}',
                      'criterion max_jerk: min 5 > max 1: no value passes'),
    'equals mixed with max': ('criteria: {stopping_distance: {max: 1000, equals: 5}}',
                              'criterion stopping_distance: equals cannot be combined'),
    'unknown metric': ('criteria: {stoping_distance: {max: 100}}',
                       'criterion stoping_distance: no such run metric (did you mean '
                       'stopping_distance?)'),
    'text bound': ('criteria: {max_jerk: {max: high}}', "max_jerk: max 'high' is not a number"),
    'bool bound': ('criteria: {max_jerk: {max: true}}', 'max_jerk: max True is not a number'),
    'yes/no metric with a bound': ('criteria: {stopped: {min: 1}}',
                                   'criterion stopped: a true/false metric takes equals'),
    'yes/no metric equals a number': ('criteria: {stopped: {equals: 1}}',
                                      'criterion stopped: equals must be true or false'),
    'number metric equals text': ('criteria: {blocking_count: {equals: none}}',
                                  "blocking_count: equals 'none' is not a number"),
    'empty criterion': ('criteria: {max_jerk: {}}', 'criterion max_jerk: expected a mapping'),
    'unknown bound': ('criteria: {max_jerk: {maximum: 1}}', 'criterion max_jerk: expected'),
}


@pytest.mark.parametrize('case', sorted(REFUSED_SCENARIOS))
def test_scenario_file_is_refused_when_read_naming_file_and_key(tmp_path, case):
    text, message = REFUSED_SCENARIOS[case]
    path = _scenario(tmp_path, f'duration: 5.0\n{text}\n')
    with pytest.raises(ConfigError) as info:
        Scenario.load(path)
    line = str(info.value)
    assert line.startswith(f'{path}: ') and message in line, line
    assert '\n' not in line


@pytest.mark.parametrize('text, message', [
    ('{}', 'a scenario is a mapping with at least duration'),
    ('duration: -1', 'duration: must be > 0 s'),
    ('duration: .nan', 'duration: must be > 0 s'),
    ('duration: true', 'duration: expected a number of seconds'),
    ('duration: 1.0e12', 'duration: must be <='),
    ('duration: [1', 'while parsing'),
])
def test_scenario_without_a_usable_duration_is_refused(tmp_path, text, message):
    with pytest.raises(ConfigError, match='duration|parsing') as info:
        Scenario.load(_scenario(tmp_path, text + '\n'))
    assert message in str(info.value)


def test_parameters_file_keys_are_checked_like_the_offline_command(tmp_path):
    params = _scenario(tmp_path, '/**/train_dynamics:\n  ros__parameters:\n'
                       '    num_coachs: 4\n', 'train.yaml')
    path = _scenario(tmp_path, 'parameters_file: train.yaml\nduration: 5.0\n')
    with pytest.raises(ConfigError, match=f"{params}: unknown parameter.*'num_coachs'"):
        Scenario.load(path)


def test_a_configuration_the_offline_command_refuses_is_refused(tmp_path):
    # each value is valid alone; together the outputs would not land on whole steps
    path = _scenario(tmp_path, 'duration: 5.0\n'
                     'parameters: {integration_step: 0.003, publish_rate: 100.0}\n')
    with pytest.raises(ConfigError, match='publish_rate 100 Hz and integration_step'):
        Scenario.load(path)


def test_relative_consist_file_is_found_next_to_the_scenario_file(tmp_path, monkeypatch):
    """The scenario file is where the path rule looks first (not the run folder)."""
    folder = tmp_path / 'scenarios'
    folder.mkdir()
    consist = folder / 'two_coaches.yaml'
    consist.write_text('vehicles:\n  - {type: paper_coach, count: 2}\n', encoding='utf-8')
    path = _scenario(folder, 'duration: 5.0\nparameters: {consist_file: two_coaches.yaml}\n')
    monkeypatch.chdir(tmp_path)          # neither the current folder nor config/ holds it
    scenario = Scenario.load(path)
    assert scenario.parameters['consist_file'] == str(consist)


def test_run_uses_the_consist_file_next_to_the_scenario_file(tmp_path):
    from train_dynamics.recording.bags import read_topics

    folder = tmp_path / 'scenarios'
    folder.mkdir()
    (folder / 'four.yaml').write_text('vehicles:\n  - {type: paper_coach, count: 4}\n')
    path = _scenario(folder, 'parameters: {consist_file: four.yaml, initial_speed: 10.0}\n'
                     'duration: 0.5\n')
    run = run_scenario(path, ECHO, tmp_path / 'run')
    assert run.passed, run.report()
    names = next(msg.name for topic, _, msg in read_topics(run.bag, ['coaches']))
    assert list(names) == ['coach_1', 'coach_2', 'coach_3', 'coach_4']


def test_relative_paths_of_a_scenario_built_in_python_are_taken_from_the_current_folder(
        tmp_path, monkeypatch):
    (tmp_path / 'two.yaml').write_text('vehicles:\n  - {type: paper_coach, count: 2}\n')
    (tmp_path / 'train.yaml').write_text('/**/train_dynamics:\n  ros__parameters: {}\n')
    monkeypatch.chdir(tmp_path)
    scenario = Scenario(duration=2, parameters={'consist_file': 'two.yaml'},
                        parameters_file=Path('train.yaml'))
    scenario.check()
    assert scenario.parameters['consist_file'] == str(tmp_path / 'two.yaml')
    assert scenario.parameters_file == tmp_path / 'train.yaml'
    assert scenario.duration == 2.0 and isinstance(scenario.duration, float)


def test_refused_scenario_starts_nothing_and_creates_no_folder(tmp_path):
    marker = tmp_path / 'controller_ran'
    controller = [sys.executable, '-c', f'open({str(marker)!r}, "w")']
    out = tmp_path / 'run'
    path = _scenario(tmp_path, 'duration: 5.0\nparameters: {inital_speed: 10.0}\n')
    with pytest.raises(ConfigError, match='inital_speed'):
        run_scenario(path, controller, out)
    assert not out.exists() and not marker.exists()


def test_command_line_exits_2_with_one_line_for_a_refused_scenario(tmp_path):
    path = _scenario(tmp_path, 'duration: 5.0\ncriteria: {max_jerk: {min: 5, max: 1}}\n')
    out = tmp_path / 'run'
    proc = subprocess.run([sys.executable, '-m', 'train_dynamics.testing', str(path),
                           '--output', str(out), '--', 'true'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f'python -m train_dynamics.testing: error: {path}: criterion max_jerk: min 5 > max 1:'
        ' no value passes']
    assert not out.exists()


def test_command_line_exits_1_for_a_failed_criterion_and_prints_the_report(tmp_path):
    # the brake stays released: the train does not stop
    path = _scenario(tmp_path, SHORT + 'criteria: {stopped: {equals: true}}\n')
    proc = subprocess.run([sys.executable, '-m', 'train_dynamics.testing', str(path),
                           '--output', str(tmp_path / 'run'), '--'] + ECHO,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert proc.stdout.splitlines()[0] == 'FAIL stopped == True: False'
    assert proc.stdout.splitlines()[-1].startswith('FAILED (1 criteria; bag ')


# -- options and the output folder ------------------------------------------------------------

@pytest.mark.parametrize('options, message', [
    ({'timeout': 0}, 'timeout: expected a finite number of seconds > 0'),
    ({'timeout': float('nan')}, 'timeout: expected a finite number'),
    ({'lockstep_timeout': -1.0}, 'lockstep_timeout: must be >= 0'),
    ({'real_time_factor': -2.0}, 'real_time_factor: must be >= 0'),
])
def test_bad_harness_options_are_refused_before_anything_runs(tmp_path, options, message):
    out = tmp_path / 'run'
    with pytest.raises(ConfigError, match=message):
        run_scenario(_scenario(tmp_path, SHORT), ECHO, out, **options)
    assert not out.exists()


@pytest.mark.parametrize('controller, message', [
    (['no-such-controller-command'],
     "command not found or not executable: 'no-such-controller-command'"),
    ('python3 ctrl.py', 'expected a command as a list of strings'),
    ([], 'expected a command as a list of strings'),
])
def test_a_controller_command_that_cannot_start_is_refused(tmp_path, controller, message):
    out = tmp_path / 'run'
    with pytest.raises(ConfigError, match=message):
        run_scenario(_scenario(tmp_path, SHORT), controller, out)
    assert not out.exists()


def test_reused_output_folder_is_refused_before_anything_runs(tmp_path):
    out = tmp_path / 'run'
    out.mkdir()
    (out / 'bag').mkdir()                       # an earlier run's bag
    marker = tmp_path / 'controller_ran'
    controller = [sys.executable, '-c', f'open({str(marker)!r}, "w")']
    with pytest.raises(ConfigError, match=f'output folder {out}: not empty'):
        run_scenario(_scenario(tmp_path, SHORT), controller, out)
    assert not marker.exists()
    assert sorted(p.name for p in out.iterdir()) == ['bag']     # nothing added or removed
    file_out = tmp_path / 'a_file'
    file_out.write_text('')
    with pytest.raises(ConfigError, match='exists and is not a folder'):
        harness.prepare_directory(file_out)
    empty = tmp_path / 'empty'
    empty.mkdir()
    assert harness.prepare_directory(empty) == empty        # an empty folder is fine


# -- the controller's processes -----------------------------------------------------------------

def test_controller_that_exits_at_once_is_reported_as_dead_not_as_a_node_timeout(tmp_path):
    crash = [sys.executable, '-c', 'import sys; print("no model file"); sys.exit(3)']
    run = run_scenario(_scenario(tmp_path, SHORT), crash, tmp_path / 'run', timeout=120.0)
    assert not run.passed
    assert run.controller_returncode == 3
    assert run.error.startswith('the controller exited with status 3 '), run.error
    assert 'before the run ended (controller.log: no model file)' in run.error
    assert 'did not finish' not in run.error
    assert run.returncode is not None                        # the node was ended too


def test_controller_that_exits_0_before_the_run_ends_is_reported(tmp_path):
    quits = [sys.executable, '-c', 'pass']
    run = run_scenario(_scenario(tmp_path, SHORT), quits, tmp_path / 'run',
                       lockstep_timeout=1.0, timeout=120.0)
    assert not run.passed
    assert run.error.startswith('the controller exited with status 0 '), run.error


def _wrapped_echo(pid_file: Path) -> tuple[list[str], dict[str, str]]:
    """Return a controller started through a shell that stays beside it (the grandchild)."""
    script = ' '.join(ECHO) + f' & echo $! > {pid_file}; wait'     # its id, at once
    return ['sh', '-c', script], {**os.environ, 'ECHO_PID_FILE': f'{pid_file}.ready'}


def _gone(pid: int) -> bool:
    try:
        with open(f'/proc/{pid}/stat') as fh:
            return fh.read().rsplit(')', 1)[1].split()[0] in ('Z', 'X')
    except OSError:
        return True


def test_shell_wrapped_controller_is_ended_with_its_children_after_a_pass(tmp_path):
    pid_file = tmp_path / 'pid'
    controller, env = _wrapped_echo(pid_file)
    run = run_scenario(_scenario(tmp_path, SHORT), controller, tmp_path / 'run', env=env)
    assert run.passed, run.report()
    grandchild = int(pid_file.read_text())
    assert _gone(grandchild), f'controller process {grandchild} outlived the harness'


def test_shell_wrapped_controller_is_ended_after_a_timeout(tmp_path):
    pid_file = tmp_path / 'pid'
    controller, env = _wrapped_echo(pid_file)
    env['ECHO_SILENT'] = '1'                   # the node waits for ever (lockstep_timeout 0)
    run = run_scenario(_scenario(tmp_path, SHORT), controller, tmp_path / 'run', env=env,
                       lockstep_timeout=0.0, timeout=20.0)
    assert run.error.startswith('sim_node did not finish within 20 s'), run.error
    assert _gone(int(pid_file.read_text()))
    assert not any(group_members(pgid) for pgid in run.process_groups.values())


def test_ctrl_c_ends_the_controller_and_the_node(tmp_path, monkeypatch):
    """A Ctrl-C (SIGINT to the harness) in the wait ends both process groups, then propagates."""
    pid_file = tmp_path / 'pid'
    controller, env = _wrapped_echo(pid_file)
    env['ECHO_SILENT'] = '1'
    started = {}

    def interrupted(sim, ctl, timeout, lockstep_timeout):
        started.update(sim=sim.pid, ctl=ctl.pid)
        end = time.monotonic() + 120.0
        while not Path(f'{pid_file}.ready').exists() and time.monotonic() < end:
            time.sleep(0.05)
        os.kill(os.getpid(), signal.SIGINT)          # Ctrl-C, as the terminal sends it
        time.sleep(60.0)                             # (interrupted at once)

    monkeypatch.setattr(harness, '_supervise', interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_scenario(_scenario(tmp_path, SHORT), controller, tmp_path / 'run', env=env,
                     lockstep_timeout=0.0)
    assert Path(f'{pid_file}.ready').exists()          # it was up and subscribed
    assert _gone(int(pid_file.read_text()))
    assert not group_members(started['ctl']) and not group_members(started['sim'])


# -- what reaches the controller, what the report costs -----------------------------------------

def test_controller_parameters_reach_the_controller_as_ros_parameters(tmp_path):
    path = _scenario(tmp_path, SHORT + 'controller_parameters:\n  target_stop: 120.5\n'
                     '  mode: gentle\n  gains: [1, 2.5]\n  enabled: true\n'
                     '  limits: {jerk: 0.8}\n')
    run = run_scenario(path, ECHO, tmp_path / 'run', namespace='/ctl_params')
    assert run.passed, run.report()
    line = next(x for x in (run.directory / 'controller.log').read_text().splitlines()
                if x.startswith('parameters: '))
    assert json.loads(line[len('parameters: '):]) == {
        'target_stop': 120.5, 'mode': 'gentle', 'gains': [1.0, 2.5], 'enabled': True,
        'limits.jerk': 0.8}


def test_report_figures_are_off_unless_asked(tmp_path):
    plain = run_scenario(_scenario(tmp_path, SHORT), ECHO, tmp_path / 'plain')
    assert plain.passed, plain.report()
    assert sorted(p.name for p in (plain.directory / 'report').iterdir()) == [
        'summary.json', 'summary.md']
    drawn = run_scenario(_scenario(tmp_path, SHORT + 'figures: true\n', 'fig.yaml'), ECHO,
                         tmp_path / 'drawn')
    assert drawn.passed, drawn.report()
    assert (drawn.directory / 'report' / 'coupler_force.png').is_file()
    # the same run metrics either way (the brake stays released: the same physics)
    assert plain.metrics == drawn.metrics
