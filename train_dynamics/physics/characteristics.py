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

Two more ways to give an end (:func:`coupling_table` takes both):

- a tabulated curve (:func:`check_curve`): force over stroke for loading and for unloading,
  as a buffer's or draw gear's test diagram gives it; linear between the points;
- the screw coupling's pretension P_0 (``coupling_pretension``): tightened at rest until
  buffers and draw gear carry the elastic force P_0, both then act in parallel, F(y) =
  T(d_t0 + y) - C(d_c0 - y), each device's part 0 once it is unloaded
  (:func:`pretension_table`).
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
    """
    Return True when one end's ``device`` (buffer, draw_gear) needs the coupling's tables.

    A preload, a final force, a tabulated curve, or the screw coupling's pretension.
    """
    return (end[f'{device}_preload'] > 0.0 or end[f'{device}_final_force'] > 0.0
            or end.get(f'{device}_characteristic', 0.0) > 0.0
            or end.get('coupling_pretension', 0.0) > 0.0)


def check_curve(curve, kb: float = 1.0e8):
    """
    Return a tabulated force-stroke curve as arrays (d [m], L [N], U [N]); ValueError if bad.

    ``curve``: a mapping ``stroke`` [m] (from 0, increasing), ``loading`` and ``unloading``
    [N] (increasing after the first point, 0 <= unloading <= loading), as many points each.
    A force at stroke 0 is a preload: the end stays rigid up to it (a ramp of the blocked
    stiffness K_b [N/m] over L_0 / K_b, as :func:`end_loading`), the unloading branch in
    the same proportion over the ramp. Linear between the points.
    """
    if not isinstance(curve, dict) or set(curve) != {'stroke', 'loading', 'unloading'}:
        raise ValueError('a curve is a mapping of stroke [m], loading [N] and unloading [N]')
    try:
        d, load, unload = (np.asarray(curve[k], dtype=float)
                           for k in ('stroke', 'loading', 'unloading'))
    except (TypeError, ValueError):
        raise ValueError('stroke, loading and unloading must be lists of numbers') from None
    if d.ndim != 1 or d.size < 2 or load.shape != d.shape or unload.shape != d.shape:
        raise ValueError('stroke, loading and unloading need as many values each, >= 2')
    if not np.all(np.isfinite(np.concatenate((d, load, unload)))):
        raise ValueError('values must be finite')
    if d[0] != 0.0 or np.any(np.diff(d) <= 0.0):
        raise ValueError('stroke must start at 0 and increase')
    if np.any(np.diff(load) <= 0.0) or np.any(np.diff(unload) <= 0.0):
        raise ValueError('loading and unloading forces must increase with the stroke')
    if np.any(unload < 0.0) or np.any(unload > load):
        raise ValueError('0 <= unloading <= loading at every stroke')
    if load[0] > 0.0:
        dp = load[0] / kb
        if dp >= d[1]:
            raise ValueError(f'force {load[0]:g} N at stroke 0 over the blocked stiffness '
                             f'{kb:g} N/m reaches past the second point')
        d = np.concatenate(([0.0, dp], d[1:]))
        load = np.concatenate(([0.0], load))
        unload = np.concatenate(([0.0], unload))
    return d, load, unload


def _end_curves(end: dict, device: str, curves=()):
    """
    Return (d [m], L [N], U [N]) of one end's device, dense, increasing.

    ``curves``: the consist's tabulated curves ((d, L, U) of :func:`check_curve` and the
    preload [N]); the end's ``{device}_characteristic`` is 1 + its index there (0: none, the
    datasheet figures).
    """
    code = int(end.get(f'{device}_characteristic', 0.0))
    if code > 0:
        d, load, unload = curves[code - 1][:3]
        dense = np.unique(np.concatenate((d, np.linspace(0.0, d[-1], _DENSE))))
        return dense, np.interp(dense, d, load), np.interp(dense, d, unload)
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


def _end_preload(end: dict, device: str, curves=()) -> float:
    """Return one end's preload [N]: its curve's force at stroke 0, else its ``*_preload``."""
    code = int(end.get(f'{device}_characteristic', 0.0))
    if code > 0:
        return float(curves[code - 1][3])
    return end[f'{device}_preload']


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


