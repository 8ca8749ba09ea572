"""
The pneumatic brake against the published requirements for UIC air brakes.

Figures used (UIC leaflet 540, 5th ed. 2006, with UIC 541-1 and EN 15355 for the
distributor valve):
- emergency propagation speed along the brake pipe >= 250 m/s;
- P regime: brake cylinder at 95 % of its maximum 3-5 s after an emergency application,
  released below 0.4 bar 15-20 s after the release begins; G regime: 18-30 s and 45-60 s;
- sensitivity: a brake-pipe drop of 0.6 bar in 6 s applies the brake within 1.2 s;
  insensitivity: a drop of 0.3 bar in 60 s does not apply it;
- full service: the pipe 1.5 bar below the 5 bar running pressure (3.5 bar), maximum
  cylinder pressure 3.8 bar.
"""
import numpy as np
import pytest

from train_dynamics.physics import pneumatic as pn
from train_dynamics.physics.brake_valve import BrakeValveModel
from train_dynamics.physics.kernel import pneumatic as pk

H = 0.002
BAR = 1.0e5
P_MAX = 380000.0


def make(n=1, regime='P', length=25.0, **spec):
    """Pneumatic brake of n vehicles, charged, h = 2 ms."""
    return pn.PneumaticBrake([length] * n, [P_MAX] * n, [regime] * n, H,
                             pn.PneumaticSpec().replace(**spec))


def run(brake, seconds, command=None, every=0.01):
    """Advance; ``command(t)`` (gauge Pa) sets the valve every ``every`` s; samples."""
    out = []
    steps = int(round(every / H))
    for _ in range(int(round(seconds / every))):
        if command is not None:
            brake.set_command(command(brake.t))
        brake.advance(steps)
        out.append((brake.t, brake.pipe_pressure, brake.cylinder_pressure,
                    brake.applied.copy()))
    return out


def first_time(samples, predicate):
    """Time of the first sample for which predicate(sample) holds, else inf."""
    for s in samples:
        if predicate(s):
            return s[0]
    return np.inf


def test_orifice_law():
    rt = pk.R_AIR * 293.15
    assert pk.orifice_flow(5e5, 5e5, 1e-5, rt) == 0.0
    assert pk.orifice_flow(4e5, 5e5, 1e-5, rt) == 0.0
    choked = pk.orifice_flow(6e5, 1e5, 1e-5, rt)
    assert choked == pytest.approx(1e-5 * 6e5 * pk.PSI_CHOKED / np.sqrt(rt))
    # continuous at the critical ratio, and the flow falls toward equal pressures
    below = pk.orifice_flow(1e5, pk.R_CRIT * 1e5 * (1 - 1e-9), 1e-5, rt)
    above = pk.orifice_flow(1e5, pk.R_CRIT * 1e5 * (1 + 1e-9), 1e-5, rt)
    assert above == pytest.approx(below, rel=1e-4)
    assert pk.orifice_flow(1e5, 0.9e5, 1e-5, rt) > pk.orifice_flow(1e5, 0.99e5, 1e-5, rt)


@pytest.mark.parametrize('regime, fill_range, release_range, t_release', [
    ('P', (3.0, 5.0), (15.0, 20.0), 20.0),
    ('G', (18.0, 30.0), (45.0, 60.0), 50.0),
])
def test_fill_and_release_times(regime, fill_range, release_range, t_release):
    """UIC 540: 95 % of the emergency cylinder pressure, then below 0.4 bar on release."""
    brake = make(regime=regime)
    samples = run(brake, t_release, lambda t: 0.0)
    final = samples[-1][2][0]
    assert final == pytest.approx(P_MAX, rel=0.02)
    t95 = first_time(samples, lambda s: s[2][0] >= 0.95 * final)
    assert fill_range[0] <= t95 <= fill_range[1]
    # the cylinder fills gradually (a choke, not a jump): a third of the way at 20 % time
    assert 0.0 < np.interp(0.2 * t95, [s[0] for s in samples],
                           [s[2][0] for s in samples]) < 0.5 * final
    samples = run(brake, release_range[1] + 10.0, lambda t: 500000.0)
    t_rel = first_time(samples, lambda s: s[2][0] < 0.4 * BAR) - t_release
    assert release_range[0] <= t_rel <= release_range[1]
    assert samples[-1][2][0] < 0.1 * BAR and not samples[-1][3][0]


