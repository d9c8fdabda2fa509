"""Condition numbers (MODEL.md 8.1): the closed forms against numpy's SVD / cond."""

from __future__ import annotations

import numpy as np
import pytest

from arcube.evaluation import indices
from arcube.model.mechanism import inverse_kinematics, jacobians

from naive import vec


def _svd_kappa(M):
    s = np.linalg.svd(M, compute_uv=False)
    with np.errstate(divide="ignore"):
        return np.where(s[..., -1] > 0, s[..., 0] / s[..., -1], np.inf)


def test_kappa_diag_matches_svd(rng):
    for k in (2, 3):
        d = rng.normal(size=(500, k)) * rng.uniform(0.01, 100, (500, 1))
        d[::7, 0] *= 1e-6  # some ill-conditioned
        np.testing.assert_allclose(indices.kappa_diag(d), _svd_kappa(d[..., :, None] * np.eye(k)), rtol=1e-12)
        np.testing.assert_allclose(indices.kappa_diag(d), np.linalg.cond(d[..., :, None] * np.eye(k)), rtol=1e-12)
    # hand values, signs do not matter
    assert indices.kappa_diag([-2.0, 8.0]) == 4.0
    assert indices.kappa_diag([3.0, -3.0, 3.0]) == 1.0


def test_kappa_diag_rank_deficient_is_inf():
    np.testing.assert_array_equal(indices.kappa_diag(np.array([[0.0, 1.0], [0.0, 0.0], [2.0, -0.0]])), np.inf)


@pytest.mark.parametrize("n", [2, 3, 5])
def test_kappa_2xn_matches_svd(rng, n):
    M = rng.normal(size=(1000, 2, n)) * rng.uniform(0.01, 100, (1000, 1, 1))
    # nearly dependent rows for a share of them (kappa up to ~1e3)
    M[::5, 1] = M[::5, 0] * 3.0 + 1e-2 * rng.normal(size=(200, n)) * np.abs(M[::5, 0]).max(-1, keepdims=True)
    ref = _svd_kappa(M)
    keep = ref < 1e3
    assert keep.sum() > 800 and ref[keep].max() > 100
    np.testing.assert_allclose(indices.kappa_2xn(M)[keep], ref[keep], rtol=1e-9)
    np.testing.assert_allclose(indices.kappa_2xn(M)[keep], np.linalg.cond(M)[keep], rtol=1e-9)


@pytest.mark.parametrize("n", [2, 3])
def test_kappa_2xn_accurate_for_ill_conditioned_full_rank_matrices(rng, n):
    """kappa ~ 1e5..1e7 is well inside double precision: the SVD (and the closed form with g taken
    as the root of the sum of squared 2x2 minors, as the docstring and MODEL.md 8.1 say) agree to
    ~1e-8. Computing g^2 as |r0|^2 |r1|^2 - (r0.r1)^2 cancels catastrophically (error ~ eps kappa^2)."""
    M = rng.normal(size=(1000, 2, n)) * rng.uniform(0.01, 100, (1000, 1, 1))
    M[:, 1] = M[:, 0] * 3.0 + 1e-6 * rng.normal(size=(1000, n)) * np.abs(M[:, 0]).max(-1, keepdims=True)
    ref = _svd_kappa(M)
    keep = (ref > 1e5) & (ref < 1e7)
    assert keep.sum() > 100  # enough ill-conditioned samples for every n
    # the oracle itself: Cauchy-Binet with explicit minors reproduces the SVD
    i, j = np.triu_indices(n, 1)
    minors = M[:, 0, i] * M[:, 1, j] - M[:, 0, j] * M[:, 1, i]
    cb = indices.kappa_from_invariants(np.sum(M * M, axis=(-2, -1)), np.sqrt(np.sum(minors**2, axis=-1)))
    np.testing.assert_allclose(cb[keep], ref[keep], rtol=1e-6)
    np.testing.assert_allclose(indices.kappa_2xn(M)[keep], ref[keep], rtol=1e-6)


def test_kappa_2xn_hand_values_and_rank_deficiency():
    # singular values 3 and 1
    assert indices.kappa_2xn(np.array([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0]])) == pytest.approx(3.0, rel=1e-15)
    # orthogonal rows of equal length: kappa = 1
    assert indices.kappa_2xn(np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0]])) == pytest.approx(1.0, rel=1e-15)
    # exactly rank 1 and rank 0 -> +inf
    assert indices.kappa_2xn(np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0]])) == np.inf
    assert indices.kappa_2xn(np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])) == np.inf
    assert indices.kappa_2xn(np.zeros((2, 3))) == np.inf


