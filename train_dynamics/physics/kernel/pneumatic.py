"""
Pneumatic brake, compiled: pipe flow, relay valve and distributors on packed arrays.

The model (finite-volume brake pipe, orifice law, driver's brake valve, UIC distributors) is
described in :mod:`train_dynamics.physics.pneumatic`, which packs the arrays these functions
advance: cells (``C_*`` rows, one column per pipe cell), faces (``F_*``), vehicles (``V_*``),
scalars (``S_*``) and integers (``I_*``). All inside pressures are absolute [Pa], air masses
[kg].
"""
from __future__ import annotations

import math

from train_dynamics.physics.kernel.compiler import jit


#: specific gas constant of air [J/(kg K)]
R_AIR = 287.05


#: nozzle law for air (kappa = 1.4): critical pressure ratio and the choked flow function
R_CRIT = 0.5283


PSI_CHOKED = 0.6847


# Rows of the cell array, the face array and the vehicle array; slots of the scalars.
C_M, C_VOL, C_LEAK = range(3)


N_CELL_ROWS = 3


F_W, F_OPEN, F_LEN, F_K = range(4)


N_FACE_ROWS = 4


(V_MCR, V_MAUX, V_MCYL, V_MQS, V_APPLIED, V_VCR, V_VAUX, V_VCYL, V_VQS, V_PMAX, V_AAPP,
 V_AREL, V_CELL, V_PEXT, V_ACC, V_ACCOPEN, V_RATE, V_PPREV, V_INSHOT, V_REMOTE, V_RCMD,
 V_RLAP, V_VALVE, V_VSTROKE, V_PSPRING) = range(25)


N_VEH_ROWS = 25


#: V_VALVE: what the cylinder's valve did in the last step (distributor relay part, EP valves
#: or car control device): filling it, lapped (holding), venting it
VALVE_FILL, VALVE_LAP, VALVE_VENT = 1.0, 0.0, -1.0


(S_H, S_RT, S_AREA, S_DIAM, S_MU, S_PATM, S_CMD, S_PMR, S_ACHG, S_AVENT, S_AEM, S_BAND,
 S_EMTH, S_GCR, S_APPTH, S_RELTH, S_SPAN, S_AAUX, S_AQS, S_LAP, S_DBAND, S_ACCRATE, S_ACCAREA,
 S_ACCCLOSE, S_ACCTAU, S_EPCMD, S_EPAPP, S_EPREL, S_ECPPIPE, S_AINSHOT, S_ACCDROP) = range(31)


N_SCALARS = 31


I_SUB, I_EXTERNAL, I_LAP, I_SYSTEM, I_LINE = range(5)


N_INT = 5


#: brake systems (I_SYSTEM): UIC distributors only, EP valves added, ECP car control devices
SYS_PNEUMATIC, SYS_EP, SYS_ECP = range(3)


@jit
def orifice_flow(p_up: float, p_dn: float, area: float, rt: float) -> float:
    """Mass flow [kg/s] through an orifice of effective area [m^2], p_up >= p_dn absolute."""
    if p_up <= p_dn or area <= 0.0:
        return 0.0
    r = p_dn / p_up
    if r <= R_CRIT:
        psi = PSI_CHOKED
    else:
        psi = math.sqrt(7.0 * (r ** (2.0 / 1.4) - r ** (2.4 / 1.4)))
    return area * p_up * psi / math.sqrt(rt)


@jit
def _exchange(p1, v1, p2, v2, area, h, rt):
    """Mass [kg] moving from volume 1 to 2 in h (negative: 2 to 1), never past equality."""
    if p1 >= p2:
        dm = orifice_flow(p1, p2, area, rt) * h
        eq = (p1 - p2) / (rt * (1.0 / v1 + 1.0 / v2))
        return min(dm, eq)
    dm = orifice_flow(p2, p1, area, rt) * h
    eq = (p2 - p1) / (rt * (1.0 / v1 + 1.0 / v2))
    return -min(dm, eq)


@jit
def cylinder_pressure(m, v0, vs, ps, patm, rt):
    """
    Absolute pressure [Pa] of a brake cylinder holding air mass ``m`` [kg].

    Dead volume ``v0`` [m^3] (piston released), stroke volume ``vs`` [m^3] (pistons' area x
    stroke), return spring holding the piston in up to ``ps`` [Pa gauge] (spring force /
    piston area). Isothermal p V = m R T over three ranges of m: below the spring pressure the
    piston rests (V = v0); at it the piston travels out at constant pressure patm + ps (the
    volume grows with m: V = m R T / (patm + ps)); at full stroke V = v0 + vs. With vs = 0 it
    is m R T / v0 throughout.
    """
    m1 = (patm + ps) * v0 / rt
    if m <= m1:
        return m * rt / v0
    if m < (patm + ps) * (v0 + vs) / rt:
        return patm + ps
    return m * rt / (v0 + vs)


