"""
Layout of the packed state that the chain kernel advances in place.

The compiled kernel (:func:`train_dynamics.physics.kernel.fixed_step.advance_chain`) takes a few
packed arrays instead of some forty arguments (numba's call overhead grows with the
argument count). Each layout below names the rows (or slots) of one array, once: the
index of a name is its position, the count is the length of the layout. Inside the kernel
``coach[COACH.V]`` compiles to a constant row index (numba freezes global tuples).

- :data:`COACH`: rows of ``coach``, shape (len(COACH), N), one column per coach.
- :data:`COUPLER`: rows of ``cpl``, shape (len(COUPLER), N-1), one column per coupler.
- :data:`SCALAR`: slots of ``sc``, the float scalars.
- :data:`FLAG`: slots of ``iv``, the integer scalars.
- :data:`WORK`: rows of ``ws``, the kernel's scratch memory, shape (len(WORK), N).
"""
from __future__ import annotations

from collections import namedtuple


def _indices(rows):
    """Return the named tuple class ``rows`` filled with its row indices 0, 1, ..."""
    return rows(*range(len(rows._fields)))


CoachRows = namedtuple('CoachRows', [
    'X',            # position, distance travelled since t = 0 [m]
    'V',            # speed [m/s]
    'MASS',         # [kg]
    'PCYL',         # brake-cylinder pressure, gauge [Pa]
    'PPIPE',        # brake-pipe pressure at the coach, gauge [Pa]
    'PIPE_IN',      # input: local pipe pressure (pipe_per_coach) [Pa]
    'CYL_IN',       # input: cylinder pressure (cylinder_per_coach) [Pa]
    'FB_AVAIL',     # braking force available at the end of the last step, eq. (13) [N]
    'FB_APPLIED',   # |braking force| applied over the last step [N]
    'DELAY',        # brake-pipe delay of the coach [steps]
    'APPLIED',      # distributor state: 1.0 applied, 0.0 released
    'HELD',         # 1.0 while the brake holds the coach at rest
    # real trains (issue 11); MASS above is the mass for inertia, m (1 + rotating_mass_factor)
    'BMASS',        # m mu_i / mu_a [kg]: eq. (13) with the vehicle's own adhesion coefficient
    'WEIGHT',       # m g [N]: gravity, curve resistance, traction adhesion
    'LENGTH',       # vehicle length [m]
    'FRONT0',       # track position of the vehicle's front at t = 0 [m]
    'DAVIS_A',      # running resistance A [N]
    'DAVIS_B',      # running resistance B [N s/m]
    'DAVIS_C',      # running resistance C [N s^2/m^2]
    'T_FORCE',      # locomotive: maximum tractive force [N]
    'T_POWER',      # locomotive: traction power [W]
    'DB_FORCE',     # locomotive: maximum dynamic braking force [N]
    'DB_POWER',     # locomotive: dynamic braking power [W]
    'DB_FADE',      # locomotive: dynamic brake fade speed [m/s]
    'T_ADH',        # locomotive: traction adhesion at rest
    'T_BUILD',      # locomotive: force build-up time [s]
    'T_CMD',        # input: traction command in [-1, 1]
    'T_EFF',        # effective (rate-limited) command at the end of the last step
    'F_TRAC',       # output: traction / dynamic-brake force at the step's end [N, fwd > 0]
    'F_RES',        # output: running + curve resistance at the step's end [N, fwd > 0]
    'F_GRADE',      # output: gradient force at the step's end [N, fwd > 0]
])
COACH = _indices(CoachRows)

CouplerRows = namedtuple('CouplerRows', [
    'KE',           # buffer stiffness k_e [N/m]
    'KF',           # buffer friction k_f [N/m]
    'KEC',          # draw-gear stiffness k_ec [N/m]
    'KFC',          # draw-gear friction k_fc [N/m]
    'GT',           # draw-gear slack g_t [m]
    'GC',           # buffer slack g_c [m]
    'ST',           # draw-gear stroke S_t [m]
    'SC',           # buffer stroke S_c [m]
    'KB',           # blocked stiffness K_b [N/m]
])
COUPLER = _indices(CouplerRows)

