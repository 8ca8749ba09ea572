"""
``train-dynamics report`` under hostile input: non-finite samples, a full disk.

A bag whose ``couplers`` or ``coaches`` hold a NaN or an infinite value is refused (one
line naming the topic, field, joint and time; exit 2; no report), never reported with wrong
numbers or as invalid JSON. A report that cannot be written whole (ENOSPC) leaves nothing.
"""
from __future__ import annotations

import errno
import json
import math

import numpy as np
import pytest

from train_dynamics.cli import offline
from train_dynamics.recording import metrics_report as report_mod
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.messages import joint_state

NAMES_C = ['coupler_1', 'coupler_2']
NAMES_V = ['coach_1', 'coach_2', 'coach_3']


def braking_bag(path, *, bad=None, samples=301):
    """Write a 3-coach run braking at 1 m/s^2; ``bad`` = (topic, field, column, k, value)."""
    with BagRecorder(path) as rec:
        for k in range(samples):
            t = k * 0.01
            v = np.full(3, max(20.0 - t, 0.0))
            x = np.array([0.0, -25.0, -50.0]) + 20.0 * t - 0.5 * t * t
            y, yd, f = np.zeros(2), np.zeros(2), np.full(2, -1e4)
            fields = {'couplers': [y, yd, f], 'coaches': [x, v, np.full(3, 4.5e4)]}
            if bad is not None and k == bad[3]:
                arr = fields[bad[0]][bad[1]].copy()
                arr[bad[2]] = bad[4]
                fields[bad[0]][bad[1]] = arr
            stamp = 10 ** 9 + k * 10 ** 7
            rec.write_msg('couplers', stamp, joint_state(t, NAMES_C, *fields['couplers']))
            rec.write_msg('coaches', stamp, joint_state(t, NAMES_V, *fields['coaches']))
    return path


def test_report_of_a_finite_bag_is_written(tmp_path):
    bag = braking_bag(tmp_path / 'ok')
    assert offline.main(['report', str(bag), '--output', str(tmp_path / 'r'), '-q']) == 0
    doc = json.loads((tmp_path / 'r' / 'summary.json').read_text())
    assert doc['train']['peak_deceleration'] == pytest.approx(1.0, rel=1e-3)


@pytest.mark.parametrize('topic,field,name,value', [
    ('coaches', 1, 'velocity', math.inf),       # was: JSON ValueError, exit 1
    ('coaches', 1, 'velocity', math.nan),       # was: exit 0, peak deceleration 901 m/s^2
    ('couplers', 2, 'effort', math.nan),        # was: dropped silently
    ('coaches', 0, 'position', -math.inf),
])
def test_report_nonfinite_speed_refused(tmp_path, capsys, topic, field, name, value):
    bag = braking_bag(tmp_path / 'bad', bad=(topic, field, 1, 150, value))
    out = tmp_path / 'r'
    assert offline.main(['report', str(bag), '--output', str(out), '-q']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f'{topic}: 1 non-finite value(s), the first {name} of ' in err
    assert 't = 1.5 s' in err and 'no report written' in err
    assert not out.exists()


def test_report_disk_full_leaves_nothing_partial(tmp_path, capsys, monkeypatch):
    bag = braking_bag(tmp_path / 'ok')

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, 'No space left on device')

    # summary.json and summary.md are written, then the first figure hits ENOSPC
    monkeypatch.setattr(report_mod, 'force_envelope', full)
    out = tmp_path / 'deep' / 'r'
    assert offline.main(['report', str(bag), '--output', str(out), '-q']) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'No space left on device' in err, err
    assert not (tmp_path / 'deep').exists()
    # into an existing folder: what was there stays, nothing of the failed report is added
    out.mkdir(parents=True)
    (out / 'mine.txt').write_text('x')
    assert offline.main(['report', str(bag), '--output', str(out), '-q']) == 1
    assert sorted(p.name for p in out.iterdir()) == ['mine.txt']