@jit
def _cylinder_volume(p, v0, vs, ps, patm):
    """Volume [m^3] of the cylinder at absolute pressure p: v0 below the spring, then full."""
    if p < patm + ps:
        return v0
    return v0 + vs


@jit
def _cylinder_mass_to(target, p, m, v0, vs, ps, patm, rt):
    """
    Mass [kg] to add (negative: remove) for the cylinder at p (mass m) to reach ``target``.

    The inverse of :func:`cylinder_pressure`; a fixed volume (vs = 0): (target - p) v0 / (R T).
    """
    if vs == 0.0:
        return (target - p) * v0 / rt
    if target < patm + ps:
        return target * v0 / rt - m
    return target * (v0 + vs) / rt - m


@jit
def _pipe_transport(cells, faces, sc, h):
    """One forward-backward Euler step of the pipe flow (module docstring)."""
    nc = cells.shape[1]
    rt = sc[S_RT]
    area = sc[S_AREA]
    diam = sc[S_DIAM]
    mu = sc[S_MU]
    m = cells[C_M]
    vol = cells[C_VOL]
    w = faces[F_W]
    for j in range(1, nc):
        if faces[F_OPEN, j] == 0.0:
            w[j] = 0.0
            continue
        rho_l = m[j - 1] / vol[j - 1]
        rho_r = m[j] / vol[j]
        rho = 0.5 * (rho_l + rho_r)
        dx = faces[F_LEN, j]
        aw = abs(w[j])
        re = aw * diam / (area * mu)
        # resistance r [1/s] in dw/dt = ... - r w
        r_lam = 32.0 * mu / (rho * diam * diam)
        r = r_lam
        if re > 1.0:
            f_turb = 0.3164 * re ** -0.25
            r_turb = f_turb * aw / (2.0 * rho * area * diam)
            if r_turb > r:
                r = r_turb
        r += faces[F_K, j] * aw / (2.0 * rho * area * dx)
        drive = area * (rho_l - rho_r) * rt / dx
        w[j] = (w[j] + h * drive) / (1.0 + h * r)
    for j in range(nc):
        m[j] += h * (w[j] - w[j + 1])


@jit
def _relay_valve(cells, c, cmd, sc, h):
    """
    Regulate pipe cell c to ``cmd`` [Pa gauge] with a brake valve (module docstring).

    The driver's at the head, or a remote locomotive's.
    """
    rt = sc[S_RT]
    patm = sc[S_PATM]
    vol = cells[C_VOL, c]
    p = cells[C_M, c] * rt / vol
    if cmd < sc[S_EMTH]:
        # open to atmosphere (both ways: the column's inertia may overshoot below it)
        cells[C_M, c] -= _exchange(p, vol, patm, 1.0e9, sc[S_AEM], h, rt)
        return
    target = cmd + patm
    err = target - p
    if err > 0.0:
        s = min(err / sc[S_BAND], 1.0)
        dm = min(orifice_flow(sc[S_PMR] + patm, p, sc[S_ACHG] * s, rt) * h, err * vol / rt)
        cells[C_M, c] += dm
    elif err < 0.0:
        s = min(-err / sc[S_BAND], 1.0)
        dm = min(orifice_flow(p, patm, sc[S_AVENT] * s, rt) * h, -err * vol / rt)
        cells[C_M, c] -= dm


@jit
def _accelerator(veh, sc, i, p_l, v_l, p_cr, h):
    """
    Vent the pipe at vehicle i through its emergency accelerator.

    The local pipe (p_l, volume v_l) falling faster than
    S_ACCRATE [Pa/s] (its rate low-pass filtered, time constant S_ACCTAU) while more than
    S_ACCDROP below the control reservoir p_cr (deeper than any service application) opens
    a vent of S_ACCAREA to atmosphere; it stays open until the local pipe is below
    S_ACCCLOSE (gauge), then closes and re-arms. Returns the pipe mass vented [kg] in h.
    """
    rt = sc[S_RT]
    patm = sc[S_PATM]
    rate = (p_l - veh[V_PPREV, i]) / h
    veh[V_PPREV, i] = p_l
    veh[V_RATE, i] += (rate - veh[V_RATE, i]) * min(h / sc[S_ACCTAU], 1.0)
    if veh[V_ACC, i] < 0.5:
        return 0.0
    if veh[V_ACCOPEN, i] < 0.5:
        if (veh[V_RATE, i] < -sc[S_ACCRATE] and p_cr - p_l > sc[S_ACCDROP]
                and p_l - patm > sc[S_ACCCLOSE]):
            veh[V_ACCOPEN, i] = 1.0
        else:
            return 0.0
    if p_l - patm < sc[S_ACCCLOSE]:
        veh[V_ACCOPEN, i] = 0.0
        return 0.0
    dm = orifice_flow(p_l, patm, sc[S_ACCAREA], rt) * h
    return min(dm, (p_l - patm) * v_l / rt)


