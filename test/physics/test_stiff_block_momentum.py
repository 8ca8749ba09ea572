"""
Momentum at every accepted blocked stiffness: impacts of stiff blocks conserve it (eq. 8).

A locomotive pulls wagons whose couplings have 50 mm of free play and 1 mm strokes: the slack
runs out and the wagons rattle on their blocked buffers and draw gear. The couplers' forces
are internal (equal and opposite), so the train's momentum changes by the impulse of the
external forces alone, at every ``blocked_stiffness`` the configuration accepts, from 1e6 N/m
to its upper bound, in both stepping modes. The expected impulse is computed here, not read
from the simulator's own bookkeeping: traction in closed form (a linear build-up, then the
constant starting effort), the gradient force (m g G / 1000 per vehicle) and the brakes
(constant cylinder pressures) in closed form, the running resistance from its samples.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.physics.config import PARAMETERS, SimConfig
from train_dynamics.physics.train import TrainSimulator

#: [N] starting tractive effort: constant while traction is below power and adhesion limits
F_TRACTION = 400000.0
#: [s] the build-up: the effective command rises linearly from 0 to 1
T_BUILD = 0.5
G = 9.81

K_HIGH = PARAMETERS['blocked_stiffness'].high
#: the accepted range, log-spaced: 1e6 ... the upper bound
STIFFNESSES = np.logspace(6.0, np.log10(K_HIGH), 7)
MODES = {'fixed': 0.0, 'error_controlled': 1e-3}

END = ('draw_gear_slack: 0.025, buffer_slack: 0.025, draw_gear_stroke: 0.0005, '
       'buffer_stroke: 0.0005, blocked_stiffness: {k}')
CONSIST = """
vehicles:
  - {{type: electric_freight_locomotive, max_tractive_force: 400000.0, max_power: 1.0e8,
     traction_adhesion: 1.0, traction_build_up_time: 0.5, {resist}{end}}}
  - {{type: freight_wagon_loaded, count: {n}, {resist}{end}}}
"""
NO_RESISTANCE = 'davis_a: 0.0, davis_b: 0.0, davis_c: 0.0, '


def train(tmp_path, k, tolerance, n, resistance, **params) -> TrainSimulator:
    """Return the train with blocked stiffness k [N/m] per vehicle end, traction on."""
    path = tmp_path / 'rattle.yaml'
    path.write_text(CONSIST.format(n=n, resist='' if resistance else NO_RESISTANCE,
                                   end=END.format(k=float(k))))
    sim = TrainSimulator(SimConfig.from_dict({
        'consist_file': str(path), 'brake_regime': 'G', 'integration_tolerance': tolerance,
        **params}))
    sim.set_traction_command(1.0, 0)
    return sim


def traction_impulse(t):
    """Return the impulse of the traction [N s] at t >= T_BUILD: F (t - T_BUILD / 2)."""
    return F_TRACTION * (t - 0.5 * T_BUILD)


@pytest.mark.parametrize('mode', MODES)
@pytest.mark.parametrize('k', STIFFNESSES)
def test_item5_momentum_from_rest_is_the_traction_impulse(tmp_path, k, mode):
    # no brake, no resistance, level: only traction acts on the train from outside
    sim = train(tmp_path, k, MODES[mode], 8, False, initial_speed=0.0)
    assert sim.momentum == 0.0
    rattle = 0.0
    for t in (1.0, 2.0, 3.0):
        while sim.t < t - 1e-9:
            sim.advance_to(sim.t + 0.01)
            rattle = max(rattle, float(np.ptp(sim.v)))
        assert sim.fault is None
        assert sim.momentum == pytest.approx(traction_impulse(t), rel=1e-9)
    assert np.all(sim.traction_force[1:] == 0.0) and sim.traction_force[0] == F_TRACTION
    assert rattle > 0.1          # the wagons did rattle in their free play [m/s]
    # and hit their blocks: the draw gear's spring gives at most (k + k_f) S = 7.9 kN at the
    # end of its 1 mm stroke (5.46e6 + 2.43e6 N/m per coupling)
    assert np.max(sim.coupler_force_envelope[0]) > 1e5


@pytest.mark.parametrize('mode', MODES)
@pytest.mark.parametrize('k', STIFFNESSES)
def test_item5_momentum_balance_with_resistance_gradient_and_brakes(tmp_path, k, mode):
    gradient = 2.0            # [permille] rising
    pressure = 60000.0        # [Pa] in every cylinder, from t = 0
    # every coupler at y = 0 (mid free play) at t = 0: the loco's force builds up, the braked
    # wagons lag, the slack runs out in a snatch
    sim = train(tmp_path, k, MODES[mode], 6, True, initial_speed=5.0,
                initial_state='unstressed', brake_input='cylinder_per_coach',
                track_gradient_positions=[-1.0e6], track_gradients=[gradient])
    sim.set_cylinder_pressure(np.full(sim.n, pressure))
    p0 = sim.momentum
    weight = sim.masses * G
    dt = 0.002
    # the library's wagons brake on a friction law (their force follows the speed): the
    # brakes' impulse is integrated like the resistance's
    res, brakes, t_prev, f_prev, b_prev = 0.0, 0.0, 0.0, None, None
    while sim.t < 3.0 - 1e-9:
        sim.advance_to(sim.t + dt)
        f = float(np.sum(sim.resistance_force))
        b = float(np.sum(sim.brake_force))
        if f_prev is None:
            f_prev, b_prev = f, b
        res += 0.5 * (f + f_prev) * (sim.t - t_prev)
        brakes += 0.5 * (b + b_prev) * (sim.t - t_prev)
        t_prev, f_prev, b_prev = sim.t, f, b
        assert np.all(sim.v > 0.0)       # every vehicle moving forward: brakes retard
    brake = sim.brake_force
    assert brake.min() > 0.0 and sim.fault is None
    t = sim.t
    expected = (traction_impulse(t) - np.sum(weight) * gradient * 1e-3 * t
                - brakes + res)
    assert sim.momentum - p0 == pytest.approx(expected, rel=1e-5, abs=1e-6 * p0)
    assert sim.momentum - p0 > 0.5 * traction_impulse(t)    # the train still gains speed
    assert np.max(sim.coupler_force_envelope[0]) > 1e5      # the slack ran out: blocked
