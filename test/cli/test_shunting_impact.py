"""The shipped shunting impact: category buffers absorb the energy of the relative motion."""
from pathlib import Path

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.physics.config import consist
from train_dynamics.recording.bags import read_topics

SCENARIO = Path(__file__).resolve().parents[2] / 'config' / 'shunting_impact.yaml'
GAP = 1.0           # the locomotive's front-end buffer free play in the consist file [m]


def category_a_end(lib):
    """
    Return d(F) and W(F) of one category A buffer, from its datasheet figures by hand.

    Preload P up to P / K_b, then P + (F_f - P) x^q over the rest of the stroke, q such that
    the loading branch absorbs the category's energy W_A up to the stroke.
    """
    P, Ff, WA = lib['buffer_preload'], lib['buffer_final_force'], lib['buffer_energy']
    dp = P / lib['blocked_stiffness']
    travel = lib['buffer_stroke'] - dp
    q = (Ff - P) * travel / (WA - 0.5 * P * dp - P * travel) - 1.0

    def x(F):
        return ((F - P) / (Ff - P)) ** (1.0 / q)

    def deflection(F):
        return dp + travel * x(F)

    def energy(F):
        return 0.5 * P * dp + P * travel * x(F) + (Ff - P) * travel * x(F) ** (q + 1) / (q + 1)
    return deflection, energy


def test_category_a_buffers_absorb_the_impact_energy_on_their_datasheet_curve(tmp_path):
    """
    A locomotive runs into a standing wagon with UIC 526-1 category A buffers.

    At the largest compression both move together: the kinetic energy of the relative motion
    at contact, mu v^2 / 2 (mu the reduced inertia), is what the coupling's loading branch
    absorbed: the wagon's end, two category A buffers in parallel (each at F / 2 on its curve,
    by hand from P, F_f, W_A), plus the locomotive's linear end F^2 / (2 (k + k_f)): the peak
    force and compression follow within 1 %. On
    unloading every end gives back (k - k_f) / (k + k_f) of its loading force, so the
    vehicles part at sqrt of that ratio times the impact speed (coefficient of restitution).
    """
    out = tmp_path / 'impact'
    assert cli.main(['simulate', '--params', str(SCENARIO), '--duration', '2.0',
                     '--output', str(out), '-q']) == 0
    cp = [m for _, _, m in read_topics(str(out), [topics.COUPLERS_TOPIC])]
    co = [m for _, _, m in read_topics(str(out), [topics.COACHES_TOPIC])]
    y = np.array([m.position[0] for m in cp])
    force = np.array([m.effort[0] for m in cp])
    v = np.array([m.velocity for m in co])
    contact = int(np.argmax(y < -GAP))
    assert contact > 0 and np.all(force[:contact] == 0.0)      # free run up to the buffers
    v_impact = v[contact - 1, 1] - v[contact - 1, 0]
    assert 1.0 < v_impact < 2.0                                  # a shunting speed [m/s]

    types = consist.library_types()
    wagon, loco = types['freight_wagon_loaded_category_a'], types['electric_freight_locomotive']
    inertia = [t['mass'] * (1.0 + t['rotating_mass_factor']) for t in (wagon, loco)]
    mu = inertia[0] * inertia[1] / sum(inertia)
    k_loco = loco['buffer_stiffness'] + loco['buffer_friction']
    deflection, energy = category_a_end(wagon)
    kinetic = 0.5 * mu * v_impact ** 2
    n = wagon['buffers_per_end']
    assert n == 2                            # UIC: two side buffers, the category per buffer
    lo, hi = n * wagon['buffer_preload'] * 1.0001, n * wagon['buffer_final_force']
    for _ in range(100):                     # bisection: energy absorbed at force F = kinetic
        mid = 0.5 * (lo + hi)
        absorbed = n * energy(mid / n) + mid ** 2 / (2 * k_loco)
        lo, hi = (mid, hi) if absorbed < kinetic else (lo, mid)
    peak = 0.5 * (lo + hi)
    assert -force.min() == pytest.approx(peak, rel=0.01)
    assert -y.min() - GAP == pytest.approx(deflection(peak / n) + peak / k_loco, rel=0.01)
    assert energy(peak / n) < wagon['buffer_energy']             # within the category A buffer

    assert force[-1] == 0.0 and y[-1] > -GAP                     # parted again
    ratio = (loco['buffer_stiffness'] - loco['buffer_friction']) / k_loco
    assert wagon['buffer_stiffness'] - wagon['buffer_friction'] == pytest.approx(
        ratio * (wagon['buffer_stiffness'] + wagon['buffer_friction']))
    v_part = v[-1, 0] - v[-1, 1]
    assert v_part / v_impact == pytest.approx(np.sqrt(ratio), rel=0.01)