@jit
def _distributors(cells, veh, sc, iv, external, h):
    """
    Advance every vehicle's distributor, accelerator, reservoirs and cylinder one step.

    ECP cars: the car control device instead of the distributor.
    """
    rt = sc[S_RT]
    patm = sc[S_PATM]
    system = iv[I_SYSTEM]
    line = iv[I_LINE] != 0
    ep_frac = min(max(sc[S_EPCMD], 0.0), 1.0)
    for i in range(veh.shape[1]):
        c = int(veh[V_CELL, i])
        if external:
            p_l = veh[V_PEXT, i] + patm
            v_l = 1.0e9
        else:
            v_l = cells[C_VOL, c]
            p_l = cells[C_M, c] * rt / v_l
        v_cr = veh[V_VCR, i]
        v_aux = veh[V_VAUX, i]
        v0 = veh[V_VCYL, i]
        vs = veh[V_VSTROKE, i]
        ps = veh[V_PSPRING, i]
        m_cyl = veh[V_MCYL, i]
        p_cr = veh[V_MCR, i] * rt / v_cr
        p_aux = veh[V_MAUX, i] * rt / v_aux
        p_cyl = cylinder_pressure(m_cyl, v0, vs, ps, patm, rt)
        v_cyl = _cylinder_volume(p_cyl, v0, vs, ps, patm)
        veh[V_VALVE, i] = VALVE_LAP
        dm_pipe = 0.0
        if not external:
            dm_pipe -= _accelerator(veh, sc, i, p_l, v_l, p_cr, h)
        a_app = veh[V_AAPP, i]
        a_rel = veh[V_AREL, i]
        if system == SYS_ECP:
            # car control device: the cylinder follows the head-end unit's command; a lost
            # train line or a pipe below S_ECPPIPE (gauge) is a penalty: full application
            if line and p_l - patm >= sc[S_ECPPIPE]:
                target = patm + veh[V_PMAX, i] * ep_frac
            else:
                target = patm + veh[V_PMAX, i]
            veh[V_APPLIED, i] = 1.0 if target > patm else 0.0
            if p_l > p_aux:
                dm = _exchange(p_l, v_l, p_aux, v_aux, sc[S_AAUX], h, rt)
                veh[V_MAUX, i] += dm
                dm_pipe -= dm
                p_aux += dm * rt / v_aux
            err = target - p_cyl
            if err > sc[S_LAP]:
                if p_aux > p_cyl:
                    s = min(err / sc[S_DBAND], 1.0)
                    dm = _exchange(p_aux, v_aux, p_cyl, v_cyl, s * sc[S_EPAPP], h, rt)
                    dm = min(dm, _cylinder_mass_to(target, p_cyl, m_cyl, v0, vs, ps, patm, rt))
                    veh[V_MAUX, i] -= dm
                    veh[V_MCYL, i] += dm
                    veh[V_VALVE, i] = VALVE_FILL
            elif err < -sc[S_LAP]:
                s = min(-err / sc[S_DBAND], 1.0)
                dm = orifice_flow(p_cyl, patm, s * sc[S_EPREL], rt) * h
                dm = min(dm, -_cylinder_mass_to(target, p_cyl, m_cyl, v0, vs, ps, patm, rt))
                veh[V_MCYL, i] -= dm
                veh[V_VALVE, i] = VALVE_VENT
            if not external:
                cells[C_M, c] += dm_pipe
            continue
        gap = p_cr - p_l
        applied = veh[V_APPLIED, i] > 0.5
        if not applied and gap > sc[S_APPTH]:
            applied = True
        elif applied and gap < sc[S_RELTH]:
            applied = False
            veh[V_MQS, i] = patm * veh[V_VQS, i] / rt     # quick-service bulb vented
        veh[V_APPLIED, i] = 1.0 if applied else 0.0
        if not applied:
            # CR follows the pipe through its nozzle (linear, time constant 1/g)
            dm = sc[S_GCR] * h * (p_l - p_cr) * v_cr / rt
            eq = (p_l - p_cr) / (rt * (1.0 / v_l + 1.0 / v_cr))
            dm = min(dm, eq) if dm > 0.0 else max(dm, eq)
            veh[V_MCR, i] += dm
            dm_pipe -= dm
            target = patm
        else:
            # quick-service bulb fills from the pipe (first stage)
            v_qs = veh[V_VQS, i]
            p_qs = veh[V_MQS, i] * rt / v_qs
            if p_l > p_qs:
                dm = _exchange(p_l, v_l, p_qs, v_qs, sc[S_AQS], h, rt)
                veh[V_MQS, i] += dm
                dm_pipe -= dm
            frac = min(gap / sc[S_SPAN], 1.0)
            target = patm + veh[V_PMAX, i] * frac
        # AR charges from the pipe through its check valve
        if p_l > p_aux:
            dm = _exchange(p_l, v_l, p_aux, v_aux, sc[S_AAUX], h, rt)
            veh[V_MAUX, i] += dm
            dm_pipe -= dm
            p_aux += dm * rt / v_aux
        # EP valves (train line healthy): the cylinder holds at least the commanded
        # fraction of p_max, filled and vented through the EP valves
        by_ep = False
        if system == SYS_EP and line:
            a_rel = sc[S_EPREL]
            ep_target = patm + veh[V_PMAX, i] * ep_frac
            if ep_target > target:
                target = ep_target
                a_app = sc[S_EPAPP]
                by_ep = True
        # relay part: fill BC from AR, or vent BC, toward the target
        # (valve openings in proportion to the error, full at S_DBAND); first stage
        # (inshot): below V_INSHOT (gauge) an applied distributor also fills through S_AINSHOT
        err = target - p_cyl
        if err > sc[S_LAP]:
            if p_aux > p_cyl:
                s = min(err / sc[S_DBAND], 1.0)
                area = s * a_app
                if applied and p_cyl - patm < veh[V_INSHOT, i]:
                    area += sc[S_AINSHOT]
                dm = _exchange(p_aux, v_aux, p_cyl, v_cyl, area, h, rt)
                dm = min(dm, _cylinder_mass_to(target, p_cyl, m_cyl, v0, vs, ps, patm, rt))
                veh[V_MAUX, i] -= dm
                veh[V_MCYL, i] += dm
                veh[V_VALVE, i] = VALVE_FILL
        elif err < -sc[S_LAP] or (not applied and not by_ep and p_cyl > patm):
            s = min(-err / sc[S_DBAND], 1.0)
            if not applied and not by_ep:
                s = 1.0
            dm = orifice_flow(p_cyl, patm, s * a_rel, rt) * h
            dm = min(dm, -_cylinder_mass_to(target, p_cyl, m_cyl, v0, vs, ps, patm, rt))
            veh[V_MCYL, i] -= dm
            if dm > 0.0:
                veh[V_VALVE, i] = VALVE_VENT
        if not external:
            cells[C_M, c] += dm_pipe


