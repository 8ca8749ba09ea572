"""
``report`` and ``plot`` of hostile bags: what is refused and how.

A list a reviewer can read. Every refusal is exit 2, one line on stderr naming the bag, the
topic and the message (its number and time), and nothing written:

- a ``JointState`` with names but empty arrays (was: ``report`` exit 0, ``stopped: true``,
  ``stopping_distance: 0``; ``plot`` exit 0 with empty figures);
- a ragged ``JointState``: fewer values than names in one message (was: NaN-padded, exit 0);
- a ``JointState`` without names (was: ``report`` exit 1, ``ValueError: a train has at least 2
  vehicles``);
- more values than names;
- ``brake_cylinders`` with an empty ``velocity`` is what the outputs carry: accepted; a ragged
  one is refused.

Non-finite values (NaN, inf) are refused as before (test_report_refusals.py).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from train_dynamics.cli import offline
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.messages import joint_state

NAMES_C = ['coupler_1', 'coupler_2']
NAMES_V = ['coach_1', 'coach_2', 'coach_3']


def braking_bag(path, damage=None, samples=301, cylinders=False):
    """
    Write a 3-coach run braking at 1 m/s^2 from 20 m/s.

    ``damage(topic, k, names, fields) -> (names, fields)`` may change message ``k`` (0-based)
    of ``topic``; ``fields`` = [position, velocity, effort] (None: empty).
    """
    with BagRecorder(path) as rec:
        for k in range(samples):
            t = k * 0.01
            v = np.full(3, max(20.0 - t, 0.0))
            x = np.array([0.0, -25.0, -50.0]) + 20.0 * t - 0.5 * t * t
            msgs = {'couplers': (NAMES_C, [np.zeros(2), np.zeros(2), np.full(2, -1e4)]),
                    'coaches': (NAMES_V, [x, v, np.full(3, 4.5e4)])}
            if cylinders:
                msgs['brake_cylinders'] = (NAMES_V, [np.full(3, 3.8e5), None,
                                                     np.full(3, 0.0)])
            for topic, (names, fields) in msgs.items():
                if damage is not None:
                    names, fields = damage(topic, k, list(names), list(fields))
                rec.write_msg(topic, 10 ** 9 + k * 10 ** 7, joint_state(t, names, *fields))
    return path


def run(command, bag, out, capsys):
    code = offline.main([command, str(bag), '--output', str(out), '-q'])
    return code, capsys.readouterr().err.strip()


def every_message(topic_wanted, change):
    def damage(topic, k, names, fields):
        return change(names, fields) if topic == topic_wanted else (names, fields)
    return damage


def one_message(topic_wanted, k_wanted, change):
    def damage(topic, k, names, fields):
        if topic == topic_wanted and k == k_wanted:
            return change(names, fields)
        return names, fields
    return damage


def test_a_sound_bag_is_reported_and_plotted(tmp_path, capsys):
    bag = braking_bag(tmp_path / 'ok', cylinders=True)      # brake_cylinders: velocity empty
    assert run('report', bag, tmp_path / 'r', capsys)[0] == 0
    doc = json.loads((tmp_path / 'r' / 'summary.json').read_text())
    assert doc['train']['peak_deceleration'] == pytest.approx(1.0, rel=1e-3)
    assert run('plot', bag, tmp_path / 'p', capsys)[0] == 0


CASES = {
    # names, every array empty: read as a train standing still (was: exit 0, "stopped")
    'empty arrays': (every_message('couplers', lambda n, f: (n, [None, None, None])),
                     'couplers: message 1 (t = 0 s', '0 position value(s) for 2 names'),
    'empty coaches velocity': (every_message('coaches', lambda n, f: (n, [f[0], None, f[2]])),
                               'coaches: message 1 (t = 0 s',
                               '0 velocity value(s) for 3 names'),
    # one message with two speeds for three coaches (was: NaN-padded, exit 0)
    'ragged': (one_message('coaches', 150, lambda n, f: (n, [f[0], f[1][:2], f[2]])),
               'coaches: message 151 (t = 1.5 s', '2 velocity value(s) for 3 names'),
    'more values than names': (one_message('couplers', 7, lambda n, f: (n, [
        np.zeros(3), f[1], f[2]])), 'couplers: message 8 (t = 0.07 s',
        '3 position value(s) for 2 names'),
    # no names at all (was: report exit 1 "ValueError: a train has at least 2 vehicles")
    'no names': (every_message('coaches', lambda n, f: ([], [None, None, None])),
                 'coaches: message 1 (t = 0 s', 'no joint names'),
    'ragged cylinders': (one_message('brake_cylinders', 20, lambda n, f: (n, [
        f[0], np.zeros(1), f[2]])), 'brake_cylinders: message 21 (t = 0.2 s',
        '1 velocity value(s) for 3 names'),
}


@pytest.mark.parametrize('command', ['report', 'plot'])
@pytest.mark.parametrize('case', sorted(CASES))
def test_a_message_without_one_value_per_name_is_refused(tmp_path, capsys, command, case):
    damage, where, why = CASES[case]
    bag = braking_bag(tmp_path / 'bad', damage, cylinders=True)
    out = tmp_path / 'deep' / 'out'
    code, err = run(command, bag, out, capsys)
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f'train-dynamics: error: {bag}: {where}'), err
    assert why in err and 'refused, nothing written' in err, err
    assert not (tmp_path / 'deep').exists()
