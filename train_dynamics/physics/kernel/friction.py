"""
Friction brakes, compiled: a friction law's coefficient and the retarding force.

The models, their sources and the two routes to a vehicle's force level (the EN 14531-1 force
chain, the UIC 544-1 braked mass) are described in :mod:`train_dynamics.physics.friction`;
the materials (shipped and user-defined) in :mod:`train_dynamics.physics.friction_laws`;
this module holds what the kernel evaluates every brake tick.

A vehicle of a material other than ``paper`` brakes with

    F_r = mu(v, N / n_blocks) N rho,   N = max(p K1 - K0, 0)

p its cylinder pressure [Pa, gauge], K1 [N/Pa] and K0 [N] its force chain reduced to a line
(chain: K1 = n_cyl A eta_c i eta_r, K0 = n_cyl F_spring i eta_r; braked mass: K1 = N_full /
p_max, K0 = 0), rho the radius ratio (1 tread, r_eff / r_wheel disc) and v the vehicle's
speed [m/s]. Paper vehicles keep eq. (13) (:func:`~.brakes.braking_force`).

A friction law is a vector of :data:`LAW_LEN` numbers (one column of the vehicle rows
``LAW0 ..``, layout.py), its first the kind:

- :data:`COEFF_LAW`, Karwatzki-type coefficients a, b, c, d, e (slots 1-5):
  mu = a (F + b) / (F + c) * (v + d) / (v + e), F the block or pad force [N], v [m/s];
- :data:`TABLE_LAW`, a table of mu over speed and block force: slot 1 the number of speeds
  nv <= :data:`MAX_SPEEDS`, slot 2 the number of forces nf <= :data:`MAX_FORCES`, then the
  speeds [m/s] (:data:`MAX_SPEEDS` slots, ascending), the forces [N] (:data:`MAX_FORCES`
  slots, ascending) and mu (speed-major: mu[i, j] at slot MU0 + i MAX_FORCES + j); bilinear
  between the knots, clamped at both ends of each axis;
- :data:`PAPER_LAW` (0): eq. (13), no law.
"""
from __future__ import annotations

from train_dynamics.physics.kernel.compiler import jit

#: the kinds of a friction law (slot 0)
PAPER_LAW, COEFF_LAW, TABLE_LAW = 0, 1, 2
#: the largest table of mu: speeds and block forces
MAX_SPEEDS = 12
MAX_FORCES = 4
#: slots of a table law: the speeds, the forces, mu
V0 = 3
F0 = V0 + MAX_SPEEDS
MU0 = F0 + MAX_FORCES
#: slots of one friction law (rows LAW0 .. of the vehicle constants)
LAW_LEN = MU0 + MAX_SPEEDS * MAX_FORCES


@jit(inline=True)
def _locate(law, start: int, n: int, x: float):
    """Return (k, w): x between knots k and k + 1 of ``law[start:start + n]`` at fraction w."""
    if n < 2 or x <= law[start]:
        return 0, 0.0
    if x >= law[start + n - 1]:
        return n - 2, 1.0
    k = 0
    while law[start + k + 1] < x:
        k += 1
    return k, (x - law[start + k]) / (law[start + k + 1] - law[start + k])


@jit(inline=True)
def law_friction(law, v: float, block_force: float) -> float:
    """
    Return the friction coefficient [-] of the law ``law`` (module docstring) at v [m/s].

    ``block_force`` [N] the force of one block or pad; the speed enters as |v|.
    """
    s = abs(v)
    f = max(block_force, 0.0)
    if law[0] == COEFF_LAW:
        return law[1] * (f + law[2]) / (f + law[3]) * (s + law[4]) / (s + law[5])
    nv = int(law[1])
    nf = int(law[2])
    i, wv = _locate(law, V0, nv, s)
    j, wf = _locate(law, F0, nf, f)
    row = MU0 + i * MAX_FORCES + j
    lo = law[row]
    hi = law[row + MAX_FORCES] if nv > 1 else lo
    if nf > 1:
        lo += wf * (law[row + 1] - lo)
        if nv > 1:
            hi += wf * (law[row + MAX_FORCES + 1] - hi)
        else:
            hi = lo
    return lo + wv * (hi - lo)


@jit(inline=True)
def friction_braking_force(coach_material, laws, p_cyl, v, gain, offset, blocks, rho, out):
    """
    Overwrite ``out`` [N] for each vehicle of a material other than paper (module docstring).

    Arrays per vehicle: material codes (0 paper), friction laws (LAW_LEN, N), cylinder
    pressure [Pa], speed [m/s], K1 [N/Pa], K0 [N], number of blocks or pads, radius ratio.
    """
    for i in range(out.shape[0]):
        if int(coach_material[i]) == 0:
            continue
        normal = max(p_cyl[i] * gain[i] - offset[i], 0.0)
        if normal == 0.0:
            out[i] = 0.0
            continue
        out[i] = law_friction(laws[:, i], v[i], normal / blocks[i]) * normal * rho[i]
