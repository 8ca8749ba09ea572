"""
Independent reference of the coach chain: scipy Radau, events at the coupler law's kinks.

Written apart from the compiled kernel (no kernel code is called): the coupler law with free
play and blocking is evaluated here in numpy from its equations (paper eqs. 2-3 / 15-16,
tanh friction eq. 14, slack g_t, g_c, strokes S_t, S_c, blocked stiffness K_b [N/m]):

    y > g_t:    d = y - g_t, F = (k_ec + k_fc s) d + K_b max(d - S_t, 0)
    y < -g_c:   d = y + g_c, F = (k_e  - k_f  s) d + K_b min(d + S_c, 0)
    otherwise:  F = 0 (free play),                 s = tanh(u ydot),

and, for a coupling of preloaded or progressive ends, its tables instead of the linear springs
(elastic force E and friction amplitude R linear between knots, constant beyond the last:
F = E_t(d) + s R_t(d) in tension, F = -(E_c(a) - s R_c(a)) in compression, a = -(y + g_c);
evaluated here with numpy's interp from the knots), with its analytical Jacobian, and the
equations of motion m_i a_i = F_{i-1} - F_i - Fb_i + E_i
(eqs. 5-7; E_i a constant external force [N], e.g. gravity on a constant gradient). The
integration is restarted at every input instant (the braking forces are a staircase: zero-order
hold) and at every crossing of a breakpoint of the law
(:func:`train_dynamics.physics.couplers.law_breakpoints`), located as an event, so Radau never
steps across a kink or a jump. Every coach must keep moving forward (the reference does not
model the brake holding a coach at rest). Tests and benchmarks measure the simulator against
it; it is plain Python on scipy and slow (seconds for a few coaches over seconds).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from train_dynamics.physics.couplers import law_breakpoints, table_knots, table_side
from train_dynamics.physics.kernel.layout import COUPLER, TABLE_ROWS


@dataclass(frozen=True)
class ChainLaw:
    """Per-coupler constants (arrays of N-1): stiffness and friction [N/m], travel [m]."""

    ke: np.ndarray
    kf: np.ndarray
    kec: np.ndarray
    kfc: np.ndarray
    gt: np.ndarray
    gc: np.ndarray
    st: np.ndarray
    sc: np.ndarray
    kb: np.ndarray
    u: float
    tables: np.ndarray | None = None     # (len(TABLE_ROWS), N-1) or None: no tabled coupling

    @classmethod
    def of_simulator(cls, sim) -> ChainLaw:
        """Return the law of the couplers of a built ``TrainSimulator`` (its constants only)."""
        return cls(sim.ke.copy(), sim.kf.copy(), sim.kec.copy(), sim.kfc.copy(),
                   sim.draw_gear_slack, sim.buffer_slack, sim.draw_gear_stroke,
                   sim.buffer_stroke, sim.cpl[COUPLER.KB].copy(), float(sim.u),
                   sim.cpl[TABLE_ROWS].copy())

    def force(self, y: np.ndarray, ydot: np.ndarray) -> np.ndarray:
        """Return F [N] (tension > 0) of every coupler at y [m], ydot [m/s]."""
        return self._law(y, ydot)[0]

    def _side(self, j, side, a):
        """Return (E, R, dE/da, dR/da) of coupler j's table on one side at a >= 0 [m]."""
        rows = self.tables[:, j]
        e, r = table_side(rows, side)
        grid = table_knots(rows, side)
        if grid[1] == 0.0:           # no preload ramp: knot 0 is knot 1
            grid, e, r = grid[1:], e[1:], r[1:]
        seg = np.clip(np.searchsorted(grid, a, side='right') - 1, 0, grid.size - 2)
        inside = a < grid[-1]
        width = np.diff(grid)[seg]
        de = np.where(inside, np.diff(e)[seg] / width, 0.0)
        dr = np.where(inside, np.diff(r)[seg] / width, 0.0)
        return np.interp(a, grid, e), np.interp(a, grid, r), de, dr

    def _tabled(self, j, y, s, ds):
        """Return (F, dF/dy, dF/dydot) of tabled coupler j at y (any shape), s, ds/dydot."""
        gt, gc, st, sc, kb = self.gt[j], self.gc[j], self.st[j], self.sc[j], self.kb[j]
        dt = np.maximum(y - gt, 0.0)
        dc = np.maximum(-(y + gc), 0.0)
        et, rt, det, drt = self._side(j, 0, dt)
        ec, rc, dec, drc = self._side(j, 1, dc)
        draw = y > gt
        buff = y < -gc
        f_t = et + s * rt + kb * np.maximum(dt - st, 0.0)
        k_t = det + s * drt + np.where(dt > st, kb, 0.0)
        f_c = s * rc - ec - kb * np.maximum(dc - sc, 0.0)
        k_c = dec - s * drc + np.where(dc > sc, kb, 0.0)
        tight = (gt == 0.0) & (gc == 0.0)
        f = np.where(draw, f_t, np.where(buff, f_c, 0.0))
        slope = np.where(draw, k_t, np.where(buff, k_c, 0.5 * (k_t + k_c) if tight else 0.0))
        dfdv = np.where(draw, rt * ds, np.where(buff, rc * ds, 0.0))
        return f, slope, dfdv

    def _law(self, y, ydot):
        """Return (F, dF/dy, dF/dydot) of every coupler."""
        f, slope, dfdv = self._linear(y, ydot)
        if self.tables is None or not np.any(self.tables[0]):
            return f, slope, dfdv
        s = np.tanh(self.u * ydot)
        ds = self.u * (1.0 - s * s)
        for j in np.flatnonzero(self.tables[0] != 0.0):
            f[..., j], slope[..., j], dfdv[..., j] = self._tabled(
                j, y[..., j], s[..., j], ds[..., j])
        return f, slope, dfdv

    def _linear(self, y, ydot):
        """Return (F, dF/dy, dF/dydot) of every coupler with linear springs."""
        s = np.tanh(self.u * ydot)
        ds = self.u * (1.0 - s * s)
        draw = y > self.gt
        buff = y < -self.gc
        tight = (self.gt == 0.0) & (self.gc == 0.0) & (y == 0.0)
        d = np.where(draw, y - self.gt, np.where(buff, y + self.gc, 0.0))
        k = np.where(draw, self.kec, self.ke)
        kfr = np.where(draw, self.kfc, -self.kf)
        stiff = k + kfr * s
        f = stiff * d
        over = draw & (d > self.st)
        under = buff & (d < -self.sc)
        f = f + np.where(over, self.kb * (d - self.st), 0.0) \
            + np.where(under, self.kb * (d + self.sc), 0.0)
        slope = stiff + np.where(over | under, self.kb, 0.0)
        engaged = draw | buff
        slope = np.where(engaged, slope, np.where(
            tight, 0.5 * (self.ke - self.kf * s) + 0.5 * (self.kec + self.kfc * s), 0.0))
        dfdv = np.where(engaged, kfr * d * ds, 0.0)
        return np.where(engaged, f, 0.0), slope, dfdv


