"""
Brake cylinders of the pneumatic brake: dead volume, piston stroke, return spring, first stage.

Closed forms: Boyle's law (isothermal p V = m R T) for the cylinder over its three ranges
(piston resting on the spring, travelling out at the spring pressure, at full stroke); the
auxiliary reservoir's fall when it has filled the cylinder (mass balance, nothing else draws
on it in an emergency); the piston's travel time at the choked flow of the application choke
(ISO 6358 nozzle law: w = A p_up psi* / sqrt(R T)).
"""
import math

import numpy as np
import pytest

from train_dynamics.physics import pneumatic as pn
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import pneumatic as pk
from train_dynamics.physics.train import TrainSimulator

H = 0.002
P_MAX = 380000.0
PATM = 101325.0
RT = pk.R_AIR * 293.15
SPEC = pn.PneumaticSpec()
# a vehicle with two 10 inch cylinders (0.0507 m^2 each), 0.1 m stroke, 1.5 kN springs
AREA, CYLINDERS, STROKE, SPRING = 0.0507, 2, 0.1, 1500.0
V0 = 0.002                                 # dead volume [m^3] (a guess: clearance, pipes)
VS = CYLINDERS * AREA * STROKE             # 0.01014 m^3
PS = SPRING / AREA                         # 29586 Pa: the piston moves out at 0.30 bar


def emergency_trace(seconds=12.0, **kw):
    """One P vehicle, emergency at t = 0: (t, cylinder, auxiliary reservoir) every step."""
    brake = pn.PneumaticBrake([25.0], [P_MAX], ['P'], H, **kw)
    brake.set_command(0.0)
    n = int(round(seconds / H))
    t, cyl, aux = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(n):
        brake.advance(1)
        t[k], cyl[k], aux[k] = brake.t, brake.cylinder_pressure[0], brake.auxiliary_pressure[0]
    return t, cyl, aux


def test_cylinder_pressure_is_boyle_over_the_three_ranges():
    """Resting piston: m R T / V0; travelling: the spring pressure; full stroke: m R T / V."""
    m_rest = (PATM + PS) * V0 / RT
    m_full = (PATM + PS) * (V0 + VS) / RT
    f = pk.cylinder_pressure
    assert f(0.5 * m_rest, V0, VS, PS, PATM, RT) == pytest.approx(0.5 * m_rest * RT / V0)
    assert f(0.5 * (m_rest + m_full), V0, VS, PS, PATM, RT) == PATM + PS
    assert f(2.0 * m_full, V0, VS, PS, PATM, RT) == pytest.approx(2.0 * (PATM + PS))
    # continuous at both ends of the travel
    assert f(m_rest, V0, VS, PS, PATM, RT) == pytest.approx(PATM + PS, rel=1e-12)
    assert f(m_full, V0, VS, PS, PATM, RT) == pytest.approx(PATM + PS, rel=1e-12)
    # no stroke: one fixed volume
    assert f(0.01, 0.008, 0.0, PS, PATM, RT) == 0.01 * RT / 0.008


def test_stroke_volume_comes_out_of_the_auxiliary_reservoir():
    """Boyle: p_AR drops by ((patm + p_C) (V0 + Vs) - patm V0) / V_AR; the piston adds Vs."""
    kw = {'dead_volume': V0, 'stroke_volume': VS, 'spring_pressure': PS}
    t, cyl, aux = emergency_trace(**kw)
    p_c = cyl[-1]
    assert p_c == pytest.approx(P_MAX, rel=0.02)
    drop = ((PATM + p_c) * (V0 + VS) - PATM * V0) / SPEC.aux_volume
    assert aux[0] - aux[-1] == pytest.approx(drop, rel=1e-9)
    # the fixed 8 l cylinder draws less (no stroke): the same law with V0 = 0.008, Vs = 0
    _, cyl8, aux8 = emergency_trace()
    drop8 = (cyl8[-1] * SPEC.cylinder_volume) / SPEC.aux_volume
    assert aux8[0] - aux8[-1] == pytest.approx(drop8, rel=1e-9)


