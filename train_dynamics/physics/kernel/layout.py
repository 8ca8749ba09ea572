"""
Layout of the packed state that the kernel advances in place, grouped by lifetime.

The compiled drivers (:func:`~train_dynamics.physics.kernel.fixed_step.advance_chain`,
:func:`~train_dynamics.physics.kernel.adaptive.advance_adaptive`) take a few packed arrays
instead of some forty arguments: numba unboxes every array argument at every call (about
70 ns each here), and the pneumatic brake calls the chain once per step. So each array
holds several groups of rows (or slots), and each group is one lifetime with its own name
(the pneumatic brake's own arrays are laid out in :mod:`.pneumatic`).
A group below is a named tuple whose fields are the row indices in its array, counted on
from the groups before it (``coach[STATE.V]``); inside the kernel they compile to constant
indices (numba freezes global tuples).

Each group below says what it holds and who writes it.

``coach``: float, shape (len(COACH), N), one column per vehicle (front = column 0)

- ``VEHICLE``: per-vehicle constants (masses, track position, pipe delay, then the consist
  fields the kernel reads as is: length, resistance, traction; their rows are declared with
  the fields in the parameter table); written by ``TrainSimulator.__init__`` only. First,
  so ``coach[len(VEHICLE):]`` is everything ``reset()`` rewrites.
- ``STATE``: integrated state (position, speed, pipe, distributor, cylinder, available
  braking force, holding, traction ramp); ``reset()``, then the kernel each step.
- ``INPUT``: inputs held until the next ``set_*`` call (local pipe, cylinder, traction
  command); ``reset()`` and the ``set_*`` methods (the pneumatic brake writes CYL).
- ``OUTPUT``: forces of the last step (braking force applied, traction, resistance,
  gradient); ``reset()``, then the kernel each step.

``cpl``: float, shape (len(COUPLER), N-1), one column per coupler

- ``COUPLER``: per-coupler constants (stiffness, friction, slack, stroke, blocked
  stiffness; the tables of a coupling with a preloaded or progressive end); written by
  ``TrainSimulator.__init__`` only.

``sc``: float, shape (len(SCALAR),)

- ``PARAM``: scalar constants (step, tanh scale, pressures, adhesion, gravity, displacement
  limit, tolerance); ``__init__``, and ``set_model`` (U). First, so ``sc[len(PARAM):]`` is
  everything ``reset()`` rewrites.
- ``TOTAL``: integrals since t = 0 (work of each force, impulse of the external forces);
  ``reset()``, then the kernel each step.
- ``SCALAR_INPUT``: the head-end pipe pressure; ``reset()`` and ``set_head_pipe_pressure``.
- ``CONTROL``: the step-size controller (proposed step, error of the last step, the step the
  stage weights were made for) and its smallest steps; ``reset()``, then the
  error-controlled driver.

``iv``: int64, shape (len(INTEGER),)

- ``OPTION``: settings (coupler law, brake mode, external forces on, track, landing period,
  step budget); ``__init__``, and ``set_model`` (MODEL). First, so ``iv[len(OPTION):]`` is
  everything ``reset()`` rewrites.
- ``CLOCK``: where the run stands (brake ticks, the chain's tick, the head-pressure ring's
  write position); ``reset()``, then the kernel.
- ``CACHE``: validity flags of the caches kept in ``ws``; ``reset()`` and ``set_model``
  clear them, the kernel sets them.
- ``COUNT``: statistics counters (accepted and rejected steps, fall-back periods, holding
  solves); ``reset()``, then the kernel; read by ``TrainSimulator.integration_stats``.

``ws``: float, shape (len(WORK), N): ``WORK``, the kernel's scratch memory (rows of N-1 used
for couplers), the caches that skip repeated work (bit for bit) and the in-train force
envelope; made by :func:`~train_dynamics.physics.kernel.step.make_workspace`, written by the
kernel (``reset()`` clears the envelope, the caches are invalidated through ``CACHE``).

Other arrays the drivers take: ``fill``, ``rel`` (2 R, L) cylinder tables (times [s],
p/p_max of each of the R table sets, one per brake regime of the train; constants),
``ring`` the head-pressure history [Pa] (state), ``gprof``, ``cprof`` (3, K) gradient and
curve profiles (constants), ``tick_fb``, ``tick_te`` the brake ticks of one output period
(error-controlled driver; state).
"""
from __future__ import annotations

from collections import namedtuple

from train_dynamics.physics.config.table import KERNEL_ROWS
from train_dynamics.physics.kernel.friction import LAW_LEN


