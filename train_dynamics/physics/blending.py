"""
The brake control unit (BCU) of a multiple unit: brake blending, ``blending: builtin``.

A train-wide brake demand (``brake_demand``: a fraction of full service, or a deceleration
[m/s^2], ``brake_demand_mode``) becomes, once per ``blending_period`` T [s]:

1. a demanded deceleration a_ref [m/s^2], moved toward the demand at most J T per cycle
   (J = ``blending_jerk_limit`` [m/s^3]; release likewise) and the demanded force
   F = a_ref sum_i M_i, M_i = m_i (1 + rotating_mass_factor) [kg] (the brake force that
   decelerates the train at a_ref on level track; resistance is not counted on);
2. the electro-dynamic (ED) brake of the motor cars first (vehicles with
   ``max_dynamic_brake_force`` > 0): car k can give E_k(v) = min(F_db, P_db / |v|,
   mu(v) m g) min(|v| / v_fade, 1) (``kernel/traction.py``, the locomotive's dynamic brake:
   force and power limits, adhesion, fade-out). ``blending_scope`` train: the ED force is
   min(F, sum E_k), every motor car at the same fraction of its E_k; car: each motor car
   brakes its own share a_ref M_k, up to E_k. The ED command acts through the motor car's
   build-up rate (``traction_build_up_time``), as a locomotive's;
3. the friction brake of every car makes up the rest: scope train: R = F - sum(ED), the ED
   force the motor cars will give over the coming period (their build-up rate applied),
   shared by all cars in proportion to their mass M_i (load-weighed: the loaded mass);
   scope car: a_ref M_i - (that ED of car i). The force becomes a cylinder pressure by
   inverting the car's brake law at its speed (eq. 13, or its friction material), clamped
   to [0, p_max]. The cylinder follows the commanded pressure with a first-order lag of
   time constant tau = ``friction_response_time`` (the EP valve and cylinder); the BCU
   commands p* + tau dp*/dt (lead compensation), so a ramp of p* (the ED fading out at low
   speed) is followed without a lag: the handover keeps the deceleration.

Emergency (``brake_emergency``) bypasses the blending: every cylinder to p_max through the
same lag, ED commands to 0, no jerk limit; the cars' magnetic track brakes
(``track_brake_force``, :mod:`train_dynamics.physics.track_brake`) after their delay.
ED trip (``ed_brake/trip``: line voltage lost): the ED force drops to 0 at once; the
friction takes over within its response (3 tau for 95 %).
Regenerated energy: the work of the ED forces, ``TrainSimulator.work_traction`` (negative
while braking; its energy balance books it, ``observables.TrainBalances``).

While the demand is 0 and the unit has released, the motor cars' traction commands are left
to their own input (``coach_<i>/traction/command``).
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.kernel.creep import DRY_ADHESION
from train_dynamics.physics.kernel.layout import INPUT, OUTPUT, PARAM, STATE, VEHICLE
from train_dynamics.physics.kernel.step import available_braking_force
from train_dynamics.physics.kernel.traction import CK_AT_REST
from train_dynamics.physics.track_brake import TrackBrakes

#: bisection steps inverting a friction material's brake law (p_max / 2^30 resolution)
_BISECTIONS = 30


def ed_available(c: np.ndarray, motors: list[int], speed: np.ndarray | None = None) -> np.ndarray:
    """
    Return the ED force each motor car can give at its speed [N] (``kernel/traction.py``).

    min(F_db, P_db / |v|, mu(v) m g) min(|v| / v_fade, 1), mu(v) from ``traction_adhesion``
    scaled by the track's adhesion (OUTPUT.ADH_LOW / DRY_ADHESION, as the kernel does);
    ``speed`` [m/s] overrides the vehicles' present speeds (one per motor car).
    """
    idx = np.asarray(motors, dtype=int)
    v = np.abs(c[STATE.V, idx] if speed is None else np.asarray(speed, dtype=float))
    # kernel/traction.py, available_force and traction_force, on arrays; the track's
    # adhesion scales the vehicle's as in the kernel (kernel/rosenbrock2.py, traction)
    mu0 = c[VEHICLE.T_ADH, idx]
    low = c[OUTPUT.ADH_LOW, idx]
    mu0 = np.where(low != DRY_ADHESION, mu0 * (low / DRY_ADHESION), mu0)
    mu = mu0 * (0.161 + 7.5 / (3.6 * v + 44.0)) / CK_AT_REST
    f = np.minimum(c[VEHICLE.DB_FORCE, idx], mu * c[VEHICLE.WEIGHT, idx])
    power = c[VEHICLE.DB_POWER, idx]
    f = np.where(power < f * v, power / np.where(v > 0.0, v, 1.0), f)
    f = f * np.minimum(v / c[VEHICLE.DB_FADE, idx], 1.0)
    return np.where(v == 0.0, 0.0, f)


def allocate_ed(a_ref: float, motor_mass: np.ndarray, total_mass: float, avail: np.ndarray,
                per_car: bool) -> np.ndarray:
    """
    Return the ED force [N] asked of each motor car for the deceleration a_ref [m/s^2].

    ``motor_mass`` M_k [kg] and ``avail`` E_k [N] of the motor cars, ``total_mass`` sum M_i of
    the train [kg]. Car scope (``per_car``): a_ref M_k, up to E_k. Train scope: the ED force
    min(a_ref sum M_i, sum E_k), every motor car at the same fraction of its E_k.
    """
    if per_car:
        return np.minimum(a_ref * motor_mass, avail)
    total = float(avail.sum())
    share = min(a_ref * total_mass, total) / total if total > 0.0 else 0.0
    return avail * share


def friction_make_up(a_ref: float, mass: np.ndarray, ed: np.ndarray,
                     per_car: bool) -> np.ndarray:
    """
    Return the friction force [N] of each car: what the achieved ED force ``ed`` leaves.

    mass M_i [kg] and ``ed`` [N] (0 for trailers) of every car. Car scope: a_ref M_i - ed_i;
    train scope: (a_ref sum M - sum ed) M_i / sum M (load-weighed). Never below 0.
    """
    if per_car:
        return np.maximum(a_ref * mass - ed, 0.0)
    total = float(mass.sum())
    rest = max(a_ref * total - float(ed.sum()), 0.0)
    return rest * mass / total


def ed_forces(sim) -> np.ndarray:
    """Return each vehicle's ED (dynamic-brake) force [N, >= 0 while braking, else 0]."""
    c = sim.coach
    f = -c[OUTPUT.F_TRAC] * np.where(c[STATE.V] < 0.0, -1.0, 1.0)
    return np.maximum(f, 0.0)


