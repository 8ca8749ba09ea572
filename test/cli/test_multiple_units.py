"""
The shipped multiple units with builtin blending, run offline; the unit's inputs from a bag.

config/emu_flirt_4.yaml and config/hs_ice3_8.yaml: a full-service stop from top speed each.
"""
import json
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.param_files import load_param_file
from train_dynamics.recording import messages
from train_dynamics.recording.bags import read_topics
from train_dynamics.recording.cdr import encode_float64
from train_dynamics.simulation.runner import command_events, InputSchedule, run_simulation

CONFIG = Path(__file__).resolve().parents[2] / 'config'
EPOCH_NS = 1_700_000_000_000_000_000


def _stop(params: str, duration: float):
    """Run ``params`` offline; return the config, the simulator and the stop (t, distance)."""
    cfg = load_param_file(str(CONFIG / params))
    inputs = InputSchedule(cfg.brake_input, [], None, 'schedule', command_events(cfg, []))
    t_demand = cfg.demand_schedule_times[0]
    state = {}

    def on_sample(s):
        if s.t <= t_demand + 1e-9:
            state['x0'] = float(s.sim.x[0])
        elif 'stop' not in state and s.sim.v.max() == 0.0:
            state['stop'] = (s.t - t_demand, float(s.sim.x[0]) - state['x0'])
    sim = run_simulation(cfg, duration, inputs, on_sample=on_sample)
    assert sim.fault is None and 'stop' in state
    return cfg, sim, state['stop']


@pytest.mark.parametrize('params, duration, regen_share', [
    ('emu_flirt_4.yaml', 50.0, (0.55, 0.70)),
    ('hs_ice3_8.yaml', 110.0, (0.35, 0.50)),
])
def test_shipped_unit_stops_from_top_speed(params, duration, regen_share):
    """
    Full service from top speed: distance within its closed-form bounds, energy balance.

    Upper bound: the demanded deceleration a after a jerk-limited ramp of a / J, resistance
    ignored: v0 a / (2 J) + v0^2 / (2 a). Lower bound: a plus the resistance of the whole
    train at v0 all the way: v0^2 / (2 (a + R(v0) / M)).
    """
    cfg, sim, (t_stop, dist) = _stop(params, duration)
    v0 = float(cfg.initial_speed)
    a = float(cfg.full_service_deceleration)
    jerk = float(cfg.blending_jerk_limit)
    mass = float(sim.inertia.sum())
    c = sim.consist
    resist = float(np.sum(c['davis_a'] + c['davis_b'] * v0 + c['davis_c'] * v0 ** 2))
    assert v0 ** 2 / (2 * (a + resist / mass)) < dist < v0 * a / (2 * jerk) + v0 ** 2 / (2 * a)
    assert t_stop < v0 / a + a / jerk
    ke0 = 0.5 * mass * v0 ** 2
    regen, friction = -sim.work_traction, sim.work_brake
    booked = regen + friction + sim.work_resistance + sim.work_coupler - sim.elastic_energy
    assert booked == pytest.approx(ke0, rel=5e-3)
    assert regen_share[0] < regen / ke0 < regen_share[1]
    assert friction > 0.25 * ke0             # the friction brakes took over below the ED


