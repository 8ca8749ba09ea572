"""
The line: gradients and curves, and the forces they put on each vehicle.

Positions s [m] are along the track in the direction of travel. Vehicle i occupies
[p_i - L_i, p_i] with p_i = initial_position - (L_1 + ... + L_{i-1}) + x_i (its front).

- Gradient G(s) [per mille, > 0 uphill], piecewise constant from each of
  ``track_gradient_positions`` on, 0 before the first. The gradient force on vehicle i is
  -m_i g G_i / 1000 with G_i the mean of G over the length the vehicle occupies, so it changes
  continuously while a vehicle crosses a change of gradient (a train on a hump or in a sag
  feels in-train forces from gravity alone). The mean is (H(p) - H(p - L)) / L with the
  elevation H(s) = integral of G / 1000: the force is minus the derivative of the potential
  energy m g (mean of H over the vehicle), :func:`potential_energy`.
- Curves [start, end) of radius R [m]: Roeckl's specific resistance r = 650 / (R - 55) per
  mille for R >= 300 m, 500 / (R - 30) for R < 300 m (standard-gauge main lines; Roeckl 1880,
  as given by Wende, Fahrdynamik des Schienenverkehrs, 2003). The curve resistance of vehicle
  i is m_i g r_i / 1000 against the motion, r_i the mean of r over the vehicle's length.

- Adhesion mu_low(s) [-], the available wheel-rail adhesion at low speed (UIC 541-05's rail
  conditions), piecewise constant from each of ``track_adhesion_positions`` on, dry
  (Curtius-Kniffler's 0.331 at rest) before the first; a vehicle's available adhesion is the
  mean of mu_low over its length, falling with speed as Curtius-Kniffler's law
  (:func:`~train_dynamics.physics.kernel.traction.adhesion`). It limits the wheelsets' creep
  force (:mod:`~train_dynamics.physics.wheelset`) and scales the traction adhesion of a
  locomotive (``traction_adhesion`` x mu_low / 0.331). Stored as its deviation from dry, so
  the empty profile is dry everywhere.

A profile is stored as breakpoints ``xs``, the value on [xs[k], xs[k+1]) ``vals`` (the last
one to infinity) and the integral from xs[0] to xs[k] ``cum``: the mean over any interval is
two look-ups (``profile_mean`` of :mod:`train_dynamics.physics.kernel.track`, compiled with
numba for the kernel).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from train_dynamics.physics.kernel.track import profile_integral, track_forces
from train_dynamics.physics.kernel.traction import CK_AT_REST as DRY_ADHESION


def roeckl(radius: float) -> float:
    """Return Roeckl's specific curve resistance [per mille] of a curve of ``radius`` [m]."""
    if radius >= 300.0:
        return 650.0 / (radius - 55.0)
    return 500.0 / (radius - 30.0)


def _cumulative(xs: np.ndarray, vals: np.ndarray) -> np.ndarray:
    cum = np.zeros(xs.shape[0])
    if xs.shape[0] > 1:
        cum[1:] = np.cumsum(vals[:-1] * np.diff(xs))
    return cum


