"""The identification model (MODEL.md 21.2-21.3): the residuals' Jacobian against central differences, the
identifiability by QR with pivoting on hand-built and hand-derived cases, O1 by hand, the fast greedy
D-optimal choice against the criterion computed directly, and the calibrated budget's full-covariance
first order against the diagonal one of arcube.accuracy and against a Monte Carlo with the exact FK.
"""

from __future__ import annotations


import numpy as np
import pytest
from conftest import reachable_poses

from arcube.accuracy.first_order import budget_from_jacobians, source_jacobians
from arcube.accuracy.monte_carlo import exact_errors, split
from arcube.accuracy.sources import N_SOURCES
from arcube.calibrate.budget import correlated_draws, first_order_rms
from arcube.calibrate.identifiability import identifiability, observability
from arcube.calibrate.model import UNKNOWNS, make_problem, model_pose, unknown_values
from arcube.calibrate.poses import greedy_d_optimal, tip_and_tilt_rows
from arcube.model.design import Design
from designs import DEMO, DEMO_MODE, plan_right
from arcube.model.mechanism import inverse_kinematics, parse_mode

U = {n: i for i, n in enumerate(UNKNOWNS)}


def reading_rows(design: Design, mode: str, points: int = 5, poses=None):
    """(q_read deg (P, 5), E, e, assembly) at the poses (default: the plan's points) the design reaches (IK, q0 = 0)."""
    if poses is None:
        _, task = plan_right(points)
        poses = (task.E, task.e)
    E, e = poses
    sol = inverse_kinematics(design.to_vector(), E, e, parse_mode(mode))
    ok = sol.reachable
    q = np.rad2deg(np.concatenate([sol.rho, sol.delta], axis=-1))[ok]
    return q, E[ok], e[ok], sol.assembly[ok]


def _problem(design=DEMO, mode=DEMO_MODE, points=5, poses=None):
    q, E, e, asm = reading_rows(design, mode, points, poses)
    rng = np.random.default_rng(3)
    # measured poses a few tenths of a mm and degree off the nominal ones: residuals not 0
    E = E + rng.normal(0.0, 0.3, E.shape)
    e = e + rng.normal(0.0, 0.005, e.shape)
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    return make_problem(design.to_vector(), np.zeros(5), q, E, e, 0.15, 0.1, assembly=asm)


@pytest.mark.parametrize("spread", [0.0, 1.0])
def test_residual_jacobian_equals_central_differences(spread):
    p = _problem()
    z = np.random.default_rng(7).normal(0.0, spread, len(UNKNOWNS))
    J = p.jacobian(p.pose(z))
    h = 1e-5
    for k in range(len(UNKNOWNS)):
        dz = np.zeros_like(z)
        dz[k] = h
        fd = (p.residuals(p.pose(z + dz)) - p.residuals(p.pose(z - dz))) / (2.0 * h)
        scale = max(np.max(np.abs(J[..., k])), 1e-3)
        assert np.max(np.abs(J[..., k] - fd)) <= 1e-6 * scale + 1e-8, UNKNOWNS[k]
    # sigma_e converted to radians: the axis rows of a zero offset equal its J_e column / (0.1 deg in rad)
    x, q0 = p.state(z)
    pose = model_pose(x, q0, p.q_read, p.assembly)
    np.testing.assert_allclose(
        J[:, 3:, U["q0_rho_x"]], -pose.de[..., U["q0_rho_x"]] * p.scale[U["q0_rho_x"]] / np.deg2rad(0.1)
    )


