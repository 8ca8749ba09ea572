"""Traction / dynamic-brake force curves and Davis running resistance, by hand."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from train_dynamics.physics import resistance
from train_dynamics.physics.kernel import resistance as kernel_resistance, traction

W = 84000.0 * 9.81    # weight of an 84 t locomotive [N]


def test_curtius_kniffler_adhesion():
    assert traction.adhesion(0.0, 0.33) == pytest.approx(0.33)
    # 100 km/h: 0.161 + 7.5 / 144 = 0.213083, scaled by 0.33 / 0.331455
    assert traction.adhesion(100.0 / 3.6, 0.33) == pytest.approx(
        0.33 * (0.161 + 7.5 / 144.0) / (0.161 + 7.5 / 44.0))


def test_tractive_effort_curve_force_power_and_adhesion_limits():
    # at rest: the smaller of 300 kN and adhesion 0.33 * 824 kN = 272 kN
    assert traction.available_force(0.0, 300e3, 6.4e6, 0.33, W) == pytest.approx(0.33 * W)
    assert traction.available_force(0.0, 200e3, 6.4e6, 0.33, W) == pytest.approx(200e3)
    # 40 m/s: power limit 6.4 MW / 40 m/s = 160 kN
    assert traction.available_force(40.0, 300e3, 6.4e6, 0.33, W) == pytest.approx(160e3)
    # command fraction, forward even when rolling back
    assert traction.traction_force(0.5, 40.0, 300e3, 6.4e6, 0, 0, 1.4, 0.33, W) == \
        pytest.approx(80e3)
    assert traction.traction_force(1.0, -1.0, 200e3, 6.4e6, 0, 0, 1.4, 0.33, W) == \
        pytest.approx(200e3)


def test_dynamic_brake_opposes_motion_fades_and_never_pushes_at_rest():
    args = (300e3, 6.4e6, 150e3, 6.4e6, 1.4, 0.33, W)
    assert traction.traction_force(-1.0, 30.0, *args) == pytest.approx(-150e3)
    assert traction.traction_force(-1.0, 60.0, *args) == pytest.approx(-6.4e6 / 60.0)
    assert traction.traction_force(-1.0, -30.0, *args) == pytest.approx(150e3)
    assert traction.traction_force(-0.5, 0.7, *args) == pytest.approx(-0.5 * 150e3 * 0.5)
    assert traction.traction_force(-1.0, 0.0, *args) == 0.0


def test_force_build_up_is_a_rate_limit():
    c = 0.0
    for _ in range(100):
        c = traction.ramp(c, 1.0, 0.01, 4.0)
    assert c == pytest.approx(0.25)
    assert traction.ramp(0.25, -1.0, 1.0, 4.0) == pytest.approx(0.0)
    assert traction.ramp(0.3, 0.2, 1.0, 4.0) == 0.2
    assert traction.ramp(0.0, -0.7, 0.002, 0.0) == -0.7


def test_davis_by_hand():
    assert kernel_resistance.davis(-20.0, 1000.0, 40.0, 5.0) == pytest.approx(1000 + 800 + 2000)
    out = kernel_resistance.running_resistance(np.array([0.0, 10.0]), np.array([100.0, 100.0]),
                                               np.array([1.0, 1.0]), np.array([0.5, 0.5]),
                                               np.empty(2))
    assert list(out) == [100.0, 160.0]
    assert resistance.equivalent_mass(1000.0, 0.1) == pytest.approx(1100.0)


@pytest.mark.parametrize('a, b, c', [(1000.0, 40.0, 5.0), (800.0, 20.0, 0.0),
                                     (600.0, 0.0, 0.0)])
def test_coast_down_closed_form_matches_the_ode(a, b, c):
    m, v0 = 90000.0, 30.0
    sol = solve_ivp(lambda t, v: [-(a + b * v[0] + c * v[0] ** 2) / m], (0.0, 600.0), [v0],
                    rtol=1e-10, atol=1e-10, dense_output=True)
    t = np.linspace(0.0, 600.0, 13)
    exact = resistance.coast_down_speed(t, v0, m, a, b, c)
    ode = sol.sol(t)[0]
    moving = exact > 0.0
    assert np.allclose(exact[moving], ode[moving], rtol=1e-7, atol=1e-7)