def _group(name: str, fields: list, after=()):
    """Return the named tuple ``name`` of ``fields``, numbered on after the groups ``after``."""
    start = sum(len(g) for g in after)
    return namedtuple(name, fields)(*range(start, start + len(fields)))


# -- coach: one column per vehicle ---------------------------------------------------------
#: rows whose value is derived from fields (written by ``TrainSimulator._set_constants``)
DERIVED_VEHICLE_ROWS = [
    'MASS',         # mass for inertia, m (1 + rotating_mass_factor) [kg]
    'BMASS',        # m mu_i / mu_a [kg]: eq. (13) with the vehicle's own adhesion coefficient
    'WEIGHT',       # m g [N]: gravity, curve resistance, traction adhesion
    'FRONT0',       # track position of the vehicle's front at t = 0 [m]
    'DELAY',        # brake-pipe delay of the vehicle [steps]
    'BRAKE_GAIN',   # friction brakes: normal force per cylinder pressure K1 [N/Pa]
    'BRAKE_OFF',    # friction brakes: normal force lost to the return springs K0 [N]
    'WHEEL_MASS',   # wheelsets: reduced mass of the wheelset J / r^2 [kg]
    'TABLE',        # the vehicle's cylinder table set in fill/rel (its brake regime's) [-]
] + [f'LAW{k}' for k in range(LAW_LEN)]     # friction law (kernel/friction.py), LAW0 its kind
#: then one row per per-vehicle field that the kernel reads as is, in table order: the
#: ``row`` of its ParamSpec (config/table.py, :data:`KERNEL_ROWS`: name, unit, range there)
VEHICLE = _group('VehicleRows', DERIVED_VEHICLE_ROWS + list(KERNEL_ROWS.values()))
STATE = _group('StateRows', [
    'X',            # position, distance travelled since t = 0 [m]
    'V',            # speed [m/s]
    'PPIPE',        # brake-pipe pressure at the vehicle, gauge [Pa]
    'APPLIED',      # distributor state: 1.0 applied, 0.0 released
    'PCYL',         # brake-cylinder pressure, gauge [Pa]
    'FB_AVAIL',     # braking force available at the end of the last step, eq. (13) [N]
    'HELD',         # 1.0 while the brake holds the vehicle at rest
    'T_EFF',        # effective (rate-limited) traction command at the end of the last step
    'WHEEL',        # wheelsets: wheel peripheral speed [m/s] (>= 0, in the motion's sense)
    'WDECEL',       # wheelsets: wheel deceleration over the last step [m/s^2]
    'WSP_CUT',      # 1.0 while the slide-protection valves keep the cylinder below its input
    # per-bogie wheelsets (PARAM.BOGIES, kernel/bogie.py): bogie 1 (the front one) keeps
    # WHEEL, WDECEL; each bogie has its own cylinder behind its own valves, fed by PCYL
    'WHEEL_B2',     # bogies: wheel peripheral speed of bogie 2 [m/s]
    'WDECEL_B2',    # bogies: its wheel deceleration over the last step [m/s^2]
    'PCYL_B1',      # bogies: brake-cylinder pressure of bogie 1, gauge [Pa]
    'PCYL_B2',      # bogies: brake-cylinder pressure of bogie 2, gauge [Pa]
    'CUT_B1',       # bogies: 1.0 while bogie 1's valves keep its cylinder below PCYL
    'CUT_B2',       # bogies: the same for bogie 2
], after=(VEHICLE,))
INPUT = _group('InputRows', [
    'PIPE',         # local pipe pressure (pipe_per_coach), gauge [Pa]
    'CYL',          # cylinder pressure (cylinder_per_coach, or the pneumatic brake's) [Pa]
    'T_CMD',        # traction command in [-1, 1]
    'VALVE',        # slide-protection valve (wsp external): 0 normal, 1 hold, 2 vent
    'VALVE_B2',     # bogies: bogie 2's valve (wsp external); bogie 1's is VALVE
], after=(VEHICLE, STATE))
OUTPUT = _group('OutputRows', [
    'FB_APPLIED',   # |braking force| applied over the last step [N]
    'F_TRAC',       # traction / dynamic-brake force at the step's end [N, fwd > 0]
    'F_RES',        # running + curve resistance at the step's end [N, fwd > 0]
    'F_GRADE',      # gradient force at the step's end [N, fwd > 0]
    'ADH_LOW',      # track's available adhesion at low speed, mean over the vehicle [-]
    'F_CREEP',      # wheelsets: creep force of the last step [N, positive retarding]
    'ADH_USED',     # wheelsets: creep force / axle load of the last step [-]
    'ADH_AVAIL',    # wheelsets: available adhesion at the vehicle's speed [-]
    'VALVE',        # wheelsets: slide-protection valve state of the last step (0, 1, 2)
    'SLIDE_T',      # wheelsets (or adhesion limit): time the wheels slid since t = 0 [s]
    'SLIDE_X',      # wheelsets: distance the vehicle ran on sliding wheels since t = 0 [m]
    'ADH_CUT',      # adhesion limit: braking force beyond mu(v) m g, cut off [N] (0: none)
    # per-bogie wheelsets: bogie 1 keeps F_CREEP, ADH_USED, ADH_AVAIL, VALVE; SLIDE_T and
    # SLIDE_X count the vehicle (either bogie sliding)
    'F_CREEP_B2',   # bogies: creep force of bogie 2 [N, positive retarding]
    'ADH_USED_B2',  # bogies: its creep force / axle load [-]
    'ADH_AVAIL_B2',  # bogies: its available adhesion (rail conditioned by bogie 1) [-]
    'VALVE_B2',     # bogies: its valve state of the last step (0, 1, 2)
], after=(VEHICLE, STATE, INPUT))
#: all rows of ``coach``; VEHICLE first, so ``coach[len(VEHICLE):]`` is what reset() rewrites
COACH = range(len(VEHICLE) + len(STATE) + len(INPUT) + len(OUTPUT))

