"""Physical performance at the drill tip (MODEL.md 15): oracles written from the spec, not the code.

* J_E and J_e against central finite differences of the closed-form forward kinematics (MODEL.md
  5.5 with 13: E = C - L e in the patient frame), with and without a mounting rotation and tool
  offset; and, with neither, against J_LV of MODEL.md 7.1 restated by hand;
* the 15.2 box maxima against dense Monte Carlo samples of the joint errors;
* the 15.3 torques against virtual work with FK displacements and a dense sweep of lateral forces;
* the 15.4 deflection against the spring equilibrium solved directly, and λ_max against eigvalsh;
* a hand-worked example of every metric (units: mm/rad, N·mm -> N·m, N·m/rad -> N·mm/rad);
* invariance to the spin-free basis b1, b2 and to the frame; batch = loop; NaN / -1 where the IK
  fails; bad parameters raise InputError naming the parameter.

Reachable tasks with a mounting rotation and tool offset are made by hand (MODEL.md 13): a pose
(E_p, e_p) that a paper-frame design reaches becomes, for the same links mounted with rotation R and
offset L, e_w = R e_p, C_w = m + R (E_p - m), E_w = C_w - L e_w.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.evaluation.performance import ACTUATOR_NAMES, TipMetrics, forward_jacobian, tip_metrics
from arcube.model.mechanism import forward_kinematics, inverse_kinematics

from designs import placed_case
from naive import ALL_MODES_ORACLE, rotation


CASES = [
    # (design seed or None for the paper, mount (deg), L (mm), mode index)
    (None, (0.0, 0.0, 0.0), 0.0, 0),
    (None, (20.0, -35.0, 170.0), 60.0, 0),
    (11, (-135.0, -144.74, -67.63), 140.0, 5),
    (22, (0.0, 0.0, 0.0), 90.0, 10),
    (33, (30.0, 10.0, -50.0), 0.0, 15),
]


def _case(seed, mount, L, mode_index, n=6, rng_seed=5):
    """A placed case of :data:`CASES` (designs.placed_case), with n poses from the random stream ``rng_seed``."""
    return placed_case(seed, mount, L, mode_index, n, rng_seed)


def _fd(x, E, e, mode, h=1e-5):
    """Central differences of the FK (E, e in R_w) in each of the five joints: (..., 3, 5) twice."""
    sol = inverse_kinematics(x, E, e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    dE, de = [], []
    for j in range(5):
        step = np.zeros(5)
        step[j] = h
        plus = forward_kinematics(x, (q + step)[..., :3], (q + step)[..., 3:], sol.assembly)
        minus = forward_kinematics(x, (q - step)[..., :3], (q - step)[..., 3:], sol.assembly)
        assert plus.valid.all() and minus.valid.all()
        dE.append((plus.E - minus.E) / (2 * h))
        de.append((plus.e - minus.e) / (2 * h))
    return np.stack(dE, axis=-1), np.stack(de, axis=-1)


def _perp_basis(e):
    """An orthonormal pair (..., 3, 2) orthogonal to e, from the SVD (not the code's construction)."""
    _, _, Vt = np.linalg.svd(np.asarray(e)[..., None, :])
    return np.swapaxes(Vt[..., 1:3, :], -1, -2)


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_jacobians_match_finite_differences_of_forward_kinematics(seed, mount, L, mode_index):
    x, E, e, mode = _case(seed, mount, L, mode_index)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    assert J_E.shape == J_e.shape == (len(E), 3, 5)
    fd_E, fd_e = _fd(x, E, e, mode)
    scale_E = np.max(np.abs(fd_E), axis=(-2, -1), keepdims=True)
    scale_e = np.max(np.abs(fd_e), axis=(-2, -1), keepdims=True)
    assert np.all(np.abs(J_E - fd_E) <= 1e-6 * scale_E)
    assert np.all(np.abs(J_e - fd_e) <= 1e-6 * scale_e)
    # e stays a unit vector: every column of J_e is orthogonal to e.
    np.testing.assert_allclose(np.einsum("pi,pij->pj", e, J_e), 0.0, atol=1e-12 * scale_e.max())
    if L > 0:  # the offset matters: the tip's Jacobian is not the centre's
        fd_C = fd_E + L * fd_e
        assert np.max(np.abs(fd_C - J_E)) > 1e-3 * scale_E.max()


def test_unrotated_zero_offset_tip_jacobian_is_J_LV_by_hand():
    """MODEL.md 7.1: with R = I and L = 0, E moves only with rho: Ė = diag(-p_u cos rho_u) rho_dot."""
    x, E, e, mode = _case(None, (0.0, 0.0, 0.0), 0.0, 0)
    J_E, _ = forward_jacobian(x, E, e, mode)
    rho = inverse_kinematics(x, E, e, mode).rho
    p = x[6:9]
    want = np.zeros((len(E), 3, 5))
    for u in range(3):
        want[:, u, u] = -p[u] * np.cos(rho[:, u])
    np.testing.assert_allclose(J_E, want, rtol=1e-12, atol=1e-12)


def test_hand_worked_example_of_every_metric():
    """e = z; J_E = diag(100, 50, 80) mm/rad on rho, J_e = 0.5 rad/rad of x on delta_x."""
    J_E = np.zeros((3, 5))
    J_E[0, 0], J_E[1, 1], J_E[2, 2] = 100.0, 50.0, 80.0
    J_e = np.zeros((3, 5))
    J_e[0, 3] = 0.5
    m = tip_metrics(J_E, J_e, [0.0, 0.0, 1.0])
    eps = np.radians(0.01)
    np.testing.assert_allclose(m.tip_error_mm, eps * np.sqrt(100**2 + 50**2 + 80**2), rtol=1e-13)
    np.testing.assert_allclose(m.lateral_error_mm, eps * np.sqrt(100**2 + 50**2), rtol=1e-13)
    np.testing.assert_allclose(m.axial_error_mm, eps * 80.0, rtol=1e-13)
    np.testing.assert_allclose(m.axis_error_deg, 0.5 * 0.01, rtol=1e-13)
    # torques (N·mm): 10·100, 10·50, 30·80, 0, 0 -> N·m
    np.testing.assert_allclose(m.torque_per_actuator_Nm, [1.0, 0.5, 2.4, 0.0, 0.0], rtol=1e-13)
    assert m.torque_Nm == pytest.approx(2.4, rel=1e-13)
    assert int(m.torque_actuator) == 2 and ACTUATOR_NAMES[2] == "rho_z"
    # C_E = diag(100², 50², 80²) / (1e4 N·m/rad = 1e7 N·mm/rad) mm/N; no thrust push; λ_max = 1e-3
    assert m.deflection_mm == pytest.approx(10.0 * 1e-3, rel=1e-13)
    # per-actuator encoder and stiffness
    m2 = tip_metrics(
        J_E,
        J_e,
        [0.0, 0.0, 1.0],
        encoder_deg=[0.02, 0.01, 0.01, 0.04, 0.01],
        stiffness_Nm_per_rad=[1e3, 1e4, 1e4, 1e4, 1e4],
        thrust_N=0.0,
        lateral_N=5.0,
    )
    np.testing.assert_allclose(m2.tip_error_mm, np.radians(np.sqrt(2.0**2 + 0.5**2 + 0.8**2)), rtol=1e-13)
    np.testing.assert_allclose(m2.axis_error_deg, 0.5 * 0.04, rtol=1e-13)
    assert m2.deflection_mm == pytest.approx(5.0 * 100.0**2 / 1e6, rel=1e-13)


@pytest.mark.parametrize("encoder", [0.01, [0.01, 0.02, 0.005, 0.01, 0.015]])
def test_accuracy_box_maxima_against_monte_carlo(encoder):
    x, E, e, mode = _case(11, (-135.0, -144.74, -67.63), 140.0, 5, n=4)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    m = tip_metrics(J_E, J_e, e, encoder_deg=encoder)
    eps = np.radians(np.broadcast_to(np.asarray(encoder, dtype=float), (5,)))
    rng = np.random.default_rng(3)
    n = 20000
    uniform = rng.uniform(-1.0, 1.0, (n, 5))
    vertexy = np.where(rng.random((n, 5)) < 0.8, rng.choice([-1.0, 1.0], (n, 5)), rng.uniform(-1, 1, (n, 5)))
    dq = np.concatenate([uniform, vertexy]) * eps  # (2n, 5) rad
    for k in range(len(E)):
        dE = dq @ J_E[k].T
        lat = dE - np.outer(dE @ e[k], e[k])
        mc = {
            "tip_error_mm": np.max(np.linalg.norm(dE, axis=1)),
            "lateral_error_mm": np.max(np.linalg.norm(lat, axis=1)),
            "axial_error_mm": np.max(np.abs(dE @ e[k])),
            "axis_error_deg": np.degrees(np.max(np.linalg.norm(dq @ J_e[k].T, axis=1))),
        }
        for name, sampled in mc.items():
            bound = getattr(m, name)[k]
            assert sampled <= bound * (1 + 1e-12), name
            assert sampled >= 0.99 * bound, name
        # the uniform samples alone never exceed it either
        assert np.max(np.linalg.norm(uniform * eps @ J_E[k].T, axis=1)) <= m.tip_error_mm[k] * (1 + 1e-12)


def test_virtual_work_with_fk_displacements():
    """tau = -J_E^T f (N·mm) does the virtual work of the tip force: tau·dq = -f·dE, dE from the FK."""
    x, E, e, mode = _case(None, (20.0, -35.0, 170.0), 60.0, 0, n=4)
    J_E, _ = forward_jacobian(x, E, e, mode)
    sol = inverse_kinematics(x, E, e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    rng = np.random.default_rng(8)
    h = 1e-5
    for _ in range(5):
        f = rng.normal(size=(len(E), 3)) * 20.0
        dq = rng.normal(size=(len(E), 5))
        plus = forward_kinematics(x, (q + h * dq)[:, :3], (q + h * dq)[:, 3:], sol.assembly)
        minus = forward_kinematics(x, (q - h * dq)[:, :3], (q - h * dq)[:, 3:], sol.assembly)
        dE = (plus.E - minus.E) / (2 * h)
        tau = -np.einsum("pij,pi->pj", J_E, f)
        lhs, rhs = np.sum(tau * dq, axis=1), -np.sum(f * dE, axis=1)
        np.testing.assert_allclose(lhs, rhs, rtol=1e-6, atol=1e-6 * np.abs(rhs).max())


@pytest.mark.parametrize(("thrust", "lateral"), [(30.0, 10.0), (0.0, 10.0), (50.0, 0.0)])
def test_worst_case_torques_against_sweep_of_lateral_forces(thrust, lateral):
    x, E, e, mode = _case(22, (0.0, 0.0, 0.0), 90.0, 10, n=4)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    m = tip_metrics(J_E, J_e, e, thrust_N=thrust, lateral_N=lateral)
    phi = np.linspace(0.0, 2 * np.pi, 3600, endpoint=False)
    mags = np.array([0.0, 0.5, 1.0])
    b = _perp_basis(e)
    for k in range(len(E)):
        u = np.cos(phi)[:, None] * b[k, :, 0] + np.sin(phi)[:, None] * b[k, :, 1]  # (n, 3) unit, ⊥ e
        f = thrust * e[k] + lateral * (mags[:, None, None] * u[None]).reshape(-1, 3)
        tau = -f @ J_E[k]  # (n, 5) N·mm
        worst = np.max(np.abs(tau), axis=0) / 1000.0
        formula = m.torque_per_actuator_Nm[k]
        assert np.all(worst <= formula * (1 + 1e-12) + 1e-15)
        np.testing.assert_allclose(worst, formula, rtol=1e-5, atol=1e-12)
        assert m.torque_Nm[k] == pytest.approx(worst.max(), rel=1e-5)
        assert m.torque_actuator[k] == int(np.argmax(worst))


@pytest.mark.parametrize("stiffness", [1e4, [2e3, 1e4, 5e3, 8e3, 3e4]])
@pytest.mark.parametrize("thrust", [0.0, 30.0])
def test_deflection_against_spring_equilibrium(stiffness, thrust):
    x, E, e, mode = _case(33, (30.0, 10.0, -50.0), 0.0, 15, n=4)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    F_l = 10.0
    m = tip_metrics(J_E, J_e, e, thrust_N=thrust, lateral_N=F_l, stiffness_Nm_per_rad=stiffness)
    K = np.broadcast_to(np.asarray(stiffness, dtype=float), (5,)) * 1000.0  # N·mm/rad
    phi = np.linspace(0.0, 2 * np.pi, 1440, endpoint=False)
    mags = np.linspace(0.0, 1.0, 5)
    b = _perp_basis(e)
    for k in range(len(E)):
        u = np.cos(phi)[:, None] * b[k, :, 0] + np.sin(phi)[:, None] * b[k, :, 1]
        f = thrust * e[k] + F_l * (mags[:, None, None] * u[None]).reshape(-1, 3)
        tau = -f @ J_E[k]  # N·mm
        dq = tau / K  # rad
        dE = dq @ J_E[k].T  # mm
        lateral = np.linalg.norm(dE - np.outer(dE @ e[k], e[k]), axis=1).max()
        bound = m.deflection_mm[k]
        assert lateral <= bound * (1 + 1e-12)
        if thrust == 0.0:
            assert lateral >= 0.99 * bound
        else:  # triangle inequality: max >= max(F_t|P C e|, F_l λ) >= bound / 2
            assert lateral >= 0.5 * bound
        # the formula's terms, basis-free: C_E and eigvalsh of P C P
        C = (J_E[k] / K) @ J_E[k].T
        P = np.eye(3) - np.outer(e[k], e[k])
        lam = np.linalg.eigvalsh(P @ C @ P)[-1]
        want = thrust * np.linalg.norm(P @ C @ e[k]) + F_l * lam
        assert bound == pytest.approx(want, rel=1e-9)


def test_invariant_to_the_spin_free_basis_and_to_the_frame():
    x, E, e, mode = _case(11, (-135.0, -144.74, -67.63), 140.0, 5, n=5)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    b = _perp_basis(e)
    for angle in (0.3, 2.0, -1.1):
        c, s = np.cos(angle), np.sin(angle)
        for flip in (1.0, -1.0):
            b2 = np.stack([c * b[..., 0] + s * b[..., 1], flip * (-s * b[..., 0] + c * b[..., 1])], axis=-1)
            K_E, K_e = forward_jacobian(x, E, e, mode, basis=b2)
            np.testing.assert_allclose(K_E, J_E, rtol=1e-9, atol=1e-9 * np.abs(J_E).max())
            np.testing.assert_allclose(K_e, J_e, rtol=1e-9, atol=1e-9 * np.abs(J_e).max())
    # the metrics are norms: rotating the Jacobians and e together changes nothing
    m = tip_metrics(J_E, J_e, e)
    Q = rotation((37.0, -71.0, 123.0))
    r = tip_metrics(Q @ J_E, Q @ J_e, e @ Q.T)
    for name in TipMetrics._fields:
        np.testing.assert_allclose(getattr(r, name), getattr(m, name), rtol=1e-9, atol=1e-15, err_msg=name)
    # and so does flipping e (P⊥ and |e^T J| do not see its sign)
    r = tip_metrics(J_E, J_e, -e)
    for name in TipMetrics._fields:
        np.testing.assert_allclose(getattr(r, name), getattr(m, name), rtol=1e-12, atol=1e-15, err_msg=name)


def test_batch_equals_loop_and_unreachable_points_give_nan():
    mode = ALL_MODES_ORACLE[0]
    xs, Es, es = [], [], []
    for seed, mount, L in [
        (None, (0.0, 0.0, 0.0), 0.0),
        (None, (20.0, -35.0, 170.0), 60.0),
        (44, (-10.0, 80.0, 5.0), 30.0),
    ]:
        x, E, e, _ = _case(seed, mount, L, 0, n=3, rng_seed=9)
        xs.append(x), Es.append(E), es.append(e)
    X = np.stack(xs)
    far = X[0, :3] + np.array([5e3, -5e3, 5e3])
    E = np.concatenate([*Es, far[None]])
    e = np.concatenate([*es, [[0.0, 0.0, 1.0]]])
    J_E, J_e = forward_jacobian(X[:, None, :], E[None], e[None], mode)
    assert J_E.shape == (3, len(E), 3, 5)
    m = tip_metrics(J_E, J_e, e[None])
    finite = np.isfinite(J_E).all(axis=(-2, -1))
    for d in range(3):  # each design reaches its own points
        assert finite[d, 3 * d : 3 * d + 3].all()
    assert not finite[:, -1].any()
    for d in range(3):
        for p in range(len(E)):
            one_E, one_e = forward_jacobian(X[d], E[p], e[p], mode)
            np.testing.assert_allclose(J_E[d, p], one_E, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(J_e[d, p], one_e, rtol=1e-12, atol=1e-12)
            one = tip_metrics(one_E, one_e, e[p])
            for name in TipMetrics._fields:
                np.testing.assert_allclose(getattr(m, name)[d, p], getattr(one, name), rtol=1e-12, atol=1e-15)
    bad = ~finite
    assert bad.any()
    assert np.isnan(J_E[bad]).all() and np.isnan(J_e[bad]).all()
    for name in TipMetrics._fields:
        value = getattr(m, name)[bad]
        if name == "torque_actuator":
            assert (value == -1).all() and value.dtype.kind == "i"
        else:
            assert np.isnan(value).all(), name
    assert ((m.torque_actuator[finite] >= 0) & (m.torque_actuator[finite] < 5)).all()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"encoder_deg": 0.0}, "encoder_deg"),
        ({"encoder_deg": -0.01}, "encoder_deg"),
        ({"encoder_deg": float("nan")}, "encoder_deg"),
        ({"encoder_deg": [0.01] * 4}, "encoder_deg"),
        ({"encoder_deg": "fine"}, "encoder_deg"),
        ({"thrust_N": -1.0}, "thrust_N"),
        ({"thrust_N": float("nan")}, "thrust_N"),
        ({"thrust_N": float("inf")}, "thrust_N"),
        ({"thrust_N": [30.0, 30.0]}, "thrust_N"),
        ({"lateral_N": -0.5}, "lateral_N"),
        ({"lateral_N": float("nan")}, "lateral_N"),
        ({"stiffness_Nm_per_rad": 0.0}, "stiffness_Nm_per_rad"),
        ({"stiffness_Nm_per_rad": [1e4] * 3}, "stiffness_Nm_per_rad"),
        ({"stiffness_Nm_per_rad": [1e4, 1e4, float("inf"), 1e4, 1e4]}, "stiffness_Nm_per_rad"),
    ],
)
def test_bad_parameters_raise_input_error_naming_them(kwargs, name):
    J = np.ones((3, 5))
    with pytest.raises(InputError, match=name) as info:
        tip_metrics(J, J, [0.0, 0.0, 1.0], **kwargs)
    assert "\n" not in str(info.value)
    assert info.value.param == name and str(info.value).startswith(f"{name} ")


def test_zero_forces_are_allowed():
    J = np.arange(15.0).reshape(3, 5)
    m = tip_metrics(J, J, [0.0, 0.0, 1.0], thrust_N=0.0, lateral_N=0.0)
    assert m.torque_Nm == 0.0 and m.deflection_mm == 0.0
    assert m.tip_error_mm > 0.0
