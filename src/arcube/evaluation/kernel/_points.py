"""The per-point pass of one design: TLS, RTS and TMS inverse kinematics, the seven condition
numbers, the local guards, the IK domain excess (model §3-8, 12.2) and each point's guard grade
(model §16), in the reference's order.

Long module: one scalarized pass per point (IK, guards, clearances, the envelope of 19.5, the tip metrics' hand-off)
that Numba compiles as one unit; splitting its loop would hand what it carries from point to point (the RTS of the
last direction, the clearance caps, bounds and flags) between functions."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from arcube.evaluation.clearance import ARC_CHORDS
from arcube.model.body import N_SEGMENTS, N_SPHERES, PRIMITIVE_PART
from arcube.evaluation.kernel._layout import GRADE_CLEARANCE, GRADE_ENVELOPE, GRADE_RHO, GRADE_SINE, GRADE_Z_DYAD
from arcube.evaluation.kernel._layout import (
    CODE_ENVELOPE,
    CODE_KAPPA,
    CODE_PATIENT,
    CODE_RHO,
    CODE_SELF,
    CODE_SINGULAR,
    CODE_TRANS,
    CODE_Z_DYAD,
)
from arcube.evaluation.kernel._layout import (
    G_C,
    G_C_Z,
    G_COS_ALPHA,
    G_COS_BETA,
    G_D,
    G_F,
    G_L,
    G_M,
    G_O,
    G_P,
    G_R,
    G_SIN_ALPHA,
    G_SIN_BETA,
    G_T,
)
from arcube.evaluation.kernel._layout import INF as _INF
from arcube.evaluation.kernel._layout import NAN as _NAN
from arcube.evaluation.kernel._layout import (
    O_EXACT,
    O_KAPPA_MAX,
    O_KAPPA_MAX_ON,
    O_RHO_MAX,
    O_RHO_MAX_ON,
    O_SINGLE_ASSEMBLY_MODE,
)
from arcube.evaluation.kernel._layout import O_TRANSMISSION, O_TRANSMISSION_ON, O_Z_DYAD
from arcube.evaluation.kernel._layout import (
    O_CLEARANCE,
    O_CLEARANCE_MIN_EXACT,
    O_CLEARANCE_ON,
    O_DO_CLEARANCE,
    O_DO_SELF_CLEARANCE,
)
from arcube.evaluation.kernel._layout import (
    O_HOLDING_TORQUE,
    O_MOTOR_LENGTH,
    O_SELF_CLEARANCE,
    O_SELF_CLEARANCE_ON,
    O_TIP_METRICS,
)
from arcube.evaluation.kernel._layout import X_CLEARANCE_MM, X_CLEARANCE_PART, X_GUARD_GRADE, X_SELF_CLEARANCE_MM
from arcube.evaluation.kernel._layout import (
    O_DO_ENVELOPE,
    O_ENVELOPE,
    O_ENVELOPE_ON,
    X_ENVELOPE_CLEARANCE_MM,
    X_ENVELOPE_PART,
    X_ENVELOPE_REGION,
)
from arcube.evaluation.kernel._envelope import _envelope_pick, _envelope_regions, _envelope_skin, state_size
from arcube.evaluation.kernel._body import _body_world
from arcube.evaluation.kernel._clearance import _anatomy_clearance, _carry_bounds
from arcube.evaluation.kernel._self import _self_clearance, self_moves
from arcube.evaluation.kernel._masses import _holding_torque
from arcube.evaluation.kernel._performance import _no_metrics, _tip_metrics
from arcube.evaluation.kernel._scalar import (
    _clip_excess,
    cross,
    _harmonic,
    _kdiag2,
    _kdiag3,
    _kinv,
    _nan_to_num,
    _pos,
    _term,
    _wrap,
    rot_t,
    z_link,
)
from arcube.evaluation.kernel._stages import _tls_leg, _tms_leg
from arcube.evaluation.kernel._state import RTS, TLS, TMS

N_LINES = N_SEGMENTS + N_SPHERES
N_PRIMS = N_LINES + 4  # and the four spherical arcs
PRIM_PART = PRIMITIVE_PART.astype(np.int64)


@njit(cache=True, error_model="numpy")
def _rts_leg(sa, ca, cb, o, eu, ev, ew, eps):
    """RTS IK of one leg (model §5.2) in its own axes (u, v, w), from sin/cos of alpha, cos beta, o (rad) and
    the drill axis (eu, ev, ew): the harmonic equation's argument, sigma, sin/cos of sigma (NaN where sigma
    is) and u_beta's components (u, v, w)."""
    lam, arg = _harmonic((-sa) * ew, sa * ev, cb - ca * eu, eps)
    sig = _wrap(lam - o)
    lam2 = sig + o
    if sig == sig:
        ss = math.sin(sig)
        cs = math.cos(sig)
    else:
        ss = cs = _NAN
    return arg, sig, ss, cs, ca + 0.0 * lam2, sa * math.sin(lam2), (-sa) * math.cos(lam2)


