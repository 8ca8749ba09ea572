"""
Friction brakes as a brake controller sees them: materials, force chain, braked mass, load.

Retarding force at the rail of one vehicle [N], for a friction material other than
``paper`` (the paper's eq. 13, :func:`~train_dynamics.physics.kernel.brakes.braking_force`):

    F_r = mu_m(v, F_block) * N * rho

with N [N] the total normal force of the blocks or pads, mu_m the material's friction law
(:mod:`~train_dynamics.physics.friction_laws`: a table of mu over speed and block force
or Karwatzki-type coefficients; the shipped materials are entries of the vehicle library's
``friction_materials:``; :func:`material_friction`) at the speed of the rubbing surface v
[m/s] (the wheel's peripheral speed; disc: the same wheel speed, the curves are given
against train speed), F_block = N / n_blocks [N] the force of one block, and rho the radius
ratio: 1 for tread brakes, r_eff / r_wheel for disc brakes (pads act at the disc's effective
radius).

**Force chain** (EN 14531-1, "Railway applications - methods for calculation of stopping and
slowing distances", tread and disc brake force formulae), :func:`chain_normal_force`:

    F_piston = p A eta_c - F_spring        (cylinder pressure p [Pa, gauge], piston area A
                                            [m^2], cylinder efficiency eta_c, return spring
                                            F_spring [N]; never negative)
    N        = n_cyl F_piston i eta_r      (rigging ratio i, rigging efficiency eta_r)

**Braked mass** (UIC 544-1): a vehicle's label gives its braked weight B [kg] per regime; the
braked-weight percentage lambda = 100 B / m [%]. The relation between lambda and the stopping
distance used here is the Minden formula of the DB test centre (the empirical relation the
UIC braked-weight percentages of P-braked trains were set on; quoted by Wende, Fahrdynamik
des Schienenverkehrs, 2003, ch. 8):

    s [m] = 3.85 v0^2 / (6.1 psi (1 + lambda / 10) + i)     v0 [km/h], i [per mille, > 0
                                                             uphill], psi = 1 (P regime)

:func:`braked_mass_normal_force` turns B into the normal force N_full at full cylinder
pressure so that the vehicle's stop from the reference speed on the level reproduces s (free
run for the equivalent response time t_e = fill time / 2, EN 14531-1, then the material's
friction curve integrated over the speed: exact for a constant pressure).

**G and P from one braked weight** (UIC 544-1: a vehicle's braked weights in G and P are
equal, the same cylinder pressure and rigging, unless its label gives G its own figure): the
normal force always follows from the braked weight in P, with the equivalent response time
of the standard P filling (:data:`P_RESPONSE_TIME`, the tables of config/table.py), whatever
the vehicle's regime and the train's filling tables. A G vehicle uses the same force, built up
with its slower G fill: it stops LONGER, by about v0 times the difference of the response
times. ``braked_mass_g`` is the label of a vehicle whose G braked weight differs: it wins for
a vehicle braking in G (turned into a force by the same P relation); a vehicle with only
``braked_mass_g`` uses it in either regime.

**Load-weighing** (:func:`load_weighed_force`): an empty/loaded changeover (two force
levels, switched at a changeover mass) or a continuous load-proportional valve (linear
between the empty and the loaded level).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from train_dynamics.physics import friction_laws
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.config.table import P_FILL_FRACTION, P_FILL_TIME
from train_dynamics.physics.friction_laws import FrictionLaw

#: the shipped materials (vehicle library) by their historical codes: paper is 0
MATERIALS = friction_laws.SHIPPED
MATERIAL_CODES = {name: code for code, name in enumerate(MATERIALS)}
PAPER, CAST_IRON, COMPOSITE_K, COMPOSITE_LL, DISC = range(len(MATERIALS))

#: Minden formula constants (see the module docstring)
MINDEN_K = 3.85
MINDEN_D = 6.1


@functools.lru_cache(maxsize=1)
def _library() -> dict:
    """Return the vehicle library's friction laws (read once per process)."""
    return friction_laws.library_laws()


def law_of(material) -> FrictionLaw:
    """Return the friction law of ``material``: a law, a library name or a shipped code."""
    if isinstance(material, FrictionLaw):
        return material
    name = MATERIALS[material] if isinstance(material, (int, np.integer)) else material
    if name == friction_laws.PAPER:
        return friction_laws.paper_law()
    return _library()[name]