ScalarSlots = namedtuple('ScalarSlots', [
    'H',            # integration step [s]
    'U',            # tanh scale factor u [s/m]
    'PMAX',         # maximum cylinder pressure, gauge [Pa]
    'MU',           # adhesion coefficient mu_a
    'G',            # gravity [m/s^2]
    'PNOM',         # brake-pipe running pressure, gauge [Pa]
    'PFS',          # pipe pressure at full service, gauge [Pa]
    'SENS',         # distributor sensitivity [Pa]
    'HEAD_IN',      # input: head-end pipe pressure (pipe_head) [Pa]
    'YLIM',         # largest physically possible |y| [m]
    'WB',           # work of the brakes since t = 0 [J]
    'WC',           # work on the couplers since t = 0 [J]
    'WR',           # work of the running and curve resistance since t = 0 [J]
    'WT',           # work of traction and dynamic braking since t = 0 [J]
    'WG',           # work of gravity on gradients since t = 0 [J]
    'PEXT',         # impulse of all external forces since t = 0 [N s]
    # error-controlled stepping (issue 14; adaptive.advance_adaptive)
    'TOL',          # integration_tolerance: local coupler-force error / force level [-]
    'FFLOOR',       # force level below which the tolerance is absolute [N]
    'HPROP',        # the controller's proposed next step [s]
    'HEVAL',        # the step the couplers' stage weights in ws were made for [s] (-1: none)
    'ERRPREV',      # error norm of the last accepted step (PI controller)
    'NSTEPS',       # accepted chain steps since reset
    'NREJ',         # rejected chain steps since reset
    'HMIN',         # smallest accepted step since reset [s] (not the landing steps)
    'NFALLBACK',    # output periods that ran out of step budget (finished at fixed steps)
    'INT_STEPS',    # chain steps of the last output period
    'INT_STEPS_MAX',    # largest INT_STEPS since reset
    'INT_HMIN',     # smallest step of the last output period [s]
    # standstill (issue 14; standstill.py): the holding LCP
    'HOLD_SOLVES',  # chain solves beyond the first of each step (active set changes)
    'HOLD_CAPPED',  # steps that ended at the iteration cap with the set still inconsistent
])
SCALAR = _indices(ScalarSlots)

FlagSlots = namedtuple('FlagSlots', [
    'MODEL',        # coupler law: couplers.SIGN or couplers.TANH
    'MODE',         # brake input: brakes.PIPE_HEAD, PIPE_PER_COACH or CYLINDER_PER_COACH
    'RING_POS',     # write position of the head-pressure ring buffer
    'WS_VALID',     # 1 when the WORK rows F, DFDY, KK, K0, FRAC hold the present state
    'EXT',          # 1: external forces (resistance, track, traction) act; 0: the paper's
    'TRACK',        # 1: the line has gradients or curves
    # error-controlled stepping (issue 14)
    'TICK',         # brake-system ticks done (fixed step SCALAR.H): the simulator's steps
    'CHAIN_TICK',   # the tick the coach chain has reached (it lands on LAND multiples)
    'LAND',         # the chain's landing period in ticks (one output period)
    'BUDGET',       # largest number of error-controlled steps per landing period
    # fixed-step standstill (fixed_step._repeats_standstill)
    'STEADY',       # 1: the last step started and ended with every vehicle held
])
FLAG = _indices(FlagSlots)

WorkRows = namedtuple('WorkRows', [
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
    # standstill (issue 14; standstill.py): the holding LCP's scratch
    'LZ',           # velocity change over the step per 2 h [m/s^2]
    'LR',           # right-hand side r = A z + f of the step just solved [N]
    'LC',           # Thomas algorithm: upper factor
    'LW',           # Thomas algorithm: inverse pivots [1/kg]
    'LS',           # the set before the pivoting (2 held, else WORK.RELDIR)
    # caches of the fixed-step path (bench: per-vehicle-step cost of real trains)
    'YKEY',         # y [m] of coupler j at which the rows F, DFDY, KK were evaluated
    'VKEY',         # its ydot [m/s]; column N-1: the g h [s] the weights KK were made for
    'XKEY',         # COACH.X [m] at which RSTAT and GR1 were computed (NaN: none yet)
    'FBPREV',       # WORK.FB of the last step, when it held every vehicle (FLAG.STEADY)
    'TEPREV',       # WORK.TEFF of that step
    # the in-train force envelope (issue 14): extremes over every accepted step since reset
    'FHI',          # largest tension of coupler j [N] (>= 0; N-1 used)
    'FLO',          # largest compression of coupler j, as a force [N] (<= 0)
])
WORK = _indices(WorkRows)
