"""
Brake systems of real trains on the pneumatic model.

Emergency accelerators, the pipe's wave speed, EP and ECP brakes, distributed power (remote
locomotives over a radio link).

Figures: UIC 540 (emergency propagation >= 250 m/s), UIC 541-5 (EP brake: electric
application and holding at every vehicle, pneumatic back-up), AAR S-4200 (ECP: the head-end
unit commands each car's cylinder pressure; loss of the train line is a penalty application).
"""
import math

import numpy as np
import pytest

from train_dynamics.physics import pneumatic as pn
from train_dynamics.physics.kernel import pneumatic as pk

H = 0.002
BAR = 1.0e5
P_MAX = 380000.0


def make(n, regime='P', length=25.0, **kw):
    """Charged brake of n vehicles; keyword arguments of the brake or of its spec."""
    spec = {k: kw.pop(k) for k in list(kw) if k in pn.PneumaticSpec.__dataclass_fields__}
    return pn.PneumaticBrake([length] * n, [P_MAX] * n, [regime] * n, H,
                             pn.PneumaticSpec().replace(**spec), **kw)


def run(brake, seconds, every=0.01, at=()):
    """Advance, sampling (t, pipe, cylinder, applied); ``at`` [(t, action)] acts on the way."""
    out = []
    steps = int(round(every / H))
    pending = sorted(at, key=lambda a: a[0])
    for _ in range(int(round(seconds / every))):
        while pending and pending[0][0] <= brake.t + 1e-9:
            pending.pop(0)[1](brake)
        brake.advance(steps)
        out.append((brake.t, brake.pipe_pressure, brake.cylinder_pressure,
                    brake.applied.copy()))
    t = np.array([s[0] for s in out])
    return t, np.array([s[1] for s in out]), np.array([s[2] for s in out]), \
        np.array([s[3] for s in out])


def first(t, mask):
    """First instant at which mask holds (per column), inf where never."""
    mask = np.asarray(mask)
    hit = mask.any(axis=0)
    return np.where(hit, t[np.argmax(mask, axis=0)], np.inf)


def emergency(brake):
    brake.set_command(0.0)


# -- emergency accelerators ----------------------------------------------------------------
def test_accelerators_carry_the_emergency_along_a_passenger_train():
    """1000 m, 40 coaches: 1 bar drop >= 250 m/s, last cylinder 95 % within t1 + L/250 + 1."""
    single = make(1)
    t, _, cyl, _ = run(single, 8.0, at=[(0.0, emergency)])
    t_single = first(t, cyl[:, 0] >= 0.95 * cyl[-1, 0])
    assert 3.0 <= t_single <= 5.0
    n, length = 40, 25.0
    brake = make(n, accelerators=True)
    t, pipe, cyl, _ = run(brake, 12.0, at=[(0.0, emergency)])
    drop = first(t, pipe < pipe[0] - 1.0 * BAR)
    assert np.all(np.isfinite(drop)) and np.all(np.diff(drop) >= 0.0)
    distance = (n - 1) * length
    assert distance / (drop[-1] - drop[0]) >= 250.0
    final = cyl[-1, -1]
    assert final == pytest.approx(P_MAX, rel=0.02)
    t95 = first(t, cyl[:, -1] >= 0.95 * final)
    assert t95 <= t_single + n * length / 250.0 + 1.0
    assert brake.accelerator_open.sum() == 0        # closed again once the pipe is empty


def test_accelerators_off_reproduce_the_slow_tail():
    """Without accelerators: the pipe's 1 bar drop crawls (~80 m/s), bit for bit as before."""
    plain = make(40)
    off = make(40, accelerators=False)
    t, pipe, cyl, _ = run(off, 12.0, at=[(0.0, emergency)])
    t2, pipe2, cyl2, _ = run(plain, 12.0, at=[(0.0, emergency)])
    assert np.array_equal(pipe, pipe2) and np.array_equal(cyl, cyl2)
    drop = first(t, pipe < pipe[0] - 1.0 * BAR)
    assert 39 * 25.0 / (drop[-1] - drop[0]) < 120.0
    assert first(t, cyl[:, -1] >= 0.95 * P_MAX) > 12.0