def material_friction(material, v: float, block_force: float, g: float = 9.81) -> float:
    """
    Return the friction coefficient [-] of ``material`` at v [m/s], block force [N].

    ``material`` a :class:`FrictionLaw`, a library name or a shipped code (MATERIAL_CODES);
    ``g`` is not used (kept for callers of the former signature: the laws are in newtons).
    """
    return law_of(material).mu(v, block_force)


def chain_normal_force(p: float, area: float, spring: float, rigging_ratio: float,
                       rigging_efficiency: float, cylinders: int = 1,
                       cylinder_efficiency: float = 1.0) -> float:
    """
    Return the total normal force N [N] of the blocks or pads at cylinder pressure p [Pa].

    EN 14531-1: piston force p A eta_c - F_spring (>= 0) through the rigging, ratio i and
    efficiency eta_r, times the number of cylinders.
    """
    piston = max(p * area * cylinder_efficiency - spring, 0.0)
    return cylinders * piston * rigging_ratio * rigging_efficiency


def retarding_force(material, v: float, normal: float, blocks: int,
                    radius_ratio: float = 1.0, g: float = 9.81) -> float:
    """Return the retarding force at the rail [N]: mu_m(v, N / blocks) N rho (module docstring)."""
    return material_friction(material, v, normal / blocks, g) * normal * radius_ratio


def minden_distance(v0: float, braked_percentage: float, gradient: float = 0.0,
                    psi: float = 1.0) -> float:
    """Return the Minden-formula stopping distance [m] from v0 [m/s] at lambda [%]."""
    kmh = 3.6 * v0
    return MINDEN_K * kmh * kmh / (MINDEN_D * psi * (1.0 + braked_percentage / 10.0) + gradient)


def minden_percentage(v0: float, distance: float, gradient: float = 0.0,
                      psi: float = 1.0) -> float:
    """Return the braked-weight percentage lambda [%] that stops from v0 [m/s] in distance [m]."""
    kmh = 3.6 * v0
    return 10.0 * ((MINDEN_K * kmh * kmh / distance - gradient) / (MINDEN_D * psi) - 1.0)


def braked_mass_normal_force(braked_mass: float, mass: float, material, blocks: int,
                             response_time: float, radius_ratio: float = 1.0,
                             v_ref: float = 120.0 / 3.6, g: float = 9.81,
                             inertia: float = 0.0) -> float:
    """
    Return the normal force at full cylinder pressure N_full [N] that gives braked mass B.

    The stop from v_ref [m/s] on the level: free run v_ref t_e (t_e = ``response_time`` [s],
    the equivalent response time of the cylinder's filling, :func:`response_time`), then
    (m + m_rot) v dv / F_r(v) integrated to rest must equal the Minden distance of
    lambda = 100 B / m; ``inertia`` m_rot [kg] the rotating masses' allowance (the brake stops
    them too; the percentage is of the mass m).
    The cast-iron friction depends on the block force, so N_full is found by fixed-point
    iteration (it converges in a few steps: the block-force factor varies slowly).
    """
    lam = 100.0 * braked_mass / mass
    braking = minden_distance(v_ref, lam) - v_ref * response_time
    if braking <= 0.0:
        raise ValueError(f'braked mass {braked_mass} kg of a {mass} kg vehicle asks a stop '
                         f'shorter than its brake fill time allows')
    law = law_of(material)
    speeds = np.linspace(0.0, v_ref, 401)
    normal = mass * v_ref ** 2 / (2.0 * braking * 0.25 * radius_ratio)   # first guess
    for _ in range(50):
        mus = np.array([law.mu(v, normal / blocks) for v in speeds])
        # s = int m v dv / (mu(v) N rho)  =>  N = m int v / mu dv / (s rho)
        integral = float(np.sum(0.5 * (speeds[1:] / mus[1:] + speeds[:-1] / mus[:-1])
                                * np.diff(speeds)))
        new = (mass + inertia) * integral / (braking * radius_ratio)
        if abs(new - normal) <= 1e-12 * new:
            return new
        normal = new
    return normal