def test_brake_demand_emergency_and_trip_from_an_input_bag(tmp_path):
    """The bag's brake_demand replaces the schedule; ED trip, then emergency: all friction."""
    consist = (CONFIG / 'consist_flirt_4.yaml').read_text()
    (tmp_path / 'consist_flirt_4.yaml').write_text(consist)
    params = (CONFIG / 'emu_flirt_4.yaml').read_text().replace(
        'demand_schedule_times: [1.0]', 'demand_schedule_times: [0.1]')
    (tmp_path / 'p.yaml').write_text(params)
    with Writer(tmp_path / 'in', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        store = messages.typestore()
        conns = {t: w.add_connection(t, topics.FLOAT64, typestore=store) for t in (
            topics.BRAKE_DEMAND_TOPIC, topics.ED_TRIP_TOPIC, topics.BRAKE_EMERGENCY_TOPIC)}
        for t, topic, value in [(0.0, topics.BRAKE_DEMAND_TOPIC, 0.0),
                                (0.5, topics.BRAKE_DEMAND_TOPIC, 0.5),
                                (4.0, topics.ED_TRIP_TOPIC, 1.0),
                                (8.0, topics.BRAKE_EMERGENCY_TOPIC, 1.0)]:
            w.write(conns[topic], EPOCH_NS + int(t * 1e9), encode_float64(value))
    assert cli.main(['simulate', '--params', str(tmp_path / 'p.yaml'), '--input',
                     str(tmp_path / 'in'), '--duration', '12', '--output',
                     str(tmp_path / 'out'), '-q']) == 0
    out = tmp_path / 'out'
    echoed = [(t, m.data) for _, t, m in read_topics(out, [topics.BRAKE_DEMAND_TOPIC])]
    assert echoed == [(0, 0.0), (500_000_000, 0.5)]      # the schedule's 1.0 at 0.1 s: replaced
    coaches = {t: m for _, t, m in read_topics(tmp_path / 'out', ['coaches'])}
    mass = np.array([34000.0, 26000.0, 26000.0, 34000.0])
    inertia = mass * np.array([1.08, 1.04, 1.04, 1.08])
    # 3.9 s: half of 1.1 m/s^2, the ED at work (friction short of it)
    fb = np.array(coaches[3_900_000_000].effort)
    assert fb.sum() < 0.5 * 1.1 * inertia.sum() * 0.8
    # 7.9 s: the ED tripped at 4 s, friction alone gives the demand
    fb = np.array(coaches[7_900_000_000].effort)
    assert fb.sum() == pytest.approx(0.5 * 1.1 * inertia.sum(), rel=0.01)
    assert fb / fb.sum() == pytest.approx(inertia / inertia.sum(), rel=1e-3)  # by mass
    # 11.9 s: emergency, every cylinder at p_max: mu_a m g
    fb = np.array(coaches[11_900_000_000].effort)
    assert fb == pytest.approx(0.16 * 9.81 * mass, rel=1e-3)
    # the brake control unit's outputs: per car ED / friction / track; demand and achieved
    per_car = {t: m for _, t, m in read_topics(out, [topics.BRAKE_BLENDING_TOPIC])}
    state = {t: m for _, t, m in read_topics(out, [topics.BRAKE_DEMAND_STATE_TOPIC])}
    assert len(per_car) == len(state) == len(coaches)
    m = per_car[3_900_000_000]
    assert list(m.name) == ['coach_1', 'coach_2', 'coach_3', 'coach_4']
    assert m.position[0] > 20000.0 and m.position[1] == 0.0           # ED of motor cars only
    assert np.array(m.velocity) == pytest.approx(coaches[3_900_000_000].effort)
    s = state[7_900_000_000]
    assert list(s.name) == ['demand', 'achieved']
    assert s.position[0] == pytest.approx(0.55) and s.position[1] == pytest.approx(0.55, rel=0.01)
    assert s.effort[1] == 0.0                                          # ED tripped


def test_report_books_regenerated_and_friction_energy(tmp_path):
    """report: energies from the bag match the simulator's work, friction share, stop."""
    out = tmp_path / 'run'
    assert cli.main(['simulate', '--params', str(CONFIG / 'emu_flirt_4.yaml'), '--duration',
                     '45', '--output', str(out), '-q']) == 0
    assert cli.main(['report', str(out), '--output', str(tmp_path / 'rep'), '-q']) == 0
    doc = json.loads((tmp_path / 'rep' / 'summary.json').read_text())
    b = doc['blending']
    cfg, sim, (t_stop, dist) = _stop('emu_flirt_4.yaml', 45.0)
    assert b['energy_regenerated'] == pytest.approx(-sim.work_traction, rel=5e-3)
    assert b['energy_friction'] == pytest.approx(sim.work_brake, rel=5e-3)
    assert b['friction_share'] == pytest.approx(
        sim.work_brake / (sim.work_brake - sim.work_traction), rel=1e-2)
    assert b['stopping_distance'] == pytest.approx(dist, abs=0.5)
    assert b['stopping_time'] == pytest.approx(t_stop, abs=0.011)
    assert b['max_tracking_error'] < 0.05              # the demand followed within 5 %
    assert b['max_jerk'] <= cfg.blending_jerk_limit * 1.05
    assert '## Brake blending' in (tmp_path / 'rep' / 'summary.md').read_text()