# -- cpl: one column per coupler ------------------------------------------------------------
#: knots of each coupling table: d = 0, the end of the preload ramp, then equal spacing to
#: the coupling's stroke (physics/characteristics.py; the trapezoids keep the energy of an x^3
#: curve within 0.5 %)
TABLE_KNOTS = 16
COUPLER = _group('CouplerRows', [
    'KE',           # buffer stiffness k_e [N/m]
    'KF',           # buffer friction k_f [N/m]
    'KEC',          # draw-gear stiffness k_ec [N/m]
    'KFC',          # draw-gear friction k_fc [N/m]
    'GT',           # draw-gear slack g_t [m]
    'GC',           # buffer slack g_c [m]
    'ST',           # draw-gear stroke S_t [m]
    'SC',           # buffer stroke S_c [m]
    'KB',           # blocked stiffness K_b [N/m]
    # a coupling with a preloaded or progressive end: its characteristic as tables
    # (physics/characteristics.py builds them, kernel/couplers.py reads them); TAB = 0: none, the
    # linear law of the rows above
    'TAB',          # 1.0: the coupling's law is its tables
    'T_D1',         # draw gear: end of the preload ramp [m] (knot 1; knot 0 is d = 0)
    'T_IH',         # draw gear: 1 / spacing of the knots 1 .. TABLE_KNOTS - 1 [1/m]
    'C_D1',         # buffers: as T_D1
    'C_IH',         # buffers: as T_IH
] + [f'{side}_{what}{k}' for side in 'TC' for what in 'ER' for k in range(TABLE_KNOTS)])
#: draw gear (T) and buffers (C): the elastic (mean) force E_k [N] and the friction
#: amplitude R_k [N] at each knot k: F = E + s R on the spring's deflection (s the friction
#: sign, eqs. 1 / 14); rows T_E0, T_R0, C_E0, C_R0 + k
TABLE_ROWS = range(COUPLER.TAB, len(COUPLER))

