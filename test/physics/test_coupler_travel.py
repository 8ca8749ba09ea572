"""The coupler law with free play (slack), stroke limits and blocking."""
import math

import numpy as np
import pytest

from train_dynamics.physics import couplers
from train_dynamics.physics.kernel import couplers as kernel_couplers

# k_e, k_f, k_ec, k_fc [N/m]; g_t, g_c [m]; S_t, S_c [m]; K_b [N/m]
K = {'ke': 2.0e6, 'kf': 1.0e6, 'kec': 4.0e6, 'kfc': 2.0e6, 'gt': 0.02, 'gc': 0.01, 'st': 0.05,
     'sc': 0.08, 'kb': 1.0e8}


def law(y, ydot, model='sign', u=1000.0, **over):
    """Return (F, dF/dy, dF/dydot) of one coupler with the constants K."""
    c = {**K, **over}
    return kernel_couplers.coupler_force_travel_scalar(
        y, ydot, c['ke'], c['kf'], c['kec'], c['kfc'], c['gt'], c['gc'], c['st'], c['sc'],
        c['kb'], kernel_couplers.MODEL_CODES[model], u)


@pytest.mark.parametrize('model', ['sign', 'tanh'])
def test_free_play_carries_no_force(model):
    for y in (0.0, 0.019, -0.0099, 0.02, -0.01):
        f, dfdy, dfdv = law(y, 0.3, model)
        assert f == 0.0 and dfdy == 0.0 and dfdv == 0.0


def test_sign_model_spring_zone_by_hand():
    # draw gear loading: d = 0.05 - 0.02 = 0.03, F = (4e6 + 2e6) * 0.03
    f, dfdy, _ = law(0.05, 0.1)
    assert f == pytest.approx(180000.0, rel=1e-12) and dfdy == pytest.approx(6.0e6)
    # unloading: (4e6 - 2e6) * 0.03
    assert law(0.05, -0.1)[0] == pytest.approx(60000.0, rel=1e-12)
    # buffers loading (ydot < 0, s = -1): d = -0.05 + 0.01 = -0.04, F = (2e6 + 1e6) * -0.04
    f, dfdy, _ = law(-0.05, -0.1)
    assert f == pytest.approx(-120000.0, rel=1e-12) and dfdy == pytest.approx(3.0e6)
    assert law(-0.05, 0.1)[0] == pytest.approx(-40000.0, rel=1e-12)


def test_sign_model_blocked_zone_by_hand():
    # draw gear: d = 0.07, 0.02 beyond the stroke: 6e6 * 0.07 + 1e8 * 0.02
    f, dfdy, _ = law(0.09, 0.1)
    assert f == pytest.approx(2.42e6, rel=1e-12)
    assert dfdy == pytest.approx(1.06e8, rel=1e-12)       # the slope includes K_b
    # buffers: d = -0.09, 0.01 beyond the stroke: 3e6 * -0.09 + 1e8 * -0.01
    f, dfdy, _ = law(-0.10, -0.1)
    assert f == pytest.approx(-1.27e6, rel=1e-12)
    assert dfdy == pytest.approx(1.03e8, rel=1e-12)


def test_tanh_model_each_zone_by_hand():
    t1 = 0.7615941559557649      # tanh(1): u = 1000 s/m, ydot = 1 mm/s
    assert law(0.015, 0.001, 'tanh')[0] == 0.0
    f, _, dfdv = law(0.05, 0.001, 'tanh')
    assert f == pytest.approx((4.0e6 + 2.0e6 * t1) * 0.03, rel=1e-12)
    # dF/dydot = k_fc d u sech^2(u ydot)
    assert dfdv == pytest.approx(2.0e6 * 0.03 * 1000.0 * (1.0 - t1 * t1), rel=1e-9)
    f, _, _ = law(0.09, -0.001, 'tanh')
    assert f == pytest.approx((4.0e6 - 2.0e6 * t1) * 0.07 + 1.0e8 * 0.02, rel=1e-12)
    f, _, _ = law(-0.05, -0.001, 'tanh')
    assert f == pytest.approx((2.0e6 + 1.0e6 * t1) * -0.04, rel=1e-12)
    f, _, _ = law(-0.10, 0.001, 'tanh')
    assert f == pytest.approx((2.0e6 - 1.0e6 * t1) * -0.09 - 1.0e8 * 0.01, rel=1e-12)


@pytest.mark.parametrize('model', ['sign', 'tanh'])
def test_tight_unblocked_coupling_is_the_papers_law_bit_for_bit(model):
    rng = np.random.default_rng(1)
    y = np.concatenate([rng.normal(0.0, 0.01, 200), [0.0, -0.0]])
    ydot = rng.normal(0.0, 0.01, y.size)
    code = kernel_couplers.MODEL_CODES[model]
    for a, b in zip(y, ydot):
        ref = kernel_couplers.coupler_force_scalar(a, b, 2.8e6, 1.4e6, 5.46e6, 2.43e6, code,
                                                   1000.0)
        new = kernel_couplers.coupler_force_travel_scalar(a, b, 2.8e6, 1.4e6, 5.46e6, 2.43e6,
                                                          0.0, 0.0, 0.06, 0.105, 1.0e8, code,
                                                          1000.0)
        assert ref[0] == new[0] and ref[1] == new[1] and ref[2] == new[2]


def test_stored_energy_is_the_integral_of_the_elastic_force():
    c = {**K, 'kf': 0.0, 'kfc': 0.0}
    for y in (-0.12, -0.05, 0.0, 0.03, 0.08):
        e = lambda z: float(couplers.elastic_energy_travel(  # noqa: E731
            z, c['ke'], c['kec'], c['gt'], c['gc'], c['st'], c['sc'], c['kb']))
        h = 1e-7
        assert (e(y + h) - e(y - h)) / (2 * h) == pytest.approx(law(y, 0.0, **c)[0],
                                                                rel=1e-5, abs=1e-3)


def test_force_is_continuous_at_every_zone_boundary():
    for y in (0.02, -0.01, 0.07, -0.09):
        for ydot in (0.1, -0.1):
            lo, hi = law(y - 1e-12, ydot)[0], law(y + 1e-12, ydot)[0]
            assert abs(hi - lo) < 1.0


def test_deflection_bounds():
    lo, hi = couplers.deflection_bounds(2.0e6, 0.02, 0.01, 0.05, 0.08, 1.0e8)
    assert hi == pytest.approx(0.09) and lo == pytest.approx(-0.11)
    # a deflection the law gives for force F lies within the bound of F
    for y in (0.095, -0.13):
        f = law(y, 0.0)[0]
        lo, hi = couplers.deflection_bounds(f, 0.02, 0.01, 0.05, 0.08, 1.0e8)
        assert lo <= y <= hi
    assert math.isclose(law(0.0, 0.0)[0], 0.0)