@dataclass
class ChainSolution:
    """Samples of the reference: t [s] (K), x, v (K, N) [m, m/s], y, F (K, N-1) [m, N]."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    y: np.ndarray
    F: np.ndarray
    segments: int       # solver restarts (inputs and kinks)


def solve_chain(inertia, law: ChainLaw, v0, brake_steps, t_eval, *, external=None,
                brake_of_t=None, rtol: float = 1e-9, atol: float = 1e-12) -> ChainSolution:
    """
    Integrate the chain from rest deformation (x = 0, v = v0) to t_eval[-1] [s].

    ``inertia`` (N,) [kg]; ``brake_steps``: (times (K,) [s] ascending, forces (K, N) [N]):
    from times[k] on, the braking forces are forces[k] (positive retarding; zero before
    times[0]); ``brake_of_t(t) -> (N,)`` [N] an optional continuous braking force added to
    them (give its kinks as further ``times``, with the same forces); ``external`` (N,) [N] a
    constant force, forward > 0. Returns the samples at ``t_eval`` (ascending, > 0).
    """
    from scipy.integrate import solve_ivp     # tests and benchmarks only

    m = np.asarray(inertia, float)
    n = m.shape[0]
    ext = np.zeros(n) if external is None else np.asarray(external, float)
    times, forces = (np.asarray(a, float) for a in brake_steps)
    t_eval = np.asarray(t_eval, float)
    t_end = float(t_eval[-1])
    bps = [np.unique(b) for b in law_breakpoints(law.gt, law.gc, law.st, law.sc,
                                                 law.tables).T]
    all_ = np.arange(n)

    def rhs_of(fb):
        def rhs(t, z):
            x, v = z[:n], z[n:]
            F = law.force(x[:-1] - x[1:], v[:-1] - v[1:])
            net = np.zeros(n)
            net[1:] += F
            net[:-1] -= F
            brake = fb if brake_of_t is None else fb + brake_of_t(t)
            return np.concatenate([v, (net - brake + ext) / m])
        return rhs

    def jac(t, z):
        x, v = z[:n], z[n:]
        _, dfdy, dfdv = law._law(x[:-1] - x[1:], v[:-1] - v[1:])
        J = np.zeros((2 * n, 2 * n))
        J[all_, n + all_] = 1.0
        for blk, dd in ((0, dfdy), (n, dfdv)):
            # coupler j pulls coach j+1 forward and coach j back: dF_j/dy_j with y = x_j - x_j+1
            for j in range(n - 1):
                a, b = j, j + 1
                J[n + a, blk + a] -= dd[j] / m[a]
                J[n + a, blk + b] += dd[j] / m[a]
                J[n + b, blk + a] += dd[j] / m[b]
                J[n + b, blk + b] -= dd[j] / m[b]
        return J

    def events_for(z):
        y0 = z[:n - 1] - z[1:n]
        evs = []
        for j in range(n - 1):
            live = bps[j][np.abs(y0[j] - bps[j]) > 1e-12]
            if live.size == 0:
                continue

            def ev(t, zz, j=j, live=live):
                return float(np.prod((zz[j] - zz[j + 1]) - live))
            ev.terminal = True
            evs.append(ev)
        return evs

    z = np.concatenate([np.zeros(n), np.broadcast_to(np.asarray(v0, float), (n,))])
    t = 0.0
    out = np.empty((t_eval.size, 2 * n))
    filled = 0
    segments = 0
    cuts = list(times[times > 0.0]) + [np.inf]
    k_in = int(np.searchsorted(times, 0.0, side='right')) - 1
    while t < t_end:
        fb = forces[k_in] if k_in >= 0 else np.zeros(n)
        t_stop = min(t_end, cuts[0])
        sol = solve_ivp(rhs_of(fb), (t, t_stop), z, method='Radau', jac=jac,
                        events=events_for(z), dense_output=True, rtol=rtol, atol=atol)
        if sol.status < 0:
            raise RuntimeError(sol.message)
        segments += 1
        t_new = float(sol.t[-1])
        last = filled
        while filled < t_eval.size and t_eval[filled] <= t_new:
            filled += 1
        if filled > last:
            out[last:filled] = sol.sol(t_eval[last:filled]).T
        z = sol.y[:, -1].copy()
        t = t_new
        if sol.status == 0 and t_stop == cuts[0]:      # an input instant: the next stair
            cuts.pop(0)
            k_in += 1
    x, v = out[:, :n], out[:, n:]
    y = x[:, :-1] - x[:, 1:]
    F = law.force(y, v[:, :-1] - v[:, 1:])
    return ChainSolution(t_eval, x, v, y, F, segments)
