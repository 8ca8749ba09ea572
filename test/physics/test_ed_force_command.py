"""
The ED brake commanded as a force [N] (``blending: external``, physics/ed_force.py).

Offline on the simulator, and in the node: ``coach_<i>/ed_brake/force`` answered in
lock-step (``lockstep_inputs: [blending]``) by ``test/ed_force_controller.py``.
"""
from __future__ import annotations

from pathlib import Path
import sys

import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.blending import ed_forces
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import run_scenario
from train_dynamics.testing.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]
V0 = 83.333            # [m/s] the ICE 3's initial speed (config/hs_ice3_8.yaml)
P_DB = 2.0e6           # [W] ED power limit of an ICE 3 motor car (config/consist_ice3_8.yaml)


def _ice3_external() -> TrainSimulator:
    cfg = load_param_file(str(ROOT / 'config' / 'hs_ice3_8.yaml'))
    cfg = cfg.replace(blending='external', demand_schedule_times=[],
                      demand_schedule_values=[])
    return TrainSimulator(cfg)


def test_ed_force_command_gives_that_force_and_no_more_than_available():
    sim = _ice3_external()
    assert sim.bcu is None and sim.ed_force.motors == [0, 2, 5, 7]
    sim.ed_force.set_force(10.0e3, 0)   # below the power limit P / v = 24 kN at 300 km/h
    sim.ed_force.set_force(60.0e3, 2)   # above it: the car gives what it has
    sim.advance_to(3.0)                 # past the 2 s build-up
    ed = ed_forces(sim)
    assert ed[0] == pytest.approx(10.0e3, rel=2e-3)
    assert ed[2] == pytest.approx(P_DB / abs(float(sim.v[2])), rel=2e-3)
    assert ed[5] == 0.0 and ed[1] == 0.0           # no command; a trailer
    sim.ed_force.set_force(0.0, 0)                  # released: the ED fades out
    sim.advance_to(6.0)
    assert ed_forces(sim)[0] == 0.0


@pytest.mark.parametrize('value, index, why', [
    (-1.0, 0, 'finite and >= 0'), (float('nan'), 0, 'finite and >= 0'),
    (1.0e3, 1, 'not a motor car')])
def test_ed_force_command_refuses_a_bad_value_or_a_trailer(value, index, why):
    with pytest.raises(ValueError, match=why):
        _ice3_external().ed_force.set_force(value, index)


def test_node_takes_ed_force_commands_in_lockstep(tmp_path):
    force = 30.0e3          # [N] below the FLIRT motor car's 1300 kW / 22 m/s = 58 kN
    scenario = Scenario(duration=2.5, name='flirt_ed_force', parameters={
        'consist_file': str(ROOT / 'config' / 'consist_flirt_4.yaml'),
        'initial_speed': 22.2, 'brake_input': 'cylinder_per_coach', 'blending': 'external',
        'lockstep_inputs': ['blending'], 'publish_rate': 50.0,
        'buffer_stiffness': 2.0e7, 'buffer_friction': 5.0e6,
        'draw_gear_stiffness': 2.0e7, 'draw_gear_friction': 5.0e6},
        controller_parameters={'force': force, 'motor_cars': [1, 4]})
    run = run_scenario(scenario, [sys.executable, str(ROOT / 'test' / 'ed_force_controller.py')],
                       tmp_path / 'run')
    assert run.returncode == 0 and not run.error, run.report()
    outputs = sum(1 for _ in read_topics(run.bag, ['coaches']))
    for topic in ('coach_1/ed_brake/force', 'coach_4/ed_brake/force'):
        assert sum(1 for _ in read_topics(run.bag, [topic])) == outputs, topic
    last = [m for _, t, m in read_topics(run.bag, ['brake_blending']) if t >= 2.0e9]
    assert last
    for m in last:          # built up (1.5 s): the commanded force, the trailers none
        assert m.position[0] == pytest.approx(force, rel=3e-3)
        assert m.position[3] == pytest.approx(force, rel=3e-3)
        assert m.position[1] == 0.0 and m.position[2] == 0.0