@njit(cache=True, error_model="numpy")
def _rts_direction(g, e0, e1, e2, epsR0, epsR1):
    """RTS IK (model §5.2) and its Jacobian invariants for one drill direction (e0, e1, e2) in mechanism axes.

    Returns the :class:`~arcube.evaluation.kernel._state.RTS` of that direction: e, sigma_x, sigma_y, their
    arguments, sin/cos of both sigmas, the J_AS diagonal, det[x_b, y_b, e], kappa(J_AS), kappa(J_AP) and the
    axes x_beta, y_beta (world components of R_m).
    """
    sa0, ca0, cb0, o0 = g[G_SIN_ALPHA], g[G_COS_ALPHA], g[G_COS_BETA], g[G_O]
    sa1, ca1, cb1, o1 = g[G_SIN_ALPHA + 1], g[G_COS_ALPHA + 1], g[G_COS_BETA + 1], g[G_O + 1]
    # leg x: (e_u, e_v, e_w) = (e0, e1, e2)
    arg0, sig0, ss0, cs0, xb0, xb1, xb2 = _rts_leg(sa0, ca0, cb0, o0, e0, e1, e2, epsR0)
    # leg y: (e_u, e_v, e_w) = (e1, e2, e0); local (u, v, w) -> world (y, z, x)
    arg1, sig1, ss1, cs1, yb1, yb2, yb0 = _rts_leg(sa1, ca1, cb1, o1, e1, e2, e0, epsR1)
    # J_AS = (u_alpha x u_beta) . e, as np.cross + einsum
    jas0 = ((0.0 * xb2 - 0.0 * xb1) * e0 + (xb1 - 0.0 * xb0) * e2) + (0.0 * xb0 - xb2) * e1
    jas1 = ((yb2 - 0.0 * yb1) * e0 + (0.0 * yb1 - yb0) * e2) + (0.0 * yb0 - 0.0 * yb2) * e1
    # J_AP rows u_beta x e
    q0, q1, q2 = cross(xb0, xb1, xb2, e0, e1, e2)
    q3, q4, q5 = cross(yb0, yb1, yb2, e0, e1, e2)
    F_ap = ((((q0 * q0 + q1 * q1) + q2 * q2) + q3 * q3) + q4 * q4) + q5 * q5
    # det[x_b, y_b, e] = (x_b x y_b) . e; NumPy's einsum sums 3 products as (p0 + p2) + p1
    det = ((xb1 * yb2 - xb2 * yb1) * e0 + (xb0 * yb1 - xb1 * yb0) * e2) + (xb2 * yb0 - xb0 * yb2) * e1
    kAS = _kdiag2(jas0, jas1)
    kAP = _kinv(F_ap, abs(det))
    return RTS(
        e0, e1, e2, sig0, sig1, arg0, arg1, ss0, cs0, ss1, cs1, jas0, jas1, det, kAS, kAP, xb0, xb1, xb2, yb0, yb1, yb2
    )