def test_accelerators_ignore_a_full_service_application():
    """A step of the command to full service (3.5 bar) does not fire any accelerator."""
    brake = make(40, accelerators=True)
    opened = []
    t, pipe, cyl, _ = run(brake, 10.0, at=[(0.0, lambda b: b.set_command(3.5 * BAR))])
    for _ in range(200):
        brake.advance(5)
        opened.append(brake.accelerator_open.any())
    assert not any(opened)
    assert pipe[-1].min() > 3.3 * BAR


def test_closed_pipe_step_arrives_at_l_over_c():
    """Frictionless closed pipe: a small step reaches the far end at L / c, c = sqrt(R T)."""
    spec = {'viscosity': 1.0e-12, 'hose_loss': 0.0}
    brake = make(2, length=500.0, **spec)
    brake.set_lap(True)
    dp = 0.05 * BAR
    cells = brake.cells
    left = slice(0, int(brake.start[1]))
    cells[pk.C_M, left] *= 1.0 + dp / (brake.spec.nominal_pressure
                                       + brake.spec.atmospheric_pressure)
    x_step = float(np.sum(cells[pk.C_VOL, left])) / brake.sc[pk.S_AREA]
    x_end = (np.sum(cells[pk.C_VOL]) - 0.5 * cells[pk.C_VOL, -1]) / brake.sc[pk.S_AREA]
    c = math.sqrt(brake.rt)
    ts, far = [], []
    p0 = brake.cell_pressure[-1]
    for _ in range(int(2.5 / H)):
        brake.advance(1)
        ts.append(brake.t)
        far.append(brake.cell_pressure[-1] - p0)
    # the wave of height dp/2 doubles on the closed end: its half height there is dp/2
    arrival = first(np.array(ts), np.array(far) >= 0.5 * dp)
    assert arrival == pytest.approx((x_end - x_step) / c, rel=0.02)


# -- EP brake ------------------------------------------------------------------------------
def test_ep_applies_every_vehicle_within_the_valve_delay_and_graduates():
    brake = make(16, brake_system='ep')           # 400 m
    delay = brake.spec.ep_valve_delay
    steps = [(1.0, 0.5), (5.0, 0.25), (9.0, 1.0), (13.0, 0.0)]
    t, pipe, cyl, _ = run(brake, 20.0, at=[(ts, lambda b, f=f: b.set_ep_command(f))
                                           for ts, f in steps])
    start = first(t, cyl > 0.05 * BAR)
    assert np.all(start >= 1.0 + delay) and np.all(start <= 1.0 + delay + 0.05)
    for (ts, f), (te, _) in zip(steps[:-1], steps[1:]):
        at_end = cyl[np.searchsorted(t, te - 0.02)]
        assert at_end == pytest.approx(np.full(16, f * P_MAX), abs=0.05 * BAR)
    assert cyl[-1].max() < 0.1 * BAR                # released
    assert pipe.min() > 4.9 * BAR                    # the pipe stays charged
    assert brake.ep_command_received == 0.0


def test_ep_line_cut_falls_back_to_the_pneumatic_brake():
    brake = make(16, brake_system='ep')
    t, pipe, cyl, applied = run(brake, 25.0, at=[(0.0, lambda b: b.set_train_line(False)),
                                                 (1.0, lambda b: b.set_ep_command(0.5))])
    # the head regulates the pipe to 5 - 0.5 * 1.5 bar; the distributors apply p_max / 2
    assert pipe[-1] == pytest.approx(np.full(16, 4.25 * BAR), abs=0.05 * BAR)
    assert applied[-1].all()
    assert cyl[-1] == pytest.approx(np.full(16, 0.5 * P_MAX), abs=0.15 * BAR)
    assert not brake.train_line