# -- sc: float scalars ---------------------------------------------------------------------
PARAM = _group('ParamSlots', [
    'H',            # integration step (the brake system's tick) [s]
    'U',            # tanh scale factor u [s/m]
    'PMAX',         # maximum cylinder pressure, gauge [Pa]
    'MU',           # adhesion coefficient mu_a
    'G',            # gravity [m/s^2]
    'PNOM',         # brake-pipe running pressure, gauge [Pa]
    'PFS',          # pipe pressure at full service, gauge [Pa]
    'SENS',         # distributor sensitivity [Pa]
    'YLIM',         # largest physically possible |y| [m]
    'TOL',          # integration_tolerance: local coupler-force error / force level [-]
    'FFLOOR',       # force level below which the tolerance is absolute [N]
    'FRICTION',     # 1.0: some vehicle brakes with a friction material (not paper)
    'MRTOL',        # multirate_tolerance: local coupler-force error / force level [-]; 0 off
    'MRVW',         # multirate_reversal_weight: velocity error at the reversal slope [-]; 0 off
    'ADHLIM',       # 1.0: braking force limited by the adhesion (adhesion_limit, no wheelsets)
    'BOGIES',       # 1.0: two wheelsets per vehicle, one per bogie (kernel/bogie.py)
    'CONDITION',    # bogies: rail conditioning by the leading bogie [-] (rail_conditioning)
])
TOTAL = _group('TotalSlots', [
    'WB',           # work of the brakes since t = 0 [J]
    'WC',           # work on the couplers since t = 0 [J]
    'WR',           # work of the running and curve resistance since t = 0 [J]
    'WT',           # work of traction and dynamic braking since t = 0 [J]
    'WG',           # work of gravity on gradients since t = 0 [J]
    'PEXT',         # impulse of all external forces since t = 0 [N s]
    'WWB',          # wheelsets: work of the brakes at the wheels since t = 0 [J]
    'WCREEP',       # wheelsets: work of the creep forces (wheel-rail contact) since t = 0 [J]
], after=(PARAM,))
SCALAR_INPUT = _group('ScalarInputSlots', [
    'HEAD',         # head-end pipe pressure (pipe_head), gauge [Pa]
], after=(PARAM, TOTAL))
CONTROL = _group('ControlSlots', [
    'HPROP',        # the controller's proposed next step [s]
    'HEVAL',        # the step the couplers' stage weights in ws were made for [s] (-1: none)
    'ERRPREV',      # error norm of the last accepted step (PI controller)
    'HMIN',         # smallest accepted step since reset [s] (not the landing steps)
    'INT_HMIN',     # smallest step of the last output period [s]
], after=(PARAM, TOTAL, SCALAR_INPUT))
#: all slots of ``sc``; PARAM first, so ``sc[len(PARAM):]`` is what reset() rewrites
SCALAR = range(len(PARAM) + len(TOTAL) + len(SCALAR_INPUT) + len(CONTROL))

# -- iv: integer scalars -------------------------------------------------------------------
OPTION = _group('OptionSlots', [
    'MODEL',        # coupler law: couplers.SIGN or couplers.TANH
    'MODE',         # brake input: brakes.PIPE_HEAD, PIPE_PER_COACH or CYLINDER_PER_COACH
    'EXT',          # 1: external forces (resistance, track, traction) act; 0: the paper's
    'TRACK',        # 1: the line has gradients or curves
    'LAND',         # the error-controlled chain's landing period in ticks (one output period)
    'BUDGET',       # largest number of error-controlled steps per landing period
    'WHEELS',       # 1: rotating wheelsets with the creep law (kernel/wheelset.py)
    'WSP',          # slide protection: wheelset.WSP_NONE, WSP_BUILTIN or WSP_EXTERNAL
    'ADHESION',     # 1: the track has an adhesion profile (OUTPUT.ADH_LOW per step)
])
CLOCK = _group('ClockSlots', [
    'TICK',         # brake-system ticks done (fixed step PARAM.H): the simulator's steps
    'CHAIN_TICK',   # the tick the coach chain has reached (it lands on LAND multiples)
    'RING_POS',     # write position of the head-pressure ring buffer
], after=(OPTION,))
CACHE = _group('CacheSlots', [
    'WS_VALID',     # 1 when the WORK rows F, DFDY, KK, K0, FRAC hold the present state
    'STEADY',       # 1: the last fixed step started and ended with every vehicle held
], after=(OPTION, CLOCK))
COUNT = _group('CountSlots', [
    'NSTEPS',       # accepted error-controlled chain steps since reset
    'NREJ',         # rejected chain steps since reset
    'NFALLBACK',    # output periods that ran out of step budget (finished at fixed steps)
    'INT_STEPS',    # chain steps of the last output period
    'INT_STEPS_MAX',    # largest INT_STEPS since reset
    'HOLD_SOLVES',  # chain solves beyond the first of each step (active set changes)
    'HOLD_CAPPED',  # steps that ended at the iteration cap with the set still inconsistent
    'MR_CLUSTERS',  # multirate: vehicle groups re-integrated in sub-steps since reset
    'MR_SUBSTEPS',  # multirate: their accepted sub-steps since reset
    'MR_DECLINED',  # multirate: groups kept at the long step (a vehicle held or stopping)
    'BLOCK_SOLVES',     # chain solves redone with a blocked coupler's slope in the matrix
], after=(OPTION, CLOCK, CACHE))
#: all slots of ``iv``; OPTION first, so ``iv[len(OPTION):]`` is what reset() rewrites
INTEGER = range(len(OPTION) + len(CLOCK) + len(CACHE) + len(COUNT))

