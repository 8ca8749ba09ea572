"""
The active set of held vehicles: which vehicles the brake holds at rest over the step.

Braking is friction: a coach at rest stays at rest while the braking force can hold it
(|net coupler force| <= Fb), and the brake never pushes a coach backwards. The step treats
resting coaches as held (their rows fixed at zero velocity) and finds the set of held
coaches by a short, capped active-set iteration: a moving coach whose velocity would change
sign is stopped; then the coaches at rest whose required holding force exceeds the
available braking force make the holding a box-constrained LCP on the stage matrix
(:mod:`.standstill`), whose set the step is solved with once more; a
coach released from rest that ends the step moving against its brake sticks. Momentum
bookkeeping is exact: the held coaches' brake force is the one that the stage equations
require.
"""
from __future__ import annotations

from train_dynamics.physics.kernel import standstill
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.coupler_rows import eval_couplers, raise_blocked_slopes
from train_dynamics.physics.kernel.layout import COUNT, OPTION, PARAM, STATE, TOTAL, VEHICLE, WORK
from train_dynamics.physics.kernel.rosenbrock2 import GAMMA, ros2_step

#: chain solves per step at most: the first, then after stops or a new holding set
HOLD_SOLVES = 6
#: tridiagonal solves of one holding LCP at most (standstill.pivot)
HOLD_PIVOTS = 12
#: solves of one chain solve at most with blocked slopes added (coupler_rows.raise_blocked_slopes)
BLOCK_SOLVES = 8

#: [m/s] a braked coach slower than this is at rest (standstill.V_REST)
V_REST = standstill.V_REST


@jit
def _stops(v0, v1, fb):
    """
    Tell whether a moving coach stops within the step.

    Its velocity v0 -> v1 [m/s] changes sign, or a braked coach (fb [N] > 0) ends the step
    slower than V_REST.
    """
    if v0 == 0.0:
        return False
    if v0 * v1 <= 0.0:
        return True
    return fb > 0.0 and abs(v1) < V_REST


@jit(inline=True)
def _signed_brake(ws):
    """
    Sign the braking force over the step against each coach's motion [N] (WORK.SIGNED).

    From WORK.FB, positive retarding; a coach released from rest at this step
    (WORK.VSTART = 0) is braked against the direction WORK.RELDIR it slides in.
    """
    v_start = ws[WORK.VSTART]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    signed = ws[WORK.SIGNED]
    for i in range(v_start.shape[0]):
        if v_start[i] > 0.0:
            signed[i] = fb[i]
        elif v_start[i] < 0.0:
            signed[i] = -fb[i]
        else:
            signed[i] = rel_dir[i] * fb[i]


@jit(inline=True)
def _hold_stopping(held, masses, ws, extra_work, sc):
    """
    Hold the moving coaches that stop within the step from the step's start.

    Their kinetic energy m v^2 / 2 [J] goes to the brakes' work: return (whether any
    stopped, ``extra_work`` plus that energy); their momentum m v [N s] is taken off the
    external impulse (TOTAL.PEXT, ``sc``). Each is marked (WORK.STOPPED = 1, its speed in
    WORK.VSTOP) for :func:`_undo_stops`; a coach whose stop was undone in this step
    (STOPPED = -1) is not stopped again.
    """
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    stopped = ws[WORK.STOPPED]
    v_stop = ws[WORK.VSTOP]
    changed = False
    for i in range(held.shape[0]):
        if (not held[i]) and rel_dir[i] == 0.0 and stopped[i] == 0.0 and _stops(
                v_start[i], v_new[i], fb[i]):
            held[i] = True
            extra_work += 0.5 * masses[i] * v_start[i] * v_start[i]
            sc[TOTAL.PEXT] -= masses[i] * v_start[i]
            stopped[i] = 1.0
            v_stop[i] = v_start[i]
            v_start[i] = 0.0
            changed = True
    return changed, extra_work


@jit(inline=True)
def _undo_stops(h, held, masses, ws, extra_work, sc):
    """
    Undo the stops of the coaches that their friction cannot hold; return (any, work [J]).

    Stopping a coach at the step's start (:func:`_hold_stopping`) gives its momentum m v
    [N s] to its brake: right when the friction stops it and then holds it, |WORK.HOLD| <=
    WORK.FB (Coulomb friction can stop a motion, never reverse it). A coach held over that
    limit whose momentum is more than its friction gives over the step, m |v| > Fb h (h
    [s]), is reversed by its couplers (a stiff impact of buffers or blocked draw gear
    reverses a coach within a step): it keeps its speed (WORK.VSTOP back in VSTART, the
    momentum and energy booked back) and moves through the step braked against its
    starting motion, as a free coach whose speed changes sign within a step; STOPPED = -1.
    Released from rest instead, as the holding LCP releases the others (a coach that
    creeps against its brake, whose momentum the brake can take), the momentum would be
    lost: 96 % of a 20-wagon train's within 5 s at a blocked stiffness of 1e12 N/m.
    """
    v_start = ws[WORK.VSTART]
    hold = ws[WORK.HOLD]
    fb = ws[WORK.FB]
    stopped = ws[WORK.STOPPED]
    v_stop = ws[WORK.VSTOP]
    changed = False
    for i in range(held.shape[0]):
        vi = v_stop[i]
        if (stopped[i] == 1.0 and held[i] and masses[i] * abs(vi) > fb[i] * h
                and abs(hold[i]) > fb[i] * (1.0 + standstill.HOLD_MARGIN)):
            held[i] = False
            v_start[i] = vi
            extra_work -= 0.5 * masses[i] * vi * vi
            sc[TOTAL.PEXT] += masses[i] * vi
            stopped[i] = -1.0
            changed = True
    return changed, extra_work


