"""arcube.model.sensitivity: the analytic derivatives of the closed-form FK against central differences of
the FK itself (every one of the 27 parameter columns and the 5 joint columns), against MODEL.md 15.1's
J_E / J_e, the IK front end against the FK front end, and batches against loops."""

from __future__ import annotations

import numpy as np
import pytest
from designs import SENSITIVITY_CASES as CASES, sensitivity_case as _case

from arcube.evaluation.performance import forward_jacobian
from arcube.model.design import ANGLE_NAMES, PARAM_NAMES
from arcube.model.mechanism import forward_kinematics, inverse_kinematics
from arcube.model.sensitivity import fk_derivatives, pose_derivatives

H = 1e-5  # central-difference step: mm for lengths, rad for angles (converted to the design's degrees)


def _central(x, rho, delta, asm, j=None, k=None):
    """Central difference of the FK's (E, e) in parameter j (per mm or per rad) or joint k (per rad)."""
    xp, xm = x.copy(), x.copy()
    qp = np.concatenate([rho, delta], axis=-1)
    qm = qp.copy()
    if j is not None:
        step = np.degrees(H) if PARAM_NAMES[j] in ANGLE_NAMES else H
        xp[j] += step
        xm[j] -= step
    else:
        qp[..., k] += H
        qm[..., k] -= H
    plus = forward_kinematics(xp, qp[..., :3], qp[..., 3:], asm)
    minus = forward_kinematics(xm, qm[..., :3], qm[..., 3:], asm)
    assert plus.valid.all() and minus.valid.all()
    return (plus.E - minus.E) / (2 * H), (plus.e - minus.e) / (2 * H)


def _close(analytic, fd, name):
    scale = np.max(np.abs(fd))
    err = np.max(np.abs(analytic - fd))
    assert err <= 2e-6 * scale + 1e-9, f"{name}: |analytic - central| = {err:.3g}, column scale {scale:.3g}"


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_every_column_equals_central_differences_of_the_fk(seed, mount, L, mode_index):
    x, E, e, mode = _case(seed, mount, L, mode_index)
    sol = inverse_kinematics(x, E, e, mode)
    d = fk_derivatives(x, sol.rho, sol.delta, sol.assembly)
    assert d.dE_dp.shape == d.de_dp.shape == (len(E), 3, 27) and d.dE_dq.shape == (len(E), 3, 5) and d.valid.all()
    np.testing.assert_allclose(d.E, E, atol=1e-9)
    np.testing.assert_allclose(d.e, e, atol=1e-12)
    for j, name in enumerate(PARAM_NAMES):
        fd_E, fd_e = _central(x, sol.rho, sol.delta, sol.assembly, j=j)
        _close(d.dE_dp[..., j], fd_E, f"dE/d{name}")
        _close(d.de_dp[..., j], fd_e, f"de/d{name}")
    for k in range(5):
        fd_E, fd_e = _central(x, sol.rho, sol.delta, sol.assembly, k=k)
        _close(d.dE_dq[..., k], fd_E, f"dE/dq{k}")
        _close(d.de_dq[..., k], fd_e, f"de/dq{k}")
    # d_z does not move the tool; the axis stays a unit vector (every de column is perpendicular to e)
    assert np.all(d.dE_dp[..., PARAM_NAMES.index("d_z")] == 0.0) and np.all(
        d.de_dp[..., PARAM_NAMES.index("d_z")] == 0.0
    )
    np.testing.assert_allclose(np.einsum("pi,pij->pj", e, d.de_dp), 0.0, atol=1e-12)
    if L > 0:  # the tool offset moves the tip by -e per mm, and nothing of the axis
        np.testing.assert_allclose(d.dE_dp[..., PARAM_NAMES.index("L")], -e, atol=1e-15)


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_joint_columns_are_the_forward_jacobian_and_the_ik_front_end_agrees(seed, mount, L, mode_index):
    x, E, e, mode = _case(seed, mount, L, mode_index)
    J_E, J_e = forward_jacobian(x, E, e, mode)
    sol = inverse_kinematics(x, E, e, mode)
    d = fk_derivatives(x, sol.rho, sol.delta, sol.assembly)
    np.testing.assert_allclose(d.dE_dq, J_E, rtol=0, atol=1e-10 * np.max(np.abs(J_E)))
    np.testing.assert_allclose(d.de_dq, J_e, rtol=0, atol=1e-10 * np.max(np.abs(J_e)))
    p = pose_derivatives(x, E, e, mode)
    for field in ("dE_dp", "de_dp", "dE_dq", "de_dq"):
        a, b = getattr(p, field), getattr(d, field)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * np.max(np.abs(b)))


def test_batch_over_designs_and_points_equals_the_loop_and_unreachable_is_nan():
    cases = [_case(*c, n=5) for c in CASES[1:4]]
    x = np.stack([c[0] for c in cases])  # (3, 27)
    E = np.concatenate([c[1] for c in cases] + [np.full((1, 3), 5000.0)])  # (16, 3): the last one is out of reach
    e = np.concatenate([c[2] for c in cases] + [np.array([[0.0, 0.0, 1.0]])])
    mode = np.stack([c[3] for c in cases])[:, None, :]
    batch = pose_derivatives(x[:, None, :], E[None], e[None], mode)
    assert batch.dE_dp.shape == (3, 16, 3, 27) and batch.dE_dq.shape == (3, 16, 3, 5)
    for i in range(3):
        loop = pose_derivatives(x[i], E, e, mode[i, 0])
        for field in loop._fields:
            np.testing.assert_array_equal(getattr(batch, field)[i], getattr(loop, field))
        assert not loop.valid[-1] and np.all(np.isnan(loop.dE_dp[-1])) and np.all(np.isnan(loop.de_dq[-1]))
        own = slice(5 * i, 5 * i + 5)
        assert loop.valid[own].all()
