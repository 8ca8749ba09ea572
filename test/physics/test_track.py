"""Track: gradient force averaged over the vehicle length, Roeckl curve resistance."""
import numpy as np
import pytest

from train_dynamics.physics import track

G = 9.81


def test_roeckl_by_hand():
    assert track.roeckl(500.0) == pytest.approx(650.0 / 445.0)
    assert track.roeckl(300.0) == pytest.approx(650.0 / 245.0)
    assert track.roeckl(250.0) == pytest.approx(500.0 / 220.0)


def test_gradient_force_is_averaged_over_the_vehicle_length():
    t = track.Track.from_lists(0.0, [100.0], [10.0])
    m, length = 50000.0, 20.0
    # front at 110 m: half of the vehicle on 10 per mille -> mean 5 per mille
    grade, curve = t.forces([110.0], [length], [m], G)
    assert grade[0] == pytest.approx(-m * G * 5e-3)
    assert curve[0] == 0.0
    assert t.forces([90.0], [length], [m], G)[0][0] == 0.0
    assert t.forces([130.0], [length], [m], G)[0][0] == pytest.approx(-m * G * 10e-3)
    # continuous while crossing: small moves give small changes
    xs = np.linspace(95.0, 125.0, 3001)
    f = np.array([t.forces([x], [length], [m], G)[0][0] for x in xs])
    assert np.max(np.abs(np.diff(f))) < m * G * 10e-3 * 0.011 / length * 1.01


def test_profile_mean_far_from_the_first_position():
    """A span inside one piece has that piece's value exactly, a crossing span its mean."""
    from train_dynamics.physics.kernel.track import profile_mean
    t = track.Track.from_lists(0.0, adhesion_positions=[-1.0e6, 1.0e3], adhesion=[0.05, 0.1])
    ax, av, ac = t.adhesion_profile
    rng = np.random.default_rng(3)
    for front in rng.uniform(0.0, 975.0, 500):
        # the running integral from 1000 km back would be off by ~1e-11 relative here
        assert profile_mean(front - 25.0, front, ax, av, ac) == av[0]
        assert track.DRY_ADHESION + profile_mean(front - 25.0, front, ax, av, ac) <= 0.05 * (
            1.0 + 1e-15)
    # 10 m on 0.05, 15 m on 0.1: (10 * 0.05 + 15 * 0.1) / 25 = 0.08
    assert track.DRY_ADHESION + profile_mean(990.0, 1015.0, ax, av, ac) == pytest.approx(
        0.08, rel=1e-9)
    assert profile_mean(-2.0e6, -1.5e6, ax, av, ac) == 0.0         # before the first: dry


def test_uphill_positive_gradient_pulls_back_and_downhill_pushes():
    t = track.Track.from_lists(0.0, [-1000.0, 0.0], [5.0, -8.0])
    grade, _ = t.forces([500.0, -200.0], [20.0, 20.0], [1000.0, 1000.0], G)
    assert grade[0] == pytest.approx(+1000.0 * G * 8e-3)
    assert grade[1] == pytest.approx(-1000.0 * G * 5e-3)


def test_vehicle_positions_from_initial_position_and_lengths():
    t = track.Track.from_lists(1000.0, [980.0], [10.0])
    # vehicle 1 front at 1000, vehicle 2 front at 980 (L1 = 20): its mean is 0 on [960, 980]
    grade, _ = t.forces([0.0, 0.0], [20.0, 20.0], [1.0, 1.0], G)
    assert grade[0] == pytest.approx(-G * 10e-3)
    assert grade[1] == 0.0


def test_curve_resistance_mean_over_length():
    t = track.Track.from_lists(0.0, curve_starts=[100.0], curve_ends=[200.0],
                               curve_radii=[500.0])
    r = 650.0 / 445.0
    curve = [t.forces([x], [10.0], [1000.0], G)[1][0] for x in (105.0, 150.0, 215.0)]
    assert curve[0] == pytest.approx(1000.0 * G * r * 0.5e-3)
    assert curve[1] == pytest.approx(1000.0 * G * r * 1e-3)
    assert curve[2] == pytest.approx(0.0)


def test_gradient_force_is_minus_the_derivative_of_potential_energy():
    t = track.Track.from_lists(0.0, [0.0, 50.0, 80.0], [4.0, -12.0, 6.0])
    lengths = np.array([20.0, 15.0])
    masses = np.array([80000.0, 30000.0])
    for x0 in (-10.0, 40.0, 60.0, 95.0):
        x = np.array([x0, x0])
        h = 1e-4
        dpe = (t.potential_energy(x + h, lengths, masses, G)
               - t.potential_energy(x - h, lengths, masses, G)) / (2 * h)
        grade, _ = t.forces(x, lengths, masses, G)
        assert -dpe == pytest.approx(grade.sum(), rel=1e-6, abs=1e-6)


@pytest.mark.parametrize('kwargs, word', [
    ({'gradient_positions': [0.0, 10.0], 'gradients': [1.0]}, 'same length'),
    ({'gradient_positions': [10.0, 0.0], 'gradients': [1.0, 2.0]}, 'increase'),
    ({'curve_starts': [0.0], 'curve_ends': [0.0], 'curve_radii': [400.0]}, 'end after'),
    ({'curve_starts': [0.0, 50.0], 'curve_ends': [100.0, 150.0],
      'curve_radii': [400.0, 400.0]}, 'overlap'),
])
def test_bad_track_is_rejected(kwargs, word):
    with pytest.raises(ValueError, match=word):
        track.Track.from_lists(0.0, **kwargs)
