"""
Validation cases of the brakes: published stopping distances and ours, case by case.

Each case runs the simulator (``TrainSimulator``, the model the node and the offline command
run) on a published case and returns :class:`Row` s: the published stopping distance [m],
ours [m] and, where there is one, the published model's own figure. ``bench/validation.py``
runs them all and writes ``docs/validation.md``; ``test/physics/test_validation.py`` asserts
the cheap subset (:data:`QUICK`, :func:`gp_case`, the single shunting calculation).

Sources:

- [Minden] the Minden formula of the DB test centre, s = 3.85 v0^2 / (6.1 (1 + lambda / 10)),
  v0 [km/h], lambda the braked-weight percentage: the relation UIC 544-1 braked weights of
  P-braked trains were set on (Wende, Fahrdynamik des Schienenverkehrs, Teubner 2003, ch. 8;
  physics/friction.py ``minden_distance``).
- [C&O] L. Cantone, A. Ottati, "Modelling of friction coefficient for shunting operation"
  and the slip and emergency-brake figures of their paper as quoted, with the inputs of
  each case, by [Pfaff]; Cantone & Ottati, The Open Transportation Journal 12 (2018),
  doi:10.2174/1874447801812010114, tables 5 (slip tests of an Eanos wagon) and 7
  (emergency stops from 30 km/h of 800-2500 t trains, cast-iron P10 and LL blocks).
- [Pfaff] R. Pfaff et al., "Braking curves in low-speed on-sight operation - a simulation
  study for the development of assistance and automation systems"; its code and results
  are public (github.com/RailProfAC/ShuntingBrakingCurves, ``Code.ipynb``: the inputs and
  printed results of every case quoted here; read, not copied: the reference model below is
  written from the equations the notebook states).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
import tempfile

import numpy as np

from train_dynamics.physics import friction
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.config.table import P_FILL_FRACTION, P_FILL_TIME
from train_dynamics.physics.pfaff_reference import (BLOCKS, CYL_DIAMETER, ETA, G, LOCO_FORCE,
                                                    LOCO_MASS, PFAFF_K, pfaff_model,
                                                    pfaff_wagon, SPRING)
from train_dynamics.physics.train import TrainSimulator


@dataclass
class Row:
    """One line of a result table."""

    case: str
    published: float
    ours: float
    note: str = ''
    reference: float = math.nan      # the published model's own figure, where there is one

    @property
    def diff(self) -> float:
        """Return ours - published over published [%]."""
        return 100.0 * (self.ours - self.published) / self.published


# -- running the simulator -------------------------------------------------------------------

def stop(values: dict, consist_text: str | None = None, pipe: str = 'head') -> float:
    """
    Return the stopping distance [m] of the lead vehicle after an emergency at t = 0.

    ``pipe`` 'head': the head-end pipe vented (the brake wave runs at
    brake_propagation_speed); 'all': every vehicle's pipe vented at once (a single vehicle's
    slip test).
    """
    with tempfile.TemporaryDirectory() as tmp:
        values = dict(values)
        if consist_text is not None:
            path = Path(tmp) / 'consist.yaml'
            path.write_text(consist_text)
            values['consist_file'] = str(path)
        values.setdefault('brake_model', 'empirical')
        values['brake_input'] = 'pipe_head' if pipe == 'head' else 'pipe_per_coach'
        sim = TrainSimulator(SimConfig.from_dict(values))
        if pipe == 'head':
            sim.set_head_pipe_pressure(0.0)
        else:
            sim.set_pipe_pressure(0.0)
        while np.any(sim.v > 0.0) and sim.t < 600.0:
            sim.advance_to(sim.t + 2.0)
        return float(sim.x[0])


def stop_filled(values: dict, consist_text: str, fills: list, dt: float = 0.01) -> float:
    """
    Return the stopping distance [m] with each vehicle's cylinder filled as published.

    ``fills``: per vehicle (t_f [s], G mode): [Pfaff]'s filling, p = 3.8 bar times t / t_f
    (P) or 0.1 + 0.9 t / t_f (G) until t_f, the brake wave's arrival already in t_f; given
    to the simulator as its cylinder pressures (``brake_input: cylinder_per_coach``, the
    paper's own way with measured fillings), updated every ``dt`` at the interval's middle.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'consist.yaml'
        path.write_text(consist_text)
        cfg = SimConfig.from_dict({**values, 'consist_file': str(path),
                                   'brake_input': 'cylinder_per_coach'})
        sim = TrainSimulator(cfg)
        tf = np.array([f[0] for f in fills])
        g_mode = np.array([f[1] for f in fills], dtype=bool)
        while np.any(sim.v > 0.0) and sim.t < 600.0:
            t = sim.t + 0.5 * dt
            frac = np.where(g_mode, 0.1 + 0.9 * t / tf, t / tf)
            sim.set_cylinder_pressure(3.8e5 * np.minimum(frac, 1.0))
            sim.advance_to(sim.t + dt)
        return float(sim.x[0])


def _pfaff_fills(loco: tuple | None, wagons: list[tuple], lengths: list[float],
                 loco_length: float = 10.5) -> list:
    """Return [Pfaff]'s (t_f, G) per vehicle: the wagons' t_f stretched by the wave's arrival."""
    out = [loco] if loco else []
    front = loco_length if loco else 0.0
    for (tf, g), length in zip(wagons, lengths):
        out.append((tf + front / 250.0, g))
        front += length
    return out


def _strahl(mass: float) -> dict:
    """Return the Davis fields of [Pfaff]'s Strahl resistance of a vehicle of ``mass`` [kg]."""
    return {'davis_a': 1.6e-3 * mass * G, 'davis_b': 0.0,
            'davis_c': 5.7e-3 * mass * G / 27.8 ** 2}


def _fill(regime: str, seconds: float) -> dict:
    """Return [Pfaff]'s filling: linear over ``seconds`` (P), 10 % at once then linear (G)."""
    if regime == 'P':
        return {'cylinder_fill_time': [0.0, seconds], 'cylinder_fill_fraction': [0.0, 1.0]}
    return {'cylinder_fill_time': [0.0, 1e-3, seconds],
            'cylinder_fill_fraction': [0.0, 0.1, 1.0]}


def _wagon_type(name: str, mass: float, ratio: float, rot: float, diameter: float = CYL_DIAMETER,
                blocks: int = BLOCKS, length: float = 14.0) -> str:
    """
    Return a consist-file vehicle type of [Pfaff]'s wagon.

    Mapping: the force chain N = (p A - F_spring) i with cylinder and rigging efficiency 1
    and the rigging efficiency 0.83 applied at the rail (brake_radius_ratio): [Pfaff] takes
    the block force before the rigging loss into the friction law and the loss after it.
    """
    fields = {'mass': mass, 'length': length, 'rotating_mass_factor': rot - 1.0,
              'friction_material': 'pfaff_k', 'brake_cylinder_area': math.pi * diameter ** 2 / 4,
              'brake_cylinder_efficiency': 1.0, 'brake_spring_force': SPRING,
              'rigging_ratio': ratio, 'rigging_efficiency': 1.0, 'brake_radius_ratio': ETA,
              'brake_blocks': float(blocks), **_strahl(mass)}
    return f'  {name}: {{{", ".join(f"{k}: {v!r}" for k, v in fields.items())}}}\n'


def _consist(types: str, vehicles: list[tuple[str, int]], loco: bool = False) -> str:
    """Return a consist file of [Pfaff]'s law, ``types`` and (type, count) front to rear."""
    text = ('friction_materials:\n'
            f'  pfaff_k: {{coefficients: {PFAFF_K}}}\n'
            '  flat: {speeds: [0.0], mu: [0.25]}\n'
            'vehicle_types:\n' + types)
    if loco:
        # a constant force F_loco at full pressure: a constant mu 0.25 on N = F_loco / 0.25
        ratio = LOCO_FORCE / 0.25 / (380000.0 * 0.05)
        text += (f'  class_363: {{mass: {LOCO_MASS}, length: 10.5, friction_material: flat, '
                 'brake_cylinder_area: 0.05, brake_cylinder_efficiency: 1.0, '
                 f'rigging_ratio: {ratio!r}, rigging_efficiency: 1.0, brake_blocks: 8.0}}\n')
    text += 'vehicles:\n' + ''.join(f'  - {{type: {t}, count: {c}}}\n' for t, c in vehicles)
    return text


# -- the cases ---------------------------------------------------------------------------------

def minden_cases(percentages=(50, 70, 90, 110, 130, 150), speeds=(120.0, 100.0, 80.0),
                 material='cast_iron') -> list[Row]:
    """
    [Minden]: a vehicle of braked weight B (lambda = 100 B / m), regime P, every pipe vented.

    Mapping: two identical 50 t vehicles (no in-train force: the pipes are vented together),
    braked_mass_p = lambda m / 100 on ``material``, the standard P filling (UIC 540, config/
    table.py), no resistance. The force is calibrated on the Minden stop from 120 km/h
    (physics/friction.py), so 120 km/h checks the implementation and the other speeds the
    shape of the material's mu(v) against the formula's v0^2 law.
    """
    rows = []
    for kmh in speeds:
        for lam in percentages:
            values = {'num_coaches': 2, 'coach_mass': 50000.0, 'friction_material': material,
                      'braked_mass_p': lam * 500.0, 'brake_blocks': 8.0,
                      'initial_speed': kmh / 3.6}
            ours = stop(values, pipe='all')
            rows.append(Row(f'P, {material}, lambda {lam} %, {kmh:.0f} km/h',
                            friction.minden_distance(kmh / 3.6, lam), ours))
    return rows


def g_regime_cases(percentages=(50, 70, 90), kmh=100.0, material='composite_k') -> list[Row]:
    """
    UIC 544-1's G/P rule: equal braked weights; G stops later by v0 (t_e,G - t_e,P).

    Published: the Minden P distance plus v0 times the difference of the equivalent
    response times of the standard G and P fillings (config/table.py: 95 % in 24 s and 4 s).
    """
    t_p = friction.response_time(P_FILL_TIME, P_FILL_FRACTION)
    from train_dynamics.physics.config.table import G_FILL_TIME
    t_g = friction.response_time(G_FILL_TIME, P_FILL_FRACTION)
    rows = []
    for lam in percentages:
        values = {'num_coaches': 2, 'coach_mass': 50000.0, 'friction_material': material,
                  'braked_mass_p': lam * 500.0, 'brake_blocks': 8.0,
                  'initial_speed': kmh / 3.6, 'brake_regime': 'G'}
        ours = stop(values, pipe='all')
        published = friction.minden_distance(kmh / 3.6, lam) + kmh / 3.6 * (t_g - t_p)
        rows.append(Row(f'G, {material}, lambda {lam} %, {kmh:.0f} km/h', published, ours,
                        f'P {friction.minden_distance(kmh / 3.6, lam):.0f} m + '
                        f'{kmh / 3.6 * (t_g - t_p):.0f} m'))
    return rows


def slip_cases() -> list[Row]:
    """
    [C&O] table 5 slip tests of an Eanos wagon (P, composition blocks), as [Pfaff] maps them.

    One wagon (here two identical ones, pipes vented together), P filling linear over 4 s,
    [Pfaff]'s K-block law and wagon (module constants); loaded 90 t i = 5.65, empty 25.5 t
    i = 2.4, augment 1.04 / 1.15.
    """
    rows = []
    for case, mass, i, rot, kmh, published, ref in (
            ('Eanos loaded, 100 km/h', 90000.0, 5.65, 1.04, 100.0, 596.0, 597.2),
            ('Eanos empty, 100 km/h', 25500.0, 2.4, 1.15, 100.0, 421.0, 422.8),
            ('Eanos empty, 120 km/h', 25500.0, 2.4, 1.15, 120.0, 634.0, 604.6)):
        text = _consist(_wagon_type('eanos', mass, i, rot), [('eanos', 2)])
        ours = stop({'initial_speed': kmh / 3.6, **_fill('P', 4.0)}, text, pipe='all')
        rows.append(Row(case, published, ours, 'measured; [Pfaff] calibrated i on 100 km/h',
                        ref))
    return rows


def calibrated_ratio(material: str, distance: float = 596.0, kmh: float = 100.0) -> float:
    """
    Return the rigging ratio i that stops [Pfaff]'s loaded wagon on ``material`` in ``distance``.

    The [C&O] table 5 slip test (loaded Eanos, 100 km/h, 596 m) as [Pfaff] calibrated its K
    blocks, here for a library law (bisection on [Pfaff]'s one-mass model with that law).
    """
    law = friction.law_of(material).mu
    lo, hi = 1.0, 30.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        s = pfaff_model(kmh / 3.6, [pfaff_wagon(i=mid)], law=law, dt=0.02)
        lo, hi = (lo, mid) if s < distance else (mid, hi)
    return 0.5 * (lo + hi)


def shunting_cases(quick: bool = False) -> list[Row]:
    """
    [Pfaff]'s own cases: the single brake calculation and the class 363 shunting set.

    Published: [Pfaff]'s model (Code.ipynb: "Braking distance: 40.9 m"; Monte Carlo mean
    59.24 m, SD 0.68 m, of 5 loaded wagons in G (t_f 24 s) behind the class 363 in G (t_f 4 s)
    from 25 km/h; ours at the nominal inputs). The fillings as published, per vehicle
    (``stop_filled``).
    """
    rows = []
    types = (_wagon_type('w90a', 90000.0, 6.5, 1.04, length=13.0)
             + _wagon_type('w90b', 90000.0, 5.5, 1.04, length=13.0)
             + _wagon_type('w45', 45000.0, 6.0, 1.04, diameter=0.300, blocks=8, length=17.0))
    text = _consist(types, [('w90a', 1), ('w90b', 1), ('w45', 1)])
    fills = _pfaff_fills(None, [(4.0, False)] * 3, [13.0, 13.0, 17.0])
    ours = stop_filled({'initial_speed': 25 / 3.6}, text, fills)
    ref = pfaff_model(25 / 3.6, [pfaff_wagon(i=6.5, length=13.0),
                                 pfaff_wagon(i=5.5, length=13.0),
                                 pfaff_wagon(mass=45000.0, i=6.0, d=0.3, n=8, length=17.0)])
    rows.append(Row('3 wagons (90, 90, 45 t), P, 25 km/h', 40.9, ours,
                    '[Pfaff] single calculation', ref))
    if quick:
        return rows
    text = _consist(_wagon_type('eanos', 90000.0, 5.65, 1.04), [('class_363', 1), ('eanos', 5)],
                    loco=True)
    fills = _pfaff_fills((4.0, True), [(24.0, True)] * 5, [14.0] * 5)
    ours = stop_filled({'initial_speed': 25 / 3.6}, text, fills)
    loco = {'mass': LOCO_MASS, 'force': LOCO_FORCE, 'length': 10.5, 'tf': 4.0, 'g': True}
    wagons = [pfaff_wagon(g=True, tf=24.0) for _ in range(5)]
    ref = pfaff_model(25 / 3.6, wagons, loco)
    once = pfaff_model(25 / 3.6, wagons, loco, loco_twice=False)
    rows.append(Row('class 363 + 5 loaded wagons, G, 25 km/h', 59.24, ours,
                    '[Pfaff] Monte Carlo mean; its model with the force of the locomotive '
                    f'counted '
                    f'once: {once:.1f} m ({100 * (ours - once) / once:+.1f} %)', ref))
    return rows


#: [C&O] table 7 as [Pfaff] maps it: (case, wagons, their regime, the locomotive's regime,
#: published P10 [m], published LL [m]); [Pfaff]'s GP case runs the wagons in P, its LL case
#: the first four wagons in G (Code.ipynb)
TABLE_7 = (('800 t, P', 9, ['P'] * 9, 'P', 56.4, 51.0),
           ('1200 t, GP', 13, ['P'] * 13, 'G', 58.4, 52.7),
           ('1600 t, LL', 18, ['G'] * 4 + ['P'] * 14, 'G', 66.1, 62.0),
           ('2500 t, G', 28, ['G'] * 28, 'G', 88.4, 92.3))


def emergency_cases(cases=TABLE_7) -> list[Row]:
    """
    [C&O] table 7: emergency stops from 30 km/h, class 363 + 90 t wagons, as [Pfaff] maps them.

    The fillings as published per vehicle (P 4 s, G 24 s with 10 % at once; the brake wave's
    arrival added, ``stop_filled``). Three block laws on the wagons: [Pfaff]'s K-block law
    (i = 5.65, calibrated by [Pfaff] on the table 5 slip test) and the library's cast_iron
    (P10) and composite_ll, each with the rigging ratio that gives the same slip test
    (596 m from 100 km/h, :func:`calibrated_ratio`); published P10 and LL side by side.
    """
    rows = []
    ratios = {'cast_iron': calibrated_ratio('cast_iron'),
              'composite_ll': calibrated_ratio('composite_ll')}
    for case, n, regimes, loco_regime, p10, ll in cases:
        fills = _pfaff_fills((4.0 if loco_regime == 'P' else 24.0, loco_regime == 'G'),
                             [(4.0 if r == 'P' else 24.0, r == 'G') for r in regimes],
                             [14.0] * n)
        k_text = _consist(_wagon_type('eanos', 90000.0, 5.65, 1.04),
                          [('class_363', 1), ('eanos', n)], loco=True)
        ours_k = stop_filled({'initial_speed': 30 / 3.6}, k_text, fills)
        loco = {'mass': LOCO_MASS, 'force': LOCO_FORCE, 'length': 10.5, 'tf': fills[0][0],
                'g': fills[0][1]}
        ws = [pfaff_wagon(g=r == 'G', tf=4.0 if r == 'P' else 24.0) for r in regimes]
        ref = pfaff_model(30 / 3.6, ws, loco)
        once = pfaff_model(30 / 3.6, ws, loco, loco_twice=False)
        rows.append(Row(f'{case}, K blocks of [Pfaff] vs P10', p10, ours_k,
                        f'the model of [Pfaff], locomotive counted once {once:.1f} m', ref))
        for material, published in (('cast_iron', p10), ('composite_ll', ll)):
            text = _consist(_wagon_type('eanos', 90000.0, ratios[material], 1.04)
                            .replace("'pfaff_k'", material),
                            [('class_363', 1), ('eanos', n)], loco=True)
            ours = stop_filled({'initial_speed': 30 / 3.6}, text, fills)
            rows.append(Row(f'{case}, {material} (i = {ratios[material]:.2f}) vs '
                            f'{"P10" if material == "cast_iron" else "LL"}', published, ours))
    return rows


def model_cases(cases=TABLE_7, first_stage: bool = True) -> list[Row]:
    """
    [C&O] table 7 in both brake models (the pipe vented at the head).

    The wagons as in the table above on the library's cast_iron (its slip-test ratio), the
    brake positions as [Pfaff] maps them, the locomotive a constant force (as [Pfaff]); the
    simulator's own brake: ``brake_model: empirical`` (the 250 m/s wave, each vehicle its
    own regime's filling table) and ``pneumatic`` (pipe gas
    dynamics, UIC distributors, each vehicle its own regime, with the distributor first
    stage of UIC 540 (``inshot_pressure`` 0.4 bar, the default) and, for the trains with G
    vehicles, without it on any vehicle (0). The note gives
    the cylinder pressure of the first and the last wagon at 4 s and 10 s [p / p_max].
    """
    # cases: rows of TABLE_7; first_stage: also the runs without the first stage
    rows = []
    ratio = calibrated_ratio('cast_iron')
    for case, n, regimes, loco_regime, p10, _ in cases:
        types = ''.join(
            _wagon_type(f'e{r}', 90000.0, ratio, 1.04).replace("'pfaff_k'", 'cast_iron')
            .replace('{mass', f'{{brake_regime: {r}, mass') for r in sorted(set(regimes)))
        text = _consist(types, [('class_363', 1)] + [(f'e{r}', 1) for r in regimes],
                        loco=True).replace('class_363: {mass',
                                           f'class_363: {{brake_regime: {loco_regime}, mass')
        models = ['empirical', 'pneumatic']
        models += ['pneumatic, no first stage'] if first_stage and 'G' in regimes else []
        for model in models:
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / 'consist.yaml'
                inshot = 'inshot_pressure: 0.0, ' if 'first stage' in model else ''
                path.write_text(text.replace('{brake_regime: ', '{' + inshot + 'brake_regime: '))
                sim = TrainSimulator(SimConfig.from_dict({
                    'consist_file': str(path), 'initial_speed': 30 / 3.6,
                    'brake_model': model.split(',')[0], 'brake_input': 'pipe_head'}))
                sim.set_head_pipe_pressure(0.0)
                fills = {}
                while np.any(sim.v > 0.0) and sim.t < 300.0:
                    sim.advance_to(sim.t + 0.5)
                    if round(2 * sim.t) in (8, 20):
                        p = sim.cylinder_pressure / 3.8e5
                        fills[round(sim.t)] = f'{p[1]:.2f} / {p[-1]:.2f}'
                note = '; '.join(f'{t} s: {f}' for t, f in fills.items())
                rows.append(Row(f'{case}, cast_iron, {model}', p10, float(sim.x[0]), note))
    return rows


#: the cheap subset the tests assert: (name, function, tolerance [%] of ours vs published)
QUICK = (('slip', slip_cases, 5.0),)


def gp_case() -> list[Row]:
    """[C&O] table 7's 1200 t GP train in both brake models (:func:`model_cases`)."""
    return model_cases(TABLE_7[1:2], first_stage=False)