def test_kappa_from_invariants(rng):
    M = rng.normal(size=(300, 2, 3))
    F = np.sum(M * M, axis=(-2, -1))
    g = np.sqrt(np.linalg.det(M @ np.swapaxes(M, -1, -2)))
    np.testing.assert_allclose(indices.kappa_from_invariants(F, g), _svd_kappa(M), rtol=1e-9)
    np.testing.assert_allclose(indices.kappa_from_invariants(F, -g), _svd_kappa(M), rtol=1e-9)  # |g| used
    assert indices.kappa_from_invariants(5.0, 0.0) == np.inf
    # F = s1^2 + s2^2 = 10, g = s1 s2 = 3 -> kappa = 3
    assert indices.kappa_from_invariants(10.0, 3.0) == pytest.approx(3.0, rel=1e-15)


def test_condition_numbers_match_svd_of_jacobians(pose_bank):
    """All seven kappas, in JACOBIAN_NAMES order, against numpy.linalg.svd of jacobians()."""
    assert indices.JACOBIAN_NAMES == ("J_LV", "J_AV", "J_sigma", "J_AS", "J_AP", "J_rho", "J_delta")
    for x, mode, E, e in pose_bank:
        sol = inverse_kinematics(x, E, e, mode)
        kap = indices.condition_numbers(sol, x)
        J = jacobians(sol, x)
        assert kap.shape == (len(E), 7)
        for i, name in enumerate(indices.JACOBIAN_NAMES):
            np.testing.assert_allclose(kap[:, i], _svd_kappa(J[name]), rtol=1e-9, err_msg=name)
            np.testing.assert_allclose(kap[:, i], np.linalg.cond(J[name]), rtol=1e-9, err_msg=name)
        # MODEL.md 8.1: g^2 of J_AV is the sum of its squared 2x2 minors; g of J_AP is |det[x_b, y_b, e]|
        Jav, Jap = J["J_AV"], J["J_AP"]
        np.testing.assert_allclose(
            np.linalg.det(Jav @ np.swapaxes(Jav, -1, -2)),
            (Jav[:, 0, 1] * Jav[:, 1, 0]) ** 2
            + (Jav[:, 0, 2] * Jav[:, 1, 0]) ** 2
            + (Jav[:, 0, 1] * Jav[:, 1, 2]) ** 2,
            rtol=1e-9,
        )
        det = np.linalg.det(np.stack([sol.u_beta[:, 0], sol.u_beta[:, 1], e], axis=-1))
        np.testing.assert_allclose(np.sqrt(np.linalg.det(Jap @ np.swapaxes(Jap, -1, -2))), np.abs(det), rtol=1e-8)
        assert np.all(kap >= 1.0)


def test_condition_numbers_inf_at_singularity_and_nan_where_unreachable():
    """rho_x = 0 exactly (TLS argument 0) makes G_x = 0: kappa(J_rho) = +inf, the rest finite."""
    vals = dict(
        m_x=10.0,
        m_y=-20.0,
        m_z=30.0,
        f_x=40.0,
        f_y=50.0,
        f_z=60.0,
        p_x=100.0,
        p_y=110.0,
        p_z=90.0,
        d_x=120.0,
        d_y=130.0,
        d_z=80.0,
        c_x=150.0,
        c_y=160.0,
        t_x=60.0,
        t_y=70.0,
        r=60.0,
        o_x=10.0,
        o_y=-20.0,
        alpha_x=60.0,
        alpha_y=60.0,
        beta_x=60.0,
        beta_y=60.0,
    )
    x = vec(vals)
    E = np.array([10.0 - 40.0 - 60.0, -20.0 - 50.0 - 60.0 + 30.0, 30.0 - 60.0 - 60.0])  # rho_x = 0, rho_y != 0
    e = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    sol = inverse_kinematics(x, E, e)
    assert sol.reachable and sol.rho[0] == 0.0 and sol.rho[1] != 0.0
    kap = indices.condition_numbers(sol, x)
    i_rho = indices.JACOBIAN_NAMES.index("J_rho")
    assert kap[i_rho] == np.inf
    assert np.all(np.isfinite(np.delete(kap, i_rho)))
    with np.errstate(invalid="ignore"):
        sol_bad = inverse_kinematics(x, E + np.array([500.0, 0, 0]), e)
        kap_bad = indices.condition_numbers(sol_bad, x)
    assert np.isnan(kap_bad[0])  # J_LV of a NaN crank angle
