"""The offline command with per-bogie wheelsets: bogie valves from an input bag, outputs."""
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


def test_bogie_valves_from_an_input_bag_and_each_bogie_recorded(tmp_path, capsys):
    """
    coach_2/bogie_2 vented from t = 1 s: that cylinder alone falls as exp(-(t - 1) / VENT_TAU).

    coach_1/bogie_1 and coach_1/bogie_2 held from 1.5 s; a vehicle's topic (coach_1/wsp/valve)
    is not taken with bogie_wheelsets (named, ignored); the wheelsets and bogie_cylinders
    outputs name coach_<i>/bogie_<j>.
    """
    p = tmp_path / 'p.yaml'
    p.write_text("""train_dynamics:
  ros__parameters:
    num_coaches: 3
    initial_speed: 20.0
    brake_input: cylinder_per_coach
    wsp: external
    bogie_wheelsets: true
""")
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    for i in (1, 2, 3):
        rec.add_topic(f'coach_{i}/brake_cylinder/pressure', topics.FLUID_PRESSURE)
        rec.write(f'coach_{i}/brake_cylinder/pressure', 0, encode_fluid_pressure(0, ATM + 1.0e5))
    rec.add_topic('coach_2/bogie_2/wsp/valve', topics.INT8)
    rec.add_topic('coach_1/wsp/valve', topics.INT8)
    rec.add_topic('coach_1/bogie_1/wsp/valve', topics.INT8)
    rec.add_topic('coach_1/bogie_2/wsp/valve', topics.INT8)
    rec.add_topic('coach_3/bogie_1/wsp/valve', topics.INT8)
    rec.write('coach_2/bogie_2/wsp/valve', 1_000_000_000, _int8(2))    # vent from t = 1 s
    rec.write('coach_1/wsp/valve', 1_000_000_000, _int8(2))            # ignored
    rec.write('coach_1/bogie_1/wsp/valve', 1_500_000_000, _int8(1))    # hold from 1.5 s
    rec.write('coach_1/bogie_2/wsp/valve', 1_500_000_000, _int8(1))
    rec.write('coach_3/bogie_1/wsp/valve', 1_000_000_000, _int8(7))    # rejected
    rec.close()
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--input', str(inp), '--duration', '2',
                     '--output', str(out), '-q']) == 0
    err = capsys.readouterr().err
    assert 'coach_1/wsp/valve' in err and 'coach_3/bogie_1/wsp/valve' not in err.split(
        'rejected')[0]
    info = bag_info(str(out))
    assert info.topics['coach_2/bogie_2/wsp/valve'][0] == topics.INT8
    names = [f'coach_{i}/bogie_{j}' for i in (1, 2, 3) for j in (1, 2)]
    cyl = [m for _, _, m in read_topics(str(out), [topics.BOGIE_CYLINDERS_TOPIC])][-1]
    assert list(cyl.name) == names
    assert cyl.position[3] == pytest.approx(1.0e5 * np.exp(-1.0 / VENT_TAU), rel=1e-6)
    np.testing.assert_allclose(np.delete(np.array(cyl.position), 3), 1.0e5)
    assert list(cyl.effort) == [1.0, 1.0, 0.0, 2.0, 0.0, 0.0]
    source = [m for _, _, m in read_topics(str(out), [topics.BRAKE_CYLINDERS_TOPIC])][-1]
    assert list(source.position) == pytest.approx([1.0e5] * 3)
    wheels = [m for _, _, m in read_topics(str(out), [topics.WHEELSETS_TOPIC])][-1]
    assert list(wheels.name) == names
    assert wheels.effort[3] < 0.05 * wheels.effort[2]      # the vented bogie's brake is off
    assert 0.0 < wheels.velocity[2] < 20.0