@jit
def advance(n_steps, cells, faces, veh, sc, iv, trace):
    """
    Advance the brake system ``n_steps`` steps of sc[S_H] seconds, in place.

    cells (3, n_cells), faces (4, n_cells + 1), veh (N_VEH_ROWS, N): the layouts C_*, F_*, V_*;
    sc, iv: scalars S_*, I_*. ``trace`` (n_steps, N) or (0, N): when it has rows, row k
    receives each vehicle's cylinder pressure, gauge [Pa], at the end of step k.
    """
    h = sc[S_H]
    nsub = iv[I_SUB]
    hs = h / nsub
    external = iv[I_EXTERNAL] != 0
    rt = sc[S_RT]
    patm = sc[S_PATM]
    m = cells[C_M]
    vol = cells[C_VOL]
    leak = cells[C_LEAK]
    record = trace.shape[0] > 0
    for k in range(n_steps):
        if not external:
            for _ in range(nsub):
                _pipe_transport(cells, faces, sc, hs)
            for j in range(m.shape[0]):
                if leak[j] > 0.0:
                    m_atm = patm * vol[j] / rt
                    m[j] = m_atm + (m[j] - m_atm) / (1.0 + h * leak[j])
            if iv[I_LAP] == 0:
                _relay_valve(cells, 0, sc[S_CMD], sc, h)
            for i in range(veh.shape[1]):
                if veh[V_REMOTE, i] > 0.5 and veh[V_RLAP, i] < 0.5:
                    _relay_valve(cells, int(veh[V_CELL, i]), veh[V_RCMD, i], sc, h)
        _distributors(cells, veh, sc, iv, external, h)
        if record:
            for i in range(veh.shape[1]):
                trace[k, i] = cylinder_pressure(veh[V_MCYL, i], veh[V_VCYL, i],
                                                veh[V_VSTROKE, i], veh[V_PSPRING, i], patm,
                                                rt) - patm