@dataclass
class Track:
    """Gradient and curve-resistance profiles (per mille) and the start position [m]."""

    initial_position: float = 0.0
    gx: np.ndarray = None
    gv: np.ndarray = None
    gc: np.ndarray = None
    cx: np.ndarray = None
    cv: np.ndarray = None
    cc: np.ndarray = None
    ax: np.ndarray = None
    av: np.ndarray = None
    ac: np.ndarray = None

    @classmethod
    def from_lists(cls, initial_position=0.0, gradient_positions=(), gradients=(),
                   curve_starts=(), curve_ends=(), curve_radii=(), adhesion_positions=(),
                   adhesion=()) -> 'Track':
        """Build and check a track; raise ValueError naming the parameter at fault."""
        gp = np.asarray(gradient_positions, dtype=float).reshape(-1)
        gr = np.asarray(gradients, dtype=float).reshape(-1)
        if gp.shape != gr.shape:
            raise ValueError(f'track_gradient_positions and track_gradients must have the same '
                             f'length ({gp.size} != {gr.size})')
        if np.any(np.diff(gp) <= 0.0):
            raise ValueError('track_gradient_positions: must strictly increase')
        cs, ce, cr = (np.asarray(a, dtype=float).reshape(-1)
                      for a in (curve_starts, curve_ends, curve_radii))
        if not cs.size == ce.size == cr.size:
            raise ValueError('track_curve_starts, track_curve_ends and track_curve_radii must '
                             f'have the same length ({cs.size}, {ce.size}, {cr.size})')
        order = np.argsort(cs, kind='stable')
        cs, ce, cr = cs[order], ce[order], cr[order]
        if np.any(ce <= cs):
            raise ValueError('track_curve_ends: each curve must end after it starts')
        if np.any(cs[1:] < ce[:-1]):
            raise ValueError('track curves: curves must not overlap')
        if np.any(cr <= 55.0):
            raise ValueError('track_curve_radii: must be > 55 m (Roeckl)')
        xs, vals = [], []
        for a, b, r in zip(cs, ce, cr):
            if xs and xs[-1] == a:
                vals[-1] = roeckl(r)
            else:
                xs.append(a)
                vals.append(roeckl(r))
            xs.append(b)
            vals.append(0.0)
        cx = np.asarray(xs, dtype=float)
        cv = np.asarray(vals, dtype=float)
        ax, av = adhesion_profile(adhesion_positions, adhesion)
        return cls(float(initial_position), gp, gr, _cumulative(gp, gr), cx, cv,
                   _cumulative(cx, cv), ax, av, _cumulative(ax, av))

    @property
    def adhesion_profile(self) -> np.ndarray:
        """Return the adhesion profile (3, K) for the kernel: positions, mu_low - dry, integral."""
        return np.array([self.ax, self.av, self.ac], dtype=float).reshape(3, -1)

    def adhesion_at(self, s) -> np.ndarray:
        """Return the available adhesion at low speed [-] at track positions s [m]."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if self.ax.size == 0:
            return np.full_like(s, DRY_ADHESION)
        k = np.searchsorted(self.ax, s, side='right') - 1
        return DRY_ADHESION + np.where(k >= 0, self.av[np.maximum(k, 0)], 0.0)

    @property
    def flat_and_straight(self) -> bool:
        """Return True when no gradient and no curve is set (the paper's idealisation)."""
        return self.gx.size == 0 and self.cx.size == 0

    def fronts(self, lengths) -> np.ndarray:
        """Return the front position of each vehicle at t = 0 [m]."""
        lengths = np.asarray(lengths, dtype=float)
        return self.initial_position - np.concatenate(([0.0], np.cumsum(lengths[:-1])))

    def gradient_at(self, s) -> np.ndarray:
        """Return the gradient [per mille] at track positions s [m]."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if self.gx.size == 0:
            return np.zeros_like(s)
        k = np.searchsorted(self.gx, s, side='right') - 1
        return np.where(k >= 0, self.gv[np.maximum(k, 0)], 0.0)

    def elevation(self, s) -> np.ndarray:
        """Return the height H(s) [m] of the track relative to the first gradient change."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        return np.array([profile_integral(float(p), self.gx, self.gv, self.gc)
                         for p in s]) * 1e-3

    def mean_elevation(self, lo: float, hi: float) -> float:
        """Return the mean of H over [lo, hi] [m] (H is piecewise linear: exact)."""
        inner = self.gx[(self.gx > lo) & (self.gx < hi)]
        pts = np.concatenate(([lo], inner, [hi]))
        h = self.elevation(pts)
        return float(np.sum(0.5 * (h[1:] + h[:-1]) * np.diff(pts)) / (hi - lo))

    def potential_energy(self, x, lengths, masses, g: float) -> float:
        """Return the potential energy of the train [J]: sum of m g (mean H over each vehicle)."""
        fronts = self.fronts(lengths) + np.asarray(x, dtype=float)
        return float(sum(m * g * self.mean_elevation(p - length, p)
                         for p, length, m in zip(fronts, lengths, masses)))

    def forces(self, x, lengths, masses, g: float):
        """Return (gradient force [N, forward > 0], curve resistance [N, >= 0]) per vehicle."""
        x = np.asarray(x, dtype=float)
        lengths = np.asarray(lengths, dtype=float)
        grade = np.empty(x.shape[0])
        curve = np.empty(x.shape[0])
        track_forces(x, self.fronts(lengths), lengths, np.asarray(masses, float) * g,
                     self.gx, self.gv, self.gc, self.cx, self.cv, self.cc, grade, curve)
        return grade, curve


def adhesion_profile(positions, values) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (positions, mu_low - dry) of a track adhesion profile; raise ValueError at a fault.

    ``track_adhesion_positions`` [m] strictly increasing, ``track_adhesion`` [-] in (0, 1],
    one per position.
    """
    ap = np.asarray(positions, dtype=float).reshape(-1)
    av = np.asarray(values, dtype=float).reshape(-1)
    if ap.shape != av.shape:
        raise ValueError(f'track_adhesion_positions and track_adhesion must have the same '
                         f'length ({ap.size} != {av.size})')
    if np.any(np.diff(ap) <= 0.0):
        raise ValueError('track_adhesion_positions: must strictly increase')
    if np.any(~np.isfinite(av)) or np.any(av <= 0.0) or np.any(av > 1.0):
        raise ValueError('track_adhesion: each value must be in (0, 1]')
    return ap, av - DRY_ADHESION
