"""The offline command with wheelsets: valves from an input bag, ``wheelsets`` recorded."""
import struct

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.physics.kernel.wheelset import VENT_TAU
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.cdr import encode_fluid_pressure

ATM = 101325.0


def _int8(value: int) -> bytes:
    return b'\x00\x01\x00\x00' + struct.pack('<b', value)     # CDR little endian


def test_valves_from_an_input_bag_and_wheelsets_recorded(tmp_path):
    p = tmp_path / 'p.yaml'
    p.write_text("""train_dynamics:
  ros__parameters:
    num_coaches: 3
    initial_speed: 20.0
    brake_input: cylinder_per_coach
    wsp: external
""")
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    for i in (1, 2, 3):
        rec.add_topic(f'coach_{i}/brake_cylinder/pressure', topics.FLUID_PRESSURE)
        rec.write(f'coach_{i}/brake_cylinder/pressure', 0, encode_fluid_pressure(0, ATM + 1.0e5))
    rec.add_topic('coach_1/wsp/valve', topics.INT8)
    rec.add_topic('coach_2/wsp/valve', topics.INT8)
    rec.write('coach_1/wsp/valve', 1_000_000_000, _int8(2))      # vent from t = 1 s
    rec.write('coach_2/wsp/valve', 1_000_000_000, _int8(5))      # rejected: not 0, 1, 2
    rec.close()
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--input', str(inp), '--duration', '2',
                     '--output', str(out), '-q']) == 0
    info = bag_info(str(out))
    assert info.topics[topics.WHEELSETS_TOPIC][0] == topics.JOINT_STATE
    assert info.topics['coach_1/wsp/valve'][0] == topics.INT8
    cyl = [m for _, _, m in read_topics(str(out), [topics.BRAKE_CYLINDERS_TOPIC])][-1]
    assert cyl.position[0] == pytest.approx(1.0e5 * np.exp(-1.0 / VENT_TAU), rel=1e-6)
    assert cyl.position[1] == pytest.approx(1.0e5)
    wheels = [m for _, _, m in read_topics(str(out), [topics.WHEELSETS_TOPIC])][-1]
    assert list(wheels.name) == ['coach_1', 'coach_2', 'coach_3']
    assert wheels.header.frame_id == topics.TRACK_FRAME
    assert info.topics[topics.WHEELSETS_TOPIC][1] == info.topics[topics.COACHES_TOPIC][1]
    # a braked wheel turns a little slower than its vehicle; the vented one's creep force is
    # the least (the brake of coach 1 is off)
    assert wheels.effort[0] < 0.05 * wheels.effort[1]
    assert 0.0 < wheels.velocity[1] < 20.0