@njit(cache=True, error_model="numpy")
def _centre_m(g, E0, E1, E2, e0, e1, e2):
    """Mechanism coordinates of the centre C = E + L e of the spherical stage: R^T (C - m) (model §13)."""
    L = g[G_L]
    if L != 0.0:
        E0 = E0 + L * e0
        E1 = E1 + L * e1
        E2 = E2 + L * e2
    return rot_t(g, E0 - g[G_M], E1 - g[G_M + 1], E2 - g[G_M + 2])


@njit(cache=True, error_model="numpy")
def _stage_failure(ta0, ta1, ta2, rarg0, rarg1, marg0, marg1):
    """Code of the first failing stage check, in FAILURES order (0: every stage solvable)."""
    if abs(ta0) > 1.0:
        return 1
    if abs(ta1) > 1.0:
        return 2
    if abs(ta2) > 1.0:
        return 3
    if abs(rarg0) > 1.0:
        return 4
    if abs(rarg1) > 1.0:
        return 5
    if not (abs(marg0) <= 1.0):
        return 6
    if not (abs(marg1) <= 1.0):
        return 7
    return 0


@njit(cache=True, error_model="numpy")
def _eta(tls, tms, rts, full, kappa_row):
    """eta_raw = max of the seven kappas (NaN -> inf) and the code of the first singular one (0 if none).

    With ``full`` the kappas are written to ``kappa_row`` (7,) in JACOBIAN_NAMES order.
    """
    k_lv = _kdiag3(tls.pcr0, tls.pcr1, tls.pcr2)  # |-p cos rho|
    D0, D1, E0, E1 = tms.D0, tms.D1, tms.E0, tms.E1
    F_av = ((D0 * D0 + E0 * E0) + E1 * E1) + D1 * D1
    g_av = math.sqrt(((D0 * E1) * (D0 * E1) + (E0 * E1) * (E0 * E1)) + (D0 * D1) * (D0 * D1))
    k_av = _kinv(F_av, g_av)
    k_sg = _kdiag2(tms.H0, tms.H1)
    k_rh = _kdiag2(tms.G0, tms.G1)
    k_dl = _kdiag2(tms.F0, tms.F1)
    eta_raw = 0.0
    sing = 0
    for j in range(7):
        if j == 0:
            kj = k_lv
        elif j == 1:
            kj = k_av
        elif j == 2:
            kj = k_sg
        elif j == 3:
            kj = rts.kAS
        elif j == 4:
            kj = rts.kAP
        elif j == 5:
            kj = k_rh
        else:
            kj = k_dl
        if full:
            kappa_row[j] = kj
        if not math.isfinite(kj):
            if sing == 0:
                sing = CODE_SINGULAR + j
            if kj != kj:
                kj = _INF
        if kj > eta_raw:
            eta_raw = kj
    return eta_raw, sing