class BrakeControlUnit:
    """The builtin blending controller of one train (see the module's text)."""

    def __init__(self, sim) -> None:
        """Attach to ``sim`` (a TrainSimulator with brake_input cylinder_per_coach)."""
        self.sim = sim
        cfg = sim.cfg
        c = sim.coach
        self.motors = [i for i in sim.consist.commanded if c[VEHICLE.DB_FORCE, i] > 0.0]
        self._idx = np.array(self.motors, dtype=int)
        self.period_steps = max(1, int(round(float(cfg.blending_period) / sim.h)))
        self.period = self.period_steps * sim.h
        self.tau = float(cfg.friction_response_time)
        self.alpha = 1.0 - math.exp(-self.period / self.tau)
        self.jerk = float(cfg.blending_jerk_limit)
        self.per_car = cfg.blending_scope == 'car'
        self.scale = (float(cfg.full_service_deceleration)
                      if cfg.brake_demand_mode == 'fraction' else 1.0)
        self.pmax = float(cfg.max_cylinder_pressure)
        #: the magnetic track brakes, applied with the emergency (physics/track_brake.py)
        self.track = TrackBrakes(sim)
        self.reset()

    # -- inputs ----------------------------------------------------------------------------
    def reset(self) -> None:
        """Released, ED available, no demand; the first cycle runs at the present time."""
        n = self.sim.n
        self.demand = 0.0           # as brake_demand_mode
        self.emergency = False
        self.ed_ok = True
        self.a_ref = 0.0            # demanded deceleration [m/s^2], jerk-limited
        self.force_demand = 0.0     # demanded brake force of the train [N]
        self.p_cyl = np.zeros(n)    # cylinder pressure, kernel units (train's p_max) [Pa]
        self.p_target = np.zeros(n)
        self.friction_target = np.zeros(n)   # friction force the BCU asks of each car [N]
        self.ed_command = np.zeros(len(self.motors))   # ED force asked of each motor car [N]
        self._braking = False
        self.track.reset()
        self._next_tick = self.sim.steps
        self.sim.schedule(self.sim.t, self._cycle)

    def set_demand(self, value: float) -> None:
        """Set the train-wide brake demand (fraction of full service or [m/s^2], >= 0)."""
        d = float(value)
        if not (math.isfinite(d) and d >= 0.0) or (self.scale != 1.0 and d > 1.0):
            raise ValueError(f'brake demand must be finite, >= 0 (a fraction: <= 1), got {d!r}')
        self.demand = d

    def set_emergency(self, active: bool) -> None:
        """Apply (True) or release (False) the emergency brake (bypasses the blending)."""
        self.emergency = bool(active)
        self.track.set_applied(self.emergency)

    def set_ed_trip(self, tripped: bool) -> None:
        """Lose (True) or restore (False) the ED brake of every motor car; lost: 0 at once."""
        self.ed_ok = not bool(tripped)
        if not self.ed_ok:
            c = self.sim.coach
            for i in self.motors:
                c[INPUT.T_CMD, i] = 0.0
                c[STATE.T_EFF, i] = 0.0     # the line breaker opens: no ramp

    # -- outputs ---------------------------------------------------------------------------
    @property
    def demanded_deceleration(self) -> float:
        """Return the demanded deceleration a_ref [m/s^2] (after the jerk limit)."""
        return self.a_ref

    def ed_force(self) -> np.ndarray:
        """Return each vehicle's achieved ED force [N, >= 0 while braking] (0: trailers)."""
        out = np.zeros(self.sim.n)
        c = self.sim.coach
        idx = self._idx
        out[idx] = -c[OUTPUT.F_TRAC, idx] * np.where(c[STATE.V, idx] < 0.0, -1.0, 1.0)
        return out

    # -- the cycle -------------------------------------------------------------------------
    def _cycle(self) -> None:
        """One BCU cycle: demand -> ED commands and cylinder pressures; the next is scheduled."""
        sim = self.sim
        self._control()
        self.track.update()
        self._next_tick += self.period_steps
        sim.schedule(self._next_tick * sim.h, self._cycle)

    def _control(self) -> None:
        """Set the ED commands and the cylinder pressures for the next period."""
        sim = self.sim
        c = sim.coach
        mass = c[VEHICLE.MASS]
        if self.emergency:
            self.a_ref = self.demand * self.scale   # resumes from the demand after release
            self.force_demand = 0.0
            self._set_ed(np.zeros(len(self.motors)), np.ones(len(self.motors)))
            self.friction_target[:] = np.inf
            self._set_pressures(np.full(sim.n, self.pmax))
            self._braking = True
            return
        target = self.demand * self.scale
        step = self.jerk * self.period
        self.a_ref = min(target, self.a_ref + step) if target > self.a_ref \
            else max(target, self.a_ref - step)
        if self.a_ref <= 0.0 and not self._braking:
            return
        self.force_demand = self.a_ref * float(mass.sum())
        avail = ed_available(c, self.motors) if self.ed_ok else np.zeros(len(self.motors))
        ed = allocate_ed(self.a_ref, mass[self.motors], float(mass.sum()), avail, self.per_car)
        self._set_ed(ed, avail)
        fric = friction_make_up(self.a_ref, mass, self._ed_expected(avail), self.per_car)
        self.friction_target = fric
        self._set_pressures(self._pressure_for(fric))
        self._braking = self.a_ref > 0.0 or bool(np.any(self.p_cyl > 1.0))

    def _ed_expected(self, avail: np.ndarray) -> np.ndarray:
        """
        Return each vehicle's ED force [N] expected over the coming period.

        The effective command moves toward the command by T / ``traction_build_up_time``
        (the motor car's build-up rate, ``kernel/traction.py``), times the ED available at
        the present speed: the friction then makes up what the ED will give, not what it
        gave a period ago.
        """
        c = self.sim.coach
        out = np.zeros(self.sim.n)
        if not self.motors:
            return out
        idx = self._idx
        eff, cmd = c[STATE.T_EFF, idx], c[INPUT.T_CMD, idx]
        build = c[VEHICLE.T_BUILD, idx]
        step = np.where(build > 0.0, self.period / np.maximum(build, 1e-300), np.inf)
        eff = np.where(cmd > eff, np.minimum(cmd, eff + step), np.maximum(cmd, eff - step))
        out[idx] = np.maximum(-eff, 0.0) * avail
        return out

    def _set_ed(self, ed: np.ndarray, avail: np.ndarray) -> None:
        """Command ED force ``ed`` [N] of each motor car (a fraction of ``avail`` [N])."""
        self.ed_command = ed
        if not self.motors:
            return
        cmd = np.zeros(len(self.motors))
        if self.ed_ok:
            ok = avail > 0.0
            cmd[ok] = -np.minimum(ed[ok] / avail[ok], 1.0)
        self.sim.coach[INPUT.T_CMD, self._idx] = cmd

    def _pressure_for(self, force: np.ndarray) -> np.ndarray:
        """
        Return the cylinder pressures [Pa, kernel units] that brake with ``force`` [N].

        Inverts the brake law at the vehicles' present speeds: eq. (13), F = mu_a M_b g p /
        p_max, in closed form; a friction material's law by bisection (it rises with p).
        """
        sim = self.sim
        c, sc = sim.coach, sim.sc
        if sc[PARAM.FRICTION] == 0.0:
            full = sc[PARAM.MU] * c[VEHICLE.BMASS] * sc[PARAM.G]
            return np.clip(force / full, 0.0, 1.0) * self.pmax
        work = c.copy()
        out = np.empty(sim.n)
        lo, hi = np.zeros(sim.n), np.full(sim.n, self.pmax)
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            work[STATE.PCYL] = mid
            available_braking_force(work, sc, out)
            below = out < force
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        return hi

    def _set_pressures(self, target: np.ndarray) -> None:
        """Command ``target`` [Pa] with lead compensation; the cylinders lag (tau)."""
        lead = target + self.tau * (target - self.p_target) / self.period
        self.p_target = target
        command = np.clip(lead, 0.0, self.pmax)
        self.p_cyl = self.p_cyl + self.alpha * (command - self.p_cyl)
        self.sim.set_cylinder_pressure(self.p_cyl * self.sim.pmax_ratio)
