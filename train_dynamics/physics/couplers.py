"""
Coupler force laws on the Python side: one coupler's law, energies, deflection bounds.

The law of a single coupler for plots and tests, the energy stored with free play and
blocking, the deflection a force allows, and one vehicle end's quasi-static deflection and
absorbed energy (a coupling is two ends in series, :mod:`~train_dynamics.physics.config.consist`).

The law itself (paper eqs. 1-4, 14-16, sign conventions and the free play and blocking of a
real coupler) is compiled: :mod:`train_dynamics.physics.kernel.couplers`.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.couplers import coupler_force, MODEL_CODES
from train_dynamics.physics.kernel.layout import TABLE_KNOTS


def force_law(y, ydot, *, ke=2.8e6, kf=1.4e6, kec=5.46e6, kfc=2.43e6, model='tanh', u=1000.0):
    """Return F [N] for scalars or arrays of y [m], ydot [m/s]; paper constants by default."""
    y = np.atleast_1d(np.asarray(y, dtype=float))
    ydot = np.broadcast_to(np.asarray(ydot, dtype=float), y.shape).copy()
    full = [np.broadcast_to(np.asarray(k, dtype=float), y.shape).copy()
            for k in (ke, kf, kec, kfc)]
    return coupler_force(y, ydot, *full, MODEL_CODES[model], float(u))


def elastic_energy_travel(y, ke, kec, gt, gc, st, sc, kb) -> np.ndarray:
    """
    Return the energy stored in each coupler [J] with free play and blocking.

    k d^2 / 2 on the spring's deflection d beyond the slack, plus K_b (|d| - S)^2 / 2 beyond
    the stroke; 0 in free play (arrays of N-1, or scalars).
    """
    y = np.asarray(y, dtype=float)
    dt = np.maximum(y - gt, 0.0)
    dc = np.maximum(-y - gc, 0.0)
    return (0.5 * kec * dt * dt + 0.5 * kb * np.maximum(dt - st, 0.0) ** 2
            + 0.5 * ke * dc * dc + 0.5 * kb * np.maximum(dc - sc, 0.0) ** 2)


def law_breakpoints(gt, gc, st, sc, tables=None) -> np.ndarray:
    """
    Return the displacements y [m] where the coupler law changes branch: (B, N-1) or (B,).

    The ends of the free play -g_c and g_t (the kink at y = 0 of a tight coupling) and the
    strokes' ends, where blocking starts, -(g_c + S_c) and g_t + S_t (the law of
    :func:`train_dynamics.physics.kernel.couplers.coupler_branch_travel`). Across each the
    slope of F(y) jumps: an integrator of order > 1 must not step over one. ``tables``: the
    couplers' table rows (``layout.TABLE_ROWS``, (len, N-1)): a tabled coupling's knots
    (:func:`table_knots`, beyond the free play on either side) are breakpoints too (B = 4 +
    2 (K - 1); an untabled coupler repeats g_t there).
    """
    gt, gc, st, sc = (np.asarray(a, dtype=float) for a in (gt, gc, st, sc))
    base = np.array(np.broadcast_arrays(-(gc + sc), -gc, gt, gt + st))
    if tables is None:
        return base
    tables = np.asarray(tables, dtype=float)
    extra = np.broadcast_to(gt, (2 * (TABLE_KNOTS - 1),) + gt.shape).copy()
    for j in np.flatnonzero(tables[0] != 0.0):
        extra[:TABLE_KNOTS - 1, j] = gt[j] + table_knots(tables[:, j], 0)[1:]
        extra[TABLE_KNOTS - 1:, j] = -(gc[j] + table_knots(tables[:, j], 1)[1:])
    return np.concatenate((base, extra))


def table_knots(rows: np.ndarray, side: int) -> np.ndarray:
    """
    Return the knots d_k [m] of one side of a coupling table (side 0 draw gear, 1 buffers).

    d_0 = 0, d_1 (end of the preload ramp), then equal spacing 1 / ``ih`` (rows of
    ``layout.COUPLER``, TAB onwards: TAB, T_D1, T_IH, C_D1, C_IH, ...).
    """
    d1, ih = rows[1 + 2 * side], rows[2 + 2 * side]
    return np.concatenate(([0.0], d1 + np.arange(TABLE_KNOTS - 1) / ih))


def deflection_bounds(force, gt, gc, st, sc, kb):
    """
    Return (lowest, highest) y [m] a coupler carrying ``force`` [N] can have.

    -(g_c + S_c + |F| / K_b) <= y <= g_t + S_t + |F| / K_b: beyond slack and stroke only
    the blocked stiffness gives (the springs' own force has the sign of F).
    """
    extra = np.abs(np.asarray(force, dtype=float)) / kb
    return -(gc + sc + extra), gt + st + extra


def end_deflection(force, k, k_friction, slack, stroke, kb):
    """
    Return one vehicle end's deflection [m] (> 0) under a quasi-static load ``force`` [N] (> 0).

    On the loading branch of the paper's law (eqs. 2-3, friction opposing the motion): the free
    play g, then F / (k + k_friction) up to the stroke S, then the blocked stiffness K_b:
    g + min(F / (k + k_fr), S) + max(F - (k + k_fr) S, 0) / K_b. The ends of a coupling carry
    the same force, so its deflection is the sum of its ends' (``config.consist``'s series rule).
    """
    force = np.asarray(force, dtype=float)
    k_load = k + k_friction
    return (slack + np.minimum(force / k_load, stroke)
            + np.maximum(force - k_load * stroke, 0.0) / kb)


def end_energy_to_blocking(k, k_friction, stroke):
    """Return the energy [J] one end absorbs loaded to blocking: (k + k_fr) S^2 / 2."""
    return 0.5 * (k + k_friction) * stroke * stroke


# ---------------------------------------------------------------- preload and progressive ends
#: points of the dense curves the series rule inverts (the tables are sampled from them)
_DENSE = 4001


def end_loading(d, *, k, k_friction, stroke, preload=0.0, final_force=0.0, energy=0.0,
                kb=1.0e8):
    """
    Return one vehicle end's loading branch L(d) [N] at deflections 0 <= d <= S [m].

    The datasheet characteristic of a buffer or draw gear (EN 15551 gives buffers so): the
    preload P [N] holds the end rigid up to P (a ramp of the blocked stiffness K_b [N/m]
    over d_p = P / K_b: the structure deflects, the spring does not), then the spring:

    - no final force: L = P + (k + k_fr)(d - d_p), the paper's loading branch (eqs. 2-3)
      shifted by the preload;
    - final force F_f [N] (at the stroke S): L = P + (F_f - P) x^q, x = (d - d_p) / (S - d_p),
      with q = 1 (linear) when ``energy`` is 0, else the q for which the loading branch
      absorbs ``energy`` W [J] up to the stroke: W = P d_p / 2 + (S - d_p) (P + (F_f - P)
      / (q + 1)), q > 1 progressive (elastomer springs), q < 1 degressive (hydraulic).

    Raises ValueError when the figures cannot make such a curve.
    """
    d = np.asarray(d, dtype=float)
    dp = preload / kb
    if dp >= stroke:
        raise ValueError(f'preload {preload:g} N over the blocked stiffness {kb:g} N/m is '
                         f'more than the stroke {stroke:g} m')
    z = np.maximum(d - dp, 0.0)
    ramp = kb * np.minimum(d, dp)
    if final_force <= 0.0:
        if energy > 0.0:
            raise ValueError('energy needs final_force (the force at the end of the stroke)')
        return ramp + (k + k_friction) * z
    if final_force <= preload:
        raise ValueError(f'final_force {final_force:g} N must be above the preload '
                         f'{preload:g} N')
    travel = stroke - dp
    q = 1.0
    if energy > 0.0:
        w = (energy - 0.5 * preload * dp - preload * travel) / ((final_force - preload) * travel)
        if not 0.02 < w < 0.98:
            lo = 0.5 * preload * dp + travel * (preload + 0.02 * (final_force - preload))
            hi = 0.5 * preload * dp + travel * (preload + 0.98 * (final_force - preload))
            raise ValueError(f'energy {energy:g} J: a curve from the preload {preload:g} N to '
                             f'the final force {final_force:g} N over {stroke:g} m absorbs '
                             f'between {lo:.4g} and {hi:.4g} J')
        q = 1.0 / w - 1.0
    return ramp + np.where(d > dp, (final_force - preload) * (z / travel) ** q, 0.0)


def unloading_ratio(k, k_friction) -> float:
    """
    Return U / L, the end's unloading over its loading force at every deflection [-].

    (k - k_fr) / (k + k_fr) as in the paper's law (eqs. 2-3): the friction of a ring-spring
    buffer or friction draw gear is proportional to the spring force, preload included.
    """
    return (k - k_friction) / (k + k_friction)


def has_characteristic(end: dict, device: str) -> bool:
    """Return True when one end's ``device`` (buffer, draw_gear) has a preload or final force."""
    return end[f'{device}_preload'] > 0.0 or end[f'{device}_final_force'] > 0.0


