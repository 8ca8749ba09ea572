"""Coupler force laws (paper eqs. 1-4 and 14-16) against values computed by hand."""
import math

import numpy as np
import pytest

from train_dynamics.physics.couplers import force_law
from train_dynamics.physics.kernel import couplers

KE, KF, KEC, KFC = 2.8e6, 1.4e6, 5.46e6, 2.43e6   # the paper's constants [N/m]


@pytest.mark.parametrize('y, ydot, expected, what', [
    # compression (buffers, eq. 2): loading (y falling) follows k_e + k_f ...
    (-0.05, -0.1, (KE + KF) * -0.05, 'compression loading'),      # -210 kN
    # ... unloading (y rising back to 0) follows k_e - k_f
    (-0.05, +0.1, (KE - KF) * -0.05, 'compression unloading'),    # -70 kN
    # extension (draw gear, eq. 3): loading k_ec + k_fc, unloading k_ec - k_fc
    (0.02, +0.1, (KEC + KFC) * 0.02, 'extension loading'),        # 157.8 kN
    (0.02, -0.1, (KEC - KFC) * 0.02, 'extension unloading'),      # 60.6 kN
    (0.0, 0.3, 0.0, 'undeformed'),
    (0.0, -0.3, 0.0, 'undeformed'),
    (-0.05, 0.0, KE * -0.05, 'compression at rest: sgn(0) = 0'),
])
def test_sign_model_by_hand(y, ydot, expected, what):
    F = force_law(y, ydot, model='sign')[0]
    assert F == pytest.approx(expected, rel=1e-12, abs=1e-9), what


def test_hand_values_in_newtons():
    # the same points, as plain numbers: guards against a convention slip in the test table
    assert force_law(-0.05, -0.1, model='sign')[0] == pytest.approx(-210000.0)
    assert force_law(-0.05, 0.1, model='sign')[0] == pytest.approx(-70000.0)
    assert force_law(0.02, 0.1, model='sign')[0] == pytest.approx(157800.0)
    assert force_law(0.02, -0.1, model='sign')[0] == pytest.approx(60600.0)


def test_tanh_model_by_hand():
    # y = -5 cm, compressing at 1 mm/s, u = 1000 s/m: s = tanh(-1) = -0.76159...
    s = math.tanh(-1.0)
    expected = (KE - KF * s) * -0.05
    assert expected == pytest.approx(-193311.5909, rel=1e-9)
    F = force_law(-0.05, -0.001, model='tanh', u=1000.0)[0]
    assert F == pytest.approx(expected, rel=1e-12)
    # extension, opening at 0.5 mm/s: tanh(0.5)
    expected = (KEC + KFC * math.tanh(0.5)) * 0.03
    assert force_law(0.03, 0.0005, model='tanh', u=1000.0)[0] == pytest.approx(expected, rel=1e-12)
    # tanh(u*0) = 0: the elastic force only
    assert force_law(0.03, 0.0, model='tanh', u=1000.0)[0] == pytest.approx(KEC * 0.03)


def test_matches_paper_formula_everywhere():
    """The implementation equals eqs. (2)+(3) with (14) written literally, on a grid."""
    y, yd = np.meshgrid(np.linspace(-0.1, 0.1, 41), np.linspace(-0.02, 0.02, 41))
    y, yd = y.ravel(), yd.ravel()
    for model, u in (('sign', 1.0), ('tanh', 300.0), ('tanh', 1e4)):
        s = np.sign(yd) if model == 'sign' else np.tanh(u * yd)
        Ft = 0.5 * (1 - np.sign(y)) * (KE - KF * s) * y
        Fc = 0.5 * (1 + np.sign(y)) * (KEC + KFC * s) * y
        np.testing.assert_allclose(force_law(y, yd, model=model, u=u), Ft + Fc, rtol=1e-12,
                                   atol=1e-9)


def test_tanh_approaches_sign_as_u_grows():
    y = np.array([-0.05, -0.05, 0.02, 0.02])
    yd = np.array([-0.001, 0.001, 0.001, -0.001])
    F_sign = force_law(y, yd, model='sign')
    errors = [np.max(np.abs(force_law(y, yd, model='tanh', u=u) - F_sign))
              for u in (1e2, 1e3, 1e4, 1e5)]
    assert all(b < a for a, b in zip(errors, errors[1:]))
    assert errors[0] > 1e4          # u = 100: tanh(0.1) is far from 1
    assert errors[-1] < 1e-6        # u = 1e5: tanh(100) == 1 in double precision


def test_friction_always_dissipates():
    """F * ydot of the friction part is >= 0: the hysteresis loop absorbs energy."""
    rng = np.random.default_rng(1)
    y = rng.uniform(-0.1, 0.1, 500)
    yd = rng.uniform(-0.05, 0.05, 500)
    for model in ('sign', 'tanh'):
        F = force_law(y, yd, model=model, u=1000.0)
        elastic = np.where(y < 0, KE * y, KEC * y)
        assert np.all((F - elastic) * yd >= 0.0)


def test_jacobian_matches_finite_differences():
    y = np.array([-0.04, -0.01, 0.015, 0.05])
    yd = np.array([-2e-4, 5e-4, -1e-4, 3e-4])
    k = [np.full(4, c) for c in (KE, KF, KEC, KFC)]
    dfdy, dfdv = couplers.coupler_force_jacobian(y, yd, *k, couplers.TANH, 1000.0)
    eps_y, eps_v = 1e-7, 1e-9

    def f(a, b):
        return couplers.coupler_force(a, b, *k, couplers.TANH, 1000.0)

    np.testing.assert_allclose(dfdy, (f(y + eps_y, yd) - f(y - eps_y, yd)) / (2 * eps_y),
                               rtol=1e-6)
    np.testing.assert_allclose(dfdv, (f(y, yd + eps_v) - f(y, yd - eps_v)) / (2 * eps_v),
                               rtol=1e-5)
    # the stiff friction derivative: u k_f |y| sech^2(u ydot) in compression
    assert dfdv[0] == pytest.approx(1000.0 * KF * 0.04 * (1 - math.tanh(-0.2) ** 2), rel=1e-12)


def test_net_force_on_the_coaches_eqs5_7():
    """Coupler j pulls coach j back and coach j+1 forward; the forces cancel in the sum."""
    F = np.array([1.0e5, -3.0e4, 2.5e4])         # tension, compression, tension [N]
    net = couplers.net_forces(F)
    np.testing.assert_array_equal(net, [-1.0e5, 1.0e5 + 3.0e4, -3.0e4 - 2.5e4, 2.5e4])
    assert net.sum() == 0.0
    # the kernel's form: only the first n_couplers entries of a longer row are read
    row = np.append(F, 7.0e9)
    assert [couplers.net_force(row, i, 3) for i in range(4)] == list(net)
