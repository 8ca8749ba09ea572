"""
Reference solution of the coach chain: scipy ``solve_ivp`` to tight tolerances.

Eqs. (5)-(7) with the tanh law (eqs. 14-16), every coach moving forward, solved with the
analytical sparse Jacobian of the chain; the tests and benchmarks measure the compiled
integrators against it. Not part of the kernel: plain Python on scipy.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import couplers


class HeadVentBraking:
    """
    Closed-form braking forces [N] after the brake pipe is vented at the head at ``t_vent`` [s].

    The pipe's brake wave reaches coach i = 1..N after (i-1) L / c [s] (coach length L [m],
    propagation speed c [m/s]); from then on its cylinder follows the filling table (paper
    eq. 13) and its braking force is Fb_i(t) = mu_a m_i g fill(t - t_vent - (i-1) L / c)
    (mu_a the adhesion coefficient, m_i [kg], g [m/s^2], fill in 0..1, zero before the wave).
    The brake system does not depend on the motion, so the references take it as a known
    function of time; its kinks (the table's knots, shifted to each coach) are where an
    integrator must restart.
    """

    def __init__(self, cfg, t_vent: float):
        self.t_vent = float(t_vent)
        self.delays = (np.arange(cfg.n_coaches, dtype=float) * cfg.coach_length
                       / cfg.brake_propagation_speed)
        self.full = cfg.adhesion_coefficient * np.asarray(cfg.mass_array, float) * cfg.gravity
        self._ft, self._ff = (np.asarray(a, float) for a in cfg.fill_table())

    def __call__(self, t: float) -> np.ndarray:
        """Braking forces [N] (N,) at time t [s], positive retarding."""
        return self.full * np.interp(t - self.t_vent - self.delays, self._ft, self._ff,
                                     left=0.0)

    def kinks(self, t_end: float) -> np.ndarray:
        """Return the instants in (0, t_end) [s] where a coach's force has a kink, ascending."""
        k = np.unique(np.concatenate([self.t_vent + d + self._ft for d in self.delays]))
        return k[(k > 0.0) & (k < t_end)]

    def steps(self, t_end: float):
        """Return the kinks as zero force steps, for a chain reference's brake input."""
        k = self.kinks(t_end)
        return k, np.zeros((k.size, self.delays.size))


def reference_solution(masses, ke, kf, kec, kfc, u, v0, brake_of_t, t_end, *,
                       t_eval=None, rtol=1e-9, atol=1e-11, method='Radau', x0=None):
    """
    Solve eqs. (5)-(7) with the tanh law (eqs. 14-16) to tight tolerances.

    ``brake_of_t(t) -> (N,)`` braking forces [N] (positive retarding), valid while every
    coach moves forward (the reference does not model the brake holding a coach at rest).
    Uses scipy ``solve_ivp`` with the analytical sparse Jacobian of the chain (state
    [x, v]). Returns the ``OdeResult`` (``.t``, ``.y`` with x = y[:N], v = y[N:]).
    """
    # scipy is imported here, not at the top: only tests and benchmarks need the reference,
    # and the node and the offline command should not pay scipy's import time.
    import scipy.sparse as sp
    from scipy.integrate import solve_ivp

    masses = np.asarray(masses, float)
    n = masses.shape[0]
    args = [np.broadcast_to(np.asarray(k, float), (n - 1,)).copy() for k in (ke, kf, kec, kfc)]
    model = couplers.TANH
    inv_m = 1.0 / masses
    D = sp.diags([np.ones(n - 1), -np.ones(n - 1)], [0, 1], shape=(n - 1, n), format='csr')
    eye = sp.identity(n, format='csr')

    def rhs(t, z):
        x, v = z[:n], z[n:]
        F = couplers.coupler_force(x[:-1] - x[1:], v[:-1] - v[1:], *args, model, float(u))
        return np.concatenate([v, (couplers.net_forces(F) - brake_of_t(t)) * inv_m])

    def jac(t, z):
        x, v = z[:n], z[n:]
        dfdy, dfdv = couplers.coupler_force_jacobian(x[:-1] - x[1:], v[:-1] - v[1:], *args,
                                                     model, float(u))
        minv = sp.diags(inv_m)
        kx = -(minv @ D.T @ sp.diags(dfdy) @ D)
        kv = -(minv @ D.T @ sp.diags(dfdv) @ D)
        return sp.bmat([[None, eye], [kx, kv]], format='csc')

    z0 = np.concatenate([np.zeros(n) if x0 is None else np.asarray(x0, float),
                         np.broadcast_to(np.asarray(v0, float), (n,))])
    return solve_ivp(rhs, (0.0, t_end), z0, method=method, jac=jac, t_eval=t_eval,
                     rtol=rtol, atol=atol)
