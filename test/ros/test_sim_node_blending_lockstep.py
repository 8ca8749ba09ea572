"""
Lock-step over the brake control unit's inputs (``lockstep_inputs: [blending]``), over DDS.

A test script (``test/lockstep_demand_controller.py``) answers every output with one value
on each of ``brake_demand``, ``brake_emergency`` and ``ed_brake/trip``, in an order that
changes from output to output: the node waits for all three and applies them in one fixed
order, so two runs give byte-identical bags.
"""
from __future__ import annotations

from pathlib import Path
import sys

from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import run_scenario
from train_dynamics.testing.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = [sys.executable, str(ROOT / 'test' / 'lockstep_demand_controller.py')]
TRIP, RESTORE, EMERGENCY = 1.0, 1.6, 2.2        # [s] the script's ED trip, restore, emergency


def _scenario() -> Scenario:
    return Scenario(duration=2.6, name='flirt_demand_lockstep', parameters={
        'consist_file': str(ROOT / 'config' / 'consist_flirt_4.yaml'),
        'initial_speed': 20.0, 'brake_input': 'cylinder_per_coach', 'blending': 'builtin',
        'brake_demand_mode': 'fraction', 'full_service_deceleration': 1.1,
        'lockstep_inputs': ['blending'], 'publish_rate': 50.0,
        'buffer_stiffness': 2.0e7, 'buffer_friction': 5.0e6,
        'draw_gear_stiffness': 2.0e7, 'draw_gear_friction': 5.0e6},
        controller_parameters={'demand_time': 0.2, 'demand': 0.8, 'trip_time': TRIP,
                               'restore_time': RESTORE, 'emergency_time': EMERGENCY})


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(bag.iterdir())}


def test_demand_emergency_and_trip_in_lockstep_give_byte_identical_bags(tmp_path):
    runs = [run_scenario(_scenario(), SCRIPT, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.returncode == 0 and not run.error, run.report()
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'
    bag = runs[0].bag
    stamps = [t for _, t, _ in read_topics(bag, ['coaches'])]
    for topic in ('brake_demand', 'brake_emergency', 'ed_brake/trip'):
        assert sum(1 for _ in read_topics(bag, [topic])) == len(stamps), topic
    # the inputs act: ED braking before the trip, none while tripped, track/emergency after
    rows = {t: (sum(m.position), sum(m.velocity))
            for _, t, m in read_topics(bag, ['brake_blending'])}
    ed = {t: row[0] for t, row in rows.items()}
    before = [f for t, f in ed.items() if 0.6e9 <= t < TRIP * 1e9]
    tripped = [f for t, f in ed.items() if (TRIP + 0.1) * 1e9 <= t < RESTORE * 1e9]
    assert before and min(before) > 1.0e4
    assert tripped and max(tripped) == 0.0
    # emergency: the ED commanded to 0 (it ramps down), every cylinder to full pressure
    emergency = [t for t in rows if t > EMERGENCY * 1e9 + 0.05e9]
    assert all(ed[b] < ed[a] for a, b in zip(emergency, emergency[1:]) if ed[a] > 0.0)
    last_service = max(t for t in rows if t < EMERGENCY * 1e9)
    assert rows[emergency[-1]][1] > 1.5 * rows[last_service][1]
