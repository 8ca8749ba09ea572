"""The train: N coaches joined by N-1 couplers (paper eqs. 5-9, generalised to N coaches).

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

from . import brakes, couplers, pneumatic
from train_dynamics.physics import integrators as I
from ._jit import jit
from train_dynamics.physics.parameters import SimConfig


@jit
def relative_motion(x: np.ndarray, v: np.ndarray):
    """Coupler displacement y_i = x_i - x_{i+1} [m] and velocity ydot_i [m/s] (eq. 9)."""
    return x[:-1] - x[1:], v[:-1] - v[1:]


@jit
def coupler_net_force(F: np.ndarray) -> np.ndarray:
    """Net coupler force on each coach, F_{i-1} - F_i [N] (eqs. 5-7), F_0 = F_N = 0."""
    n = F.shape[0] + 1
    out = np.zeros(n)
    out[:-1] -= F
    out[1:] += F
    return out


def accelerations(x, v, brake, masses, ke, kf, kec, kfc, model, u):
    """Coach accelerations [m/s^2] of eqs. (5)-(7) for brake forces ``brake`` [N] (signed,
    positive retarding)."""
    y, ydot = relative_motion(x, v)
    F = couplers.coupler_force(y, ydot, ke, kf, kec, kfc, model, u)
    return (coupler_net_force(F) - brake) / masses


class TrainSimulator:
    """Train, brake system and fixed-step integrator; see the README and ``shared/interface.md``.

    Inputs are gauge pressures [Pa] held constant until the next ``set_*`` call; a new value
    takes effect at the next integration step. Outputs are numpy arrays (copies).
    """

    #: per-coupler constants that ``coupler_constants`` may override (arrays of N-1)
    COUPLER_CONSTANTS = ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                         'draw_gear_friction')

    def __init__(self, cfg: SimConfig, coupler_constants: dict | None = None):
        """``coupler_constants``: optional arrays of N-1 values per name of
        :attr:`COUPLER_CONSTANTS` [N/m], for a train that mixes vehicles (coupler i joins
        coaches i and i+1); the scalar parameters of ``cfg`` fill the rest."""
        self.cfg = cfg
        self.n = n = cfg.n_coaches
        self.h = float(cfg.integration_step)
        self.masses = np.asarray(cfg.mass_array, dtype=float)
        self.cpl = np.empty((4, n - 1))
        extra = dict(coupler_constants or {})
        for row, name in enumerate(self.COUPLER_CONSTANTS):
            value = extra.pop(name, cfg.values[name])
            arr = np.broadcast_to(np.asarray(value, dtype=float), (n - 1,))
            if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
                raise ValueError(f'{name}: need {n - 1} finite values >= 0')
            self.cpl[row] = arr
        if extra:
            raise ValueError(f'unknown coupler constants: {", ".join(sorted(extra))}')
        if np.any(self.cpl[I.KF] >= self.cpl[I.KE]) or np.any(self.cpl[I.KFC] >= self.cpl[I.KEC]):
            raise ValueError('every coupler needs k_f < k_e and k_fc < k_ec')
        self.ke, self.kf, self.kec, self.kfc = self.cpl
        self.mode = brakes.MODE_CODES[cfg.brake_input]
        self.fill = np.asarray(cfg.fill_table(), dtype=float)
        self.rel = np.asarray(cfg.release_table(), dtype=float)
        self.delays = brakes.pipe_delays(n, cfg.coach_length, cfg.brake_propagation_speed)
        self.ws = I.make_workspace(n)
        # brake_model pneumatic: the pneumatic brake hands its cylinder pressures to the
        # chain step by step (the chain then runs as in cylinder_per_coach); the bypass
        # cylinder_per_coach keeps the input cylinders
        self.pneu = None
        if cfg.brake_model == 'pneumatic' and self.mode != brakes.CYLINDER_PER_COACH:
            self.pneu = pneumatic.from_config(cfg, self.h,
                                              external_pipe=self.mode == brakes.PIPE_PER_COACH)
            self._trace = np.zeros((0, n))
        self.model_type = cfg.model_type
        self.u = float(cfg.scale_factor)
        self.reset()

    # -- state ---------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to t = 0: coaches at ``initial_speed``, couplers undeformed, brakes released."""
        cfg = self.cfg
        n = self.n
        p_nom = float(cfg.pipe_nominal_pressure)
        self.steps = 0
        self.coach = np.zeros((I.N_COACH_ROWS, n))
        c = self.coach
        c[I.V] = float(cfg.initial_speed)
        c[I.MASS] = self.masses
        c[I.PPIPE] = p_nom
        c[I.PIPE_IN] = p_nom
        c[I.DELAY] = self.delays / self.h
        c[I.HELD] = (c[I.V] == 0.0)
        self.ring = np.full(int(np.floor(c[I.DELAY, -1])) + 2, p_nom)
        self.sc = np.zeros(I.N_SCALARS)
        self.sc[[I.S_H, I.S_PMAX, I.S_MU, I.S_G, I.S_PNOM, I.S_PFS, I.S_SENS, I.S_HEAD_IN,
                 I.S_YLIM]] = [
            self.h, cfg.max_cylinder_pressure, cfg.adhesion_coefficient, cfg.gravity, p_nom,
            cfg.full_service_pressure, cfg.distributor_sensitivity, p_nom,
            cfg.max_coupler_displacement]
        self.iv = np.zeros(I.N_INT_SCALARS, dtype=np.int64)     # I_WS_VALID = 0
        self.iv[I.I_MODE] = self.mode
        if self.pneu is not None:
            self.pneu.reset()
            self.iv[I.I_MODE] = brakes.CYLINDER_PER_COACH
            c[I.CYL_IN] = self.pneu.cylinder_pressure
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
        self.sc[I.S_U] = u
        self.iv[I.I_MODEL] = self.model
        self.iv[I.I_WS_VALID] = 0      # the couplers' Jacobian in ws depends on the model

    # -- inputs (gauge Pa) ------------------------------------------------------------------
    @staticmethod
    def _finite(p, what):
        arr = np.asarray(p, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f'{what}: pressure must be finite, got {p!r}')
        return arr

    def set_head_pipe_pressure(self, p: float) -> None:
        """Head-end brake-pipe pressure, gauge [Pa] (``pipe_head``)."""
        self.sc[I.S_HEAD_IN] = float(self._finite(p, 'head pipe'))
        if self.pneu is not None:
            self.pneu.set_command(self.sc[I.S_HEAD_IN])

    def set_pipe_pressure(self, p, index: int | None = None) -> None:
        """Local brake-pipe pressure(s), gauge [Pa] (``pipe_per_coach``); index 0-based."""
        arr = self._finite(p, 'pipe')
        if index is None:
            self.coach[I.PIPE_IN] = arr
        else:
            self.coach[I.PIPE_IN, index] = float(arr)
        if self.pneu is not None:
            self.pneu.set_pipe_pressure(arr, index)

    def set_cylinder_pressure(self, p, index: int | None = None) -> None:
        """Brake-cylinder pressure(s), gauge [Pa] (``cylinder_per_coach``); index 0-based."""
        arr = self._finite(p, 'cylinder')
        if index is None:
            self.coach[I.CYL_IN] = arr
        else:
            self.coach[I.CYL_IN, index] = float(arr)

    # -- integration -------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Simulation time [s]."""
        return self.steps * self.h

    def advance(self, n_steps: int) -> int:
        """Integrate ``n_steps`` fixed steps; returns the steps done (fewer after a fault)."""
        if self.fault is not None or n_steps <= 0:
            return 0
        if self.pneu is not None:
            return self._advance_pneumatic(int(n_steps))
        done, status = I.advance_chain(int(n_steps), self.coach, self.cpl, self.sc, self.iv,
                                       self.fill, self.rel, self.ring, self.ws)
        self.steps += done
        if status != I.OK:
            self.fault = I.STATUS_TEXT[status].format(t=self.t)
        return done

    def _advance_pneumatic(self, n_steps: int) -> int:
        """Advance the pneumatic brake n_steps ahead, then the chain under its cylinders."""
        if self._trace.shape[0] < n_steps:
            self._trace = np.zeros((n_steps, self.n))
        trace = self._trace[:n_steps]
        self.pneu.advance(n_steps, trace)
        cyl_in = self.coach[I.CYL_IN]
        done = 0
        status = I.OK
        for k in range(n_steps):
            cyl_in[:] = trace[k]
            step, status = I.advance_chain(1, self.coach, self.cpl, self.sc, self.iv,
                                           self.fill, self.rel, self.ring, self.ws)
            done += step
            if status != I.OK:
                break
        self.coach[I.PPIPE] = self.pneu.pipe_pressure
        self.steps += done
        if status != I.OK:
            self.fault = I.STATUS_TEXT[status].format(t=self.t)
        return done

    def advance_to(self, t: float) -> int:
        """Integrate whole steps until ``self.t >= t - h/2``; returns the steps done."""
        target = int(np.floor(t / self.h + 0.5))
        return self.advance(target - self.steps)

    # -- outputs -----------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        return self.coach[I.X].copy()

    @property
    def v(self) -> np.ndarray:
        return self.coach[I.V].copy()

    @property
    def held(self) -> np.ndarray:
        """Coaches at rest, held by their brakes."""
        return self.coach[I.HELD] > 0.5

    @property
    def y(self) -> np.ndarray:
        x = self.coach[I.X]
        return x[:-1] - x[1:]

    @property
    def ydot(self) -> np.ndarray:
        v = self.coach[I.V]
        return v[:-1] - v[1:]

    @property
    def coupler_force(self) -> np.ndarray:
        """F_i [N] at the present state: F at the end of the last step."""
        if self.steps == 0:
            return np.zeros(self.n - 1)
        return self.ws[0, :self.n - 1].copy()

    def coupler_force_now(self) -> np.ndarray:
        """F_i [N] evaluated from the present state and model (e.g. after a model switch)."""
        return couplers.coupler_force(self.y, self.ydot, self.ke, self.kf, self.kec, self.kfc,
                                      self.model, self.u)

    @property
    def brake_force(self) -> np.ndarray:
        return self.coach[I.FB_APPLIED].copy()

    @property
    def cylinder_pressure(self) -> np.ndarray:
        return self.coach[I.PCYL].copy()

    @property
    def pipe_pressure(self) -> np.ndarray:
        return self.coach[I.PPIPE].copy()

    @property
    def auxiliary_pressure(self) -> np.ndarray | None:
        """Auxiliary-reservoir gauge pressures [Pa] (pneumatic brake), else None."""
        return None if self.pneu is None else self.pneu.auxiliary_pressure

    @property
    def control_pressure(self) -> np.ndarray | None:
        """Control-reservoir gauge pressures [Pa] (pneumatic brake), else None."""
        return None if self.pneu is None else self.pneu.control_pressure

    @property
    def work_brake(self) -> float:
        """Work done by the brakes since t = 0 [J]."""
        return float(self.sc[I.S_WB])

    @property
    def work_coupler(self) -> float:
        """Work done on the couplers since t = 0 [J] (stored elastic + dissipated)."""
        return float(self.sc[I.S_WC])

    @property
    def kinetic_energy(self) -> float:
        return float(0.5 * np.sum(self.masses * self.coach[I.V] ** 2))

    @property
    def elastic_energy(self) -> float:
        return float(np.sum(couplers.elastic_energy(self.y, self.ke, self.kec)))

    @property
    def momentum(self) -> float:
        return float(np.sum(self.masses * self.coach[I.V]))
