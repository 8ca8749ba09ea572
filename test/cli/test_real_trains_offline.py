"""The offline command with a consist, a track and a traction schedule or bag."""
from pathlib import Path

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.cdr import encode_float64, encode_fluid_pressure

CONSIST = """
vehicles:
  - {type: electric_passenger_locomotive, traction_build_up_time: 1.0}
  - {type: passenger_coach, count: 3}
"""


def params(tmp_path, extra=''):
    (tmp_path / 'train.yaml').write_text(CONSIST)
    path = tmp_path / 'p.yaml'
    path.write_text(f"""train_dynamics:
  ros__parameters:
    consist_file: train.yaml
    initial_speed: 20.0
    track_gradient_positions: [0.0]
    track_gradients: [5.0]
{extra}
brake_valve:
  ros__parameters:
    schedule: ["0.0:release"]
""")
    return path


def forces_at_end(bag):
    msgs = [m for _, _, m in read_topics(str(bag), [topics.VEHICLE_FORCES_TOPIC])]
    return msgs[-1]


def test_traction_schedule_drives_the_locomotive_and_forces_are_recorded(tmp_path):
    p = params(tmp_path, """    traction_schedule_times: [0.0, 2.0]
    traction_schedule_commands: [1.0, -0.5]""")
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--duration', '4', '--output', str(out),
                     '-q']) == 0
    info = bag_info(str(out))
    assert info.topics[topics.VEHICLE_FORCES_TOPIC][0] == topics.JOINT_STATE
    assert info.topics['coach_1/traction/command'][0] == topics.FLOAT64
    last = forces_at_end(out)
    assert last.position[0] < 0.0 and np.all(np.asarray(last.position[1:]) == 0.0)
    assert np.all(np.asarray(last.velocity) < 0.0)                 # resistance, forward travel
    assert np.all(np.asarray(last.effort) < 0.0)                   # uphill 5 per mille
    assert last.effort[1] == pytest.approx(-46000.0 * 9.81 * 5e-3)


def test_traction_commands_from_an_input_bag(tmp_path):
    p = params(tmp_path)
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    rec.add_topic(topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE)
    rec.add_topic('coach_1/traction/command', topics.FLOAT64)
    rec.add_topic('coach_2/traction/command', topics.FLOAT64)     # a coach: ignored
    rec.write(topics.HEAD_PIPE_TOPIC, 0, encode_fluid_pressure(0, 601325.0))
    rec.write('coach_1/traction/command', 0, encode_float64(0.8))
    rec.write('coach_1/traction/command', 1_000_000_000, encode_float64(7.0))   # rejected
    rec.write('coach_2/traction/command', 0, encode_float64(1.0))
    rec.close()
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--input', str(inp), '--duration', '3',
                     '--output', str(out), '-q']) == 0
    last = forces_at_end(out)
    assert last.position[0] > 0.5 * 300e3 * 0.8 and last.position[1] == 0.0


def test_a_bad_consist_is_a_one_line_error_exit_2(tmp_path, capsys):
    (tmp_path / 'train.yaml').write_text('vehicles: [{type: paper_coach}, {type: wagon}]\n')
    p = tmp_path / 'p.yaml'
    p.write_text('train_dynamics:\n  ros__parameters:\n    consist_file: train.yaml\n')
    assert cli.main(['simulate', '--params', str(p), '--duration', '1', '--output',
                     str(tmp_path / 'out'), '-q']) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'vehicles[2]' in err and "'wagon'" in err
    assert not Path(tmp_path / 'out').exists()
