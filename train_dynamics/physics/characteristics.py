"""
Vehicle ends with a preload and a progressive (or degressive) characteristic, and their series.

A buffer or draw gear as its datasheet gives it (EN 15551 gives buffers so): stroke S, preload
P, final force F_f at the end of the stroke and the energy W absorbed on loading to it
(:func:`end_loading`); the unloading branch is the loading one times the end's (k - k_f) /
(k + k_f) (:func:`unloading_ratio`). A coupling is two ends in series (equal force through
both, strokes add: :func:`series_curve`), inverted numerically once, when the consist is
built, into one table per device (:func:`coupling_table`), which the kernel's coupler law
interpolates (:mod:`train_dynamics.physics.kernel.couplers`, ``coupler_branch_table``). Plain
numpy: imported by the configuration, never by the kernel.
"""
from __future__ import annotations

import numpy as np

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
