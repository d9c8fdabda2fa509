"""Stage-level tests (MODEL.md sections 1, 3, 4, 5, 6, 7.1-7.3) with independent oracles.

Oracles: inverse-then-forward round trips, the 3-D geometry of naive.oracle_config, central
finite differences of the constraint equations, and hand-computed special configurations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from arcube.model import poses
from arcube.model.stages import rts, solve_harmonic, tls, tms, wrap_angle, zleg

from designs import PAPER
from naive import X_HAT, Y_HAT, Z_HAT, e_of, get, leg_pair, leg_triple, rotate, vec, wrap

# =============================================================================================
# Frames and poses (MODEL.md 1.2, 1.3)


def test_leg_coords_follow_the_cyclic_table_and_triads_are_right_handed():
    a = np.array([1.0, 2.0, 3.0])
    lc = poses.leg_coords(a)
    # MODEL.md 1.2: (u, v, w) of E is (x, y, z), (y, z, x), (z, x, y) for legs x, y, z.
    np.testing.assert_array_equal(lc, [[1, 2, 3], [2, 3, 1], [3, 1, 2]])
    for row in poses.LEG_PERM:
        u, v, w = np.eye(3)[row]
        np.testing.assert_array_equal(np.cross(u, v), w)


@pytest.mark.parametrize(
    "psi_deg, theta_deg, expected",
    [
        (0.0, 0.0, (0.0, 0.0, 1.0)),
        (90.0, 0.0, (0.0, -1.0, 0.0)),
        (-90.0, 0.0, (0.0, 1.0, 0.0)),
        (0.0, 90.0, (1.0, 0.0, 0.0)),
        (30.0, 45.0, (math.sqrt(0.5), -0.5 * math.sqrt(0.5), math.sqrt(0.75) * math.sqrt(0.5))),
    ],
)
def test_e_from_angles_known_values(psi_deg, theta_deg, expected):
    e = poses.e_from_angles(np.deg2rad(psi_deg), np.deg2rad(theta_deg))
    np.testing.assert_allclose(e, expected, atol=1e-15)
    # and by explicit rotation matrices R_x(psi) R_y(theta) z
    np.testing.assert_allclose(e, e_of(np.deg2rad(psi_deg), np.deg2rad(theta_deg)), atol=1e-15)


def test_angles_from_e_inverts_e_from_angles(rng):
    psi = rng.uniform(-np.pi + 1e-3, np.pi - 1e-3, 500)
    theta = rng.uniform(-1.5, 1.5, 500)
    e = poses.e_from_angles(psi, theta)
    np.testing.assert_allclose(np.linalg.norm(e, axis=-1), 1.0, atol=1e-15)
    p2, t2 = poses.angles_from_e(e)
    np.testing.assert_allclose(wrap(p2 - psi), 0.0, atol=1e-12)
    np.testing.assert_allclose(t2, theta, atol=1e-12)
    # known: e = x -> theta = 90 deg; e = -y -> psi = 90 deg
    p, t = poses.angles_from_e(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(wrap(p - np.array([np.pi / 2, np.pi])), 0.0, atol=1e-15)
    np.testing.assert_allclose(t, [0.0, 0.0], atol=1e-15)


def test_omega_from_angle_rates_gives_edot_equal_omega_cross_e(rng):
    """MODEL.md 1.3: e_dot = omega x e with omega = psi_dot x + theta_dot (cos psi y + sin psi z)."""
    h = 1e-6
    for _ in range(50):
        psi, theta = rng.uniform(-3, 3), rng.uniform(-1.4, 1.4)
        pd, td = rng.normal(size=2)
        e_dot = (e_of(psi + h * pd, theta + h * td) - e_of(psi - h * pd, theta - h * td)) / (2 * h)
        om = poses.omega_from_angle_rates(psi, pd, td)
        np.testing.assert_allclose(np.cross(om, e_of(psi, theta)), e_dot, atol=1e-8)

        # the full frame R_x(psi) R_y(theta) turns with omega: check on its x axis too
        def Rfun(a, b):
            Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
            return Rx @ np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])

        Rdot = (Rfun(psi + h * pd, theta + h * td) - Rfun(psi - h * pd, theta - h * td)) / (2 * h)
        W = Rdot @ Rfun(psi, theta).T
        np.testing.assert_allclose([W[2, 1], W[0, 2], W[1, 0]], om, atol=1e-8)


def test_sample_trajectories_endpoints_spacing_and_axis():
    entry = np.array([[10.0, -20.0, 30.0], [0.0, 0.0, 0.0]])
    target = np.array([[40.0, 10.0, -30.0], [0.0, 0.0, -29.0]])
    N = 30
    E, e = poses.sample_trajectories(entry, target, N)
    assert E.shape == (2, N, 3) and e.shape == (2, 3)
    np.testing.assert_array_equal(E[:, 0], entry)
    np.testing.assert_allclose(E[:, -1], target, atol=1e-12)
    steps = np.diff(E, axis=1)
    np.testing.assert_allclose(
        steps, np.broadcast_to(((target - entry) / (N - 1))[:, None, :], steps.shape), atol=1e-12
    )
    # e points from the target (tip, deep) back to the entry (toward the motor)
    np.testing.assert_allclose(e[1], [0.0, 0.0, 1.0], atol=1e-15)
    d = entry[0] - target[0]
    np.testing.assert_allclose(e[0], d / np.linalg.norm(d), atol=1e-15)
    # hand: second trajectory, k = 1 is at z = -1
    np.testing.assert_allclose(E[1, 1], [0.0, 0.0, -1.0], atol=1e-15)
    with pytest.raises(ValueError):
        poses.sample_trajectories(entry, target, 1)
    with pytest.raises(ValueError):
        poses.sample_trajectories(entry, entry, 5)


# =============================================================================================
# solve_harmonic / wrap_angle


def test_solve_harmonic_solves_the_equation_on_both_branches(rng):
    A, B = rng.normal(size=(2, 400))
    C = rng.uniform(-1.5, 1.5, 400) * np.hypot(A, B)
    for eps in (1.0, -1.0):
        xs, arg = solve_harmonic(A, B, C, eps)
        ok = np.abs(C) <= np.hypot(A, B)
        np.testing.assert_array_equal(np.abs(arg) <= 1, ok)
        assert np.all(np.isnan(xs[~ok]))
        np.testing.assert_allclose(A[ok] * np.cos(xs[ok]) + B[ok] * np.sin(xs[ok]), C[ok], atol=1e-12)
        assert np.all((xs[ok] >= -np.pi) & (xs[ok] < np.pi))
        # branch: derivative of the LHS has sign -eps
        dl = -A[ok] * np.sin(xs[ok]) + B[ok] * np.cos(xs[ok])
        assert np.all(np.sign(dl) == -eps)
    # A = B = 0 has no solution
    xs, arg = solve_harmonic(0.0, 0.0, 0.0, 1.0)
    assert np.isnan(xs) and not abs(arg) <= 1


def test_wrap_angle_range():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3 * np.pi + 1e-3, 0.1, 7.0])
    w = wrap_angle(a)
    assert np.all((w >= -np.pi) & (w < np.pi))
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-12)


# =============================================================================================
# TLS (MODEL.md 3, 7.1)


def _tls_params(x):
    return leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")


def test_tls_ik_then_fk_round_trip(designs, rng):
    for x in designs:
        f, p, r = _tls_params(x)
        E_m = p * rng.uniform(-0.999, 0.999, (300, 3)) - f - r
        rho, arg = tls.ik(E_m, f, p, r)
        assert np.all(np.abs(arg) <= 1)
        assert np.all(np.cos(rho) >= 0)  # principal branch
        np.testing.assert_allclose(tls.fk(rho, f, p, r), E_m, atol=1e-10)


def test_tls_fk_then_ik_round_trip(designs, rng):
    for x in designs:
        f, p, r = _tls_params(x)
        rho = rng.uniform(-1.5, 1.5, (300, 3))
        rho2, _ = tls.ik(tls.fk(rho, f, p, r), f, p, r)
        np.testing.assert_allclose(rho2, rho, atol=1e-9)


def test_tls_ik_closes_the_planar_leg_geometry(designs, rng):
    """D_u = P_u + p(-sin rho u + cos rho w) and Q_u = E + r u share their u coordinate (3.1)."""
    for x in designs:
        f, p, r = _tls_params(x)
        E_m = p * rng.uniform(-0.99, 0.99, (100, 3)) - f - r
        rho, _ = tls.ik(E_m, f, p, r)
        for i in range(3):
            u_hat, _, w_hat = (np.eye(3)[j] for j in poses.LEG_PERM[i])
            D = -f[i] * u_hat + p[i] * (-np.sin(rho[:, i, None]) * u_hat + np.cos(rho[:, i, None]) * w_hat)
            Q = E_m + r * u_hat
            np.testing.assert_allclose(D @ u_hat, Q @ u_hat, atol=1e-10)
            np.testing.assert_allclose(D @ w_hat, tls.crank_tip_w(rho, p)[:, i], atol=1e-10)


def test_tls_special_values_by_hand():
    f = np.array([100.0, 50.0, 20.0])
    p = np.array([120.0, 80.0, 60.0])
    r = 60.0
    # argument 0 -> rho = 0 exactly; argument 1/2 -> rho = -30 deg; argument -1/2 -> +30 deg
    E_m = np.array([-160.0, -110.0 + 40.0, -80.0 - 30.0])
    rho, arg = tls.ik(E_m, f, p, r)
    np.testing.assert_array_equal(arg, [0.0, 0.5, -0.5])
    assert rho[0] == 0.0
    np.testing.assert_allclose(rho[1:], [-np.pi / 6, np.pi / 6], rtol=0, atol=1e-15)
    # J_LV = diag(-p cos rho): at rho = 0 it is -p exactly
    np.testing.assert_allclose(
        tls.jacobian_LV_diag(rho, p), -p * np.array([1.0, math.sqrt(0.75), math.sqrt(0.75)]), atol=1e-12
    )
    # outside the box: NaN angle, |arg| > 1
    rho, arg = tls.ik(np.array([-160.0 + 121.0, -110.0 - 81.0, -80.0]), f, p, r)
    assert np.isnan(rho[0]) and np.isnan(rho[1]) and rho[2] == 0.0
    assert arg[0] > 1 and arg[1] < -1


def test_tls_box_of_table2_matches_model_numbers():
    """MODEL.md 3.2: for Table 2 the box is x in [-327.7, -59.5], y in [-337.4, -37.4], z in [-227.1, -27.3]."""
    x = vec(PAPER)
    f, p, r = _tls_params(x)
    lo = tls.fk(np.full(3, np.pi / 2), f, p, r)
    hi = tls.fk(np.full(3, -np.pi / 2), f, p, r)
    np.testing.assert_allclose(lo, [-327.7, -337.4, -227.1], atol=0.06)
    np.testing.assert_allclose(hi, [-59.5, -37.4, -27.3], atol=0.06)
    # just inside / just outside the x bound
    _, arg_in = tls.ik(np.array([hi[0] - 1e-6, -200.0, -100.0]), f, p, r)
    _, arg_out = tls.ik(np.array([hi[0] + 1e-6, -200.0, -100.0]), f, p, r)
    assert abs(arg_in[0]) <= 1 < abs(arg_out[0])


def test_J_LV_matches_central_differences_of_tls_fk(designs, rng):
    h = 1e-6
    for x in designs:
        f, p, r = _tls_params(x)
        rho = rng.uniform(-1.4, 1.4, (50, 3))
        J = tls.jacobian_LV_diag(rho, p)
        for i in range(3):
            dr = np.zeros(3)
            dr[i] = h
            fd = (tls.fk(rho + dr, f, p, r) - tls.fk(rho - dr, f, p, r)) / (2 * h)
            np.testing.assert_allclose(fd[:, i], J[:, i], rtol=1e-7, atol=1e-7)
            others = [j for j in range(3) if j != i]
            np.testing.assert_allclose(fd[:, others], 0.0, atol=1e-9)  # decoupled: J_LV is diagonal


# =============================================================================================
# TMS (MODEL.md 4, 7.2). Oracle: the planar four-bar built from its points.


def _fourbar_points(v, w, rho, delta, sigma, p, d, t):
    """(v, w) coordinates of D, K, Q, T of MODEL.md 4.1, written from the geometry."""
    n = lambda phi: np.stack([np.sin(phi), -np.cos(phi)], axis=-1)  # noqa: E731
    D = np.stack([np.zeros_like(rho), p * np.cos(rho)], axis=-1)
    K = D + d[..., None] * n(delta)
    Q = np.stack([v, w], axis=-1)
    T = Q + t[..., None] * n(sigma)
    return D, K, Q, T


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _random_tms_inputs(rng, n):
    p = rng.uniform(60, 140, (n, 2))
    d = rng.uniform(60, 160, (n, 2))
    c = rng.uniform(80, 200, (n, 2))
    t = rng.uniform(40, 100, (n, 2))
    v = rng.uniform(-200, 50, (n, 2))
    w = rng.uniform(-200, 50, (n, 2))
    rho = rng.uniform(-1.3, 1.3, (n, 2))
    sigma = rng.uniform(-np.pi, np.pi, (n, 2))
    delta = rng.uniform(-np.pi, np.pi, (n, 2))
    return v, w, rho, delta, sigma, p, d, c, t


def test_tms_constraint_is_the_coupler_length_equation(rng):
    v, w, rho, delta, sigma, p, d, c, t = _random_tms_inputs(rng, 500)
    _, K, _, T = _fourbar_points(v, w, rho, delta, sigma, p, d, t)
    Phi = np.sum((T - K) ** 2, axis=-1) - c**2
    np.testing.assert_allclose(tms.constraint(v, w, rho, delta, sigma, p, d, c, t), Phi, rtol=1e-12, atol=1e-8)


def test_tms_ik_closes_the_fourbar_and_its_branch_is_sign_F(rng):
    v, w, rho, _, sigma, p, d, c, t = _random_tms_inputs(rng, 3000)
    n_ok = 0
    for eps in (1.0, -1.0):
        delta, arg = tms.ik(v, w, rho, sigma, p, d, c, t, eps)
        D, K, Q, T = _fourbar_points(v, w, rho, delta, sigma, p, d, t)
        ok = np.abs(arg) <= 1
        n_ok += ok.sum()
        # reachability <=> |d - c| <= |T - D| <= d + c (MODEL.md 4.2)
        L = np.linalg.norm(T - D, axis=-1)
        np.testing.assert_array_equal(ok, (np.abs(d - c) <= L) & (L <= d + c))
        assert np.all(np.isnan(delta[~ok]))
        np.testing.assert_allclose(np.linalg.norm(T - K, axis=-1)[ok], c[ok], rtol=1e-10)
        F_geo = _cross2(K - D, T - K)
        strong = ok & (np.abs(F_geo) > 1e-3 * d * c)
        assert np.all(np.sign(F_geo[strong]) == eps)
        # F = (1/2) eps sqrt(A^2 + B^2 - C^2) (MODEL.md 4.3), A, B, C restated from 4.2
        a = v + t * np.sin(sigma)
        b = w - t * np.cos(sigma) - p * np.cos(rho)
        A, B, C = 2 * d * b, -2 * d * a, c**2 - a**2 - b**2 - d**2
        with np.errstate(invalid="ignore"):
            F_closed = 0.5 * eps * np.sqrt(A**2 + B**2 - C**2)
        np.testing.assert_allclose(F_geo[strong], F_closed[strong], rtol=1e-7)
        terms = tms.jacobian_terms(v, w, rho, delta, sigma, p, d, t)
        np.testing.assert_allclose(terms.F[ok], F_geo[ok], rtol=1e-9, atol=1e-6)
    assert n_ok > 500


def test_tms_fk_inverts_ik_with_eps_H_equal_sign_H(rng):
    v, w, rho, _, sigma, p, d, c, t = _random_tms_inputs(rng, 3000)
    checked = 0
    for eps in (1.0, -1.0):
        delta, arg = tms.ik(v, w, rho, sigma, p, d, c, t, eps)
        D, K, Q, T = _fourbar_points(v, w, rho, delta, sigma, p, d, t)
        H_geo = _cross2(T - Q, T - K)
        F_geo = _cross2(K - D, T - K)
        ok = (np.abs(arg) <= 0.999) & (np.abs(H_geo) > 0.05 * t * c) & (np.abs(F_geo) > 0.05 * d * c)
        sig2, arg2 = tms.fk(v, w, rho, delta, p, d, c, t, np.sign(H_geo))
        assert np.all(np.abs(arg2[ok]) <= 1)
        np.testing.assert_allclose(wrap(sig2[ok] - sigma[ok]), 0.0, atol=1e-9)
        # the other assembly sign gives the other closure (different sigma, same coupler length)
        sig3, _ = tms.fk(v, w, rho, delta, p, d, c, t, -np.sign(H_geo))
        _, K3, _, T3 = _fourbar_points(v, w, rho, delta, sig3, p, d, t)
        np.testing.assert_allclose(np.linalg.norm(T3 - K3, axis=-1)[ok], c[ok], rtol=1e-9)
        assert np.all(np.abs(wrap(sig3[ok] - sigma[ok])) > 1e-6)
        checked += ok.sum()
    assert checked > 300


def test_tms_jacobian_terms_are_half_partials_of_phi(rng):
    """F = -1/2 dPhi/d delta, G = -1/2 dPhi/d rho, D = 1/2 dPhi/dv, E = 1/2 dPhi/dw, H = 1/2 dPhi/d sigma."""
    v, w, rho, delta, sigma, p, d, c, t = _random_tms_inputs(rng, 200)
    T = tms.jacobian_terms(v, w, rho, delta, sigma, p, d, t)
    args = dict(v=v, w=w, rho=rho, delta=delta, sigma=sigma)
    h = {"v": 1e-4, "w": 1e-4, "rho": 1e-6, "delta": 1e-6, "sigma": 1e-6}

    def phi(**kw):
        a = {**args, **kw}
        return tms.constraint(a["v"], a["w"], a["rho"], a["delta"], a["sigma"], p, d, c, t)

    def dphi(name):
        return (phi(**{name: args[name] + h[name]}) - phi(**{name: args[name] - h[name]})) / (2 * h[name])

    tol = dict(rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(T.F, -0.5 * dphi("delta"), **tol)
    np.testing.assert_allclose(T.G, -0.5 * dphi("rho"), **tol)
    np.testing.assert_allclose(T.D, 0.5 * dphi("v"), **tol)
    np.testing.assert_allclose(T.E, 0.5 * dphi("w"), **tol)
    np.testing.assert_allclose(T.H, 0.5 * dphi("sigma"), **tol)


def test_tms_symmetric_fourbar_by_hand():
    """rho = 0, sigma = 0, v = 0: T lies straight below D at distance L. With d = c = L the
    input link, coupler and D-T form an equilateral triangle, so delta = -60 deg for eps = +1
    (coupler turns counter-clockwise about +u from the input link) and +60 deg for eps = -1."""
    p, d, c, t, L = 100.0, 50.0, 50.0, 30.0, 50.0
    w = p + t - L  # T_w = w - t = p - L
    for eps, expected in ((1.0, -np.pi / 3), (-1.0, np.pi / 3)):
        delta, arg = tms.ik(0.0, w, 0.0, 0.0, p, d, c, t, eps)
        assert arg == pytest.approx(-0.5, abs=1e-15)
        assert delta == pytest.approx(expected, abs=1e-12)
        terms = tms.jacobian_terms(0.0, w, 0.0, delta, 0.0, p, d, t)
        # K = D + d (sin delta, -cos delta) = (-/+ 25 sqrt3, 75); T - K = (+/- 25 sqrt3, -25)
        # F = cross2(K - D, T - K) = -/+ (...) : magnitude d * c * sin(60 deg)
        assert terms.F == pytest.approx(eps * d * c * math.sin(math.pi / 3), rel=1e-12)
        assert terms.D == pytest.approx(-eps * -25 * math.sqrt(3), rel=1e-12)  # a_v
        assert terms.E == pytest.approx(-25.0, rel=1e-12)  # a_w
        assert terms.G == 0.0  # rho = 0: the best TLS posture makes J_rho singular (MODEL 10.9)
        assert terms.H == pytest.approx(t * terms.D, rel=1e-12)  # sigma = 0: H = t a_v
    # out of reach: |T - D| > d + c
    delta, arg = tms.ik(0.0, p + t - 101.0, 0.0, 0.0, p, d, c, t, 1.0)
    assert np.isnan(delta) and abs(arg) > 1


# =============================================================================================
# RTS (MODEL.md 5, 7.3). Oracle: u_beta from the leg triads.


def _ub_oracle(sigma, alpha, o):
    out = []
    for i in range(2):
        u_hat, v_hat, w_hat = [(X_HAT, Y_HAT, Z_HAT), (Y_HAT, Z_HAT, X_HAT)][i]
        lam = sigma[..., i, None] + o[..., i, None]
        out.append(
            np.cos(alpha[..., i, None]) * u_hat
            + np.sin(alpha[..., i, None]) * (np.sin(lam) * v_hat - np.cos(lam) * w_hat)
        )
    return np.stack(out, axis=-2)


def _random_rts(rng, n, lo=30.0, hi=90.0):
    alpha = np.deg2rad(rng.uniform(lo, hi, (n, 2)))
    beta = np.deg2rad(rng.uniform(lo, hi, (n, 2)))
    o = rng.uniform(-np.pi, np.pi, (n, 2))
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    return e, alpha, beta, o


def test_rts_u_beta_matches_model_formula(rng):
    e, alpha, beta, o = _random_rts(rng, 200)
    sigma = rng.uniform(-np.pi, np.pi, (200, 2))
    ub = rts.u_beta(sigma, alpha, o)
    np.testing.assert_allclose(ub, _ub_oracle(sigma, alpha, o), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(ub, axis=-1), 1.0, atol=1e-14)
    np.testing.assert_allclose(ub[:, 0, 0], np.cos(alpha[:, 0]), atol=1e-15)  # angle to +x is alpha_x
    np.testing.assert_allclose(ub[:, 1, 1], np.cos(alpha[:, 1]), atol=1e-15)  # angle to +y is alpha_y
    G = rts.constraint(e, sigma, alpha, beta, o)
    np.testing.assert_allclose(G, np.einsum("nij,nj->ni", _ub_oracle(sigma, alpha, o), e) - np.cos(beta), atol=1e-14)


def test_rts_ik_closes_and_branch_is_minus_sign_J_AS(rng):
    e, alpha, beta, o = _random_rts(rng, 3000)
    n_ok = 0
    for eps in (1.0, -1.0):
        sigma, arg = rts.ik(e, alpha, beta, o, np.full((3000, 2), eps))
        ok = np.abs(arg) <= 1
        n_ok += ok.sum()
        assert np.all(np.isnan(sigma[~ok]))
        ub = _ub_oracle(sigma, alpha, o)
        np.testing.assert_allclose(np.einsum("nij,nj->ni", ub, e)[ok], np.cos(beta)[ok], atol=1e-12)
        J_as = np.stack([np.sum(np.cross(X_HAT, ub[:, 0]) * e, -1), np.sum(np.cross(Y_HAT, ub[:, 1]) * e, -1)], axis=1)
        strong = ok & (np.abs(J_as) > 1e-3)
        assert np.all(-np.sign(J_as[strong]) == eps)
        np.testing.assert_allclose(rts.J_AS_diag(e, rts.u_beta(sigma, alpha, o))[ok], J_as[ok], atol=1e-13)
        # J_AS = -eps sqrt(A^2 + B^2 - C^2) (MODEL.md 5.3), with A, B, C restated from 5.2
        el = np.stack([e, e[:, [1, 2, 0]]], axis=1)  # leg x (x,y,z); leg y (y,z,x)
        A = -np.sin(alpha) * el[..., 2]
        B = np.sin(alpha) * el[..., 1]
        C = np.cos(beta) - np.cos(alpha) * el[..., 0]
        with np.errstate(invalid="ignore"):
            closed = -eps * np.sqrt(A**2 + B**2 - C**2)
        np.testing.assert_allclose(J_as[strong], closed[strong], rtol=1e-7, atol=1e-9)
    assert n_ok > 1000


def test_rts_two_branches_mirror_through_the_plane_u_e(rng):
    e, alpha, beta, o = _random_rts(rng, 1000)
    s_p, arg = rts.ik(e, alpha, beta, o, np.ones((1000, 2)))
    s_m, _ = rts.ik(e, alpha, beta, o, -np.ones((1000, 2)))
    ok = np.all(np.abs(arg) <= 1, axis=-1)
    ub_p, ub_m = rts.u_beta(s_p, alpha, o)[ok], rts.u_beta(s_m, alpha, o)[ok]
    for i, u_hat in enumerate((X_HAT, Y_HAT)):
        nrm = np.cross(u_hat, e[ok])
        nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
        refl = ub_p[:, i] - 2 * np.sum(ub_p[:, i] * nrm, axis=-1, keepdims=True) * nrm
        np.testing.assert_allclose(refl, ub_m[:, i], atol=1e-10)


def test_rts_fk_inverts_ik_with_eps_P_equal_sign_det(rng):
    e, alpha, beta, o = _random_rts(rng, 4000)
    checked = 0
    for mode in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        sigma, arg = rts.ik(e, alpha, beta, o, np.broadcast_to(np.array(mode, float), (4000, 2)))
        ub = _ub_oracle(sigma, alpha, o)
        with np.errstate(invalid="ignore"):
            det = np.linalg.det(np.stack([ub[:, 0], ub[:, 1], e], axis=-1))
        ok = np.all(np.abs(arg) <= 0.999, axis=-1) & (np.abs(det) > 0.05)
        e2, rad = rts.fk(sigma, alpha, beta, o, np.sign(det))
        assert np.all(rad[ok] >= 0)
        np.testing.assert_allclose(e2[ok], e[ok], atol=1e-9)
        # opposite assembly mode: the mirror image through the plane (x_beta, y_beta)
        e3, _ = rts.fk(sigma, alpha, beta, o, -np.sign(det))
        np.testing.assert_allclose(np.einsum("nij,nj->ni", ub, e3)[ok], np.cos(beta)[ok], atol=1e-10)
        np.testing.assert_allclose(np.linalg.norm(e3[ok], axis=-1), 1.0, atol=1e-12)
        with np.errstate(invalid="ignore"):
            det3 = np.linalg.det(np.stack([ub[:, 0], ub[:, 1], e3], axis=-1))
        assert np.all(np.sign(det3[ok]) == -np.sign(det[ok]))
        np.testing.assert_allclose(rts.det_beta(e, rts.u_beta(sigma, alpha, o))[ok], det[ok], atol=1e-12)
        checked += ok.sum()
    assert checked > 1000


def test_J_AS_is_dGamma_dsigma(rng):
    e, alpha, beta, o = _random_rts(rng, 300)
    sigma = rng.uniform(-np.pi, np.pi, (300, 2))
    h = 1e-6
    J = rts.J_AS_diag(e, rts.u_beta(sigma, alpha, o))
    for i in range(2):
        ds = np.zeros(2)
        ds[i] = h
        fd = (rts.constraint(e, sigma + ds, alpha, beta, o) - rts.constraint(e, sigma - ds, alpha, beta, o)) / (2 * h)
        np.testing.assert_allclose(fd[:, i], J[:, i], atol=1e-9)
        np.testing.assert_allclose(fd[:, 1 - i], 0.0, atol=1e-12)  # J_AS is diagonal


def test_J_AP_rows_match_the_rate_of_Gamma_under_rotation_of_e(rng):
    """With e_dot = omega x e and sigma fixed, Gamma_dot = -(u_beta x e) . omega, so that
    J_AS sigma_dot = J_AP omega keeps Gamma = 0 (MODEL.md 7.3)."""
    e, alpha, beta, o = _random_rts(rng, 300)
    sigma = rng.uniform(-np.pi, np.pi, (300, 2))
    ub = rts.u_beta(sigma, alpha, o)
    J = rts.J_AP(e, ub)
    h = 1e-6
    for k in range(3):
        om = np.zeros(3)
        om[k] = 1.0
        ep, em = rotate(e, h * om), rotate(e, -h * om)
        fd = (rts.constraint(ep, sigma, alpha, beta, o) - rts.constraint(em, sigma, alpha, beta, o)) / (2 * h)
        np.testing.assert_allclose(J[:, :, k], -fd, atol=1e-9)
    # rows are orthogonal to e: spin about e is free
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, e), 0.0, atol=1e-15)
    # and the sum rule: J_AS sigma_dot = J_AP omega keeps Gamma constant along a combined motion
    omega = rng.normal(size=(300, 3))
    J_as = rts.J_AS_diag(e, ub)
    sdot = np.einsum("nij,nj->ni", J, omega) / J_as
    ok = np.all(np.abs(J_as) > 0.05, axis=-1)
    G1 = rts.constraint(rotate(e, h * omega), sigma + h * sdot, alpha, beta, o)
    G0 = rts.constraint(rotate(e, -h * omega), sigma - h * sdot, alpha, beta, o)
    np.testing.assert_allclose(((G1 - G0) / (2 * h))[ok], 0.0, atol=1e-8)


def _angle(a, b):
    return np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1))


def test_rts_reachability_is_the_spherical_triangle_inequality(rng):
    """MODEL.md 5.2: reachable iff |alpha - beta| <= angle(e, +u) <= alpha + beta (alpha, beta in
    the default bounds [30, 90] deg, where alpha + beta <= 180 deg). Independent of o."""
    n = 20000
    e, alpha, beta, o = _random_rts(rng, n)
    _, arg = rts.ik(e, alpha, beta, o, np.ones((n, 2)))
    margin = 1e-6
    for i, u_hat in enumerate((X_HAT, Y_HAT)):
        ang = _angle(e, u_hat)
        lo, hi = np.abs(alpha[:, i] - beta[:, i]), alpha[:, i] + beta[:, i]
        inside = (lo + margin < ang) & (ang < hi - margin)
        outside = (ang < lo - margin) | (ang > hi + margin)
        assert inside.sum() > 1000 and outside.sum() > 1000
        assert np.all(np.abs(arg[inside, i]) <= 1)
        assert np.all(np.abs(arg[outside, i]) > 1)
    # o never matters
    _, arg2 = rts.ik(e, alpha, beta, rng.uniform(-np.pi, np.pi, (n, 2)), np.ones((n, 2)))
    np.testing.assert_allclose(arg2, arg, atol=0, rtol=0)


def test_rts_reachability_for_wide_links_includes_the_360_bound(rng):
    """For alpha + beta > 180 deg the triangle inequality also needs angle <= 360 - alpha - beta.
    (MODEL.md 5.2 states only the first two bounds; they suffice inside the default [30, 90] bounds.)"""
    n = 20000
    e, alpha, beta, o = _random_rts(rng, n, lo=5.0, hi=175.0)
    _, arg = rts.ik(e, alpha, beta, o, np.ones((n, 2)))
    margin = 1e-6
    for i, u_hat in enumerate((X_HAT, Y_HAT)):
        ang = _angle(e, u_hat)
        lo = np.abs(alpha[:, i] - beta[:, i])
        hi = np.minimum(alpha[:, i] + beta[:, i], 2 * np.pi - alpha[:, i] - beta[:, i])
        inside = (lo + margin < ang) & (ang < hi - margin)
        outside = (ang < lo - margin) | (ang > hi + margin)
        assert np.all(np.abs(arg[inside, i]) <= 1)
        assert np.all(np.abs(arg[outside, i]) > 1)


def test_rts_special_pose_e_z_with_alpha_equal_beta():
    """e = z, alpha = beta = 60 deg. Leg x: u_beta . z = -sin(a) cos(lambda) = cos(a) ->
    cos(lambda_x) = -cot(60 deg) -> lambda_x = pi +/- acos(1/sqrt 3). Leg y: u_beta . z =
    sin(a) sin(lambda) = cos(a) -> lambda_y = pi/2 +/- acos(1/sqrt 3) (upper sign: eps = +1).
    MODEL.md 5.3: in the default mode x_beta is on the -y side and y_beta on the +x side."""
    a = np.deg2rad(60.0)
    alpha = beta = np.array([a, a])
    o = np.deg2rad(np.array([-19.2229, 43.2917]))
    g = math.acos(1 / math.sqrt(3))  # 54.7356... deg
    for eps in (1.0, -1.0):
        sigma, arg = rts.ik(Z_HAT, alpha, beta, o, np.array([eps, eps]))
        # leg x: A = -sin a, B = 0, C = cos a; leg y: A = 0, B = sin a, C = cos a -> C/R = cot a
        np.testing.assert_allclose(arg, [1 / math.sqrt(3), 1 / math.sqrt(3)], atol=1e-15)
        lam_expected = np.array([np.pi + eps * g, np.pi / 2 + eps * g])
        np.testing.assert_allclose(wrap(sigma + o - lam_expected), 0.0, atol=1e-12)
        ub = rts.u_beta(sigma, alpha, o)
        if eps == 1.0:
            assert ub[0, 1] < 0 and ub[1, 0] > 0
            np.testing.assert_allclose(ub[0], [0.5, -math.sqrt(0.75) * math.sin(g), 0.5], atol=1e-12)
            np.testing.assert_allclose(ub[1], [math.sqrt(0.75) * math.sin(g), 0.5, 0.5], atol=1e-12)
        else:
            assert ub[0, 1] > 0 and ub[1, 0] < 0
    # Table 2's alpha_x + beta_x = 102.64 deg: e = -x (angle 180 deg) is out of reach of leg x
    x = vec(PAPER)
    _, arg = rts.ik(-X_HAT, leg_pair(x, "alpha"), leg_pair(x, "beta"), leg_pair(x, "o"), np.ones(2))
    assert abs(arg[0]) > 1


# =============================================================================================
# z leg (MODEL.md 6)


def test_zleg_span_and_closure(rng):
    E_m = rng.uniform(-250, 50, (500, 3))
    rho_z = rng.uniform(-1.3, 1.3, 500)
    p_z = rng.uniform(60, 140, 500)
    L = zleg.span(E_m, rho_z, p_z)
    # D_z at (x, y) = (0, p_z cos rho_z), Q_z = E + r z at (x_E, y_E) in the plane z = z_E + r
    np.testing.assert_allclose(
        L, np.linalg.norm(E_m[:, :2] - np.stack([0 * p_z, p_z * np.cos(rho_z)], -1), axis=-1), rtol=1e-14
    )
    d_z, c_z = rng.uniform(30, 150, 500), rng.uniform(30, 150, 500)
    short = zleg.closure_shortfall(L, d_z, c_z)
    closes = (np.abs(d_z - c_z) <= L) & (L <= d_z + c_z)
    np.testing.assert_array_equal(short == 0, closes)
    assert np.all(short >= 0)