def test_identifiability_of_a_built_matrix():
    rng = np.random.default_rng(1)
    x1, x2, x3 = rng.normal(size=(3, 50))
    J = np.stack([x1, x2, x1 - 3.0 * x2, x3, np.zeros(50)], axis=1)
    ident = identifiability(J)
    assert ident.rank == 3 and ident.identifiable[3] and not ident.identifiable[4]
    out = [k for k in range(3) if not ident.identifiable[k]]
    assert len(out) == 1
    k = out[0]
    conf = ident.confounded_with(k)
    assert {i for i, _ in conf} == {0, 1, 2} - {k}
    np.testing.assert_allclose(sum(c * J[:, i] for i, c in conf), J[:, k], atol=1e-12)
    assert ident.confounded_with(4) == []  # a column of zeros moves nothing: confounded with nothing
    assert all(ident.confounded_with(i) == [] for i in range(4) if ident.identifiable[i])


def _scaled_J(problem, rows="all"):
    J = problem.jacobian(problem.pose(np.zeros(len(UNKNOWNS))))
    J = J[:, :3] if rows == "tip" else J
    return J.reshape(-1, len(UNKNOWNS))


def test_radius_and_frame_links_enter_only_as_their_sum():
    """C_u = -f_u - r - p_u sin(rho_u) (MODEL.md 3.3), and r enters nowhere else: J_r = J_fx + J_fy + J_fz in design units,
    so one of the four is not identifiable and is confounded with the other three with coefficients +-1."""
    p = _problem()
    ident = identifiability(_scaled_J(p))
    group = ["r", "f_x", "f_y", "f_z"]
    out = [n for n in group if not ident.identifiable[U[n]]]
    assert len(out) == 1 and ident.rank == 30
    k = out[0]
    conf = {UNKNOWNS[i]: c for i, c in ident.confounded_with(U[k], p.scale)}
    expected = (
        {n: 1.0 for n in group if n != k} if k == "r" else {n: (1.0 if n == "r" else -1.0) for n in group if n != k}
    )
    assert set(conf) == set(expected)
    for n, c in expected.items():
        assert conf[n] == pytest.approx(c, abs=1e-9)


def test_base_position_and_frame_links_confounded_when_they_enter_the_tip_as_a_sum():
    """With no mounting rotation and L = 0 (the paper's design) the tip is E = m + C_m: a frame link f_u moves it as -m_u.
    On the tip rows alone, m_u and f_u cannot both be identified. The axis separates them: f_u also moves the
    four-bars' geometry (the TMS sees C's coordinates), so with the axis rows every m_u and f_u is identifiable."""
    paper = Design.paper()
    poses = reachable_poses(np.random.default_rng(4), paper.to_vector()[:23], np.ones(4), 40)
    p = _problem(paper, "+,+,+,+", poses=poses)
    J_tip = _scaled_J(p, "tip")
    for u in "xyz":
        # the hand relation, in design units (mm per mm): J_f_u = -J_m_u
        np.testing.assert_allclose(
            J_tip[:, U[f"f_{u}"]] / p.scale[U[f"f_{u}"]], -J_tip[:, U[f"m_{u}"]] / p.scale[U[f"m_{u}"]], atol=1e-9
        )
    ident = identifiability(J_tip)
    base = {"m_x", "m_y", "m_z", "f_x", "f_y", "f_z", "r"}
    for u in "xyz":
        assert not (ident.identifiable[U[f"m_{u}"]] and ident.identifiable[U[f"f_{u}"]])
    for k in np.flatnonzero(~ident.identifiable):
        if UNKNOWNS[k] in base:
            conf = ident.confounded_with(int(k))
            assert conf and {UNKNOWNS[i] for i, _ in conf} <= base
            np.testing.assert_allclose(
                sum(c * J_tip[:, i] for i, c in conf), J_tip[:, k], atol=1e-6 * np.abs(J_tip).max()
            )
    full = identifiability(_scaled_J(p))
    assert all(full.identifiable[U[n]] for n in ("m_x", "m_y", "m_z", "f_x", "f_y"))


def test_observability_by_hand():
    J = np.zeros((12, 2))
    J[0, 0], J[1, 1] = 2.0, 8.0  # singular values 8 and 2
    o1, cond = observability(J, n_poses=4)
    assert o1 == pytest.approx(np.sqrt(16.0) / 2.0) and cond == pytest.approx(4.0)
    o1, cond = observability(np.ones((6, 2)), 1)  # rank 1 of 2: one direction not observable at all
    assert o1 < 1e-6 and cond > 1e12


