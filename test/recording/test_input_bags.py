"""
Input bags read by the rows of the input table: every command kind the node takes, offline too.

The offline reader (``recording/inputs.py``) takes a kind's topic, type, rule, vehicles and
setter from its row of ``train_dynamics/input_kinds.py``, as the node's channels do.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.input_kinds import INPUT_KINDS, KINDS, match
from train_dynamics.physics.config import SimConfig
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.cdr import encode_float64
from train_dynamics.recording.inputs import read_command_bag
from train_dynamics.simulation.runner import command_events, InputSchedule, run_simulation

ED_FORCE = 50_000.0     # [N] commanded of each motor car (the FLIRT's ED gives more at 20 m/s)


def _flirt_external() -> SimConfig:
    return SimConfig.from_dict({'consist_file': 'config/consist_flirt_4.yaml',
                                'brake_input': 'cylinder_per_coach', 'blending': 'external',
                                'initial_speed': 20.0})


def _bag(path, messages) -> str:
    with BagRecorder(path) as rec:
        for topic, t, value in messages:
            rec.add_topic(topic, 'std_msgs/msg/Float64')
            rec.write(topic, int(t * 1e9), encode_float64(value))
    return str(path)


def test_every_topic_of_a_kind_matches_only_its_row():
    for kind in INPUT_KINDS:
        for index in (0, 6):
            found, i = match(kind.topic_of(index))
            assert found is kind
            assert i == (index if kind.per_vehicle else None)
    assert match('coach_3/unknown/command') is None


def test_ed_force_commands_of_an_input_bag_brake_the_motor_cars_offline(tmp_path):
    """
    ``coach_<i>/ed_brake/force`` in an input bag: each motor car brakes with that force.

    The FLIRT's motor cars are vehicles 1 and 4; a command for the trailer 2 is named and
    ignored, a negative one refused (the node's rule), as the node does.
    """
    cfg = _flirt_external()
    warnings = []
    path = _bag(tmp_path / 'in', [('coach_1/ed_brake/force', 0.0, ED_FORCE),
                                  ('coach_4/ed_brake/force', 0.0, ED_FORCE),
                                  ('coach_2/ed_brake/force', 0.0, ED_FORCE),
                                  ('coach_4/ed_brake/force', 0.5, -1.0)])
    events = read_command_bag(path, cfg, warn=warnings.append)
    assert [(e.kind, e.index, e.value) for e in events] == [
        ('ed_force', 0, ED_FORCE), ('ed_force', 3, ED_FORCE)]
    assert any('coach_2/ed_brake/force' in w and 'ignored' in w for w in warnings)
    assert any('1 command(s)' in w and 'rejected' in w for w in warnings)
    sim = run_simulation(cfg, 4.0, InputSchedule(cfg.brake_input,
                                                 commands=command_events(cfg, events)),
                         on_sample=lambda s: None)
    assert sim.fault is None
    force = sim.traction_force                      # [N], forward > 0: braking < 0
    # the force becomes a fraction of the ED available, refreshed every blending_period
    # while the speed falls: within 0.1 % of the command between two refreshes
    assert force[[0, 3]] == pytest.approx([-ED_FORCE, -ED_FORCE], rel=1e-3)
    assert np.all(force[[1, 2]] == 0.0)


def test_a_bag_command_replaces_the_schedule_of_its_kind_only(tmp_path):
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_system': 'ep',
                               'num_coaches': 3, 'ep_schedule_times': [2.0],
                               'ep_schedule_commands': [1.0]})
    path = _bag(tmp_path / 'in', [('brake_ep/command', 0.5, 0.25)])
    events = command_events(cfg, read_command_bag(path, cfg))
    assert [(e.kind, e.value, e.t_ns) for e in events] == [('ep', 0.25, 0)]
    assert events[0].topic == KINDS['ep'].topic
    assert [(e.kind, e.value) for e in command_events(cfg, [])] == [('ep', 1.0)]
