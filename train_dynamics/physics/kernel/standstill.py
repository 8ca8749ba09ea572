"""
Standstill: the brakes' holding of the vehicles at rest as a linear complementarity problem.

A vehicle at rest at the step's start (WORK.VSTART = 0) is either held (its velocity stays
0, the holding force H [N, positive retarding] is whatever the stage equations require, and
|H| <= Fb, the braking force plus static resistance WORK.FB) or slides in a direction d =
+-1 with the friction d Fb against it, and then it must end the step moving in direction d.
Within a ROS2 step the stage equations are linear in the velocity stages, so the forces of
the vehicles at rest enter as unknowns with box bounds |f_i| <= Fb_i, complementary to the
vehicles' motion: a box-constrained LCP on the tridiagonal stage matrix A = M + g h C_c +
(g h)^2 K_c (symmetric positive definite, so the LCP has one solution).

The LCP is posed on the step that was just solved (:func:`effective_rhs`): with z the
velocity change over the step per 2 h (an acceleration [m/s^2]) and r = A z + f built from
that step's result, A z = r - f reproduces the step exactly for its own set of held and
sliding vehicles, and A (the stage matrix) gives how z and the holding forces respond when
the set changes. Block principal pivoting (:func:`pivot`, Judice and Pires 1994) finds the
set where every vehicle at rest is consistent, in a few tridiagonal solves (no coupler
evaluation), with Murty's single pivot when the block pivots stop reducing the number of
inconsistent vehicles (that rule ends for positive definite A); a cap bounds the work.
The full step is then solved once more with that set (active_set.active_set_step).
"""
from __future__ import annotations

from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import (TOTAL, WORK)

#: [m/s] a braked vehicle slower than this is at rest (1 micrometre per second): without it
#: a vehicle whose coupler force exactly balances its sliding brake could creep for ever
V_REST = 1e-6

#: relative margin on the brake's limit: a holding force up to Fb (1 + HOLD_MARGIN) holds
HOLD_MARGIN = 1e-12
#: block pivots without fewer inconsistent vehicles before the single (Murty) pivots
STALL_PIVOTS = 3


@jit(inline=True)
def inconsistent(held, ws, flip):
    """
    Return how many held vehicles the brake cannot hold; release them if ``flip``.

    Held with |WORK.HOLD| > WORK.FB (1 + HOLD_MARGIN): released, it slides in the
    direction d = sign(HOLD) (WORK.RELDIR), braked against it.
    """
    hold = ws[WORK.HOLD]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    count = 0
    for i in range(held.shape[0]):
        if held[i] and abs(hold[i]) > fb[i] * (1.0 + HOLD_MARGIN):
            count += 1
            if flip:
                held[i] = False
                rel_dir[i] = 1.0 if hold[i] > 0.0 else -1.0
    return count


@jit(inline=True)
def stick(held, masses, ws, sc):
    """
    Stop the vehicles released from rest that end the step moving against their friction.

    Such a vehicle (VSTART = 0, RELDIR d, d WORK.VNEW < 0, or braked and slower than V_REST,
    as a moving one stops in active_set._stops) slid and stuck within the step:
    it ends at rest (VNEW = 0) and held, its friction over the step stays the sliding one
    (WORK.HOLD = SIGNED, booked as before); the impulse -m v' [N s] goes to TOTAL.PEXT
    (``sc``). Return the kinetic energy m v'^2 / 2 [J] the brakes took.
    """
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    rel_dir = ws[WORK.RELDIR]
    hold = ws[WORK.HOLD]
    signed = ws[WORK.SIGNED]
    fb = ws[WORK.FB]
    work = 0.0
    for i in range(held.shape[0]):
        if held[i] or v_start[i] != 0.0 or rel_dir[i] == 0.0:
            continue
        if rel_dir[i] * v_new[i] < 0.0 or (fb[i] > 0.0 and abs(v_new[i]) < V_REST):
            vi = v_new[i]
            work += 0.5 * masses[i] * vi * vi
            sc[TOTAL.PEXT] -= masses[i] * vi
            v_new[i] = 0.0
            held[i] = True
            hold[i] = signed[i]
    return work


@jit(inline=True)
def effective_rhs(h, held, ws):
    """
    Write the LCP's right-hand side r = A z + f [N] of the step just solved to WORK.LR.

    z = (WORK.VNEW - VSTART) / (2 h) [m/s^2] (0 on held rows; WORK.LZ), f = WORK.HOLD on
    held vehicles and WORK.SIGNED on the others; A from WORK.DIAG, KK (free rows).
    """
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    diag = ws[WORK.DIAG]
    kk = ws[WORK.KK]
    hold = ws[WORK.HOLD]
    signed = ws[WORK.SIGNED]
    z = ws[WORK.LZ]
    r = ws[WORK.LR]
    n = held.shape[0]
    s = 0.5 / h
    for i in range(n):
        z[i] = 0.0 if held[i] else (v_new[i] - v_start[i]) * s
    for i in range(n):
        a = diag[i] * z[i]
        if i > 0:
            a -= kk[i - 1] * z[i - 1]
        if i < n - 1:
            a -= kk[i] * z[i + 1]
        r[i] = a + (hold[i] if held[i] else signed[i])


