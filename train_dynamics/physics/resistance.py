"""
Running resistance on the Python side: the laws, the equivalent mass, the coast-down speed.

The coast-down speed is a reference for the tests.

Davis (1926): R = A + B |v| + C v^2 [N], compiled in
:mod:`train_dynamics.physics.kernel.resistance`. The European laws of a vehicle's
``resistance_law`` are quadratics in the speed as well, so each is handed to the kernel as
the Davis coefficients it equals (:func:`davis_of_law`, exact for any v >= 0; the kernel
takes |v|, so a train backing up sees the same law):

- ``strahl`` (Strahl 1913, freight trains; w in per mille = N/kN, V km/h):
  w = 2.5 + k ((V + dV) / 10)^2, R = m g w / 1000; k = 0.025 loaded, 0.05 mixed, 0.1 empty
  freight trains, dV = 15 km/h head wind. The form and figures as quoted in the German
  running-dynamics literature (Wende, Fahrdynamik des Schienenverkehrs, Teubner 2003,
  section on train resistance); not read in Strahl's paper itself: the constants 2.5 and the
  k values are to be checked there.
- ``sauthoff`` (F. Sauthoff, "Die Bewegungswiderstände der Eisenbahnwagen", Dr.-Ing. thesis
  TH Berlin, VDI-Verlag 1933: coach trains without the locomotive): w = 1.9 + c V [per mille]
  for running, c = 0.007 / 0.004 / 0.0024 for two-, three-, four-axle coaches, plus the air
  term 0.0048 (n + 2.7) f (V + dV)^2 [kp] for n coaches of equivalent area f (1.45 m^2),
  dV = 15 km/h. The variables and figures (c, f, n + 2.7) as de.wikipedia "Sauthoff-Formel"
  lists them (retrieved December 2026; its formula's rendering was not retrievable); the form
  and the 0.0048 and dV = 15 km/h as public train-dynamics codes write it (a specific
  resistance 1.9 + c V + 0.0048 (n + 2.7) f (V + 15)^2 / m [kp/t], m in t); not read in the
  thesis. The 0.0048 is in kp: 0.0048 kp = rho / 2 / 3.6^2 with rho = 1.22 kg/m^3 (a dynamic
  pressure per (km/h)^2), which is why it is taken in kp, to N by :data:`KP` = 9.80665 N.
  Per vehicle: each coach carries f (1 + 2.7 / n) of it, n the vehicles of the train on the
  law, so n identical coaches sum to the published train law.
Inertia: a vehicle accelerates its rotating masses (wheelsets, gears, motors) too; the
equivalent mass for inertia is m (1 + rotating_mass_factor). Gravity, the braking force (paper
eq. 13) and the resistance use m. Typical factors (Wende, Fahrdynamik des Schienenverkehrs,
2003): locomotives 0.15-0.30, coaches 0.04-0.10, loaded wagons 0.03-0.05, empty 0.08-0.10.
"""
from __future__ import annotations

import numpy as np

#: the running resistance laws of a vehicle (``resistance_law``), in the order of their codes
RESISTANCE_LAWS = ('davis', 'strahl', 'sauthoff')

#: [N] one kilopond: the unit of Sauthoff's air term
KP = 9.80665

#: [km/h per m/s]
KMH = 3.6


def strahl(v, mass, k, wind, gravity=9.81):
    """
    Return the Strahl running resistance [N] of a vehicle of ``mass`` [kg] at v [m/s] >= 0.

    R = m g (2.5 + k ((V + dV) / 10)^2) / 1000, V = 3.6 v [km/h], dV = ``wind`` [km/h]
    (sources in the module's docstring).
    """
    speed = KMH * np.asarray(v, dtype=float) + wind
    return mass * gravity * (2.5 + k * (speed / 10.0) ** 2) / 1000.0