def test_piston_travel_time_at_the_choked_application_choke():
    """
    The cylinder holds the spring pressure while the pistons travel out.

    For m_s / w seconds: m_s = (patm + p_s) Vs / (R T) the air the stroke takes, w = A_app
    p_AR psi* / sqrt(R T) the choked flow from the auxiliary reservoir (p_C / p_AR < 0.53);
    without the first stage (its port would feed the travel too).
    """
    t, cyl, aux = emergency_trace(dead_volume=V0, stroke_volume=VS, spring_pressure=PS,
                                  inshot=0.0)
    at_spring = np.abs(cyl - PS) < 1.0
    travel = np.count_nonzero(at_spring) * H
    p_ar = np.mean(aux[at_spring]) + PATM
    assert (PATM + PS) / p_ar < pk.R_CRIT                     # choked throughout
    w = SPEC.app_area_p * p_ar * pk.PSI_CHOKED / math.sqrt(RT)
    m_s = (PATM + PS) * VS / RT
    assert travel == pytest.approx(m_s / w, rel=0.005)
    # so the fill time grows: 95 % of p_max later than with a fixed cylinder of V0 + Vs
    # filled from the start
    t95 = t[np.argmax(cyl >= 0.95 * P_MAX)]
    t_fixed, cyl_fixed, _ = emergency_trace(dead_volume=V0 + VS, inshot=0.0)
    assert t95 > t_fixed[np.argmax(cyl_fixed >= 0.95 * P_MAX)]


def test_distributors_have_the_uic_first_stage_by_default_and_keep_the_uic_fill_times():
    """Default 0.4 bar first stage (UIC 540 / EN 15355); P 95 % at 4.0 s, G at 24.0 s."""
    assert pn.PneumaticSpec().inshot_pressure == pn.INSHOT_PRESSURE == 40000.0
    for regime, seconds, t95 in (('P', 12.0, 4.0), ('G', 60.0, 24.0)):
        brake = pn.PneumaticBrake([25.0], [P_MAX], [regime], H)
        brake.set_command(0.0)
        cyl = np.zeros(int(round(seconds / H)))
        for k in range(cyl.size):
            brake.advance(1)
            cyl[k] = brake.cylinder_pressure[0]
        assert (np.argmax(cyl >= 0.95 * cyl[-1]) + 1) * H == pytest.approx(t95, abs=0.05)
        # the first stage: 0.4 bar within 0.2 s in either regime (0.13 s P, 0.16 s G;
        # through the application choke alone 0.47 s and 2.7 s)
        assert (np.argmax(cyl >= 0.4e5) + 1) * H < 0.2


def test_first_stage_fills_through_the_inshot_port_up_to_its_pressure():
    """With inshot, the first 0.5 bar fill through the choke and the inshot port together."""
    t, cyl, _ = emergency_trace(inshot=50000.0)
    t0, cyl0, _ = emergency_trace(inshot=0.0)
    first, first0 = t[np.argmax(cyl >= 0.4e5)], t0[np.argmax(cyl0 >= 0.4e5)]
    assert first < 0.6 * first0
    assert cyl[-1] == pytest.approx(cyl0[-1], rel=1e-3)      # the same final pressure


def test_vehicle_fields_reach_the_pneumatic_brake(tmp_path):
    """inshot_pressure, cylinder_dead_volume, piston_stroke per vehicle of a consist."""
    (tmp_path / 'c.yaml').write_text(f"""
vehicles:
  - {{type: passenger_coach, inshot_pressure: 60000.0, cylinder_dead_volume: {V0},
     piston_stroke: {STROKE}, brake_cylinder_area: {AREA}, brake_cylinders: {CYLINDERS},
     brake_spring_force: {SPRING}}}
  - {{type: passenger_coach}}
""")
    sim = TrainSimulator(SimConfig.from_dict({'consist_file': str(tmp_path / 'c.yaml'),
                                              'brake_model': 'pneumatic'}))
    veh = sim.pneu.veh
    assert veh[pk.V_INSHOT].tolist() == [60000.0, pn.INSHOT_PRESSURE]
    assert veh[pk.V_VCYL].tolist() == [V0, 0.008]
    assert veh[pk.V_VSTROKE].tolist() == pytest.approx([VS, 0.0])
    assert veh[pk.V_PSPRING].tolist() == pytest.approx([PS, 0.0])
    (tmp_path / 'bad.yaml').write_text('vehicles: [{type: passenger_coach, piston_stroke: 0.1},'
                                       ' {type: passenger_coach}]\n')
    from train_dynamics.physics.config import ConfigError
    with pytest.raises(ConfigError, match='brake_cylinder_area'):
        SimConfig.from_dict({'consist_file': str(tmp_path / 'bad.yaml'),
                             'brake_model': 'pneumatic'})