@jit(inline=True)
def _solve_set(held, ws):
    """
    Solve A z = r - f for the set in ``held``, WORK.RELDIR (tridiagonal, Thomas) into LZ.

    Held rows: z_i = 0. Sliding from rest: f_i = RELDIR Fb; moving: f_i = WORK.SIGNED.
    """
    diag = ws[WORK.DIAG]
    kk = ws[WORK.KK]
    r = ws[WORK.LR]
    fb = ws[WORK.FB]
    signed = ws[WORK.SIGNED]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    z = ws[WORK.LZ]
    c = ws[WORK.LC]
    w = ws[WORK.LW]
    n = held.shape[0]
    for i in range(n):
        if held[i]:
            d = 1.0
            ri = 0.0
        else:
            d = diag[i]
            f = rel_dir[i] * fb[i] if v_start[i] == 0.0 else signed[i]
            ri = r[i] - f
        if i == 0:
            w[0] = 1.0 / d
            z[0] = ri * w[0]
        else:
            up = 0.0 if held[i - 1] else -kk[i - 1]
            lo = 0.0 if held[i] else -kk[i - 1]
            c[i - 1] = up * w[i - 1]
            w[i] = 1.0 / (d - lo * c[i - 1])
            z[i] = (ri - lo * z[i - 1]) * w[i]
    for i in range(n - 2, -1, -1):
        z[i] -= c[i] * z[i + 1]


@jit(inline=True)
def _pivot_once(h, held, ws, single):
    """
    Check the set against the solution in WORK.LZ; flip the inconsistent vehicles at rest.

    All of them (block pivot), or only the last one (``single``: Murty's rule). A released
    vehicle that would slide slower than V_REST over the step (2 h |z|, h [s]) is at rest:
    held for good in this LCP (WORK.LS = 3). Return how many were inconsistent.
    """
    kk = ws[WORK.KK]
    r = ws[WORK.LR]
    fb = ws[WORK.FB]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    z = ws[WORK.LZ]
    entry = ws[WORK.LS]
    n = held.shape[0]
    count = 0
    last = -1
    for i in range(n):
        if v_start[i] != 0.0 or entry[i] != 2.0:     # moving, or released earlier: fixed
            continue
        bad = False
        if held[i]:
            hf = r[i]
            if i > 0:
                hf += kk[i - 1] * z[i - 1]
            if i < n - 1:
                hf += kk[i] * z[i + 1]
            if abs(hf) > fb[i] * (1.0 + HOLD_MARGIN):
                bad = True
                if not single:
                    held[i] = False
                    rel_dir[i] = 1.0 if hf > 0.0 else -1.0
        elif rel_dir[i] * z[i] < 0.0:
            bad = True
            if not single:
                held[i] = True
                rel_dir[i] = 0.0
        elif 2.0 * h * abs(z[i]) < V_REST and fb[i] > 0.0:
            held[i] = True      # creeps: at rest, not to be released again
            rel_dir[i] = 0.0
            entry[i] = 3.0
            count += 1
            continue
        if bad:
            count += 1
            last = i
    if single and last >= 0:
        if held[last]:
            hf = r[last]
            if last > 0:
                hf += kk[last - 1] * z[last - 1]
            if last < n - 1:
                hf += kk[last] * z[last + 1]
            held[last] = False
            rel_dir[last] = 1.0 if hf > 0.0 else -1.0
        else:
            held[last] = True
            rel_dir[last] = 0.0
    return count


@jit(inline=True)
def pivot(h, held, ws, max_pivots):
    """
    Find the consistent set of the LCP on WORK.LR by block principal pivoting; in place.

    Starts from the set in ``held``, WORK.RELDIR and WORK.LS (the set the step of h [s] was
    solved with: 2 held, else RELDIR): only the vehicles held there take part, the ones
    released before in the step keep sliding (so the step's set only ever releases, and its
    solves end). At most ``max_pivots`` tridiagonal solves. Return the number of solves, negative
    when the cap stopped it unsolved.
    """
    best = held.shape[0] + 1
    stall = 0
    for k in range(max_pivots):
        _solve_set(held, ws)
        count = _pivot_once(h, held, ws, stall >= STALL_PIVOTS)
        if count == 0:
            return k + 1
        if count < best:
            best = count
            stall = 0
        else:
            stall += 1
    return -max_pivots
