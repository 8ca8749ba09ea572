"""Integrators of the coach chain: the fixed-step real-time method and a reference.

Fixed step: **ROS2**, the two-stage, second-order, L-stable Rosenbrock method of Verwer,
Spee, Blom and Hundsdorfer (SIAM J. Sci. Comput. 20, 1999), gamma = 1 + 1/sqrt(2).

Why this method: the tanh friction term makes the chain stiff. Its derivative with respect
to the coupler velocity is u k_f |y| sech^2(u ydot), about 1.4e6 * 0.02 * 1e3 = 3e7 N s/m at
u = 1e3 and ten times that at u = 1e4; on a 22.5 t reduced mass that is a decay rate of
1e3 - 1e4 1/s, so an explicit method would need steps of ~1e-5 s. A Rosenbrock method solves
one linear system per stage with the exact Jacobian instead of iterating Newton to
convergence: deterministic cost per step, no convergence failure. L-stability damps the
stiff friction modes in one step instead of letting them ring (the trapezoidal rule would
ring, and ringing around ydot = 0 is exactly the chattering the paper warns of). ROS2 keeps
order two for any Jacobian approximation (it is a W-method), so the sign model, whose
friction has no usable derivative, still integrates consistently: its friction is then
explicit and chatters around ydot = 0 as the paper reports, bounded by k_f |y|.

The Jacobian of the chain is block structured: d(x')/dv = I and
M d(v')/d(x, v) = -(D^T K D, D^T C D) with K = diag(dF/dy), C = diag(dF/dydot), so the stage
equations reduce to one tridiagonal system in the velocity stage,
(M + g h C_c + g^2 h^2 K_c) b = rhs, solved in O(N) by the Thomas algorithm (the matrix is
diagonally dominant: masses on the diagonal, k > k_friction in every branch).

Braking is friction: a coach at rest stays at rest while the braking force can hold it
(|net coupler force| <= Fb), and the brake never pushes a coach backwards. The step treats
resting coaches as held (their rows fixed at zero velocity) and finds the set of held
coaches by a short active-set iteration: a held coach whose required holding force exceeds
the available braking force is released, a moving coach whose velocity would change sign is
stopped. Momentum bookkeeping is exact: the held coaches' brake force is the one that the
stage equations require.

Reference: :func:`reference_solution`, scipy ``solve_ivp`` (Radau by default) with the
analytical sparse Jacobian and tight tolerances, for tests and benchmarks.
"""
from __future__ import annotations

import math

import numpy as np

from . import brakes, couplers
from ._jit import jit

GAMMA = 1.0 + 1.0 / np.sqrt(2.0)

#: [m/s] a braked coach slower than this is at rest (1 micrometre per second): without it a
#: coach whose coupler force exactly balances its sliding brake could creep for ever
V_REST = 1e-6

OK = 0
NON_FINITE = 1
OUT_OF_RANGE = 2
STATUS_TEXT = {
    NON_FINITE: 'state became non-finite at t = {t:.4f} s; integration stopped',
    OUT_OF_RANGE: 'a coupler displacement left the physically possible range at '
                  't = {t:.4f} s; integration stopped',
}


@jit
def solve_tridiagonal(lower: np.ndarray, diag: np.ndarray, upper: np.ndarray,
                      rhs: np.ndarray) -> np.ndarray:
    """Thomas algorithm: solve A z = rhs, A tridiagonal (lower[i] = A[i+1, i],
    upper[i] = A[i, i+1]); A must be diagonally dominant (no pivoting)."""
    n = diag.shape[0]
    c = np.empty(n)
    winv = np.empty(n)
    z = np.empty(n)
    winv[0] = 1.0 / diag[0]
    z[0] = rhs[0] * winv[0]
    for i in range(1, n):
        c[i - 1] = upper[i - 1] * winv[i - 1]
        winv[i] = 1.0 / (diag[i] - lower[i - 1] * c[i - 1])
        z[i] = (rhs[i] - lower[i - 1] * z[i - 1]) * winv[i]
    for i in range(n - 2, -1, -1):
        z[i] -= c[i] * z[i + 1]
    return z


