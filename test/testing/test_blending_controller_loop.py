"""
An external blending controller in the loop (``blending: external``), lock-step over DDS.

``examples/blending_controller.py`` is the brake control unit of the FLIRT unit
(``examples/flirt_external_blending.yaml``): it reads ``coaches`` and ``brake_blending`` and
commands each motor car's ED brake (``coach_<i>/traction/command``) and each car's cylinder
(``coach_<i>/brake_cylinder/pressure``); lock-step waits for both every period.
"""
from __future__ import annotations

from pathlib import Path
import sys

from train_dynamics.recording.bags import read_topics
from train_dynamics.recording.blending_metrics import blending_metrics
from train_dynamics.testing import run_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / 'examples' / 'flirt_external_blending.yaml'
CONTROLLER = [sys.executable, str(ROOT / 'examples' / 'blending_controller.py')]

pytest_plugins = ['train_dynamics.testing.fixture']


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(bag.iterdir())}


def test_external_blending_loop_is_byte_identical_and_passes_its_criteria(tmp_path):
    runs = [run_scenario(SCENARIO, CONTROLLER, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.returncode == 0 and not run.error and run.passed, run.report()
        checked = {r.criterion.metric: r.value for r in run.results}
        assert 0.0 < checked['blending.friction_share'] < 0.05
        assert checked['blending.energy_regenerated'] > 2.5e7
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'
    # every period answered: one cylinder command per car and one ED command per motor car
    bag = runs[0].bag
    outputs = sum(1 for _ in read_topics(bag, ['coaches']))
    for topic in ('coach_1/brake_cylinder/pressure', 'coach_3/brake_cylinder/pressure',
                  'coach_1/traction/command', 'coach_4/traction/command'):
        assert sum(1 for _ in read_topics(bag, [topic])) == outputs, topic
    # ED first: at 80 km/h the motor cars' ED gives nearly all; friction takes over at the end
    m = blending_metrics(str(bag))
    assert m['energy_regenerated'] > 0.9 * (m['energy_regenerated'] + m['energy_friction'])
    assert 0.0 < m['friction_share'] < 0.1
    last = [msg for _, _, msg in read_topics(bag, ['brake_blending'])]
    moving = [msg for msg, (_, _, c) in zip(last, read_topics(bag, ['coaches']))
              if max(c.velocity) > 0.0]
    assert sum(moving[-1].velocity) > sum(moving[-1].position)      # friction at the stop