@njit(cache=True, error_model="numpy")
def _local_guards(fc, g, opt, eta_raw, tls, tms, rts):
    """The active local guards of model §8.2 in FAILURES order: (failure code, grade, z-dyad shortfall), the
    grade being the sum of their model §16 terms min(s / S, 1) (a guard's NaN counts 0), as
    ``reference._guard_checks``; the z dyad's closure shortfall is 0 when its guard is off."""
    gr = 0.0
    zs = 0.0
    if opt[O_Z_DYAD] != 0.0:
        d2 = g[G_D + 2]
        cz = z_link(g, opt)
        reach_z = d2 + cz
        L = math.hypot(tls.C0, tls.C1 - tls.pcr2)
        short = (_pos(L - reach_z) + _pos(abs(d2 - cz) - L)) / reach_z
        if short > 0.0 and fc == 0:
            fc = CODE_Z_DYAD
        gr = gr + _nan_to_num(_term(short, GRADE_Z_DYAD))
        zs = short
    if opt[O_RHO_MAX_ON] != 0.0:
        rho_th = opt[O_RHO_MAX]
        short = ((0.0 + _pos(abs(tls.rho0) - rho_th)) + _pos(abs(tls.rho1) - rho_th)) + _pos(abs(tls.rho2) - rho_th)
        if short > 0.0 and fc == 0:
            fc = CODE_RHO
        gr = gr + _nan_to_num(_term(short, GRADE_RHO))
    if opt[O_TRANSMISSION_ON] != 0.0:
        s0 = opt[O_TRANSMISSION]
        sb0, sb1 = g[G_SIN_BETA], g[G_SIN_BETA + 1]
        q = _pos(s0 - abs(tms.F0 / (g[G_D] * g[G_C])))
        short = 0.0 + q
        tg = 0.0 + _term(q, GRADE_SINE)
        q = _pos(s0 - abs(tms.F1 / (g[G_D + 1] * g[G_C + 1])))
        short += q
        tg += _term(q, GRADE_SINE)
        q = _pos(s0 - abs(tms.H0 / (g[G_T] * g[G_C])))
        short += q
        tg += _term(q, GRADE_SINE)
        q = _pos(s0 - abs(tms.H1 / (g[G_T + 1] * g[G_C + 1])))
        short += q
        tg += _term(q, GRADE_SINE)
        q = _pos(s0 - abs(rts.jas0 / (g[G_SIN_ALPHA] * sb0)))
        short += q
        tg += _term(q, GRADE_SINE)
        q = _pos(s0 - abs(rts.jas1 / (g[G_SIN_ALPHA + 1] * sb1)))
        short += q
        tg += _term(q, GRADE_SINE)
        q = _pos(s0 - abs(rts.det / (sb0 * sb1)))
        short += q
        tg += _term(q, GRADE_SINE)
        if short > 0.0 and fc == 0:
            fc = CODE_TRANS
        gr = gr + _nan_to_num(tg)
    if opt[O_KAPPA_MAX_ON] != 0.0:
        km = opt[O_KAPPA_MAX]
        if eta_raw > km and fc == 0:
            fc = CODE_KAPPA
        gr = gr + _nan_to_num(_term(_pos(eta_raw - km), km))
    return fc, gr, zs