def coupling_table(rear: dict, front: dict, knots: int, curves=()) -> np.ndarray:
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
    ``curves``: the tabulated curves an end may name (:func:`_end_curves`). A pretensioned
    coupling (the larger ``coupling_pretension`` of its ends > 0) is
    :func:`pretension_table`.
    """
    head = []
    body = []
    series = {}
    for device in ('draw_gear', 'buffer'):
        ends = [_end_curves(e, device, curves) for e in (rear, front)]
        d_l, f_l = series_curve([(d, lo) for d, lo, _ in ends])
        d_u, f_u = series_curve([(d, up) for d, _, up in ends])
        series[device] = (d_l, f_l, d_u, f_u, float(ends[0][0][-1] + ends[1][0][-1]))
    pretension = max(rear.get('coupling_pretension', 0.0), front.get('coupling_pretension', 0.0))
    if pretension > 0.0:
        return pretension_table(series, pretension, knots)
    for device in ('draw_gear', 'buffer'):
        d_l, f_l, d_u, f_u, _ = series[device]
        preloads = [p for p in (_end_preload(e, device, curves) for e in (rear, front)) if p > 0]
        d1 = float(np.interp(min(preloads), f_l, d_l)) if preloads else 0.0
        stroke = rear[f'{device}_stroke'] + front[f'{device}_stroke']
        grid = np.concatenate(([0.0], np.linspace(d1, stroke, knots - 1)))
        load = np.interp(grid, d_l, f_l)
        unload = np.interp(grid, d_u, f_u)
        head += [d1, (knots - 2) / (stroke - d1)]
        body += [0.5 * (load + unload), 0.5 * (load - unload)]
    return np.concatenate(([1.0], head, *body))


def table_span(rows: np.ndarray, side: int) -> float:
    """Return the deflection [m] of a coupling table's last knot (side 0 draw gear, 1 buffers)."""
    return float(rows[1 + 2 * side] + (len(rows[5:]) // 4 - 2) / rows[2 + 2 * side])


def pretension_table(series: dict, pretension: float, knots: int) -> np.ndarray:
    """
    Return the table rows of a coupling whose screw coupling holds ``pretension`` P_0 [N].

    ``series``: per device (draw_gear, buffer) the coupling's loading and unloading branches
    (d_l, L, d_u, U, stroke), both ends in series (:func:`coupling_table`). Each device's
    elastic force is E = (L + U) / 2, its friction amplitude R = (L - U) / 2 (eqs. 2-3 as
    :func:`coupling_table` splits them). At rest the draw gear is stretched by d_t0 and the
    buffers compressed by d_c0, E_T(d_t0) = E_C(d_c0) = P_0: no net force. Moving by y, the
    draw gear is at d_t0 + y, the buffers at d_c0 - y, each carrying force only while it is
    loaded (argument > 0), in parallel:

        y = d > 0:  E(d) = E_T(d_t0 + d) - E_C(d_c0 - d),  R(d) = R_T(d_t0 + d) + R_C(d_c0 - d)
        y = -a < 0: E(a) = E_C(d_c0 + a) - E_T(d_t0 - a),  R(a) = R_C(d_c0 + a) + R_T(d_t0 - a)

    (the friction of both devices opposes the motion). Each side is tabled from d = 0 (knot 1,
    no preload ramp: d_1 = 0; R(0) = R_T(d_t0) + R_C(d_c0) is the friction at rest) to its
    remaining travel S_T - d_t0 (S_C - d_c0), where the device blocks: the coupling's strokes
    are these spans (:func:`table_span`). The kink where the other device unloads (d = d_c0,
    a = d_t0) lies between knots: the force there is the linear interpolation of the knots.
    At y = 0.0 exactly the kernel's tight-coupling branch gives F = 0 where both sides tend
    to s R(0): a state is there only at rest at t = 0 (s = 0), so the law is the same.
    Raises ValueError when P_0 is more than a device carries at its stroke.
    """
    parts = {}
    for device, (d_l, f_l, d_u, f_u, stroke) in series.items():
        grid = np.linspace(0.0, stroke, _DENSE)
        load = np.interp(grid, d_l, f_l)
        unload = np.interp(grid, d_u, f_u)
        e = 0.5 * (load + unload)
        if not pretension < e[-1]:
            raise ValueError(f'coupling_pretension {pretension:g} N is more than the '
                             f'{device.replace("_", " ")} carries at its stroke '
                             f'({e[-1]:.4g} N)')
        rest = float(np.interp(pretension, e, grid))
        parts[device] = (grid, e, 0.5 * (load - unload), rest, stroke)
    head = []
    body = []
    for own, other in (('draw_gear', 'buffer'), ('buffer', 'draw_gear')):
        g_o, e_o, r_o, rest_o, stroke_o = parts[own]
        g_x, e_x, r_x, rest_x, _ = parts[other]
        span = stroke_o - rest_o
        d = np.linspace(0.0, span, knots - 1)
        back = np.maximum(rest_x - d, 0.0)
        e = np.interp(rest_o + d, g_o, e_o) - np.interp(back, g_x, e_x)
        r = np.interp(rest_o + d, g_o, r_o) + np.interp(back, g_x, r_x)
        e[0] = 0.0               # E_T(d_t0) - E_C(d_c0) = P_0 - P_0
        head += [0.0, (knots - 2) / span]
        body += [np.concatenate(([e[0]], e)), np.concatenate(([r[0]], r))]
    return np.concatenate(([1.0], head, *body))