# -- ECP brake -----------------------------------------------------------------------------
def test_ecp_tracks_the_command_and_releases_graduated():
    brake = make(30, 'G', 20.0, brake_system='ecp')
    steps = [(1.0, 0.6), (6.0, 0.3), (11.0, 0.8), (16.0, 0.0)]
    t, pipe, cyl, _ = run(brake, 21.0, at=[(ts, lambda b, f=f: b.set_ep_command(f))
                                           for ts, f in steps])
    for ts, f in steps:
        window = (t >= ts + 3.0) & (t <= ts + 5.0)
        assert np.abs(cyl[window] - f * P_MAX).max() <= 0.1 * BAR
    assert pipe.min() > 4.8 * BAR


def test_ecp_penalty_on_lost_train_line_and_on_pipe_loss():
    brake = make(10, 'G', 20.0, brake_system='ecp')
    t, _, cyl, _ = run(brake, 5.0, at=[(0.5, lambda b: b.set_ep_command(0.2)),
                                       (1.0, lambda b: b.set_train_line(False))])
    assert cyl[-1] == pytest.approx(np.full(10, P_MAX), abs=0.1 * BAR)
    brake = make(10, 'G', 20.0, brake_system='ecp')
    t, pipe, cyl, _ = run(brake, 8.0, at=[(0.5, emergency)])
    assert pipe[-1].max() < 2.0 * BAR
    assert cyl[-1] == pytest.approx(np.full(10, P_MAX), abs=0.1 * BAR)


# -- distributed power ---------------------------------------------------------------------
def freight(remote_at=None, **kw):
    """1500 m: 75 wagons of 20 m (G), an optional remote locomotive at index remote_at."""
    n = 75
    remotes = np.zeros(n, dtype=bool)
    if remote_at is not None:
        remotes[remote_at] = True
    return make(n, 'G', 20.0, remotes=remotes, **kw)


@pytest.fixture(scope='module')
def head_only():
    t, _, _, applied = run(freight(), 10.0, every=0.02, at=[(0.0, emergency)])
    return first(t, applied)


@pytest.mark.parametrize('where', [74, 37])
def test_dp_remote_shortens_the_emergency(head_only, where):
    brake = freight(where)
    t, _, _, applied = run(brake, 10.0, every=0.02, at=[(0.0, emergency)])
    times = first(t, applied)
    delay = brake.spec.radio_delay
    # the remote applies its neighbours after the radio delay, long before the head's wave
    assert times[where] < delay + 0.3 < 1500.0 / math.sqrt(brake.rt)
    ratio = times.max() / head_only.max()
    if where == 74:
        assert 0.4 <= ratio <= 0.6, ratio
    else:
        assert ratio <= 0.75, ratio
    assert np.isfinite(times).all()


def test_dp_traction_after_the_radio_delay_and_loss_fallback():
    brake = freight(74)
    delay = brake.spec.radio_delay
    brake.advance(int(round(1.0 / H)))
    brake.set_traction(0.7)
    brake.advance(int(round((delay - 0.02) / H)))
    assert brake.remote_traction == 0.0
    brake.advance(int(round(0.04 / H)))
    assert brake.remote_traction == 0.7
    assert brake.radio_ok
    # every message lost: after the timeout the remote idles and holds (valve lapped)
    lossy = freight(74, radio_loss=1.0)
    lossy.set_traction(0.5)
    lossy.advance(int(round(1.0 / H)))
    assert lossy.radio_ok and lossy.remote_traction == 0.0
    lossy.advance(int(round((lossy.spec.radio_timeout + 1.0) / H)))
    assert not lossy.radio_ok and lossy.remote_traction == 0.0
    assert lossy.veh[pk.V_RLAP, 74] == 1.0
    assert lossy.radio_lost == lossy.radio_sent > 0
    # the lapped remote neither charges nor vents: an emergency from the head still
    # applies the whole train (from the head only: the tail's pipe empties slowly)
    t, pipe, _, applied = run(lossy, 20.0, every=0.02, at=[(0.0, emergency)])
    assert applied[-1].all() and pipe[-1, 0] < 0.5 * BAR
    assert np.all(np.diff(pipe[:, -1])[-100:] < 0.0)
    # some loss: the repeats get through, the link stays up
    flaky = freight(74, radio_loss=0.3)
    flaky.advance(int(round(10.0 / H)))
    assert flaky.radio_ok and 0 < flaky.radio_lost < flaky.radio_sent


