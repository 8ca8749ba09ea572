"""
Slide protection with every way the brake is commanded (offline, the simulator itself).

The builtin WSP's valves sit between the brake's source and the cylinder: whatever drives the
cylinder (the distributors of ``pipe_head`` and ``pipe_per_coach``, the input of
``cylinder_per_coach``, the pneumatic brake with its EP valves), a vented cylinder stays vented
and a held one held until the valves let go, however often the command is repeated. On 0.05
adhesion with the paper's brake (mu_a = 0.1, twice what the rail carries) an unprotected
wheel locks for most of the stop; a protected one never stays at rest for long.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.physics import wheelset as wsl
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.train import TrainSimulator

P_FULL = 3.8e5
#: a controller repeating its full-brake command every 0.1 s
PERIOD = 0.1
V0 = 60 / 3.6

#: brake_input (and brake model) -> the repeated full-brake command
MODES = {
    'cylinder_per_coach': ({'brake_input': 'cylinder_per_coach'},
                           lambda sim: sim.set_cylinder_pressure(P_FULL)),
    'pipe_per_coach': ({'brake_input': 'pipe_per_coach'},
                       lambda sim: sim.set_pipe_pressure(np.zeros(sim.n))),
    'pipe_head': ({'brake_input': 'pipe_head'}, lambda sim: sim.set_head_pipe_pressure(0.0)),
    'pneumatic_pipe_head': ({'brake_input': 'pipe_head', 'brake_model': 'pneumatic'},
                            lambda sim: sim.set_head_pipe_pressure(0.0)),
    'ep': ({'brake_input': 'pipe_head', 'brake_model': 'pneumatic', 'brake_system': 'ep'},
           lambda sim: sim.set_ep_command(1.0)),
}


def _sim(wsp: str, **overrides) -> TrainSimulator:
    values = {'num_coaches': 3, 'initial_speed': V0, 'davis_a': 300.0,
              'track_adhesion_positions': [-1.0e6], 'track_adhesion': [0.05], 'wsp': wsp}
    values.update(overrides)
    return TrainSimulator(SimConfig.from_dict(values))


def _stop(sim: TrainSimulator, command, t_end: float = 120.0) -> dict:
    """Repeat ``command`` every PERIOD until the train stops; the longest locked spell [s]."""
    steps = int(round(PERIOD / sim.h))
    zero_run = np.zeros(sim.n)
    longest = np.zeros(sim.n)
    while np.any(sim.v > 0.0) and sim.t < t_end:
        command(sim)
        for _ in range(steps // 10):
            sim.advance(10)
            locked = (sim.v > 0.0) & (sim.wheel_speed == 0.0)
            zero_run = np.where(locked, zero_run + 10 * sim.h, 0.0)
            longest = np.maximum(longest, zero_run)
    return {'longest_locked': longest, 'time': sim.t, 'sliding_time': sim.sliding_time,
            'stopped': bool(np.all(sim.v == 0.0))}


@pytest.mark.parametrize('mode', sorted(MODES))
def test_builtin_wsp_keeps_the_wheels_turning_under_a_repeated_command(mode):
    """Full brake repeated every 0.1 s on 0.05 adhesion: no wheel at rest > 0.5 s while moving."""
    overrides, command = MODES[mode]
    r = _stop(_sim('builtin', **overrides), command)
    assert r['stopped']
    assert np.all(r['longest_locked'] <= 0.5), r['longest_locked']
    assert np.all(r['sliding_time'] < 0.2 * r['time'])


def test_without_wsp_the_repeated_cylinder_command_locks_the_wheels():
    """The same run without slide protection: every wheel locked for most of the stop."""
    overrides, command = MODES['cylinder_per_coach']
    r = _stop(_sim('none', **overrides), command)
    assert r['stopped']
    assert np.all(r['longest_locked'] > 5.0)
    assert np.all(r['sliding_time'] > 0.8 * r['time'])


def test_vent_valve_empties_an_input_cylinder_whatever_the_input_repeats():
    """With wsp external: vent on coach 1, hold on coach 2, the input repeating every 20 ms."""
    sim = _sim('external', brake_input='cylinder_per_coach', track_adhesion=[0.331])
    sim.set_cylinder_pressure(P_FULL)
    sim.advance(5)
    sim.set_wsp_valve(wsl.VENT, 0)
    sim.set_wsp_valve(wsl.HOLD, 1)
    sim.advance(1)                            # the valves act from this step on
    every = int(round(0.02 / sim.h))
    for _ in range(5):                        # 0.1 s more
        sim.set_cylinder_pressure(P_FULL * 0.9)
        sim.advance(every)
    p = sim.cylinder_pressure
    assert p[0] == pytest.approx(P_FULL * np.exp(-(0.1 + sim.h) / wsl.VENT_TAU), rel=1e-9)
    assert p[1] == P_FULL                     # held above the lower input it was given
    assert p[2] == P_FULL * 0.9
    # released: the vented cylinder refills toward the input, the held one falls to it
    sim.set_wsp_valve(wsl.NORMAL, 0)
    sim.set_wsp_valve(wsl.NORMAL, 1)
    sim.set_cylinder_pressure(P_FULL * 0.9)
    sim.advance(every)
    p1 = sim.cylinder_pressure
    assert p[0] < p1[0] < P_FULL * 0.9
    assert p1[1] == P_FULL * 0.9


def test_offline_command_wsp_on_cylinder_inputs_repeated_every_0_1_s(tmp_path):
    """
    The offline command, an input bag of full cylinder pressure every 0.1 s, 0.05 adhesion.

    The recorded ``wheelsets`` and ``coaches``: no wheel at rest for over 0.5 s while its
    vehicle moves (the same run without slide protection locks every wheel for most of it).
    """
    from train_dynamics import topics
    from train_dynamics.cli import offline as cli
    from train_dynamics.recording.bags import BagRecorder, read_topics
    from train_dynamics.recording.cdr import encode_fluid_pressure
    atm = 101325.0
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    for i in (1, 2, 3):
        rec.add_topic(f'coach_{i}/brake_cylinder/pressure', topics.FLUID_PRESSURE)
    for k in range(300):                         # 30 s
        t_ns = k * 100_000_000
        for i in (1, 2, 3):
            rec.write(f'coach_{i}/brake_cylinder/pressure', t_ns,
                      encode_fluid_pressure(t_ns, atm + P_FULL))
    rec.close()
    longest = {}
    for wsp in ('builtin', 'none'):
        p = tmp_path / f'{wsp}.yaml'
        p.write_text(f"""train_dynamics:
  ros__parameters:
    num_coaches: 3
    initial_speed: {40 / 3.6}
    brake_input: cylinder_per_coach
    track_adhesion_positions: [-1000000.0]
    track_adhesion: [0.05]
    wsp: {wsp}
""")
        out = tmp_path / f'out_{wsp}'
        assert cli.main(['simulate', '--params', str(p), '--input', str(inp), '--duration',
                         '30', '--output', str(out), '-q']) == 0
        msgs = {topics.COACHES_TOPIC: [], topics.WHEELSETS_TOPIC: []}
        for topic, t_ns, m in read_topics(str(out), list(msgs)):
            msgs[topic].append((t_ns, np.array(m.velocity)))
        v = np.array([m for _, m in msgs[topics.COACHES_TOPIC]])
        u = np.array([m for _, m in msgs[topics.WHEELSETS_TOPIC]])
        dt = 1e-9 * (msgs[topics.COACHES_TOPIC][1][0] - msgs[topics.COACHES_TOPIC][0][0])
        run = np.zeros(3)
        worst = np.zeros(3)
        for vk, uk in zip(v, u):
            run = np.where((vk > 0.05) & (uk == 0.0), run + dt, 0.0)
            worst = np.maximum(worst, run)
        longest[wsp] = worst
    assert np.all(longest['builtin'] <= 0.5), longest
    assert np.all(longest['none'] > 5.0), longest