def response_time(fill_times, fill_fractions) -> float:
    """
    Return the equivalent response time t_e [s] of a filling characteristic (EN 14531-1).

    The area above the curve p / p_max against time: a step of the full force t_e after
    the command loses the same speed as the real build-up.
    """
    t = np.asarray(fill_times, dtype=float)
    f = 1.0 - np.asarray(fill_fractions, dtype=float)
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))


def braked_mass_of(regime: str, braked_p: float, braked_g: float) -> float:
    """
    Return the braked weight [kg] whose P-relation force a vehicle of ``regime`` brakes with.

    The G label where the vehicle brakes in G and has one, else the P label, else the G label
    (module docstring: G and P from one braked weight); 0 when neither is given.
    """
    if regime == 'G' and braked_g > 0.0:
        return braked_g
    return braked_p if braked_p > 0.0 else braked_g


def check_brake_fields(fields, materials, where: str = '', labels=None) -> None:
    """
    Raise ConfigError where a load-weighing field cannot act or a force level is missing.

    ``fields``: field -> array per vehicle (or entry; ``labels`` name them); ``materials``
    the consist's laws (the field friction_material indexes them). On ``paper`` (eq. 13: the
    force is adhesion_coefficient m g p / p_max, proportional to the vehicle's mass already)
    every load field must keep its default; on a friction material the fields other than
    load_empty_mass need load_empty_mass > 0 (else they would be ignored); a friction
    material needs a force level it can reach (:func:`_check_force_level`).
    """
    from train_dynamics.physics.config.table import PARAMETERS
    load = ('load_empty_mass', 'load_full_mass', 'load_changeover_mass', 'load_empty_ratio')
    for i, code in enumerate(np.asarray(fields['friction_material'], dtype=np.int64)):
        set_ = [f for f in load if float(fields[f][i]) != float(PARAMETERS[f].default)]
        name = labels[i] if labels is not None else str(i + 1)
        if set_ and materials[int(code)].paper:
            raise ConfigError(
                f'{where}vehicle {name}: {", ".join(set_)} set with friction_material paper: '
                'eq. 13 (adhesion_coefficient m g p / p_max) follows the mass already and has '
                'no load valve; give a friction material with a force level, or leave the load '
                'fields out')
        if set_ and float(fields['load_empty_mass'][i]) <= 0.0:
            raise ConfigError(f'{where}vehicle {name}: {", ".join(set_)} set without '
                              'load_empty_mass: load-weighing needs the empty mass (> 0)')
        if not materials[int(code)].paper:
            _check_force_level({f: float(v[i]) for f, v in fields.items()},
                               materials[int(code)].name, f'{where}vehicle {name}: ')


def _check_force_level(f, material: str, where: str, v_ref: float = 120.0 / 3.6) -> None:
    """
    Raise ConfigError unless a vehicle of a friction law has a force level it can reach.

    The force chain (brake_cylinder_area and rigging_ratio > 0) or a braked weight whose
    Minden stop from v_ref is longer than the free run of the P response time (else no
    force gives it: :func:`braked_mass_normal_force`); at configuration time, so a run is
    refused before it starts.
    """
    if f['brake_cylinder_area'] > 0.0 and f['rigging_ratio'] > 0.0:
        return
    braked = max(f['braked_mass_p'], f['braked_mass_g'])
    if braked <= 0.0:
        raise ConfigError(f'{where}friction_material {material} needs its force level: '
                          'brake_cylinder_area and rigging_ratio (EN 14531-1 force chain) or '
                          'braked_mass_p (braked weight, UIC 544-1)')
    mass = f['load_full_mass'] if f['load_empty_mass'] > 0.0 and f['load_full_mass'] > 0.0 \
        else f['mass']
    lam = 100.0 * braked / mass
    if minden_distance(v_ref, lam) <= v_ref * P_RESPONSE_TIME:
        raise ConfigError(f'{where}braked weight {braked:g} kg of a {mass:g} kg vehicle '
                          f'(lambda {lam:.0f} %) asks a stop from 120 km/h shorter than the '
                          'response time of the brake allows')


