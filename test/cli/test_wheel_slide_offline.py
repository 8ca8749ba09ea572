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


def test_speed_sensor_quantisation_and_noise_in_the_wheelsets_output(tmp_path):
    """
    ``wheel_speed_resolution`` and ``wheel_speed_noise``: the recorded wheel speeds.

    A coasting train (no brake: every wheel rolls at its vehicle's speed, within the
    rolling creep): each recorded speed is a multiple of the resolution, its error against
    the vehicle's speed has the mean 0 and the standard deviation sqrt(noise^2 + res^2 / 12)
    of a noise rounded to a grid (within the sampling error of 303 samples x 3), and two
    runs with the same seed record the same speeds, another seed other ones.
    """
    res, noise = 0.02, 0.05

    def run(seed, name):
        p = tmp_path / f'{name}.yaml'
        p.write_text(f"""train_dynamics:
  ros__parameters:
    num_coaches: 3
    initial_speed: 20.0
    wheelsets: true
    wheel_speed_resolution: {res}
    wheel_speed_noise: {noise}
    wheel_speed_seed: {seed}
""")
        out = tmp_path / name
        assert cli.main(['simulate', '--params', str(p), '--duration', '3',
                         '--output', str(out), '-q']) == 0
        got = {}
        for topic, t_ns, msg in read_topics(str(out), [topics.WHEELSETS_TOPIC,
                                                       topics.VEHICLE_MOTION_TOPIC]):
            got.setdefault(topic, []).append(np.array(msg.velocity))
        return np.array(got[topics.WHEELSETS_TOPIC]), np.array(got[topics.VEHICLE_MOTION_TOPIC])

    u, v = run(7, 'a')
    steps = u / res
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    err = (u - v).ravel()
    sigma = np.sqrt(noise ** 2 + res ** 2 / 12.0)
    assert abs(np.mean(err)) < 4.0 * sigma / np.sqrt(err.size)
    assert np.std(err) == pytest.approx(sigma, rel=0.15)
    again, _ = run(7, 'b')
    np.testing.assert_array_equal(again, u)
    other, _ = run(8, 'c')
    assert np.mean(other != u) > 0.5
