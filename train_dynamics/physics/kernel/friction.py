"""
Friction brakes, compiled: the material's friction coefficient and the retarding force.

The models, their sources and the two routes to a vehicle's force level (the EN 14531-1 force
chain, the UIC 544-1 braked mass) are described in :mod:`train_dynamics.physics.friction`;
this module holds what the kernel evaluates every brake tick.

A vehicle of a material other than ``paper`` brakes with

    F_r = mu_m(v, N / n_blocks) N rho,   N = max(p K1 - K0, 0)

p its cylinder pressure [Pa, gauge], K1 [N/Pa] and K0 [N] its force chain reduced to a line
(chain: K1 = n_cyl A eta_c i eta_r, K0 = n_cyl F_spring i eta_r; braked mass: K1 = N_full /
p_max, K0 = 0), rho the radius ratio (1 tread, r_eff / r_wheel disc) and v the vehicle's
speed [m/s]. Paper vehicles keep eq. (13) (:func:`~.brakes.braking_force`).
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.brakes import table_interp
from train_dynamics.physics.kernel.compiler import jit

#: friction materials, the choices of the parameter ``friction_material`` (config/table.py);
#: a material's code in the kernel is its index here; ``paper`` is eq. (13)
MATERIALS = ('paper', 'cast_iron', 'composite_k', 'composite_ll', 'disc')
PAPER, CAST_IRON, COMPOSITE_K, COMPOSITE_LL, DISC = range(len(MATERIALS))

#: speed breakpoints [km/h] of the composition-block and pad curves
CURVE_KMH = np.array([0.0, 50.0, 100.0, 160.0, 200.0, 300.0])
#: K blocks (UIC 541-4 / EN 16452 "K" level): nearly constant, a representative mean curve
#: inside the certification band (mean 0.25 +- 0.03 over the braking speed range)
COMPOSITE_K_MU = np.array([0.270, 0.255, 0.245, 0.235, 0.230, 0.220])
#: LL blocks (EN 16452 "LL" level, the retrofit of cast-iron wagons): a representative mean
#: curve; lower and slightly more speed-dependent than K, the standard tunes them to give
#: cast-iron stopping distances at the wagon's braked weight
COMPOSITE_LL_MU = np.array([0.200, 0.175, 0.160, 0.150, 0.145, 0.140])
#: organic disc pads (UIC 541-3: mean friction coefficient 0.35 with a tolerance band of
#: about +- 10 % over the speed range); a representative mean curve
DISC_MU = np.array([0.370, 0.360, 0.350, 0.340, 0.330, 0.310])


@jit(inline=True)
def karwatzki(v: float, block_force: float, g: float) -> float:
    """
    Return the friction coefficient of a cast-iron (P10) block [-] (Karwatzki).

    mu = 0.6 (16 K + 100) / (80 K + 100) * (V + 100) / (5 V + 100), K the block force in
    tonnes-force (block_force [N] / (1000 g)), V the speed [km/h] (v [m/s]): Karwatzki's
    formula (ORE B 126, as used by TrainDy); 2.2 times higher at 10 km/h than at 100 km/h
    for a given block force.
    """
    k = max(block_force, 0.0) / (1000.0 * g)
    kmh = 3.6 * abs(v)
    return 0.6 * (16.0 * k + 100.0) / (80.0 * k + 100.0) * (kmh + 100.0) / (5.0 * kmh + 100.0)


@jit(inline=True)
def material_friction(material: int, v: float, block_force: float, g: float) -> float:
    """Return the friction coefficient [-] of ``material`` (a code above) at v [m/s]."""
    if material == CAST_IRON:
        return karwatzki(v, block_force, g)
    kmh = 3.6 * abs(v)
    if material == COMPOSITE_K:
        return table_interp(kmh, CURVE_KMH, COMPOSITE_K_MU)
    if material == COMPOSITE_LL:
        return table_interp(kmh, CURVE_KMH, COMPOSITE_LL_MU)
    return table_interp(kmh, CURVE_KMH, DISC_MU)


@jit(inline=True)
def friction_braking_force(coach_material, p_cyl, v, gain, offset, blocks, rho, g, out):
    """
    Overwrite ``out`` [N] for each vehicle of a material other than paper (module docstring).

    Arrays per vehicle: material codes, cylinder pressure [Pa], speed [m/s], K1 [N/Pa],
    K0 [N], number of blocks or pads, radius ratio; g [m/s^2].
    """
    for i in range(out.shape[0]):
        material = int(coach_material[i])
        if material == PAPER:
            continue
        normal = max(p_cyl[i] * gain[i] - offset[i], 0.0)
        if normal == 0.0:
            out[i] = 0.0
            continue
        out[i] = material_friction(material, v[i], normal / blocks[i], g) * normal * rho[i]
