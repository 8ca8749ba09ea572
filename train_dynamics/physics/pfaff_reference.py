"""
[Pfaff]'s braking model, written anew from the equations its notebook states (not copied).

R. Pfaff et al., "Braking curves in low-speed on-sight operation", code and results in
github.com/RailProfAC/ShuntingBrakingCurves (Code.ipynb): the published reference model of
the validation cases (:mod:`train_dynamics.physics.validation`), with the inputs of its
cases (constants below). Units SI: m, s, kg, N.
"""
from __future__ import annotations

import math

G = 9.81
#: [Pfaff]'s Karwatzki-type law of composition (K) blocks: mu = k1 (F + k2) / (F + k3)
#: (v + k4) / (v + k5), F [N] per block, v [m/s] (Code.ipynb, "muBr")
PFAFF_K = {'a': 0.055, 'b': 200000.0, 'c': 50000.0, 'd': 150.0 / 3.6, 'e': 75.0 / 3.6}
#: [Pfaff]'s wagon: 16" cylinder, return spring 1500 N, rigging efficiency 0.83, 16 blocks,
#: 3.8 bar, rotating-mass augment 1.04 loaded / 1.15 empty, Strahl resistance
#: (1.6e-3 + 5.7e-3 (v / 27.8)^2) m g; rigging ratio 5.65 loaded / 2.4 empty (calibrated
#: by [Pfaff] on the [C&O] slip tests from 100 km/h)
CYL_DIAMETER = 0.406
SPRING = 1500.0
ETA = 0.83
BLOCKS = 16
#: [Pfaff]'s locomotive, DB class 363: 53 t, braked weight P 56 t, lambda 105 %, a constant
#: braking force m a with a = 0.0075 lambda + 0.076 = 0.86 m/s^2 (UIC 544-1 app. G 4.4)
LOCO_MASS = 53000.0
LOCO_FORCE = LOCO_MASS * round(0.0075 * math.floor(56 / 53 * 100) + 0.076, 2)


# -- [Pfaff]'s model, written from the equations the notebook states ---------------------------

def pfaff_model(v0: float, wagons: list[dict], loco: dict | None = None,
                loco_twice: bool = True, dt: float = 0.01, law=None) -> float:
    """
    Return [Pfaff]'s stopping distance [m]: one mass, explicit Euler, step ``dt``.

    Each wagon: cylinder force p A - 1500 N times its filling (P: t / t_f; G: 0.1 + 0.9 t /
    t_f; t_f stretched by the brake wave's arrival, position / 250 m/s), block force that
    times i, retarding force block force * mu(v, block force / n) * eta; the locomotive a
    constant force times its filling; Strahl resistance of the wagons' mass; the mass m_loco
    + sum(augment m). As published the locomotive's full force is added once more in the
    velocity update (``loco_twice``, the notebook's code); ``loco_twice=False`` counts it
    once. ``law(v, F)``: another friction law (default [Pfaff]'s K blocks).
    """
    def k_block(v, f):
        k = PFAFF_K
        return k['a'] * (f + k['b']) / (f + k['c']) * (v + k['d']) / (v + k['e'])
    law = law or k_block

    def filling(t, tf, g_mode):
        if t >= tf:
            return 1.0
        return 0.1 + 0.9 * t / tf if g_mode else t / tf

    v, s, t = v0, 0.0, 0.0
    front = loco['length'] if loco else 0.0
    tfs = []
    for w in wagons:
        tfs.append(w['tf'] + front / 250.0)
        front += w['length']
    mass = (loco['mass'] if loco else 0.0) + sum(w['rot'] * w['mass'] for w in wagons)
    total = sum(w['mass'] for w in wagons)
    while v > 0.0:
        force = loco['force'] * filling(t, loco['tf'], loco['g']) if loco else 0.0
        for w, tf in zip(wagons, tfs):
            fc = 3.8e5 * math.pi * w['d'] ** 2 / 4 - SPRING
            blocks = fc * filling(t, tf, w['g']) * w['i']
            force += blocks * law(v, blocks / w['n']) * ETA
        force += (1.6e-3 + 5.7e-3 * (v / 27.8) ** 2) * total * G
        if loco and loco_twice:
            force += loco['force']
        v -= force / mass * dt
        s += v * dt
        t += dt
    return s


def pfaff_wagon(mass=90000.0, i=5.65, rot=1.04, g=False, tf=4.0, d=CYL_DIAMETER, n=BLOCKS,
                length=14.0):
    """
    Return one of [Pfaff]'s wagons for :func:`pfaff_model` (its default: the loaded one).

    ``mass`` [kg], rigging ratio ``i``, rotating-mass augment ``rot``, G filling ``g``, filling
    time ``tf`` [s], cylinder diameter ``d`` [m], ``n`` blocks, ``length`` [m] (Code.ipynb).
    """
    return {'mass': mass, 'i': i, 'rot': rot, 'g': g, 'tf': tf, 'd': d, 'n': n,
            'length': length}
