"""
The train: N coaches joined by N-1 couplers (paper eqs. 5-9, generalised to N coaches).

Coach i (1 = front) has mass m_i [kg], position x_i [m] (distance travelled since t = 0) and
speed v_i [m/s]. Coupler i joins coaches i and i+1: y_i = x_i - x_{i+1} (eq. 9), force F_i
(eq. 4, F > 0 tension). The equations of motion (5)-(7), for any N:

    m_i a_i = F_{i-1} - F_i - Fb_i,      F_0 = F_N = 0,

so the couplers' forces cancel in the sum and the centre of mass obeys eq. (8) exactly:
(sum m_i) a_cm = -sum Fb_i. In matrix form, with D the (N-1) x N difference matrix
(y = D x), M a = -D^T F(D x, D v) - Fb.

:class:`TrainSimulator` is the one model that ``sim_node`` and the offline command run: the
brake system (``brakes``) and the fixed-step integrator (``integrators``) advancing the
coach chain under zero-order-hold brake inputs.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics import brakes, couplers, integrators
from train_dynamics.physics.layout import COACH, COUPLER, FLAG, SCALAR, WORK
from train_dynamics.physics.parameters import SimConfig


class TrainSimulator:
    """
    Train, brake system and fixed-step integrator (eqs. 5-9, 12-16).

    Inputs are gauge pressures [Pa] held constant until the next ``set_*`` call; a new value
    takes effect at the next integration step. Outputs are numpy arrays (copies). The state
    lives in the packed arrays of :mod:`train_dynamics.physics.layout` (``coach``, ``cpl``,
    ``sc``, ``iv``, ``ws``) that :func:`integrators.advance_chain` advances in place.
    """

    #: per-coupler constants that ``coupler_constants`` may override (arrays of N-1) and
    #: their rows in ``cpl``
    _COUPLER_ROWS = {'buffer_stiffness': COUPLER.KE, 'buffer_friction': COUPLER.KF,
                     'draw_gear_stiffness': COUPLER.KEC, 'draw_gear_friction': COUPLER.KFC}
    COUPLER_CONSTANTS = tuple(_COUPLER_ROWS)

    def __init__(self, cfg: SimConfig, coupler_constants: dict | None = None):
        """
        Build the train of ``cfg`` at t = 0.

        ``coupler_constants``: optional arrays of N-1 values per name of
        :attr:`COUPLER_CONSTANTS` [N/m], for a train that mixes vehicles (coupler i joins
        coaches i and i+1); the scalar parameters of ``cfg`` fill the rest.
        """
        self.cfg = cfg
        self.n = n = cfg.n_coaches
        self.h = float(cfg.integration_step)
        self.masses = np.asarray(cfg.mass_array, dtype=float)
        self.cpl = np.empty((len(COUPLER), n - 1))
        extra = dict(coupler_constants or {})
        for name, row in self._COUPLER_ROWS.items():
            value = extra.pop(name, cfg.values[name])
            arr = np.broadcast_to(np.asarray(value, dtype=float), (n - 1,))
            if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
                raise ValueError(f'{name}: need {n - 1} finite values >= 0')
            self.cpl[row] = arr
        if extra:
            raise ValueError(f'unknown coupler constants: {", ".join(sorted(extra))}')
        cpl = self.cpl
        if (np.any(cpl[COUPLER.KF] >= cpl[COUPLER.KE])
                or np.any(cpl[COUPLER.KFC] >= cpl[COUPLER.KEC])):
            raise ValueError('every coupler needs k_f < k_e and k_fc < k_ec')
        self.ke, self.kf, self.kec, self.kfc = (cpl[COUPLER.KE], cpl[COUPLER.KF],
                                                cpl[COUPLER.KEC], cpl[COUPLER.KFC])
        self.mode = brakes.MODE_CODES[cfg.brake_input]
        self.fill = np.asarray(cfg.fill_table(), dtype=float)
        self.rel = np.asarray(cfg.release_table(), dtype=float)
        self.delays = brakes.pipe_delays(n, cfg.coach_length, cfg.brake_propagation_speed)
        self.ws = integrators.make_workspace(n)
        self.model_type = cfg.model_type
        self.u = float(cfg.scale_factor)
        self.reset()

    # -- state ---------------------------------------------------------------------------
    def reset(self) -> None:
        """Go back to t = 0: coaches at ``initial_speed``, couplers undeformed, brakes released."""
        cfg = self.cfg
        n = self.n
        p_nom = float(cfg.pipe_nominal_pressure)
        self.steps = 0
        self.coach = np.zeros((len(COACH), n))
        c = self.coach
        c[COACH.V] = float(cfg.initial_speed)
        c[COACH.MASS] = self.masses
        c[COACH.PPIPE] = p_nom
        c[COACH.PIPE_IN] = p_nom
        c[COACH.DELAY] = self.delays / self.h
        c[COACH.HELD] = (c[COACH.V] == 0.0)
        self.ring = np.full(int(np.floor(c[COACH.DELAY, -1])) + 2, p_nom)
        self.sc = np.zeros(len(SCALAR))
        self.sc[[SCALAR.H, SCALAR.PMAX, SCALAR.MU, SCALAR.G, SCALAR.PNOM, SCALAR.PFS,
                 SCALAR.SENS, SCALAR.HEAD_IN, SCALAR.YLIM]] = [
            self.h, cfg.max_cylinder_pressure, cfg.adhesion_coefficient, cfg.gravity, p_nom,
            cfg.full_service_pressure, cfg.distributor_sensitivity, p_nom,
            cfg.max_coupler_displacement]
        self.iv = np.zeros(len(FLAG), dtype=np.int64)     # FLAG.WS_VALID = 0
        self.iv[FLAG.MODE] = self.mode
        self.set_model(self.model_type, self.u)
        self.fault: str | None = None

    def set_model(self, model_type: str, scale_factor: float) -> None:
        """Switch the coupler friction law live (state untouched)."""
        if model_type not in couplers.MODEL_CODES:
            raise ValueError(f'model_type must be sign or tanh, got {model_type!r}')
        u = float(scale_factor)
        if not np.isfinite(u) or u <= 0.0:
            raise ValueError(f'scale_factor must be > 0, got {scale_factor!r}')
        self.model_type = model_type
        self.model = couplers.MODEL_CODES[model_type]
        self.u = u
        self.sc[SCALAR.U] = u
        self.iv[FLAG.MODEL] = self.model
        self.iv[FLAG.WS_VALID] = 0      # the couplers' Jacobian in ws depends on the model

    # -- inputs (gauge Pa) ------------------------------------------------------------------
    @staticmethod
    def _finite(p, what):
        arr = np.asarray(p, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f'{what}: pressure must be finite, got {p!r}')
        return arr

    def set_head_pipe_pressure(self, p: float) -> None:
        """Set the head-end brake-pipe pressure, gauge [Pa] (``pipe_head``)."""
        self.sc[SCALAR.HEAD_IN] = float(self._finite(p, 'head pipe'))

    def set_pipe_pressure(self, p, index: int | None = None) -> None:
        """Set the local brake-pipe pressure(s), gauge [Pa] (``pipe_per_coach``); 0-based."""
        arr = self._finite(p, 'pipe')
        if index is None:
            self.coach[COACH.PIPE_IN] = arr
        else:
            self.coach[COACH.PIPE_IN, index] = float(arr)

    def set_cylinder_pressure(self, p, index: int | None = None) -> None:
        """Set the brake-cylinder pressure(s), gauge [Pa] (``cylinder_per_coach``); 0-based."""
        arr = self._finite(p, 'cylinder')
        if index is None:
            self.coach[COACH.CYL_IN] = arr
        else:
            self.coach[COACH.CYL_IN, index] = float(arr)

    # -- integration -------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Return the simulation time [s]."""
        return self.steps * self.h

    def advance(self, n_steps: int) -> int:
        """Integrate ``n_steps`` fixed steps; return the steps done (fewer after a fault)."""
        if self.fault is not None or n_steps <= 0:
            return 0
        done, status = integrators.advance_chain(int(n_steps), self.coach, self.cpl, self.sc,
                                                 self.iv, self.fill, self.rel, self.ring,
                                                 self.ws)
        self.steps += done
        if status != integrators.OK:
            self.fault = integrators.STATUS_TEXT[status].format(t=self.t)
        return done

    def advance_to(self, t: float) -> int:
        """Integrate whole steps until ``self.t >= t - h/2``; return the steps done."""
        target = int(np.floor(t / self.h + 0.5))
        return self.advance(target - self.steps)

    # -- outputs -----------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        return self.coach[COACH.X].copy()

    @property
    def v(self) -> np.ndarray:
        return self.coach[COACH.V].copy()

    @property
    def held(self) -> np.ndarray:
        """Coaches at rest, held by their brakes."""
        return self.coach[COACH.HELD] > 0.5

    @property
    def y(self) -> np.ndarray:
        x = self.coach[COACH.X]
        return x[:-1] - x[1:]

    @property
    def ydot(self) -> np.ndarray:
        v = self.coach[COACH.V]
        return v[:-1] - v[1:]

    @property
    def coupler_force(self) -> np.ndarray:
        """F_i [N] at the present state: F at the end of the last step."""
        if self.steps == 0:
            return np.zeros(self.n - 1)
        return self.ws[WORK.F, :self.n - 1].copy()

    @property
    def brake_force(self) -> np.ndarray:
        return self.coach[COACH.FB_APPLIED].copy()

    @property
    def cylinder_pressure(self) -> np.ndarray:
        return self.coach[COACH.PCYL].copy()

    @property
    def pipe_pressure(self) -> np.ndarray:
        return self.coach[COACH.PPIPE].copy()

    @property
    def work_brake(self) -> float:
        """Work done by the brakes since t = 0 [J]."""
        return float(self.sc[SCALAR.WB])

    @property
    def work_coupler(self) -> float:
        """Work done on the couplers since t = 0 [J] (stored elastic + dissipated)."""
        return float(self.sc[SCALAR.WC])

    @property
    def kinetic_energy(self) -> float:
        return float(0.5 * np.sum(self.masses * self.coach[COACH.V] ** 2))

    @property
    def elastic_energy(self) -> float:
        return float(np.sum(couplers.elastic_energy(self.y, self.ke, self.kec)))

    @property
    def momentum(self) -> float:
        return float(np.sum(self.masses * self.coach[COACH.V]))