@njit(cache=True, error_model="numpy")
def _design_points(i, k0, k1, inputs, grids, body, envelope, rows, detail):
    """Points k0..k1-1 of design i, in the reference's order.

    ``inputs``: an :class:`~arcube.evaluation.kernel._state.Inputs`, ``geometry`` (D, N_GEO) and ``modes`` (D, 4)
    of every design, the task's ``E`` (P, 3) mm and ``e`` (P, 3) unit, ``same_e`` (P,) true where e[k] equals
    e[k - 1] bitwise, the option vector ``opt`` and ``full``;
    ``grids``: the anatomy's fine and coarse grids (origin (3,) mm, spacing mm, values (nx, ny, nz) mm, for
    each), then their block gradient bounds (kernel._clearance); ``body``: the primitives' radii (27,) mm,
    their search order and the self-clearance pairs (model §14.1-14.3); ``envelope``: the envelope of the whole
    patient (model §19.5) as ``_envelope._envelope_clearance`` takes it.
    Writes this design's :class:`~arcube.evaluation.kernel._state.Rows` ``rows`` (P,) but its dexterity:
    ``failure`` (int16 code, before the global guard), ``eta`` (eta_raw),
    ``excess`` (the IK domain excess of 12.2), ``assembly`` (int8: 4 [H_x > 0] + 2 [H_y > 0] + [det > 0])
    and ``extra`` (P, N_EXTRA: the guard grade of model §16 before the global guard, the clearances, the
    tip metrics and the holding torque of 18.2); with
    ``full`` also row i of ``detail`` = (kappa (D, P, 7), rho (D, P, 3), delta (D, P, 2), sigma (D, P, 2)), rad.
    """
    geometry, modes, E, e, same_e, opt, full = inputs
    failure, eta, excess, assembly, _, extra = rows
    g = geometry[i]
    radius, order, pairs = body
    kappa_o, rho_o, delta_o, sigma_o = detail
    do_clr = opt[O_DO_CLEARANCE] != 0.0
    do_self = opt[O_DO_SELF_CLEARANCE] != 0.0
    do_env = opt[O_DO_ENVELOPE] != 0.0
    env_boxes, env_table, env_skin = envelope[0], envelope[1], envelope[2]
    env_regions = env_boxes.shape[0] + (1 if env_skin else 0) + (0 if math.isnan(env_table) else 1)
    env_state = np.empty(state_size(env_boxes.shape[0]))
    env_lower = np.empty(N_PRIMS)
    env_work = np.empty((6, 96))
    have_prev_env = np.bool_(False)  # not the constant False: numba would compile _envelope_regions for it too
    lines = np.empty((N_LINES, 2, 3))
    arcs = np.empty((4, 2, 3))
    arc_c = np.empty(3)
    chords = np.empty((4, ARC_CHORDS + 1, 3))
    work = np.empty((6, 96))
    jbuf = np.empty((2, 3, 5))
    do_perf = opt[O_TIP_METRICS] != 0.0
    do_hold = do_perf and opt[O_HOLDING_TORQUE] != 0.0
    f0, f1, f2 = g[G_F], g[G_F + 1], g[G_F + 2]
    p0, p1, p2 = g[G_P], g[G_P + 1], g[G_P + 2]
    d0, d1 = g[G_D], g[G_D + 1]
    c0, c1 = g[G_C], g[G_C + 1]
    t0, t1 = g[G_T], g[G_T + 1]
    r = g[G_R]
    epsT0, epsT1, epsR0, epsR1 = modes[i, 0], modes[i, 1], modes[i, 2], modes[i, 3]
    exact = opt[O_EXACT] != 0.0
    need_rho = full or opt[O_RHO_MAX_ON] != 0.0
    dyad_ik = opt[O_Z_DYAD] != 0.0 and g[G_C_Z] == g[G_C_Z]  # model §16's amendment: the design's own c_z

    # RTS cache (depends on the direction only): ``rts`` is set at the first point, ``have`` being False
    have = False

    # Summaries need a point's clearance exactly only when it is below the guard's limit (its shortfall)
    # or below the smallest so far over passing points: each search starts at that cap, so parts far
    # from the anatomy are pruned at once.
    run_min = _INF
    # ... and carry each primitive's proven lower bound from point to point, less how far it moved
    # (a distance is 1-Lipschitz): a part that stays far from the anatomy is then not looked up again.
    lower = np.full(N_PRIMS, -_INF)
    pair_lower = np.full(pairs.shape[0], -_INF)  # the same for the self-clearance pairs
    prev_self = np.zeros((N_LINES, 2, 3))
    move = np.empty(N_LINES)
    have_prev_self = np.bool_(False)  # as have_prev_env
    prev = np.empty((N_LINES, 2, 3))
    have_prev = False
    floor = opt[O_CLEARANCE] if opt[O_CLEARANCE_ON] != 0.0 else -_INF
    track_min = (
        opt[O_CLEARANCE_MIN_EXACT] != 0.0 or opt[O_CLEARANCE_ON] == 0.0
    )  # else only the guard's decision matters
    track_self = opt[O_CLEARANCE_MIN_EXACT] != 0.0 or opt[O_SELF_CLEARANCE_ON] == 0.0
    for k in range(k0, k1):
        if not (have and same_e[k]):
            have = True
            em0, em1, em2 = rot_t(g, e[k, 0], e[k, 1], e[k, 2])
            rts = _rts_direction(g, em0, em1, em2, epsR0, epsR1)

        # TLS (Eq 1), at the centre C in mechanism coordinates
        C0, C1, C2 = _centre_m(g, E[k, 0], E[k, 1], E[k, 2], e[k, 0], e[k, 1], e[k, 2])
        ta0, rho0, cr0, sr0 = _tls_leg(C0, f0, r, p0, need_rho, exact)
        ta1, rho1, cr1, sr1 = _tls_leg(C1, f1, r, p1, need_rho, exact)
        ta2, rho2, cr2, sr2 = _tls_leg(C2, f2, r, p2, need_rho, exact)
        pcr0 = p0 * cr0
        pcr1 = p1 * cr1
        pcr2 = p2 * cr2

        # TMS (Eq 3): leg x (v, w) = (y, z), leg y (v, w) = (z, x)
        del0, marg0, F0, G0, D0, E0, H0, cd0, sd0 = _tms_leg(
            C1, C2, pcr0, sr0, rts.ss0, rts.cs0, p0, d0, c0, t0, epsT0, full, exact
        )
        del1, marg1, F1, G1, D1, E1, H1, cd1, sd1 = _tms_leg(
            C2, C0, pcr1, sr1, rts.ss1, rts.cs1, p1, d1, c1, t1, epsT1, full, exact
        )

        fc = _stage_failure(ta0, ta1, ta2, rts.arg0, rts.arg1, marg0, marg1)
        ex = ((0.0 + _clip_excess(ta0)) + _clip_excess(ta1)) + _clip_excess(ta2)
        ex = ex + ((0.0 + _clip_excess(rts.arg0)) + _clip_excess(rts.arg1))
        ex = ex + ((0.0 + _clip_excess(marg0)) + _clip_excess(marg1))

        eta_raw = _INF
        if fc == 0:
            tls = TLS(C0, C1, C2, rho0, rho1, rho2, cr0, sr0, cr1, sr1, cr2, sr2, pcr0, pcr1, pcr2)
            tms = TMS(cd0, sd0, cd1, sd1, F0, F1, G0, G1, D0, D1, E0, E1, H0, H1)
            eta_raw, fc = _eta(tls, tms, rts, full, kappa_o[i, k] if full else kappa_o[0, 0])
            solved = fc == 0  # the IK solves the point: its guards are graded (model §16)
            fc, gr, zs = _local_guards(fc, g, opt, eta_raw, tls, tms, rts)
            if dyad_ik and zs > 0.0:  # an open z dyad is a point the IK does not reach: its excess, no guard grade
                ex = ex + zs
                solved = False
            clr = selfc = env = _NAN
            part = env_part = env_region = -1.0
            if do_clr or do_self or do_env:
                arc_r = _body_world(g, z_link(g, opt), opt[O_MOTOR_LENGTH], tls, tms, rts, lines, arcs, arc_c)
                if do_self:
                    self_cap = _INF if full or track_self else opt[O_SELF_CLEARANCE]
                    self_enough = (
                        -_INF if self_cap == _INF else self_cap - GRADE_CLEARANCE
                    )  # past it a shortfall counts 1 (16)
                    self_moves(lines, prev_self, have_prev_self, move)
                    have_prev_self = True
                    selfc = _self_clearance(
                        lines,
                        arc_c,
                        arc_r,
                        arcs,
                        radius,
                        N_LINES,
                        pairs,
                        chords,
                        self_cap,
                        self_enough,
                        pair_lower,
                        move,
                    )
                if do_clr:
                    # single_assembly_mode may fail a point later: with it on, an exact summary minimum searches every point
                    cap = (
                        _INF
                        if full
                        else (
                            floor
                            if not track_min
                            else (_INF if opt[O_SINGLE_ASSEMBLY_MODE] != 0.0 else max(floor, run_min))
                        )
                    )
                    _carry_bounds(lower, lines, prev, have_prev and cap < _INF)
                    have_prev = True
                    enough = floor - GRADE_CLEARANCE if cap == floor else -_INF
                    clr, kbest = _anatomy_clearance(
                        lines, arc_c, arc_r, arcs, radius, N_LINES, grids, order, work, cap, lower, enough
                    )
                    part = float(PRIM_PART[kbest]) if kbest >= 0 else -1.0
                    if opt[O_CLEARANCE_ON] != 0.0:
                        short = _pos(opt[O_CLEARANCE] - clr)
                        if short > 0.0 and fc == 0:
                            fc = CODE_PATIENT
                        gr = gr + _nan_to_num(_term(short, GRADE_CLEARANCE))
                if opt[O_SELF_CLEARANCE_ON] != 0.0:
                    short = _pos(opt[O_SELF_CLEARANCE] - selfc)
                    if short > 0.0 and fc == 0:
                        fc = CODE_SELF
                    gr = gr + _nan_to_num(_term(short, GRADE_CLEARANCE))
                if do_env:  # model §19.5
                    least = _envelope_regions(
                        lines, arc_c, arc_r, arcs, radius, env_boxes, env_table, env_skin, have_prev_env, env_state
                    )
                    have_prev_env = not math.isnan(least)  # a finite body: the next point carries its bounds
                    if env_skin and have_prev_env:
                        least = _envelope_skin(
                            lines, arc_c, arc_r, arcs, radius, envelope, order, env_work, env_lower, env_state, least
                        )
                    env, env_k, env_r = _envelope_pick(env_state, env_boxes.shape[0], env_regions, least)
                    if env_k >= 0:
                        env_part = float(PRIM_PART[env_k])
                        env_region = float(env_r)
                    if opt[O_ENVELOPE_ON] != 0.0:
                        short = _pos(opt[O_ENVELOPE] - env)
                        if short > 0.0 and fc == 0:
                            fc = CODE_ENVELOPE
                        gr = gr + _nan_to_num(_term(short, GRADE_ENVELOPE))
                if fc == 0 and clr < run_min:
                    run_min = clr  # the summary's minimum is over the points that pass every guard
            extra[k, X_GUARD_GRADE] = gr if solved else 0.0
            extra[k, X_CLEARANCE_MM] = clr
            extra[k, X_CLEARANCE_PART] = part
            extra[k, X_SELF_CLEARANCE_MM] = selfc
            extra[k, X_ENVELOPE_CLEARANCE_MM] = env
            extra[k, X_ENVELOPE_PART] = env_part
            extra[k, X_ENVELOPE_REGION] = env_region
            if not (do_clr or do_self):
                have_prev = False
                have_prev_self = False
            if fc == 0 and do_perf:
                _tip_metrics(g, tls, tms, rts, opt, jbuf, extra[k])
                if do_hold:  # model §18.2
                    _holding_torque(g, opt, tls, tms, rts, jbuf, extra[k])
            else:
                _no_metrics(extra[k])
        else:
            extra[k, X_GUARD_GRADE] = 0.0
            extra[k, X_CLEARANCE_MM] = _NAN
            extra[k, X_CLEARANCE_PART] = -1.0
            extra[k, X_SELF_CLEARANCE_MM] = _NAN
            extra[k, X_ENVELOPE_CLEARANCE_MM] = _NAN
            extra[k, X_ENVELOPE_PART] = -1.0
            extra[k, X_ENVELOPE_REGION] = -1.0
            _no_metrics(extra[k])
            have_prev_env = False
            have_prev = False
            have_prev_self = False
            if full:
                for j in range(7):
                    kappa_o[i, k, j] = _NAN

        failure[k] = fc
        eta[k] = eta_raw
        excess[k] = ex
        assembly[k] = (4 if H0 > 0.0 else 0) + (2 if H1 > 0.0 else 0) + (1 if rts.det > 0.0 else 0)
        if full:
            rho_o[i, k, 0] = rho0
            rho_o[i, k, 1] = rho1
            rho_o[i, k, 2] = rho2
            delta_o[i, k, 0] = del0
            delta_o[i, k, 1] = del1
            sigma_o[i, k, 0] = rts.sig0
            sigma_o[i, k, 1] = rts.sig1