def test_sensitivity_and_insensitivity():
    """UIC 541-1 / EN 15355: 0.3 bar in 60 s: no brake; 0.6 bar in 6 s: applied in 1.2 s."""
    slow = make()
    samples = run(slow, 70.0, lambda t: 500000.0 - min(t, 60.0) * 0.3 * BAR / 60.0)
    assert samples[-1][1][0] == pytest.approx(4.7 * BAR, abs=0.01 * BAR)
    assert not any(s[3][0] for s in samples)
    assert max(s[2][0] for s in samples) == 0.0
    quick = make()
    samples = run(quick, 8.0, lambda t: 500000.0 - min(t, 6.0) * 0.6 * BAR / 6.0)
    t_apply = first_time(samples, lambda s: s[3][0])
    assert t_apply <= 1.2
    assert samples[-1][2][0] > 0.5 * BAR


def test_emergency_propagation_speed_long_pipe():
    """UIC 540: the emergency application reaches the last vehicle at >= 250 m/s."""
    n, length = 40, 18.75          # 750 m, a long freight train
    brake = make(n, 'G', length)
    samples = run(brake, 4.0, lambda t: 0.0)
    t_head = first_time(samples, lambda s: s[3][0])
    t_tail = first_time(samples, lambda s: s[3][-1])
    speed = (n - 1) * length / (t_tail - t_head)
    assert speed >= 250.0
    assert speed < 340.0           # not faster than sound (isothermal c = 290 m/s)
    # every vehicle in between applies in order of its distance from the head
    times = [first_time(samples, lambda s, i=i: s[3][i]) for i in range(n)]
    assert np.all(np.diff(times) >= 0.0)


def test_service_propagates_slower_than_emergency():
    """The brake valve's service rate: the tail's pipe takes longer to reach 4 bar."""
    arrival = {}
    for position in ('emergency', 'full_service'):
        valve = BrakeValveModel(schedule=['0.0:' + position])
        valve.advance_to(0.0)
        brake = make(40, 'G', 18.75)
        samples = run(brake, 20.0, lambda t: valve.advance_to(t))
        arrival[position] = first_time(samples, lambda s: s[1][-1] < 4.0 * BAR)
        head = first_time(samples, lambda s: s[1][0] < 4.0 * BAR)
        assert head < arrival[position]
    assert arrival['emergency'] < arrival['full_service'] < np.inf


def test_full_service_settles_near_3_5_bar():
    """Full service from 5 bar: pipe near 3.5 bar along the train, cylinders at p_max."""
    brake = make(20, 'P')
    run(brake, 40.0, lambda t: 350000.0)
    p = brake.pipe_pressure
    assert np.all(np.abs(p - 3.5 * BAR) < 0.05 * BAR)
    assert np.all(brake.cylinder_pressure > 0.97 * P_MAX)
    assert np.all(brake.cylinder_pressure <= P_MAX)
    # the control reservoirs keep the 5 bar reference; the auxiliary ones stay above BC
    assert np.all(np.abs(brake.control_pressure - 5.0 * BAR) < 0.02 * BAR)
    assert np.all(brake.auxiliary_pressure > brake.cylinder_pressure)


def test_graduated_application_and_release():
    """Each deeper pipe step raises the cylinder, each partial release lowers it."""
    brake = make(2, 'P')
    levels = [4.6, 4.2, 3.8, 4.2, 4.6, 5.0]
    cyl = []
    for level in levels:
        run(brake, 25.0, lambda t, lv=level: lv * BAR)
        cyl.append(brake.cylinder_pressure[0])
    assert cyl[0] > 0.5 * BAR
    assert cyl[0] < cyl[1] < cyl[2] < P_MAX
    assert cyl[2] > cyl[3] > cyl[4] > cyl[5]
    assert cyl[5] == pytest.approx(0.0, abs=0.05 * BAR)
    # proportional: p_max per 1.5 bar of drop below the control reservoir
    for level, p in zip(levels[:3], cyl[:3]):
        assert p == pytest.approx(P_MAX * (5.0 - level) / 1.5, abs=0.1 * BAR)