def test_greedy_d_optimal_equals_the_criterion_computed_directly():
    rng = np.random.default_rng(5)
    J = rng.normal(size=(60, 5, 7)) * rng.uniform(0.1, 3.0, (60, 1, 1))
    fast = greedy_d_optimal(J, 12)
    M = 1e-9 * np.eye(7)
    free = list(range(60))
    for step in range(12):
        values = [np.linalg.slogdet(M + J[c].T @ J[c])[1] for c in free]
        best = free[int(np.argmax(values))]
        assert fast[step] == best
        free.remove(best)
        M = M + J[best].T @ J[best]


def test_tip_and_tilt_rows_keep_the_information_matrix():
    p = _problem()
    J = p.jacobian(p.pose(np.zeros(len(UNKNOWNS))))
    J5 = tip_and_tilt_rows(J, p.e)
    # the model's axis is not exactly the measured one: project on the model's (its derivative is perpendicular to it)
    J5m = tip_and_tilt_rows(J, p.pose(np.zeros(len(UNKNOWNS))).e)
    full = np.einsum("cin,cim->nm", J, J)
    np.testing.assert_allclose(np.einsum("cin,cim->nm", J5m, J5m), full, rtol=1e-10, atol=1e-8 * np.abs(full).max())
    assert J5.shape == (len(J), 5, len(UNKNOWNS))


def test_full_covariance_rms_equals_the_diagonal_budget_and_the_exact_monte_carlo():
    _, task = plan_right(4)
    x, mode = DEMO.to_vector(), parse_mode(DEMO_MODE)
    G_E, G_e, valid = source_jacobians(x, task.E, task.e, mode)
    assert valid.all()
    sig = np.random.default_rng(2).uniform(0.01, 0.2, N_SOURCES)
    lat, _, _ = first_order_rms(G_E, G_e, task.e, np.diag(sig**2))
    ref = budget_from_jacobians(G_E, G_e, task.e, 3.0 * sig, sig)  # the 20.3 RMS with a diagonal covariance
    np.testing.assert_allclose(lat, ref.lateral_rms_mm, rtol=1e-12)

    # correlated, tiny (linear regime): the exact FK's RMS over 4000 robots approaches sqrt(trace(P G Sigma G^T P))
    rng = np.random.default_rng(11)
    A = rng.normal(size=(31, 31)) * 1e-3
    cov = A @ A.T
    Sigma = np.zeros((N_SOURCES, N_SOURCES))
    Sigma[:31, :31] = cov
    lat, _, _ = first_order_rms(G_E, G_e, task.e, Sigma)
    per = np.zeros((4000, N_SOURCES))
    per[:, :31] = correlated_draws(rng, cov, 4000)
    np.testing.assert_allclose(np.cov(per[:, :31].T), cov, atol=0.1 * np.abs(cov).max())
    dp, dq0 = split(per)
    sol = inverse_kinematics(x, task.E, task.e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    err = exact_errors(x, task.E, task.e, q, sol.assembly, dp, np.broadcast_to(dq0[:, None, :], (4000, len(q), 5)))
    mc = np.sqrt(np.mean(err.lateral_mm**2, axis=0))
    np.testing.assert_allclose(mc, lat, rtol=0.08)  # 4000 draws: the RMS's sampling error is ~1.1 %


def test_unknowns_round_trip_into_a_design():
    x = DEMO.to_vector()
    q0 = np.arange(5) * 0.01
    u = unknown_values(x, q0)
    assert u.shape == (31,) and np.array_equal(u[26:], q0)
    p = make_problem(x, q0, *reading_rows(DEMO, DEMO_MODE)[:3], 0.15, 0.1)
    x2, q02 = p.state(np.zeros(31))
    assert np.array_equal(x2, x) and np.array_equal(q02, q0)