def _end_curves(end: dict, device: str):
    """Return (d [m], L [N], U [N]) of one end's device, dense, increasing."""
    stroke = end[f'{device}_stroke']
    kb = end['blocked_stiffness']
    dp = end[f'{device}_preload'] / kb
    d = np.unique(np.concatenate((np.linspace(0.0, dp, 9), np.linspace(dp, stroke, _DENSE))))
    k, kfr = end[f'{device}_stiffness'], end[f'{device}_friction']
    load = end_loading(d, k=k, k_friction=kfr, stroke=stroke,
                       preload=end[f'{device}_preload'],
                       final_force=end[f'{device}_final_force'],
                       energy=end[f'{device}_energy'], kb=kb)
    return d, load, unloading_ratio(k, kfr) * load


def series_curve(branches):
    """
    Return (d [m], F [N]) of ends in series: equal force through both ends, strokes add.

    ``branches``: one (d, F) per end, each increasing up to its stroke. At a force F each end
    deflects d_i(F) (its branch inverted); an end whose branch ends below F is at its stroke
    (it blocks: its blocked stiffness, far above the springs, is taken as rigid there until
    the other end reaches its stroke too); the coupling deflects sum_i d_i(F), up to the sum
    of the strokes at the largest final force.
    """
    top = max(float(f[-1]) for _, f in branches)
    forces = np.unique(np.concatenate([np.linspace(0.0, top, _DENSE)]
                                      + [f for _, f in branches]))
    total = np.zeros_like(forces)
    for d, f in branches:
        total += np.interp(forces, f, d, right=float(d[-1]))
    return total, forces