def force_rows(consist, inertia: np.ndarray, fill, g: float) -> np.ndarray:
    """
    Return the force chain of each vehicle reduced to a line: (2, N) K1 [N/Pa], K0 [N].

    ``consist`` the vehicles (their friction fields), ``inertia`` m (1 + rotating mass
    factor) [kg], ``fill`` the train's filling table (times, p/p_max: not used, the braked
    weight is calibrated on the standard P fill, module docstring). A vehicle of a
    material other than paper needs the force chain (brake_cylinder_area and rigging_ratio)
    or a braked mass (:func:`braked_mass_of`); else ConfigError naming the vehicle and the
    fields. Both give the loaded level (a braked mass with a load valve is the loaded
    label, its force that of a vehicle of load_full_mass when given); with load-weighing
    (load_empty_mass > 0) the valve scales the pressure on the piston, K1, by
    :func:`load_weighed_force` of the vehicle's mass (levels ``load_empty_ratio`` and 1).
    """
    rows = np.zeros((2, consist.n))
    for i in range(consist.n):
        material = consist.materials[int(consist['friction_material'][i])]
        if material.paper:
            continue
        field = lambda name: float(consist[name][i])       # noqa: E731
        area, ratio = field('brake_cylinder_area'), field('rigging_ratio')
        regime = consist.regimes[i]
        braked = braked_mass_of(regime, field('braked_mass_p'), field('braked_mass_g'))
        if area > 0.0 and ratio > 0.0:          # EN 14531-1 chain: N = p K1 - K0
            lever = field('brake_cylinders') * ratio * field('rigging_efficiency')
            rows[0, i] = area * field('brake_cylinder_efficiency') * lever
            rows[1, i] = field('brake_spring_force') * lever
        elif braked > 0.0:                       # UIC 544-1 braked mass: N = N_full p / p_max
            # with a load valve the label is the loaded braked weight, of the loaded mass
            loaded = field('load_full_mass') if field('load_empty_mass') > 0.0 else 0.0
            mass = loaded if loaded > 0.0 else field('mass')
            normal = braked_mass_normal_force(braked, mass, material,
                                              int(field('brake_blocks')), P_RESPONSE_TIME,
                                              field('brake_radius_ratio'), g=g,
                                              inertia=inertia[i] - field('mass'))
            rows[0, i] = normal / field('max_cylinder_pressure')
        else:
            raise ConfigError(
                f'vehicle {i + 1} ({consist.types[i]}): friction_material '
                f'{material.name} needs its force level: brake_cylinder_area and '
                f'rigging_ratio (EN 14531-1 force chain) or braked_mass_p (braked weight, '
                f'UIC 544-1; braked_mass_g where the G label differs)')
        empty = field('load_empty_mass')
        if empty > 0.0:                          # the load valve scales the pressure
            changeover = field('load_changeover_mass')
            if changeover <= 0.0 and field('load_full_mass') <= empty:
                raise ConfigError(f'vehicle {i + 1} ({consist.types[i]}): a continuous load '
                                  'valve needs load_full_mass above load_empty_mass')
            rows[0, i] *= load_weighed_force(field('mass'), empty, field('load_full_mass'),
                                             field('load_empty_ratio'), 1.0,
                                             changeover if changeover > 0.0 else math.nan)
    return rows


def law_rows(consist) -> np.ndarray:
    """Return the friction law of each vehicle as the kernel's rows: (LAW_LEN, N)."""
    laws = np.array([law.vector for law in consist.materials]).T
    return laws[:, consist['friction_material'].astype(np.int64)]


#: [s] equivalent response time of the standard P filling (config/table.py P_FILL_*): the
#: braked weight's force is calibrated on it (module docstring)
P_RESPONSE_TIME = response_time(P_FILL_TIME, P_FILL_FRACTION)


def load_weighed_force(mass: float, empty_mass: float, loaded_mass: float, empty_force: float,
                       loaded_force: float, changeover_mass: float = math.nan) -> float:
    """
    Return the normal force level [N] of a load-weighed vehicle of actual ``mass`` [kg].

    With ``changeover_mass`` [kg] given: the empty level below it, the loaded level at or
    above it (empty/loaded changeover); without (NaN): linear between the empty level at
    ``empty_mass`` and the loaded level at ``loaded_mass`` and held beyond them (continuous
    load-proportional valve).
    """
    if not math.isnan(changeover_mass):
        return loaded_force if mass >= changeover_mass else empty_force
    frac = min(max((mass - empty_mass) / (loaded_mass - empty_mass), 0.0), 1.0)
    return empty_force + frac * (loaded_force - empty_force)