def test_bad_ep_command_rejected():
    brake = make(2, brake_system='ep')
    for bad in (float('nan'), -0.1, 1.5):
        with pytest.raises(ValueError):
            brake.set_ep_command(bad)
    with pytest.raises(ValueError):
        make(2, brake_system='vacuum')


# -- the simulator and the offline run loop ------------------------------------------------
DP_CONSIST = """
vehicles:
  - {type: heavy_freight_locomotive}
  - {type: freight_wagon_loaded, count: 8}
  - {type: heavy_freight_locomotive, remote: true}
"""


def test_simulator_dp_traction_and_ep_command_through_the_run_loop(tmp_path):
    from train_dynamics.physics.config import ConfigError, SimConfig
    from train_dynamics.physics.kernel.layout import INPUT
    from train_dynamics.physics.train import TrainSimulator
    from train_dynamics.simulation.runner import CommandEvent, InputSchedule, run_simulation
    from train_dynamics import topics
    (tmp_path / 'dp.yaml').write_text(DP_CONSIST)
    base = {'consist_file': str(tmp_path / 'dp.yaml'), 'brake_model': 'pneumatic',
            'initial_speed': 10.0, 'radio_delay': 0.4}
    with pytest.raises(ConfigError, match='pneumatic'):
        SimConfig.from_dict({**base, 'brake_model': 'empirical'})
    with pytest.raises(ConfigError, match='consist'):
        SimConfig.from_dict({'remote': True})
    cfg = SimConfig.from_dict(base)
    sim = TrainSimulator(cfg)
    assert sim.remotes == [9] and sim.locomotives == [0] and sim.lead == 0
    with pytest.raises(ValueError, match='remote'):
        sim.set_traction_command(0.5, 9)
    sim.set_traction_command(0.5, 0)
    sim.advance(int(round(0.3 / sim.h)))
    assert sim.coach[INPUT.T_CMD, 9] == 0.0
    sim.advance(int(round(0.2 / sim.h)))
    assert sim.coach[INPUT.T_CMD, 9] == 0.5 and sim.coach[INPUT.T_CMD, 0] == 0.5
    # EP through the offline run loop: the command event reaches every cylinder
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_system': 'ep',
                               'num_coaches': 4, 'initial_speed': 10.0})
    t_ns = 1_000_000_000
    events = [CommandEvent.at('ep', None, 0.5, t_ns, cfg.integration_step)]
    assert events[0].topic == topics.EP_COMMAND_TOPIC
    seen = []
    sim = run_simulation(cfg, 4.0, InputSchedule(topics.PIPE_HEAD, commands=events),
                         on_sample=lambda s: None, on_input=seen.append)
    assert seen == events and sim.fault is None
    assert sim.pneu.cylinder_pressure == pytest.approx(np.full(4, 0.5 * P_MAX), abs=0.05 * BAR)
    with pytest.raises(ConfigError, match='brake_model pneumatic'):
        SimConfig.from_dict({'brake_system': 'ecp'})


def test_shipped_passenger_scenario_carries_the_emergency_at_250_m_s():
    """
    config/passenger_pneumatic_40.yaml (1022 m): the 1 bar drop travels at >= 250 m/s.

    The speed along the train (least squares of the drop instants against the distributors'
    positions, :func:`propagation_speed`). The locomotive at the head has no accelerator: the
    first coach drops 1 bar 0.3-0.4 s after it (only the brake valve's vent empties the head),
    which the end-to-end ratio (first to last vehicle) charges to the whole train.
    """
    import os

    from train_dynamics.physics.brake_valve import BrakeValveModel
    from train_dynamics.param_files import load_param_file
    from train_dynamics.physics.train import TrainSimulator

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    cfg = load_param_file(os.path.join(root, 'config', 'passenger_pneumatic_40.yaml'))
    sim = TrainSimulator(cfg)
    valve = BrakeValveModel(schedule=['0.0:release', '1.0:emergency'])
    lengths = np.array(cfg.consist['length'])
    every = 0.004
    t, pipe = [], []
    for k in range(int(round(7.0 / every))):
        sim.set_head_pipe_pressure(valve.advance_to(k * every))
        sim.advance_to((k + 1) * every)
        t.append(sim.t)
        pipe.append(sim.pipe_pressure)
    t, pipe = np.array(t), np.array(pipe)
    drop = first(t, pipe < pipe[0] - 1.0 * BAR)
    assert np.all(np.isfinite(drop)) and np.all(np.diff(drop[1:]) > 0.0)
    speed = pn.propagation_speed(lengths, drop)
    assert speed >= 250.0
    # the coaches alone, every one with its accelerator, as the 40-coach case
    assert pn.propagation_speed(lengths[1:], drop[1:]) >= 250.0
    # the head: the locomotive's distributor drops first, the first coach later
    assert 0.2 < drop[1] - drop[0] < 0.5