def sauthoff(v, mass, c, area, wind, n, gravity=9.81):
    """
    Return the Sauthoff running resistance [N] of one of ``n`` coaches at v [m/s] >= 0.

    R = m g (1.9 + c V) / 1000 + 0.0048 KP (1 + 2.7 / n) f (V + dV)^2, V = 3.6 v [km/h],
    c [per mille per km/h], f = ``area`` [m^2], dV = ``wind`` [km/h] (sources in the
    module's docstring).
    """
    speed = KMH * np.asarray(v, dtype=float)
    return (mass * gravity * (1.9 + c * speed) / 1000.0
            + 0.0048 * KP * (1.0 + 2.7 / n) * area * (speed + wind) ** 2)


def davis_of_law(law, mass, *, strahl_k, sauthoff_c, sauthoff_area, wind, n, gravity):
    """
    Return the Davis (A [N], B [N s/m], C [N s^2/m^2]) equal to a vehicle's law for v >= 0.

    ``law``: a code of :data:`RESISTANCE_LAWS` (arrays or scalars; 0, davis, gives None).
    The polynomials of :func:`strahl` and :func:`sauthoff` in v, expanded: with
    (3.6 v + dV)^2 = 12.96 v^2 + 7.2 dV v + dV^2,

    - strahl: w = m g k / 1e5: A = m g 2.5 / 1000 + w dV^2, B = w 7.2 dV, C = w 12.96;
    - sauthoff: a = 0.0048 KP (1 + 2.7 / n) f: A = m g 1.9 / 1000 + a dV^2,
      B = m g c 3.6 / 1000 + a 7.2 dV, C = a 12.96.
    """
    law = np.asarray(law, dtype=float)
    weight = np.asarray(mass, dtype=float) * gravity
    wind = np.asarray(wind, dtype=float)
    w = weight * np.asarray(strahl_k, dtype=float) / 1.0e5
    a = 0.0048 * KP * (1.0 + 2.7 / max(n, 1)) * np.asarray(sauthoff_area, dtype=float)
    is_strahl = law == RESISTANCE_LAWS.index('strahl')
    big_a = np.where(is_strahl, weight * 2.5e-3 + w * wind ** 2, weight * 1.9e-3 + a * wind ** 2)
    big_b = np.where(is_strahl, w * 2.0 * KMH * wind,
                     weight * np.asarray(sauthoff_c, dtype=float) * KMH / 1000.0
                     + a * 2.0 * KMH * wind)
    big_c = np.where(is_strahl, w * KMH * KMH, a * KMH * KMH)
    return big_a, big_b, big_c


def equivalent_mass(mass, rotating_mass_factor) -> np.ndarray:
    """Return m (1 + rotating_mass_factor) [kg]: the mass for inertia."""
    return np.asarray(mass, dtype=float) * (1.0 + np.asarray(rotating_mass_factor, dtype=float))


def coast_down_speed(t, v0: float, m_eq: float, a: float, b: float, c: float) -> np.ndarray:
    """
    Return v(t) [m/s] of a single vehicle coasting down from v0 under Davis resistance alone.

    m_eq dv/dt = -(a + b v + c v^2), closed form for c > 0 and 4 a c > b^2 (the usual case):
    with w = sqrt(4 a c - b^2) / 2, v(t) = (w tan(atan((v0 + b/2c) c / w) - w t / m_eq)
    - b/2) / c, until the vehicle stops (then 0). For c = 0 the linear law gives
    v = (v0 + a/b) exp(-b t/m) - a/b (b > 0) or v0 - a t / m.
    """
    t = np.asarray(t, dtype=float)
    if c > 0.0:
        disc = 4.0 * a * c - b * b
        if disc <= 0.0:
            raise ValueError('closed form needs 4 a c > b^2')
        w = 0.5 * np.sqrt(disc)
        phase = np.arctan((c * v0 + 0.5 * b) / w) - w * t / m_eq
        v = (w * np.tan(phase) - 0.5 * b) / c
        t_stop = m_eq / w * (np.arctan((c * v0 + 0.5 * b) / w) - np.arctan(0.5 * b / w))
    elif b > 0.0:
        v = (v0 + a / b) * np.exp(-b * t / m_eq) - a / b
        t_stop = m_eq / b * np.log((v0 + a / b) / (a / b)) if a > 0.0 else np.inf
    else:
        v = v0 - a * t / m_eq
        t_stop = m_eq * v0 / a if a > 0.0 else np.inf
    return np.where(t < t_stop, v, 0.0)
