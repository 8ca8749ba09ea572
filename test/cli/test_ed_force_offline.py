"""The offline command replays the motor cars' ED force commands from an input bag."""
from pathlib import Path
import struct

import pytest

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.cdr import encode_fluid_pressure

ROOT = Path(__file__).resolve().parents[2]
ATM = 101325.0


def _float64(value: float) -> bytes:
    return b'\x00\x01\x00\x00' + struct.pack('<d', value)     # CDR little endian


def test_ed_force_commands_replayed_from_an_input_bag(tmp_path, capsys):
    """
    FLIRT, blending external, 22.2 m/s: 30 kN on motor car 1 from 0 s, on car 4 from 0.5 s.

    30 kN is below the motor car's power limit (1300 kW / 22 m/s = 58 kN): once built up
    (1.5 s) each gives 30 kN (the achieved ED force of ``brake_blending``); the trailers
    none. Car 1 released (0 N) at 2 s fades out by 3.5 s. A negative force is rejected
    (counted), a trailer's topic ignored (named); the commands are recorded as applied.
    """
    p = tmp_path / 'p.yaml'
    p.write_text(f"""train_dynamics:
  ros__parameters:
    consist_file: {ROOT / 'config' / 'consist_flirt_4.yaml'}
    initial_speed: 22.2
    brake_input: cylinder_per_coach
    blending: external
""")
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    for i in (1, 2, 3, 4):
        rec.add_topic(f'coach_{i}/brake_cylinder/pressure', topics.FLUID_PRESSURE)
        rec.write(f'coach_{i}/brake_cylinder/pressure', 0, encode_fluid_pressure(0, ATM))
    for i in (1, 2, 4):
        rec.add_topic(f'coach_{i}/ed_brake/force', topics.FLOAT64)
    rec.write('coach_1/ed_brake/force', 0, _float64(30.0e3))
    rec.write('coach_4/ed_brake/force', 500_000_000, _float64(30.0e3))
    rec.write('coach_2/ed_brake/force', 500_000_000, _float64(30.0e3))    # a trailer
    rec.write('coach_4/ed_brake/force', 600_000_000, _float64(-5.0))      # rejected
    rec.write('coach_1/ed_brake/force', 2_000_000_000, _float64(0.0))     # released
    rec.close()
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--input', str(inp), '--duration', '4',
                     '--output', str(out), '-q']) == 0
    err = capsys.readouterr().err
    assert 'coach_2/ed_brake/force' in err and 'rejected (ED force command: 1)' in err
    info = bag_info(str(out))
    assert info.topics['coach_1/ed_brake/force'][0] == topics.FLOAT64
    recorded = [m.data for _, _, m in read_topics(str(out), ['coach_1/ed_brake/force'])]
    assert recorded == [30.0e3, 0.0]
    ed = {t: m.position for _, t, m in read_topics(str(out), [topics.BRAKE_BLENDING_TOPIC])}
    at_2s = ed[2_000_000_000]
    assert at_2s[0] == pytest.approx(30.0e3, rel=3e-3)
    assert at_2s[3] == pytest.approx(30.0e3, rel=3e-3)
    assert at_2s[1] == 0.0 and at_2s[2] == 0.0
    assert ed[500_000_000][3] == 0.0
    end = ed[4_000_000_000]
    assert end[0] == 0.0 and end[3] == pytest.approx(30.0e3, rel=3e-3)