# -- ws: scratch, caches, envelope ---------------------------------------------------------
WORK = _group('WorkRows', [
    'F',            # coupler forces at the step's start [N] (N-1 used)
    'DFDY',         # dF/dy [N/m]
    'KK',           # stage-matrix weights g h dF/dydot + (g h)^2 dF/dy [kg]
    'DIAG',         # diagonal of the stage matrix [kg]
    'LOWER',        # sub-diagonal of the stage matrix, held rows cut [kg]
    'RHS1',         # right-hand side of stage 1 without the brake [N]
    'RHS2',         # right-hand side of stage 2 without the brake [N]
    'B1',           # velocity stage 1 [m/s^2]
    'B2',           # velocity stage 2 [m/s^2]
    'C',            # Thomas algorithm: upper factor
    'WINV',         # Thomas algorithm: inverse pivots [1/kg]
    'F2',           # coupler forces at the stage-2 point [N]
    'FB',           # braking force over the step (trapezoid) [N]
    'SIGNED',       # braking force signed against the motion [N]
    'VSTART',       # speeds at the step's start, stopped coaches at 0 [m/s]
    'RELDIR',       # direction of a released coach's brake (+-1, 0 = by its motion)
    'VSTOP',        # speed [m/s] a coach was stopped from at this step's start (0: none)
    'STOPPED',      # 1: stopped at this step's start; -1: its stop undone (moves on); 0
    'HOLD',         # holding force of each held coach [N]
    'TARGET',       # distributors' target cylinder pressure [Pa]
    'FBNEXT',       # braking force available at the step's end [N]
    'K0',           # pipe delay, whole steps
    'FRAC',         # pipe delay, fraction of a step
    'XNEW',         # positions at the step's end [m]
    'VNEW',         # speeds at the step's end [m/s]
    'XOLD',         # positions at the step's start [m]
    'FBRAKE',       # braking force over the step, eq. (13) [N] (FB adds the resistance)
    'RSTAT',        # static resistance over the step: A + curve resistance [N]
    'TEFF',         # traction command over the step (mean of its ends)
    'E1',           # external non-friction force at stage 1 [N, forward > 0]
    'E2',           # external non-friction force at stage 2 [N, forward > 0]
    'RD1',          # speed-dependent resistance at stage 1 [N, signed retarding]
    'RD2',          # speed-dependent resistance at stage 2 [N, signed retarding]
    'TR1',          # traction force at stage 1 [N]
    'TR2',          # traction force at stage 2 [N]
    'GR1',          # gradient force at stage 1 [N]
    'GR2',          # gradient force at stage 2 [N]
    # standstill (standstill.py): the holding LCP's scratch
    'LZ',           # velocity change over the step per 2 h [m/s^2]
    'LR',           # right-hand side r = A z + f of the step just solved [N]
    'LC',           # Thomas algorithm: upper factor
    'LW',           # Thomas algorithm: inverse pivots [1/kg]
    'LS',           # the set before the pivoting (2 held, else WORK.RELDIR)
    # caches of the fixed-step path (bench: per-vehicle-step cost of real trains)
    'YKEY',         # y [m] of coupler j at which the rows F, DFDY, KK were evaluated
    'VKEY',         # its ydot [m/s]; column N-1: the g h [s] the weights KK were made for
    'XKEY',         # STATE.X [m] at which RSTAT and GR1 were computed (NaN: none yet)
    'FBPREV',       # WORK.FB of the last step, when it held every vehicle (CACHE.STEADY)
    'TEPREV',       # WORK.TEFF of that step
    # outputs kept here: the in-train force envelope, extremes over every accepted step since
    # reset (written by eval_couplers_work, read by observables; reset() zeroes them)
    'FHI',          # largest tension of coupler j [N] (>= 0; N-1 used)
    'FLO',          # largest compression of coupler j, as a force [N] (<= 0)
    # wheelsets (wheelset.py)
    'PCYL0',        # cylinder pressures at the step's start [Pa]
    'UMEAN',        # mean wheel speed over the step [m/s]
    'VABS',         # |speed| of the vehicle at the step's start [m/s]
    # multirate (multirate.py)
    'ERR',          # local error of coupler j's force over the step [N] (scratch)
    'NSUB',         # sub-steps coupler j took since reset (0: only long steps)
    # per-bogie wheelsets (bogie.py)
    'UMEAN_B2',     # mean wheel speed of bogie 2 over the step [m/s]
])
