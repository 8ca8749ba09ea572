"""
A downstream package on the typed messages, built by colcon, passes a harness scenario.

``test/downstream/typed_stop_controller`` (an ``ament_python`` package depending on
``train_dynamics_msgs``) is built by colcon in a temporary workspace on top of the virtual
environment (where ``tools/build_msgs.sh`` installed ``train_dynamics_msgs``); its installed
executable, started from the sourced workspace as ``ros2 run`` would, is a timer-driven
controller on ``use_sim_time`` reading ``train_state``. The harness runs it against
``sim_node`` with ``lockstep_answer: clock``: it stops the train at the target (the
``stop_error`` criterion) and two runs give byte-identical bags.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import run_scenario

REPO = Path(__file__).resolve().parents[2]
DOWNSTREAM = REPO / 'test' / 'downstream' / 'typed_stop_controller'
TARGET = 150.0              # [m] track position of the stopping target
SCENARIO = f"""\
parameters:
  num_coaches: 3
  initial_speed: 13.9
  target_stop_position: [{TARGET}]
  lockstep_answer: clock
  lockstep_period: 0.1
controller_parameters:
  period: 0.1
  target: {TARGET}
duration: 30.0
criteria:
  stopped: {{equals: true}}
  stop_error: {{min: -1.0, max: 1.0}}
"""


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Build the downstream package with colcon; return the workspace."""
    if shutil.which('bash') is None:
        pytest.skip('colcon needs bash for its setup files')
    ws = tmp_path_factory.mktemp('downstream_ws')
    shutil.copytree(DOWNSTREAM, ws / 'src' / DOWNSTREAM.name,
                    ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
    venv_bin = Path(sys.executable).parent
    env = dict(os.environ)
    env['PATH'] = f'{venv_bin}{os.pathsep}{env.get("PATH", "")}'
    for name in ('PYTHONPATH', 'COLCON_PREFIX_PATH'):
        env.pop(name, None)
    build = subprocess.run([str(venv_bin / 'colcon'), 'build', '--base-paths', 'src'],
                           cwd=ws, env=env, capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, f'colcon build failed:\n{build.stdout}\n{build.stderr}'
    return ws


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(bag.iterdir())}


def test_a_downstream_typed_controller_stops_at_the_target_byte_identical(workspace,
                                                                          tmp_path):
    scenario = tmp_path / 'stop.yaml'
    scenario.write_text(SCENARIO)
    exe = workspace / 'install' / DOWNSTREAM.name / 'lib' / DOWNSTREAM.name / 'stop_controller'
    assert exe.is_file()
    # as a user runs it: the sourced workspace, then the installed executable (the harness
    # appends --ros-args --params-file controller_params.yaml)
    command = ['bash', '-c', f'source {workspace}/install/setup.bash && exec {exe} "$@"',
               'stop_controller']
    runs = [run_scenario(scenario, command, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.passed, run.report()
    assert abs(runs[0].metrics['stop_error']) <= 1.0
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'
    # the controller answered every 0.1 s period from its timer, stamped on the sim clock
    stamps = [msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
              for _, _, msg in read_topics(runs[0].bag, ['brake_pipe/pressure'])]
    assert len(stamps) >= 250
    assert all(s % 100_000_000 == 0 for s in stamps)