@jit
def chain_matvec(k: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(D^T diag(k) D) w: a coupler property k spread onto the coaches [N]."""
    dk = k * (w[:-1] - w[1:])
    out = np.zeros(w.shape[0])
    out[:-1] += dk
    out[1:] -= dk
    return out


@jit
def _net_coupler(F: np.ndarray) -> np.ndarray:
    out = np.zeros(F.shape[0] + 1)
    out[:-1] -= F
    out[1:] += F
    return out


# Rows of the kernel's scratch memory (one array, no allocation inside the step loop).
(W_F, W_DFDY, W_KK, W_DIAG, W_LOWER, W_RHS1, W_RHS2, W_B1, W_B2, W_C, W_WINV, W_F2,
 W_FB, W_SIGNED, W_VSTART, W_RELDIR, W_HOLD, W_TARGET, W_FBNEXT, W_K0, W_FRAC, W_XNEW,
 W_VNEW, W_XOLD) = range(24)
N_WORK_ROWS = 24


def make_workspace(n: int) -> np.ndarray:
    """Scratch memory of the kernel (N_WORK_ROWS arrays of N)."""
    return np.zeros((N_WORK_ROWS, n))


@jit
def _coupler_w(y, ydot, ke, kf, kec, kfc, model, u):
    """One coupler's force F [N], dF/dy [N/m] and the dF/dydot [N s/m] of the stage matrix.

    The stage matrix takes, for the tanh model, the secant slope of the friction force
    through ydot = 0, k_fr |y| tanh(u ydot) / ydot, not the tangent u k_fr |y| sech^2(u ydot):
    a step that carries ydot across the 1/u-wide tanh band then still sees the friction's
    damping (the tangent is ~0 outside the band, which made the friction explicit exactly
    there and overshot the peak force of long trains by 10 % at 5 ms). ROS2 is a W-method:
    order 2 holds for any matrix. Both slopes agree as ydot -> 0. The sign model keeps 0.
    """
    if model == couplers.TANH:
        z = u * ydot
        a = abs(z)
        t = couplers.fast_tanh(a)               # tanh|z|
        s = math.copysign(t, z)
        ratio = t / a if a > 1e-3 else 1.0     # tanh(z) / z, within 4e-7 of 1 below 1e-3
    else:
        s = np.sign(ydot)
        ratio = 0.0
    f, stiff, kfr = couplers.coupler_branch(y, s, ke, kf, kec, kfc)
    return f, stiff, kfr * y * u * ratio


@jit
def _eval_couplers(x, v, ke, kf, kec, kfc, model, u, gh, ws):
    """F, dF/dy and the stage-matrix weights g h dF/dydot + (g h)^2 dF/dy of every coupler
    at (x, v), into ws."""
    F0 = ws[W_F]
    dfdy = ws[W_DFDY]
    kk = ws[W_KK]
    for j in range(x.shape[0] - 1):
        f, dy, dv = _coupler_w(x[j] - x[j + 1], v[j] - v[j + 1], ke[j], kf[j], kec[j], kfc[j],
                               model, u)
        F0[j] = f
        dfdy[j] = dy
        kk[j] = gh * dv + gh * gh * dy


@jit
def _eval_couplers_work(x, v, x_old, ke, kf, kec, kfc, model, u, gh, ws):
    """:func:`_eval_couplers` at the new state (x, v) that also returns the couplers' work
    over the step from x_old [J] (trapezoidal in the force, as before)."""
    F0 = ws[W_F]
    dfdy = ws[W_DFDY]
    kk = ws[W_KK]
    wc = 0.0
    for j in range(x.shape[0] - 1):
        y = x[j] - x[j + 1]
        f, dy, dv = _coupler_w(y, v[j] - v[j + 1], ke[j], kf[j], kec[j], kfc[j], model, u)
        wc += 0.5 * (F0[j] + f) * (y - (x_old[j] - x_old[j + 1]))
        F0[j] = f
        dfdy[j] = dy
        kk[j] = gh * dv + gh * gh * dy
    return wc


@jit
def _ros2_step(h, x, v, held, brake, masses, ke, kf, kec, kfc, model, u, ws,
               x_new, v_new, hold):
    """One ROS2 step with the coaches in ``held`` fixed at rest.

    ``brake`` [N] is the signed braking force on the moving coaches (positive retarding).
    Fills x_new, v_new and ``hold``: the holding force [N] the stage equations require of
    each held coach (signed, positive retarding; 0 on moving coaches). The couplers'
    forces and Jacobian at (x, v) must be in ws (:func:`_eval_couplers`).

    Stage equations, with A = M + g h C_c + (g h)^2 K_c (tridiagonal):
      A b1 = g(x, v) - g h K_c v - Fb,                        a1 = v + g h b1
      A b2 = g(x + h a1, v + h b1) - 2 M b1 - g h K_c r - Fb,  r = v + h b1 - 2 a1,
                                                               a2 = r + g h b2
      x' = x + h (3/2 a1 + 1/2 a2),  v' = v + h (3/2 b1 + 1/2 b2).
    Written as fused loops: assembly, LU factorisation and forward substitution in one pass.
    """
    n = x.shape[0]
    m = n - 1
    gh = GAMMA * h
    F0 = ws[W_F]
    dfdy = ws[W_DFDY]
    kk = ws[W_KK]
    diag = ws[W_DIAG]       # diagonal of the free rows (for the holding forces)
    lower = ws[W_LOWER]     # A[i+1, i] of the effective matrix
    rhs1 = ws[W_RHS1]       # right-hand sides of the free rows, brake apart
    rhs2 = ws[W_RHS2]
    b1 = ws[W_B1]
    b2 = ws[W_B2]
    c = ws[W_C]
    winv = ws[W_WINV]
    F2 = ws[W_F2]
    # stage 1: assemble, factor and forward-substitute in one sweep
    for i in range(n):
        d = masses[i]
        g = 0.0
        kv = 0.0
        if i > 0:
            d += kk[i - 1]
            g += F0[i - 1]
            kv += dfdy[i - 1] * (v[i] - v[i - 1])
        if i < m:
            d += kk[i]
            g -= F0[i]
            kv += dfdy[i] * (v[i] - v[i + 1])
        diag[i] = d
        rhs1[i] = g - gh * kv
        if held[i]:
            d = 1.0
            r1 = 0.0
        else:
            r1 = rhs1[i] - brake[i]
        if i == 0:
            winv[0] = 1.0 / d
            b1[0] = r1 * winv[0]
        else:
            up = 0.0 if held[i - 1] else -kk[i - 1]     # A[i-1, i]
            lo = 0.0 if held[i] else -kk[i - 1]         # A[i, i-1]
            lower[i - 1] = lo
            c[i - 1] = up * winv[i - 1]
            winv[i] = 1.0 / (d - lo * c[i - 1])
            b1[i] = (r1 - lo * b1[i - 1]) * winv[i]
    for i in range(n - 2, -1, -1):
        b1[i] -= c[i] * b1[i + 1]
    # stage 2 at (x + h a1, v + h b1), a1 = v + g h b1
    for j in range(m):
        dv = v[j] - v[j + 1]
        db = b1[j] - b1[j + 1]
        f, _, _ = couplers.coupler_force_scalar(
            x[j] - x[j + 1] + h * (dv + gh * db), dv + h * db, ke[j], kf[j], kec[j], kfc[j],
            model, u)
        F2[j] = f
    hr = h - 2.0 * gh            # r = v + h b1 - 2 a1 = (h - 2 g h) b1 - v
    for i in range(n):
        g = 0.0
        kr = 0.0
        ri = hr * b1[i] - v[i]
        if i > 0:
            g += F2[i - 1]
            kr += dfdy[i - 1] * (ri - (hr * b1[i - 1] - v[i - 1]))
        if i < m:
            g -= F2[i]
            kr += dfdy[i] * (ri - (hr * b1[i + 1] - v[i + 1]))
        rhs2[i] = g - 2.0 * masses[i] * b1[i] - gh * kr
        r2 = 0.0 if held[i] else rhs2[i] - brake[i]
        if i == 0:
            b2[0] = r2 * winv[0]
        else:
            b2[i] = (r2 - lower[i - 1] * b2[i - 1]) * winv[i]
    for i in range(n - 2, -1, -1):
        b2[i] -= c[i] * b2[i + 1]
    # the new state, and the holding forces the held rows of the stage equations require
    for i in range(n):
        a1 = v[i] + gh * b1[i]
        a2 = hr * b1[i] - v[i] + gh * b2[i]
        x_new[i] = x[i] + h * (1.5 * a1 + 0.5 * a2)
        v_new[i] = v[i] + h * (1.5 * b1[i] + 0.5 * b2[i])
        if not held[i]:
            hold[i] = 0.0
            continue
        ab1 = diag[i] * b1[i]
        ab2 = diag[i] * b2[i]
        if i > 0:
            ab1 -= kk[i - 1] * b1[i - 1]
            ab2 -= kk[i - 1] * b2[i - 1]
        if i < m:
            ab1 -= kk[i] * b1[i + 1]
            ab2 -= kk[i] * b2[i + 1]
        hold[i] = 0.5 * ((rhs1[i] - ab1) + (rhs2[i] - ab2))


@jit
def _stops(v0, v1, fb):
    """A moving coach stops within the step: its velocity v0 -> v1 [m/s] changes sign, or a
    braked coach (fb [N] > 0) ends the step slower than V_REST."""
    if v0 == 0.0:
        return False
    if v0 * v1 <= 0.0:
        return True
    return fb > 0.0 and abs(v1) < V_REST


# Rows of the coach array and slots of the scalar arrays passed to :func:`advance_chain`
# (few arguments keep numba's call overhead at a few microseconds).
X, V, MASS, PCYL, PPIPE, PIPE_IN, CYL_IN, FB_AVAIL, FB_APPLIED, DELAY, APPLIED, HELD = range(12)
N_COACH_ROWS = 12
KE, KF, KEC, KFC = range(4)
S_H, S_U, S_PMAX, S_MU, S_G, S_PNOM, S_PFS, S_SENS, S_HEAD_IN, S_YLIM, S_WB, S_WC = range(12)
N_SCALARS = 12
I_MODEL, I_MODE, I_RING_POS, I_WS_VALID = range(4)
N_INT_SCALARS = 4


@jit
def advance_chain(n_steps, coach, cpl, sc, iv, fill, rel, ring, ws):
    """Advance brakes and chain ``n_steps`` fixed steps, in place; returns (steps, status).

    coach: (12, N) rows X..HELD above; cpl: (4, N-1) k_e, k_f, k_ec, k_fc [N/m];
    sc: float scalars (S_*), iv: int scalars (I_*); fill, rel: (2, L) tables (times [s],
    p/p_max); ring: head-pressure history; ws: :func:`make_workspace`.

    Each step: the brake system moves to the end of the step (pipe delay, distributors,
    cylinders: it does not depend on the motion), the braking force over the step is the
    mean of its values at both ends (trapezoidal, second order), then one ROS2 step with the
    active set of held coaches.
    """
    n = coach.shape[1]
    m = n - 1
    x = coach[X]
    v = coach[V]
    masses = coach[MASS]
    p_cyl = coach[PCYL]
    p_pipe = coach[PPIPE]
    fb_avail = coach[FB_AVAIL]
    fb_applied = coach[FB_APPLIED]
    ke = cpl[KE]
    kf = cpl[KF]
    kec = cpl[KEC]
    kfc = cpl[KFC]
    h = sc[S_H]
    u = sc[S_U]
    p_max = sc[S_PMAX]
    model = iv[I_MODEL]
    mode = iv[I_MODE]
    applied = coach[APPLIED]      # float flags, updated in place by distributor_target
    fb = ws[W_FB]
    signed = ws[W_SIGNED]
    v_start = ws[W_VSTART]
    rel_dir = ws[W_RELDIR]
    hold = ws[W_HOLD]
    target = ws[W_TARGET]
    fb_next = ws[W_FBNEXT]
    x_new = ws[W_XNEW]
    v_new = ws[W_VNEW]
    x_old = ws[W_XOLD]
    hold_set = np.empty(n, dtype=np.bool_)
    tables = brakes.CylinderTables(fill[0].copy(), fill[1].copy(), rel[0].copy(),
                                   rel[1].copy(), rel[0][::-1].copy(), rel[1][::-1].copy())
    k0 = ws[W_K0]
    frac = ws[W_FRAC]
    gh = GAMMA * h
    if iv[I_WS_VALID] == 0:
        # first call after reset()/set_model(): pipe delays and the couplers at (x, v); later
        # calls find them in ws, left there by the last step of the previous call
        brakes.delay_split(coach[DELAY], k0, frac)
        _eval_couplers(x, v, ke, kf, kec, kfc, model, u, gh, ws)
        iv[I_WS_VALID] = 1
    for step in range(n_steps):
        # --- brake system to t + h
        if mode == brakes.PIPE_HEAD:
            iv[I_RING_POS] = brakes.delay_line_push(ring, iv[I_RING_POS], sc[S_HEAD_IN])
            brakes.delay_line_read(ring, iv[I_RING_POS], k0, frac, p_pipe)
        elif mode == brakes.PIPE_PER_COACH:
            p_pipe[:] = coach[PIPE_IN]
        if mode == brakes.CYLINDER_PER_COACH:
            p_cyl[:] = coach[CYL_IN]
        else:
            brakes.distributor_target(p_pipe, applied, sc[S_PNOM], sc[S_PFS], sc[S_SENS],
                                      p_max, target)
            brakes.cylinder_advance(p_cyl, target, h, p_max, tables)
        brakes.braking_force(p_cyl, p_max, sc[S_MU], masses, sc[S_G], fb_next)
        for i in range(n):
            fb[i] = 0.5 * (fb_avail[i] + fb_next[i])
            fb_avail[i] = fb_next[i]
            hold_set[i] = coach[HELD, i] > 0.5
            rel_dir[i] = 0.0
            v_start[i] = v[i]
        # --- mechanics: active-set iteration over the held coaches
        extra_work = 0.0
        for it in range(n + 2):
            if it > 0:   # the active set changed some starting velocities
                _eval_couplers(x, v_start, ke, kf, kec, kfc, model, u, gh, ws)
            for i in range(n):
                if v_start[i] > 0.0:
                    signed[i] = fb[i]
                elif v_start[i] < 0.0:
                    signed[i] = -fb[i]
                else:
                    signed[i] = rel_dir[i] * fb[i]
            _ros2_step(h, x, v_start, hold_set, signed, masses, ke, kf, kec, kfc, model, u,
                       ws, x_new, v_new, hold)
            changed = False
            stops = False
            for i in range(n):
                if hold_set[i]:
                    if abs(hold[i]) > fb[i] * (1.0 + 1e-12):
                        # the brake cannot hold it: it slides, braked against its motion
                        hold_set[i] = False
                        rel_dir[i] = 1.0 if hold[i] > 0.0 else -1.0
                        v_start[i] = 0.0
                        changed = True
                elif rel_dir[i] == 0.0 and _stops(v_start[i], v_new[i], fb[i]):
                    stops = True
            if stops and not changed:
                for i in range(n):
                    if (not hold_set[i]) and rel_dir[i] == 0.0 and _stops(v_start[i], v_new[i],
                                                                          fb[i]):
                        # stops within the step: the brake holds it from the step's start
                        hold_set[i] = True
                        extra_work += 0.5 * masses[i] * v_start[i] * v_start[i]
                        v_start[i] = 0.0
                        changed = True
            if not changed:
                break
        # --- health, then accept
        bad = OK
        for i in range(n):
            if not (np.isfinite(x_new[i]) and np.isfinite(v_new[i])):
                bad = NON_FINITE
                break
            if i < m and abs(x_new[i] - x_new[i + 1]) > sc[S_YLIM]:
                bad = OUT_OF_RANGE
        if bad != OK:
            return step, bad
        wb = extra_work
        for i in range(n):
            b = hold[i] if hold_set[i] else signed[i]
            wb += b * (x_new[i] - x[i])
            fb_applied[i] = abs(b)
            x_old[i] = x[i]
            x[i] = x_new[i]
            v[i] = v_new[i]
            coach[HELD, i] = 1.0 if hold_set[i] else 0.0
        # couplers at the new state: the work over the step, and the next step's start
        wc = _eval_couplers_work(x, v, x_old, ke, kf, kec, kfc, model, u, gh, ws)
        sc[S_WB] += wb
        sc[S_WC] += wc
    return n_steps, OK


# ----------------------------------------------------------------------------- reference
def reference_solution(masses, ke, kf, kec, kfc, u, v0, brake_of_t, t_end, *,
                       t_eval=None, rtol=1e-9, atol=1e-11, method='Radau', x0=None):
    """Tight-tolerance solution of eqs. (5)-(7) with the tanh law (eqs. 14-16).

    ``brake_of_t(t) -> (N,)`` braking forces [N] (positive retarding), valid while every
    coach moves forward (the reference does not model the brake holding a coach at rest).
    Uses scipy ``solve_ivp`` with the analytical sparse Jacobian of the chain (state
    [x, v]). Returns the ``OdeResult`` (``.t``, ``.y`` with x = y[:N], v = y[N:]).
    """
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
        return np.concatenate([v, (_net_coupler(F) - brake_of_t(t)) * inv_m])

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
