"""
Per-bogie slide protection in lock-step (``lockstep_inputs: [brake, wsp]``, ``bogie_wheelsets``).

A controller (``test/lockstep_bogie_wsp_controller.py``) vents the brake pipe and answers
every output with one valve state on each bogie's ``coach_<i>/bogie_<j>/wsp/valve``, from the
bogie's slip. On 0.05 adhesion from 60 km/h the emergency brake (0.1 g) slides the wheels;
the controller keeps every bogie's wheel turning (none at rest for 0.5 s while its car
moves), each period waits for all six bogies' answers (every output answered on every bogie
topic), and two runs give byte-identical bags.
"""
from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import run_scenario
from train_dynamics.testing.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]
TOPICS = [f'coach_{i}/bogie_{j}/wsp/valve' for i in (1, 2, 3) for j in (1, 2)]


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(Path(bag).iterdir())}


def _run(path: Path):
    scenario = Scenario(duration=8.0, name='bogie_wsp', parameters={
        'num_coaches': 3, 'initial_speed': 60 / 3.6, 'davis_a': 300.0,
        'track_adhesion_positions': [-1.0e6], 'track_adhesion': [0.05],
        'wsp': 'external', 'bogie_wheelsets': True, 'lockstep_inputs': ['brake', 'wsp'],
        'publish_rate': 50.0})
    run = run_scenario(scenario, [sys.executable,
                                  str(ROOT / 'test' / 'lockstep_bogie_wsp_controller.py')],
                       path)
    assert run.returncode == 0 and not run.error, run.report()
    return run


def test_per_bogie_wsp_in_lockstep_is_answered_per_bogie_and_reproducible(tmp_path):
    run = _run(tmp_path / 'a')
    outputs = sum(1 for _ in read_topics(run.bag, ['coaches']))
    assert outputs >= 400
    for topic in TOPICS:
        assert sum(1 for _ in read_topics(run.bag, [topic])) == outputs, topic
    v = np.array([m.velocity for _, _, m in read_topics(run.bag, ['coaches'])])
    u = np.array([m.velocity for _, _, m in read_topics(run.bag, ['wheelsets'])])
    assert np.any(u < np.repeat(v, 2, axis=1) - 0.5)         # the wheels did slip
    resting = (u == 0.0) & (np.repeat(v, 2, axis=1) > 0.0)
    longest = np.zeros(6)
    run_len = np.zeros(6)
    for row in resting:
        run_len = np.where(row, run_len + 0.02, 0.0)
        longest = np.maximum(longest, run_len)
    assert np.all(longest < 0.5), longest
    again = _run(tmp_path / 'b')
    assert _files(run.bag) == _files(again.bag)