@jit(inline=True)
def _stopping(held, ws):
    """Return how many moving coaches stop within the step (:func:`_hold_stopping` would)."""
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    stopped = ws[WORK.STOPPED]
    count = 0
    for i in range(held.shape[0]):
        if (not held[i]) and rel_dir[i] == 0.0 and stopped[i] == 0.0 and _stops(
                v_start[i], v_new[i], fb[i]):
            count += 1
    return count


@jit(inline=True)
def _settle(h, held, ws):
    """
    Make the set of the coaches at rest consistent with the step just solved; return changed.

    Nothing to do when every held coach is within its brake
    (:func:`standstill.inconsistent`). Else the holding LCP
    on the step (:func:`standstill.effective_rhs`, :func:`standstill.pivot`, at most
    HOLD_PIVOTS tridiagonal solves) gives the next set. Should it end where it began, the
    coaches over their brake's limit would creep slower than V_REST: at rest (no change),
    or, when the pivoting hit its cap, they are released.
    """
    if standstill.inconsistent(held, ws, False) == 0:
        return False
    rel_dir = ws[WORK.RELDIR]
    before = ws[WORK.LS]
    for i in range(held.shape[0]):
        before[i] = 2.0 if held[i] else rel_dir[i]
    standstill.effective_rhs(h, held, ws)
    solved = standstill.pivot(h, held, ws, HOLD_PIVOTS) > 0
    for i in range(held.shape[0]):
        if (before[i] >= 2.0) != held[i] or (before[i] < 2.0 and before[i] != rel_dir[i]):
            return True
    if solved:      # the held coaches over their limit would creep slower than V_REST
        return False
    standstill.inconsistent(held, ws, True)
    return True


@jit(inline=True)
def _blocked_solve(h, coach, cpl, model, u, held, ws, iv, gprof):
    """
    Do :func:`~.rosenbrock2.ros2_step` with the blocked slope of every coupler the step blocks.

    A step that drives couplers into their blocks without their blocked stiffness in the
    stage matrix is solved again with it (:func:`raise_blocked_slopes`), at most
    BLOCK_SOLVES times; the extra solves are counted (COUNT.BLOCK_SOLVES).
    """
    masses = coach[VEHICLE.MASS]
    for k in range(BLOCK_SOLVES + 1):
        ros2_step(h, coach, cpl, model, u, held, ws, iv[OPTION.EXT], iv[OPTION.TRACK], gprof)
        if k == BLOCK_SOLVES:
            break
        if raise_blocked_slopes(h, coach[STATE.X], ws[WORK.VSTART], masses, cpl, ws) == 0:
            break
        iv[COUNT.BLOCK_SOLVES] += 1


@jit
def active_set_step(h, coach, cpl, sc, iv, held, ws, gprof):
    """
    Do one ROS2 step of the chain with the active set of held coaches; return work [J].

    Starts from the coaches held at the end of the last step (STATE.HELD) and solves the
    step (at most HOLD_SOLVES times): first the moving coaches whose velocity would change
    sign stop at the step's start (:func:`_hold_stopping`, the couplers then re-evaluated),
    else the coaches at rest take the holding LCP's set (:func:`_settle`). A step that ends
    at the cap with coaches still to stop or over their brake's limit is counted
    (COUNT.HOLD_CAPPED), the extra solves in COUNT.HOLD_SOLVES. Coaches released from
    rest that end the step moving against their friction stick (:func:`standstill.stick`).
    WORK.FB is the braking force over the step [N]. The returned work is the kinetic energy
    of the coaches stopped at the step's start or stuck at its end. The new state and the
    holding forces are left in WORK.XNEW, VNEW, HOLD.
    """
    n = held.shape[0]
    u = sc[PARAM.U]
    model = iv[OPTION.MODEL]
    x = coach[STATE.X]
    v = coach[STATE.V]
    was_held = coach[STATE.HELD]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    stopped = ws[WORK.STOPPED]
    for i in range(n):
        held[i] = was_held[i] > 0.5
        rel_dir[i] = 0.0
        v_start[i] = v[i]
        stopped[i] = 0.0
    extra_work = 0.0
    stale = False
    for it in range(HOLD_SOLVES):
        if stale:   # stopped coaches changed some starting velocities
            eval_couplers(x, v_start, cpl, model, u, GAMMA * h, ws)
            stale = False
        _signed_brake(ws)
        _blocked_solve(h, coach, cpl, model, u, held, ws, iv, gprof)
        if it == HOLD_SOLVES - 1:
            if _stopping(held, ws) + standstill.inconsistent(held, ws, False) > 0:
                iv[COUNT.HOLD_CAPPED] += 1
            break
        stale, extra_work = _undo_stops(h, held, coach[VEHICLE.MASS], ws, extra_work, sc)
        if not stale:
            stale, extra_work = _hold_stopping(held, coach[VEHICLE.MASS], ws, extra_work, sc)
        if not (stale or _settle(h, held, ws)):
            break
        iv[COUNT.HOLD_SOLVES] += 1
    return extra_work + standstill.stick(held, coach[VEHICLE.MASS], ws, sc)