def coupling_table(rear: dict, front: dict, knots: int) -> np.ndarray:
    """
    Return the table rows of the coupling of two ends (``layout.COUPLER`` TAB onwards).

    ``rear``, ``front``: one end's fields each (stiffness, friction, stroke, preload, final
    force, energy of buffer and draw gear, blocked stiffness). For each device the loading
    branch of the coupling is the series of the ends' loading branches and the unloading
    branch the series of their unloading ones (:func:`series_curve`: both ends load or unload
    together under the one force). Each is sampled at ``knots`` deflections: 0, d_1 (where the
    coupling leaves its preload ramp: the smaller nonzero preload), then equally spaced up to
    the sum of the strokes; E = (L + U) / 2, R = (L - U) / 2. Linear between knots, so a
    curve's energy is kept to the trapezoids' error (0.5 % for an x^3 curve at 16 knots).
    """
    head = []
    body = []
    for device in ('draw_gear', 'buffer'):
        ends = [_end_curves(e, device) for e in (rear, front)]
        d_l, f_l = series_curve([(d, lo) for d, lo, _ in ends])
        d_u, f_u = series_curve([(d, up) for d, _, up in ends])
        preloads = [e[f'{device}_preload'] for e in (rear, front) if e[f'{device}_preload'] > 0]
        d1 = float(np.interp(min(preloads), f_l, d_l)) if preloads else 0.0
        stroke = rear[f'{device}_stroke'] + front[f'{device}_stroke']
        grid = np.concatenate(([0.0], np.linspace(d1, stroke, knots - 1)))
        load = np.interp(grid, d_l, f_l)
        unload = np.interp(grid, d_u, f_u)
        head += [d1, (knots - 2) / (stroke - d1)]
        body += [0.5 * (load + unload), 0.5 * (load - unload)]
    return np.concatenate(([1.0], head, *body))


def table_energy(rows: np.ndarray, device: str) -> float:
    """Return the energy [J] a tabled coupling's loading branch absorbs to its stroke."""
    side = 0 if device == 'draw_gear' else 1
    k = TABLE_KNOTS
    e = rows[5 + 2 * side * k:5 + (2 * side + 1) * k]
    r = rows[5 + (2 * side + 1) * k:5 + (2 * side + 2) * k]
    grid = table_knots(rows, side)
    load = e + r
    return float(np.sum(0.5 * (load[1:] + load[:-1]) * np.diff(grid)))