def test_propagation_speed_of_a_front_at_a_known_speed():
    """Instants x / c (plus a constant lag) give c back, whatever the vehicles' lengths."""
    lengths = np.array([19.1] + [26.4] * 10 + [14.0])
    middle = np.cumsum(lengths) - 0.5 * lengths
    assert pn.propagation_speed(lengths, 0.7 + middle / 273.0) == pytest.approx(273.0)


def test_ep_schedule_offline_commands_recorded_and_states_recorded(tmp_path):
    """ep_schedule_*: the train line's commands offline, recorded with brake_ep/state."""
    from train_dynamics import topics
    from train_dynamics.cli import offline as cli
    from train_dynamics.physics.config import ConfigError, SimConfig
    from train_dynamics.recording.bags import bag_info, read_topics

    p = tmp_path / 'ep.yaml'
    p.write_text("""train_dynamics:
  ros__parameters:
    num_coaches: 4
    initial_speed: 20.0
    brake_model: pneumatic
    brake_system: ecp
    ep_schedule_times: [1.0, 5.0]
    ep_schedule_commands: [0.5, 0.25]
brake_valve:
  ros__parameters:
    schedule: ["0.0:release"]
""")
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(p), '--duration', '9', '--output', str(out),
                     '-q']) == 0
    info = bag_info(str(out))
    assert info.topics[topics.EP_COMMAND_TOPIC][0] == topics.FLOAT64
    assert info.topics[topics.BRAKE_EP_STATE_TOPIC][0] == topics.JOINT_STATE
    commands = [(t, m.data) for _, t, m in read_topics(str(out), [topics.EP_COMMAND_TOPIC])]
    assert [c for _, c in commands] == [0.5, 0.25]
    states = [m for _, _, m in read_topics(str(out), [topics.BRAKE_EP_STATE_TOPIC])]
    cyl = [m for _, _, m in read_topics(str(out), [topics.BRAKE_CYLINDERS_TOPIC])]
    assert len(states) == len(cyl)            # at every output, as the other outputs

    def at(msgs, t):
        return next(m for m in msgs if m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                    >= t - 1e-9)
    # received 0.2 s (the valve delay) after each command; the car control devices follow
    assert np.all(np.asarray(at(states, 1.1).position) == 0.0)
    assert np.all(np.asarray(at(states, 1.3).position) == 0.5)
    assert np.all(np.asarray(at(states, 1.3).velocity) == 1.0)      # filling
    assert np.all(np.asarray(at(states, 4.9).position) == 0.5)
    assert np.allclose(at(cyl, 4.9).position, 0.5 * P_MAX, atol=0.1 * BAR)
    assert np.all(np.asarray(at(states, 5.3).velocity) == -1.0)     # graduated release
    assert np.allclose(at(cyl, 9.0).position, 0.25 * P_MAX, atol=0.1 * BAR)
    assert np.all(np.asarray(at(states, 9.0).effort) == 1.0)         # the line stayed healthy
    with pytest.raises(ConfigError, match='brake_system'):
        SimConfig.from_dict({'ep_schedule_times': [1.0], 'ep_schedule_commands': [0.5]})
    with pytest.raises(ConfigError, match='same length'):
        SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_system': 'ep',
                             'ep_schedule_times': [1.0], 'ep_schedule_commands': []})
