"""
Reference solution of the coach chain: scipy ``solve_ivp`` to tight tolerances.

Eqs. (5)-(7) with the tanh law (eqs. 14-16), every coach moving forward, solved with the
analytical sparse Jacobian of the chain; the tests and benchmarks measure the compiled
integrators against it. Not part of the kernel: plain Python on scipy.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import couplers


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