def test_closed_angle_cock_isolates_the_rear():
    brake = make(10, 'P', angle_cock_closed=4)
    run(brake, 15.0, lambda t: 0.0)
    assert np.all(brake.applied[:4])
    assert not np.any(brake.applied[4:])
    assert np.all(brake.cylinder_pressure[4:] == 0.0)
    assert np.all(np.abs(brake.pipe_pressure[4:] - 5.0 * BAR) < 1.0)
    assert np.all(brake.cylinder_pressure[:4] > 0.9 * P_MAX)


def test_air_mass_conserved_in_a_closed_pipe():
    """Lapped valve, no venting anywhere: the total air mass stays to round-off."""
    brake = make(20, 'G', leakage=0.0)
    brake.set_lap()
    # overcharge the front half by 0.5 bar: a wave runs, reservoirs charge, nothing vents
    nc = brake.cells.shape[1]
    brake.cells[pk.C_M, :nc // 2] *= 1.08
    before = brake.total_air_mass
    samples = run(brake, 20.0)
    assert brake.total_air_mass == pytest.approx(before, rel=1e-13, abs=0.0)
    p = samples[-1][1]
    assert np.ptp(p) < 0.05 * BAR               # equalised along the pipe
    assert not np.any(samples[-1][3])
    # the pipe alone, without distributors: exact telescoping of the face flows
    cells = brake.cells.copy()
    cells[pk.C_M, :nc // 3] *= 0.9
    faces = np.zeros_like(brake.faces)
    faces[pk.F_OPEN, 1:nc] = 1.0
    faces[pk.F_LEN] = brake.faces[pk.F_LEN]
    m0 = cells[pk.C_M].sum()
    for _ in range(5000):
        pk._pipe_transport(cells, faces, brake.sc, H)
    assert cells[pk.C_M].sum() == pytest.approx(m0, rel=1e-13, abs=0.0)
    rho = cells[pk.C_M] / cells[pk.C_VOL]
    assert np.ptp(rho) < 0.01 * rho.mean()      # the 10 % step has rung down (friction)


def test_leakage_lowers_the_tail():
    """
    Leakage: the lapped pipe loses pressure at the given rate.

    Fed from the head, a pressure gradient forms along the train.
    """
    rate = 500.0                               # Pa/s: 0.3 bar per minute
    brake = make(30, 'G', 18.75, leakage=rate)
    brake.set_lap()
    run(brake, 2.0)
    # the reservoirs' check valves feed the pipe nothing; CR nozzles a little: ~rate
    drop_rate = (5.0 * BAR - brake.pipe_pressure.mean()) / 2.0
    assert 0.5 * rate < drop_rate < 1.1 * rate
    fed = make(30, 'G', 18.75, leakage=rate)
    run(fed, 60.0, lambda t: 500000.0)
    p = fed.pipe_pressure
    assert p[0] > p[-1] + 50.0                 # laminar friction: ~0.3 Pa/m at the head
    assert np.all(np.diff(p) <= 1.0)
    assert p[0] > 4.99 * BAR                   # the relay valve holds the head
    assert not np.any(fed.applied)             # a leak within the insensitivity: no brake


def test_external_pipe_drives_the_distributors():
    """pipe_per_coach: given pipe pressures bypass the pipe; the rest is the same."""
    brake = pn.PneumaticBrake([25.0] * 3, [P_MAX] * 3, ['P'] * 3, H, external_pipe=True)
    brake.set_pipe_pressure([5.0 * BAR, 4.25 * BAR, 3.5 * BAR])
    trace = np.zeros((int(20.0 / H), 3))
    brake.advance(trace.shape[0], trace)
    assert trace[-1, 0] == 0.0
    assert trace[-1, 1] == pytest.approx(0.5 * P_MAX, abs=0.05 * BAR)
    assert trace[-1, 2] == pytest.approx(P_MAX, abs=0.05 * BAR)
    assert np.all(np.diff(trace[:, 2]) >= 0.0)


def test_step_independence_of_the_cylinder():
    """Steps of 2 ms and 5 ms give the same filling within a few percent."""
    out = []
    for h in (0.002, 0.005):
        brake = pn.PneumaticBrake([25.0] * 4, [P_MAX] * 4, ['P'] * 4, h)
        brake.set_command(0.0)
        trace = np.zeros((int(round(3.0 / h)), 4))
        brake.advance(trace.shape[0], trace)
        out.append(trace[-1])
    assert np.allclose(out[0], out[1], rtol=0.03)
