"""Evaluation (MODEL.md 8.2, 8.3, 12.2) and tasks (MODEL.md 1.4).

Oracles: per-design / per-point loops, numpy SVD of the Jacobians, the 3-D construction of
tests/naive.py for the guard quantities, and hand-built failing points.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.evaluation import reference as ev
from arcube.evaluation.reference import GUARDED_OPTIONS, Options, evaluate_points, evaluate_task, failure_name
from arcube.model.mechanism import inverse_kinematics
from arcube.evaluation.task import build_task

from designs import reachable_poses
from naive import X_HAT, Y_HAT, get, leg_pair, leg_triple, oracle_config, oracle_modes, svd_eta, transmission_sines

LOCAL_GUARDS = Options(z_dyad=True, rho_max_deg=75.0, min_transmission_deg=20.0, kappa_max=100.0)


def _mixed_task(designs, rng):
    """Points: 10 well-conditioned poses of designs[0] in mode (+,+,+,+), 10 of designs[1] in
    (-,+,-,+), and 5 random candidates (mostly unreachable)."""
    E0, e0 = reachable_poses(rng, designs[0], np.ones(4), 10)
    E1, e1 = reachable_poses(rng, designs[1], np.array([-1.0, 1.0, -1.0, 1.0]), 10)
    Er = rng.uniform(-300, 100, (5, 3))
    er = rng.normal(size=(5, 3))
    er /= np.linalg.norm(er, axis=-1, keepdims=True)
    return np.concatenate([E0, E1, Er]), np.concatenate([e0, e1, er])


# =============================================================================================
# Batch == loop


@pytest.mark.parametrize("options", [Options(), LOCAL_GUARDS], ids=["default", "local-guards"])
def test_evaluate_task_batch_equals_loop_of_evaluate_points(designs, rng, options):
    D = np.stack(designs)
    modes = np.array([[1, 1, 1, 1], [-1, 1, -1, 1], [1, -1, 1, -1], [-1, -1, -1, -1]], dtype=float)
    E, e = _mixed_task(designs, rng)
    res = evaluate_task(D, E, e, modes, options)
    P = len(E)
    assert res.points.reachable.shape == (len(D), P)
    for i in range(len(D)):
        loop = [evaluate_points(D[i], E[j], e[j], modes[i], options) for j in range(P)]
        for field in ev.PointResults._fields:
            got = getattr(res.points, field)[i]
            exp = np.stack([np.asarray(getattr(r, field)) for r in loop])
            if exp.dtype.kind in "bi":
                np.testing.assert_array_equal(got, exp, err_msg=field)
            else:
                np.testing.assert_allclose(got, exp, rtol=1e-12, atol=1e-12, err_msg=field)
        reach = np.array([bool(r.reachable) for r in loop])
        eta = np.array([float(r.eta_L) for r in loop])
        dex = np.array([float(r.dexterity_pct) for r in loop])
        exc = np.array([float(r.excess) for r in loop])
        grade = np.array([float(r.guard_grade) for r in loop])
        ik_fail = np.array([0 < int(r.failure) <= ev.IK_FAILURES for r in loop])
        w_G = bool(reach.all())
        assert bool(res.w_G[i]) == w_G
        assert res.reachable_fraction[i] == pytest.approx(reach.mean(), abs=1e-15)
        # MODEL.md 16: V = V_reach (IK failures and their excess) + G / (1 + G) / (2P), G = mean guard grade
        v_reach = ik_fail.mean() + exc.sum() if ik_fail.any() else 0.0
        G = grade.sum() / P
        assert res.violation_reach[i] == pytest.approx(v_reach, rel=1e-12)
        assert res.guard_grade[i] == pytest.approx(grade.sum(), rel=1e-12)
        assert res.violation[i] == pytest.approx(v_reach + G / (1.0 + G) / (2 * P), rel=1e-12)
        assert np.all(exc[~ik_fail] == 0.0) and np.all(grade[ik_fail] == 0.0)
        if w_G:
            assert res.eta_G[i] == pytest.approx(eta.mean(), rel=1e-12)
            assert res.violation[i] == 0.0
        else:
            assert res.eta_G[i] == np.inf and res.violation[i] > 0.0
        assert res.dexterity_min[i] == pytest.approx(dex.min(), abs=1e-12)
        assert res.dexterity_mean[i] == pytest.approx(dex.mean(), rel=1e-12)
        assert res.dexterity_max[i] == pytest.approx(dex.max(), rel=1e-12)
    if options == Options():
        # the task was built so that design 0 reaches its first 10 points, design 1 the next 10
        assert np.all(res.points.reachable[0, :10]) and np.all(res.points.reachable[1, 10:20])
    assert res.points.reachable.any() and (~res.points.reachable).any()


def test_evaluate_task_design_broadcasting_and_single_mode(designs, rng):
    """(2, 2, 23) designs with one mode for all == four separate calls."""
    D = np.stack(designs).reshape(2, 2, 23)
    E, e = _mixed_task(designs, rng)
    res = evaluate_task(D, E, e)
    assert res.eta_G.shape == (2, 2) and res.points.eta_L.shape == (2, 2, len(E))
    for a in range(2):
        for b in range(2):
            one = evaluate_task(D[a, b], E, e)
            np.testing.assert_array_equal(res.points.failure[a, b], one.points.failure)
            np.testing.assert_allclose(res.points.eta_L[a, b], one.points.eta_L, rtol=1e-12)
            assert res.eta_G[a, b] == one.eta_G or np.isclose(res.eta_G[a, b], one.eta_G, rtol=1e-12)


# =============================================================================================
# Definitions: eta_L, dexterity, eta_G, w_L (MODEL.md 8.2, 8.3)


def test_eta_L_dexterity_and_eta_G_definitions(pose_bank):
    for x, mode, E, e in pose_bank[::3]:
        res = evaluate_task(x, E, e, mode)
        eta, sol = svd_eta(x, E, e, mode)
        assert np.all(res.points.reachable) and bool(res.w_G)
        np.testing.assert_allclose(res.points.eta_L, eta, rtol=1e-9)
        np.testing.assert_allclose(res.points.dexterity_pct, 100.0 / eta, rtol=1e-9)
        assert res.eta_G == pytest.approx(eta.mean(), rel=1e-9)
        assert res.dexterity_mean == pytest.approx(np.mean(100.0 / eta), rel=1e-9)
        assert 100.0 / res.eta_G <= res.dexterity_mean * (1 + 1e-12)  # Jensen (MODEL.md 8.3)
        assert res.fitness == res.eta_G
        np.testing.assert_array_equal(res.points.rho, sol.rho)
        np.testing.assert_allclose(res.points.kappa.max(axis=-1), res.points.eta_L, rtol=0)


def test_unreachable_points_never_leak_nan_or_inf(paper_design, designs, rng):
    D = np.stack([paper_design, *designs])
    E = rng.uniform(-400, 250, (400, 3))
    e = rng.normal(size=(400, 3))
    e[:, 2] = np.abs(e[:, 2]) + 1.0
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    for options in (Options(), GUARDED_OPTIONS, Options(z_dyad=True)):
        res = evaluate_task(D, E, e, options=options)
        pts = res.points
        assert np.all(np.isfinite(pts.dexterity_pct))
        assert np.all((pts.dexterity_pct >= 0) & (pts.dexterity_pct <= 100))
        assert np.all(pts.dexterity_pct[~pts.reachable] == 0.0)
        assert np.all(pts.eta_L[~pts.reachable] == np.inf)
        assert np.all(np.isfinite(pts.eta_L[pts.reachable]) & (pts.eta_L[pts.reachable] >= 1))
        assert np.all(np.isfinite(pts.excess)) and np.all(pts.excess >= 0)
        np.testing.assert_array_equal(pts.reachable, pts.failure == 0)
        assert np.all(np.isfinite(res.violation)) and np.all(np.isfinite(res.fitness))
        assert np.all(res.eta_G[~res.w_G] == np.inf)
        assert np.all(np.isfinite(res.dexterity_mean))
        # every point is a mix: make sure the test sees both kinds
        assert pts.reachable.any() and (~pts.reachable).any()
    # default options: w_L == the three stages solvable (MODEL 8.2) and eta finite
    res = evaluate_task(D, E, e)
    with np.errstate(invalid="ignore"):
        sol = inverse_kinematics(D[:, None, :], E, e)
    eta, _ = svd_eta(D[:, None, :], E, e, np.ones(4))
    np.testing.assert_array_equal(res.points.reachable, sol.reachable & np.isfinite(eta))


def _find_direction(rng, x, want_x_ok, want_y_ok, margin=np.deg2rad(0.2)):
    al, be = leg_pair(x, "alpha"), leg_pair(x, "beta")
    for _ in range(100):
        e = rng.normal(size=(5000, 3))
        e /= np.linalg.norm(e, axis=-1, keepdims=True)
        oks = []
        for i, u in enumerate((X_HAT, Y_HAT)):
            ang = np.arccos(np.clip(e @ u, -1, 1))
            lo, hi = abs(al[i] - be[i]), al[i] + be[i]
            inside = (ang > lo + margin) & (ang < hi - margin)
            outside = (ang < lo - margin) | (ang > hi + margin)
            oks.append(inside if (want_x_ok, want_y_ok)[i] else outside)
        hit = oks[0] & oks[1]
        if hit.any():
            return e[np.argmax(hit)]
    raise AssertionError("no direction found")


def test_failure_reasons_name_the_failing_stage(designs, rng):
    x = designs[0]
    mode = np.ones(4)
    E, e = reachable_poses(rng, x, mode, 1)
    E, e = E[0], e[0]
    assert failure_name(int(evaluate_points(x, E, e, mode).failure)) is None
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    m = np.array([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
    for i, leg in enumerate("xyz"):
        for side in (+1, -1):
            E2 = E.copy()
            E2[i] = m[i] - f[i] - r + side * (p[i] + 1.0)  # 1 mm outside the TLS box along u
            res = evaluate_points(x, E2, e, mode)
            assert failure_name(int(res.failure)) == f"TLS/{leg}"
            assert not res.reachable and res.dexterity_pct == 0.0 and res.eta_L == np.inf
            assert res.excess >= 1.0 / p[i] * (1 - 1e-12)
    res = evaluate_points(x, E, _find_direction(rng, x, False, True), mode)
    assert failure_name(int(res.failure)) == "RTS/x"
    res = evaluate_points(x, E, _find_direction(rng, x, True, False), mode)
    assert failure_name(int(res.failure)) == "RTS/y"
    res = evaluate_points(x, E, _find_direction(rng, x, False, False), mode)
    assert failure_name(int(res.failure)) == "RTS/x"  # first failing check in FAILURES order
    # TMS: a coupler too long to close (c > d + |T - D|)
    for i, leg in enumerate("xy"):
        x2 = x.copy()
        x2[12 + i] = 5000.0
        res = evaluate_points(x2, E, e, mode)
        assert failure_name(int(res.failure)) == f"TMS/{leg}"
        assert res.excess > 0
    assert failure_name(0) is None
    assert ev.FAILURES[:7] == ("TLS/x", "TLS/y", "TLS/z", "RTS/x", "RTS/y", "TMS/x", "TMS/y")


def _tms_excess_oracle(x, E_m, sigma, legs):
    """sum over ``legs`` of min(max(|C/R| - 1, 0), 10), A, B, C of MODEL.md 4.2, rho from Eq 1."""
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    t, d, c = leg_pair(x, "t"), leg_pair(x, "d"), leg_pair(x, "c")
    out = 0.0
    for j in legs:
        rho_j = -np.arcsin((E_m[j] + f[j] + r) / p[j])
        vv, ww = (E_m[1], E_m[2]) if j == 0 else (E_m[2], E_m[0])
        a = vv + t[j] * np.sin(sigma[j])
        b = ww - t[j] * np.cos(sigma[j]) - p[j] * np.cos(rho_j)
        arg = (c[j] ** 2 - a * a - b * b - d[j] ** 2) / np.hypot(2 * d[j] * b, 2 * d[j] * a)
        out += min(max(abs(arg) - 1.0, 0.0), 10.0)
    return out


def test_graded_excess_counts_only_the_failing_arguments(designs, rng):
    """MODEL.md 12.2: the violation adds, per failing point, how far each *failing* argument lies
    outside its domain. When a crank angle (TLS) or an RTS input does not exist, the TMS argument
    of that leg is undefined, not failing: it must not add anything (in particular not the cap)."""
    x = designs[0]
    mode = np.ones(4)
    E, e = reachable_poses(rng, x, mode, 1)
    E, e = E[0], e[0]
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    m = np.array([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
    sigma = inverse_kinematics(x, E, e, mode).sigma  # RTS inputs: depend on e only
    wrong = []
    for i, leg in enumerate("xyz"):
        for side in (+1, -1):
            E2 = E.copy()
            E2[i] = m[i] - f[i] - r + side * (p[i] + 1.0)  # 1 mm outside the TLS box along u
            res = evaluate_points(x, E2, e, mode)
            expected = 1.0 / p[i] + _tms_excess_oracle(x, E2 - m, sigma, [j for j in range(2) if j != i])
            if not np.isclose(res.excess, expected, rtol=1e-9):
                wrong.append(f"TLS/{leg} {'+-'[side < 0]}1 mm: excess {float(res.excess):.6g}, expected {expected:.6g}")
    # RTS/x fails (its sigma does not exist): excess = RTS-x excess + TMS-y excess only
    e2 = _find_direction(rng, x, False, True)
    al, be = leg_pair(x, "alpha"), leg_pair(x, "beta")
    arg_x = (np.cos(be[0]) - np.cos(al[0]) * e2[0]) / (np.sin(al[0]) * np.hypot(e2[1], e2[2]))
    sigma2 = inverse_kinematics(x, E, e2, mode).sigma
    res = evaluate_points(x, E, e2, mode)
    expected = min(abs(arg_x) - 1.0, 10.0) + _tms_excess_oracle(x, E - m, sigma2, [1])
    if not np.isclose(res.excess, expected, rtol=1e-9):
        wrong.append(f"RTS/x: excess {float(res.excess):.6g}, expected {expected:.6g}")
    assert not wrong, "; ".join(wrong)


def test_exact_singularity_is_unreachable_with_reason():
    """rho_x = 0 exactly makes J_rho singular: w_L = 0 with reason singular/J_rho, eta = inf."""
    names = "m_x m_y m_z f_x f_y f_z p_x p_y p_z d_x d_y d_z c_x c_y t_x t_y r o_x o_y alpha_x alpha_y beta_x beta_y".split()
    vals = [10, -20, 30, 40, 50, 60, 100, 110, 90, 120, 130, 80, 150, 160, 60, 70, 60, 10, -20, 60, 60, 60, 60]
    x = np.array(vals, dtype=float)
    assert len(names) == 23
    E = np.array([10.0 - 40.0 - 60.0, -20.0 - 50.0 - 60.0 + 30.0, 30.0 - 60.0 - 60.0])
    e = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    res = evaluate_points(x, E, e)
    assert failure_name(int(res.failure)) == "singular/J_rho"
    assert not res.reachable and res.eta_L == np.inf and res.dexterity_pct == 0.0
    task = evaluate_task(x, np.stack([E, E + [1.0, 0.0, 0.0]]), np.stack([e, e]))
    assert not task.w_G and task.eta_G == np.inf and task.violation > 0
    assert task.points.reachable.tolist() == [False, True]


def test_violation_is_zero_iff_w_G(designs, pose_bank, rng):
    D = np.stack(designs)
    for _, mode, E, e in pose_bank[::9]:
        for options in (Options(), GUARDED_OPTIONS, Options(z_dyad=True, c_z=300.0)):
            res = evaluate_task(D, E, e, mode, options)
            assert np.all((res.violation == 0) == res.w_G)
            assert np.all(res.violation[~res.w_G] > 0)
            assert np.all(res.violation >= 0)
            np.testing.assert_array_equal(res.fitness[res.w_G], res.eta_G[res.w_G])
            assert np.all(res.fitness[~res.w_G] >= 1e6)
    # random designs on a random task: mostly w_G = 0
    E, e = _mixed_task(designs, rng)
    res = evaluate_task(D, E, e)
    assert not res.w_G.any() and np.all(res.violation > 0)
    np.testing.assert_allclose(res.fitness, 1e6 * (1 + (1 - res.reachable_fraction)), rtol=1e-15)


# =============================================================================================
# Guards (MODEL.md 8.2): each alone flips w_L exactly where its condition fails


def _guard_points(x, rng, n=60):
    """Reachable points of design x in the default mode, including nearly singular ones."""
    return reachable_poses(rng, x, np.ones(4), n, min_sine=1e-3)


def _split(values):
    """A threshold strictly between two sorted values near the median (no ties)."""
    v = np.sort(values)
    k = len(v) // 2
    return 0.5 * (v[k - 1] + v[k])


def _check_guard(x, E, e, options, condition, reason):
    base = evaluate_points(x, E, e)
    assert np.all(base.reachable)
    guarded = evaluate_points(x, E, e, options=options)
    assert condition.any() and (~condition).any(), "the test must see both outcomes"
    np.testing.assert_array_equal(guarded.reachable, base.reachable & condition)
    assert all(failure_name(int(c)) == reason for c in guarded.failure[~condition])
    np.testing.assert_array_equal(guarded.eta_L[condition], base.eta_L[condition])
    # MODEL.md 16: a guard's failure is graded apart from the IK (its excess stays 0), by terms min(s/S, 1)
    assert np.all(guarded.excess == 0)
    assert np.all(guarded.guard_grade[~condition] > 0) and np.all(guarded.guard_grade[condition] == 0)
    assert np.all(guarded.guard_grade <= 7.0)  # at most one term per transmission sine
    task = evaluate_task(x, E, e, options=options)
    assert not task.w_G and task.violation > 0 and task.violation_reach == 0 and task.violation < 1 / (2 * len(E))
    task_ok = evaluate_task(x, E[condition], e[condition], options=options)
    assert task_ok.w_G and task_ok.violation == 0


def test_guard_rho_max(designs, rng):
    x = designs[2]
    E, e = _guard_points(x, rng)
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    m = np.array([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
    rho = -np.arcsin((E - m + f + r) / p)  # Eq 1
    worst = np.rad2deg(np.max(np.abs(rho), axis=-1))
    lim = _split(worst)
    _check_guard(x, E, e, Options(rho_max_deg=lim), worst <= lim, "guard/rho_max")


def test_guard_min_transmission(designs, rng):
    x = designs[1]
    E, e = _guard_points(x, rng)
    sol = inverse_kinematics(x, E, e)
    s = np.abs(transmission_sines(oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma)))
    assert np.all(s <= 1 + 1e-12)  # the normalisations of MODEL.md 8.2 make them sines
    worst = np.min(s, axis=-1)
    lim = np.rad2deg(np.arcsin(_split(worst)))
    _check_guard(x, E, e, Options(min_transmission_deg=lim), worst >= np.sin(np.deg2rad(lim)), "guard/transmission")
    # which of the four kinds is the minimum varies: make sure more than one kind is tested
    kinds = np.argmin(s, axis=-1)
    assert len(set(np.minimum(kinds, 6) // 2)) >= 2


def test_guard_kappa_max(designs, rng):
    x = designs[3]
    E, e = _guard_points(x, rng)
    eta, _ = svd_eta(x, E, e, np.ones(4))
    lim = _split(eta)
    _check_guard(x, E, e, Options(kappa_max=lim), eta <= lim, "guard/kappa_max")


@pytest.mark.parametrize("c_z", [None, "split"])
def test_guard_z_dyad(designs, rng, c_z):
    x = designs[0]
    E, e = _guard_points(x, rng)
    sol = inverse_kinematics(x, E, e)
    cfg = oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma)
    gap = cfg.Q[:, 2] - cfg.D[:, 2]  # D_z -> Q_z, both in the plane z = z_E + r
    assert np.allclose(gap[:, 2], 0.0, atol=1e-10)
    L = np.linalg.norm(gap[:, :2], axis=-1)
    d_z = get(x, "d_z")
    if c_z is None:
        # c_z = d_z: closes iff L <= 2 d_z. Rescale d_z so that the split falls between points.
        d_z = _split(L) / 2.0
        x = x.copy()
        x[11] = d_z
        cz = d_z
        options = Options(z_dyad=True)
    else:
        cz = _split(L) - d_z
        if cz <= 0:
            cz = _split(L) + d_z  # then the lower bound |d - c| = c - d is what bites
        options = Options(z_dyad=True, c_z=cz)
    cond = (np.abs(d_z - cz) <= L) & (L <= d_z + cz)
    _check_guard(x, E, e, options, cond, "guard/z_dyad")


def test_z_dyad_off_by_default_and_guards_off_by_default():
    o = Options()
    assert (
        o.guards.z_dyad,
        o.guards.c_z,
        o.guards.rho_max_deg,
        o.guards.min_transmission_deg,
        o.guards.kappa_max,
        o.guards.single_assembly_mode,
    ) == (False, None, None, None, None, False)
    g = GUARDED_OPTIONS.guards
    assert g.z_dyad is False and g.single_assembly_mode is True
    assert (g.rho_max_deg, g.min_transmission_deg, g.kappa_max) == (75.0, 20.0, 100.0)
    with pytest.raises(InputError, match="unknown_guard"):
        Options(unknown_guard=True)


def test_guard_single_assembly_mode(designs, rng):
    x = designs[0]
    E, e = _guard_points(x, rng, n=80)
    sol = inverse_kinematics(x, E, e)
    _, asm = oracle_modes(oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma))
    codes = [tuple(a) for a in asm]
    kinds, counts = np.unique(np.array(codes), axis=0, return_counts=True)
    assert len(kinds) >= 2, "the test needs points in more than one assembly mode"
    base = evaluate_task(x, E, e)
    res = evaluate_task(x, E, e, options=Options(single_assembly_mode=True))
    assert base.w_G and not res.w_G and res.violation > 0
    # the kept points all share one assembly triple: the most common one
    majority = tuple(kinds[np.argmax(counts)])
    keep = np.array([c == majority for c in codes])
    np.testing.assert_array_equal(res.points.reachable, keep)
    assert all(failure_name(int(c)) == "guard/single_assembly_mode" for c in res.points.failure[~keep])
    assert np.all(res.points.dexterity_pct[~keep] == 0) and np.all(res.points.eta_L[~keep] == np.inf)
    # a task in a single assembly mode passes
    ok = evaluate_task(x, E[keep], e[keep], options=Options(single_assembly_mode=True))
    assert ok.w_G and ok.violation == 0


# =============================================================================================
# Tasks (MODEL.md 1.4)


def test_build_task_layout_and_sampling():
    entry = np.array([[0.0, 0.0, 10.0], [5.0, 5.0, 5.0], [1.0, 2.0, 3.0]])
    target = np.array([[0.0, 0.0, -19.0], [5.0, -24.0, 5.0], [4.0, 6.0, 3.0]])
    task = build_task(entry, target)  # paper default N = 30
    assert task.n_points == 30 and len(task) == 90
    np.testing.assert_array_equal(task.trajectory, np.repeat([0, 1, 2], 30))
    np.testing.assert_array_equal(task.k, np.tile(np.arange(30), 3))
    for t in range(3):
        Et = task.E[task.trajectory == t]
        np.testing.assert_array_equal(Et[0], entry[t])
        np.testing.assert_allclose(Et[-1], target[t], atol=1e-12)
        np.testing.assert_allclose(
            np.diff(Et, axis=0), np.broadcast_to((target[t] - entry[t]) / 29, (29, 3)), atol=1e-12
        )
        d = entry[t] - target[t]
        np.testing.assert_allclose(
            task.e[task.trajectory == t], np.broadcast_to(d / np.linalg.norm(d), (30, 3)), atol=1e-15
        )
    # hand values: trajectory 1 moves 1 mm per step along -z, trajectory 2 along -y
    np.testing.assert_allclose(task.E[5], [0.0, 0.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(task.E[30 + 7], [5.0, -2.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(task.e[0], [0, 0, 1])
    np.testing.assert_allclose(task.e[30], [0, 1, 0])
    psi, theta = task.psi_theta
    np.testing.assert_allclose(psi[30], -np.pi / 2, atol=1e-15)  # e = +y -> psi = atan2(-1, 0)
    sub = task.subset([False, True, True])
    assert len(sub) == 60 and sub.ids == ("2", "3")
    np.testing.assert_array_equal(sub.E, task.E[30:])
    np.testing.assert_array_equal(sub.trajectory, np.repeat([0, 1], 30))
