"""Whole-mechanism tests: IK/FK round trips over all 16 working modes, chain closure checked by
an independent 3-D construction, the seven Jacobians against finite differences of the
constraint equations, and the velocity model (MODEL.md 5.5, 7, 7.4) against finite differences
of the IK along pose paths.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from arcube.model import mechanism, poses
from arcube.model.mechanism import forward_kinematics, inverse_kinematics, jacobians, joint_rates, velocity_model

from naive import ALL_MODES_ORACLE, Z_HAT, leg_pair, oracle_config, oracle_modes, rotate, transmission_sines, vec, wrap

# =============================================================================================
# Working modes


def test_all_modes_are_the_16_sign_combinations():
    modes = mechanism.ALL_MODES
    assert modes.shape == (16, 4)
    assert {tuple(m) for m in modes} == {tuple(m) for m in ALL_MODES_ORACLE}
    np.testing.assert_array_equal(modes[0], [1, 1, 1, 1])
    np.testing.assert_array_equal(mechanism.DEFAULT_MODE, [1, 1, 1, 1])
    for m in modes:
        np.testing.assert_array_equal(mechanism.parse_mode(mechanism.format_mode(m)), m)
    np.testing.assert_array_equal(mechanism.parse_mode("+,-,-,+"), [1, -1, -1, 1])
    with pytest.raises(ValueError):
        mechanism.parse_mode("+,+,+")


# =============================================================================================
# IK -> FK, FK -> IK


def test_ik_then_fk_round_trip_all_modes(pose_bank):
    """For 4 designs (m != 0) x 16 working modes x 12 poses: FK(IK(pose)) = pose to 1e-9."""
    for x, mode, E, e in pose_bank:
        sol = inverse_kinematics(x, E, e, mode)
        assert np.all(sol.reachable)
        np.testing.assert_array_equal(sol.working_mode, np.broadcast_to(mode, (len(E), 4)))
        fk = forward_kinematics(x, sol.rho, sol.delta, sol.assembly)
        assert np.all(fk.valid)
        np.testing.assert_allclose(fk.E, E, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fk.e, e, rtol=0, atol=1e-9)
        np.testing.assert_allclose(wrap(fk.sigma - sol.sigma), 0.0, atol=1e-9)


def test_ik_solution_closes_every_chain_in_3d(pose_bank):
    """The IK's joint angles, put into the 3-D construction of MODEL.md 3.1/4.1/5.1, close every
    chain; the working mode and assembly signs match their geometric definitions."""
    for x, mode, E, e in pose_bank:
        sol = inverse_kinematics(x, E, e, mode)
        cfg = oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma)
        np.testing.assert_allclose(cfg.planar, 0.0, atol=1e-10)
        np.testing.assert_allclose(cfg.Phi / leg_pair(x, "c") ** 2, 0.0, atol=1e-12)
        np.testing.assert_allclose(cfg.Gamma, 0.0, atol=1e-12)
        om, oa = oracle_modes(cfg)
        np.testing.assert_array_equal(om, np.broadcast_to(mode, om.shape))
        np.testing.assert_array_equal(sol.assembly, oa)
        np.testing.assert_allclose(sol.u_beta, cfg.ub, atol=1e-14)
        np.testing.assert_allclose(sol.terms.F, cfg.F, rtol=1e-9)
        np.testing.assert_allclose(sol.terms.H, cfg.H, rtol=1e-9)
        np.testing.assert_allclose(sol.E_m, cfg.E_m, atol=0)


def test_fk_then_ik_round_trip_covers_all_16_modes(designs):
    """Random joints -> FK (random assembly signs) -> the IK in the working mode read off the
    assembled mechanism (oracle: sign F, -sign J_AS) recovers rho, delta and sigma."""
    rng = np.random.default_rng(99)
    for x in designs:
        n = 6000
        rho = rng.uniform(-1.2, 1.2, (n, 3))
        delta = rng.uniform(-np.pi, np.pi, (n, 2))
        asm = rng.choice([-1.0, 1.0], (n, 3))
        with np.errstate(invalid="ignore"):
            fk = forward_kinematics(x, rho, delta, asm)
            cfg = oracle_config(x, fk.E, fk.e, rho, delta, fk.sigma)
            s = transmission_sines(cfg)
        ok = fk.valid & np.all(np.abs(s) > 0.05, axis=-1)
        # FK output is an assembled mechanism in the requested assembly mode
        np.testing.assert_allclose(cfg.planar[ok], 0.0, atol=1e-10)
        np.testing.assert_allclose((cfg.Phi / leg_pair(x, "c") ** 2)[ok], 0.0, atol=1e-12)
        np.testing.assert_allclose(cfg.Gamma[ok], 0.0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(fk.e[ok], axis=-1), 1.0, atol=1e-13)
        mode, oasm = oracle_modes(cfg)
        np.testing.assert_array_equal(oasm[ok], asm[ok])
        codes = ((mode[ok] > 0) * [8, 4, 2, 1]).sum(axis=1)
        assert np.all(np.bincount(codes, minlength=16) >= 5), "not every working mode sampled"
        sol = inverse_kinematics(x, fk.E[ok], fk.e[ok], mode[ok])
        assert np.all(sol.reachable)
        np.testing.assert_array_equal(sol.working_mode, mode[ok])
        np.testing.assert_array_equal(sol.assembly, asm[ok])
        np.testing.assert_allclose(sol.rho, rho[ok], atol=1e-9)
        np.testing.assert_allclose(wrap(sol.delta - delta[ok]), 0.0, atol=1e-9)
        np.testing.assert_allclose(wrap(sol.sigma - fk.sigma[ok]), 0.0, atol=1e-9)
        # and some other working mode gives different joints at the same pose
        other = mode[ok].copy()
        other[:, 0] *= -1
        sol2 = inverse_kinematics(x, fk.E[ok], fk.e[ok], other)
        assert np.all(np.abs(wrap(sol2.delta[:, 0] - delta[ok][:, 0])) > 1e-6)


def test_inverse_kinematics_broadcast_equals_loop(designs, pose_bank):
    D = np.stack(designs)  # (4, 23)
    E = np.concatenate([b[2][:3] for b in pose_bank[::8]])  # a mix of poses, some unreachable for other designs
    e = np.concatenate([b[3][:3] for b in pose_bank[::8]])
    modes = ALL_MODES_ORACLE[[0, 5, 10, 15]]
    sol = inverse_kinematics(D[:, None, :], E[None], e[None], modes[:, None, :])
    for i in range(len(D)):
        for j in range(len(E)):
            s1 = inverse_kinematics(D[i], E[j], e[j], modes[i])
            for name in ("E_m", "e", "rho", "sigma", "delta", "tls_arg", "rts_arg", "tms_arg", "u_beta"):
                np.testing.assert_allclose(
                    getattr(sol, name)[i, j], getattr(s1, name), rtol=1e-13, atol=1e-13, err_msg=name
                )
            for name in ("F", "G", "D", "E", "H"):
                np.testing.assert_allclose(
                    getattr(sol.terms, name)[i, j], getattr(s1.terms, name), rtol=1e-13, atol=1e-12
                )
            assert sol.reachable[i, j] == s1.reachable


def test_unreachable_pose_gives_nan_angles_not_errors(paper_design):
    E = np.array([[1e4, 0.0, 0.0], [0.0, 0.0, 0.0]])
    e = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
    with np.errstate(invalid="ignore"):
        sol = inverse_kinematics(paper_design, E, e)
    assert not np.any(sol.reachable)
    assert np.isnan(sol.rho[0, 0]) and np.all(np.isnan(sol.delta[0]))
    assert np.isnan(sol.sigma[1, 0])


def test_special_pose_rho_zero_and_known_sigma():
    """Design with alpha = beta = 60 deg and a tip at the centre of the TLS box: rho = 0 exactly,
    sigma_u + o_u = the hand values of the e = z case (see test_stages), delta closes the four-bar."""
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
    E = np.array([10.0 - 40.0 - 60.0, -20.0 - 50.0 - 60.0, 30.0 - 60.0 - 60.0])  # E_m = -f - r
    sol = inverse_kinematics(x, E, Z_HAT)
    np.testing.assert_array_equal(sol.rho, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(sol.E_m, [-100.0, -110.0, -120.0])
    g = math.acos(1 / math.sqrt(3))
    lam = np.array([np.pi + g, np.pi / 2 + g])
    np.testing.assert_allclose(wrap(sol.sigma + np.deg2rad([10.0, -20.0]) - lam), 0.0, atol=1e-12)
    assert np.all(sol.reachable)
    cfg = oracle_config(x, E, Z_HAT, sol.rho, sol.delta, sol.sigma)
    np.testing.assert_allclose(cfg.Phi, 0.0, atol=1e-9)
    # rho = 0 -> G = 0: J_rho singular; J_LV = -diag(p)
    np.testing.assert_array_equal(sol.terms.G, [0.0, 0.0])
    J = jacobians(sol, x)
    np.testing.assert_array_equal(J["J_LV"], -np.diag([100.0, 110.0, 90.0]))


# =============================================================================================
# Jacobians against finite differences of the constraint equations (oracle geometry)


def _bank_subset(pose_bank, step=3, n=4):
    return [(x, mode, E[:n], e[:n]) for (x, mode, E, e) in pose_bank[::step]]


def test_jacobian_shapes(pose_bank):
    x, mode, E, e = pose_bank[0]
    J = jacobians(inverse_kinematics(x, E, e, mode), x)
    shapes = {
        "J_LV": (3, 3),
        "J_AV": (2, 3),
        "J_sigma": (2, 2),
        "J_AS": (2, 2),
        "J_AP": (2, 3),
        "J_rho": (2, 3),
        "J_delta": (2, 2),
    }
    assert set(J) == set(shapes)
    for k, s in shapes.items():
        assert J[k].shape == (len(E),) + s, k


def test_J_LV_is_dE_drho_of_forward_kinematics(pose_bank):
    h = 1e-6
    for x, mode, E, e in _bank_subset(pose_bank):
        sol = inverse_kinematics(x, E, e, mode)
        J = jacobians(sol, x)["J_LV"]
        for j in range(3):
            dr = np.zeros(3)
            dr[j] = h
            Ep = forward_kinematics(x, sol.rho + dr, sol.delta, sol.assembly).E
            Em = forward_kinematics(x, sol.rho - dr, sol.delta, sol.assembly).E
            np.testing.assert_allclose((Ep - Em) / (2 * h), J[:, :, j], rtol=1e-7, atol=1e-6)


def test_tms_jacobians_match_half_partials_of_the_3d_coupler_equation(pose_bank):
    """J_AV = 1/2 dPhi/dE (world columns x, y, z), J_rho = -1/2 dPhi/drho (2x3), J_delta =
    -1/2 dPhi/d delta, J_sigma = 1/2 dPhi/d sigma, with Phi = |T - K|^2 - c^2 from naive's 3-D
    construction (independent of arcube.model.stages.tms)."""
    for x, mode, E, e in _bank_subset(pose_bank):
        sol = inverse_kinematics(x, E, e, mode)
        J = jacobians(sol, x)
        rho, delta, sigma = sol.rho, sol.delta, sol.sigma

        def phi(E_=E, rho_=rho, delta_=delta, sigma_=sigma):
            return oracle_config(x, E_, e, rho_, delta_, sigma_).Phi

        hp, ha = 1e-4, 1e-6
        J_av = np.zeros((len(E), 2, 3))
        J_rho = np.zeros((len(E), 2, 3))
        for k in range(3):
            dE = np.zeros(3)
            dE[k] = hp
            J_av[:, :, k] = 0.5 * (phi(E_=E + dE) - phi(E_=E - dE)) / (2 * hp)
            dr = np.zeros(3)
            dr[k] = ha
            J_rho[:, :, k] = -0.5 * (phi(rho_=rho + dr) - phi(rho_=rho - dr)) / (2 * ha)
        J_del = np.zeros((len(E), 2, 2))
        J_sig = np.zeros((len(E), 2, 2))
        for k in range(2):
            dd = np.zeros(2)
            dd[k] = ha
            J_del[:, :, k] = -0.5 * (phi(delta_=delta + dd) - phi(delta_=delta - dd)) / (2 * ha)
            J_sig[:, :, k] = 0.5 * (phi(sigma_=sigma + dd) - phi(sigma_=sigma - dd)) / (2 * ha)
        tol = dict(rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(J["J_AV"], J_av, **tol)
        np.testing.assert_allclose(J["J_rho"], J_rho, **tol)
        np.testing.assert_allclose(J["J_delta"], J_del, **tol)
        np.testing.assert_allclose(J["J_sigma"], J_sig, **tol)
        # layout of J_AV stated in MODEL.md 7.2: leg x does not see x, leg y does not see y
        assert np.all(J["J_AV"][:, 0, 0] == 0) and np.all(J["J_AV"][:, 1, 1] == 0)
        assert np.all(J["J_rho"][:, :, 2] == 0)


def test_rts_jacobians_match_derivatives_of_gamma(pose_bank):
    """J_AS = dGamma/dsigma (diagonal); J_AP omega = -dGamma/dt under e_dot = omega x e."""
    h = 1e-6
    for x, mode, E, e in _bank_subset(pose_bank):
        sol = inverse_kinematics(x, E, e, mode)
        J = jacobians(sol, x)

        def gam(e_=e, sigma_=sol.sigma):
            return oracle_config(x, E, e_, sol.rho, sol.delta, sigma_).Gamma

        J_as = np.zeros((len(E), 2, 2))
        for k in range(2):
            ds = np.zeros(2)
            ds[k] = h
            J_as[:, :, k] = (gam(sigma_=sol.sigma + ds) - gam(sigma_=sol.sigma - ds)) / (2 * h)
        J_ap = np.zeros((len(E), 2, 3))
        for k in range(3):
            om = np.zeros(3)
            om[k] = h
            J_ap[:, :, k] = -(gam(e_=rotate(e, om)) - gam(e_=rotate(e, -om))) / (2 * h)
        np.testing.assert_allclose(J["J_AS"], J_as, atol=1e-9)
        np.testing.assert_allclose(J["J_AP"], J_ap, atol=1e-9)


# =============================================================================================
# Velocity model (MODEL.md 7.4)


def _ik_q(x, E, e, mode):
    sol = inverse_kinematics(x, E, e, mode)
    return np.concatenate([sol.rho, sol.delta], axis=-1)


def _fd_rates(x, mode, E_path, e_path, h):
    qp = _ik_q(x, E_path(h), e_path(h), mode)
    qm = _ik_q(x, E_path(-h), e_path(-h), mode)
    dq = qp - qm
    dq[..., 3:] = wrap(dq[..., 3:])
    return dq / (2 * h)


def test_velocity_model_matches_finite_differences_of_ik_rotation_path(pose_bank):
    """q_dot = B^-1 A t equals d/dt IK(E + t v, Rot(t omega) e) for random v, omega."""
    rng = np.random.default_rng(3)
    h = 1e-6
    for x, mode, E, e in pose_bank:
        v = rng.normal(size=E.shape) * 10.0
        om = rng.normal(size=E.shape) * 0.5
        model = velocity_model(inverse_kinematics(x, E, e, mode), x)
        qd = joint_rates(model, v, om)
        fd = _fd_rates(x, mode, lambda s: E + s * v, lambda s: rotate(e, s * om), h)
        scale = np.maximum(np.max(np.abs(fd), axis=-1, keepdims=True), 1.0)
        np.testing.assert_allclose(qd / scale, fd / scale, rtol=0, atol=1e-7)


def test_velocity_model_matches_finite_differences_of_ik_angle_path(pose_bank):
    """Same with e(t) = e_from_angles(psi + t psi_dot, theta + t theta_dot) and
    omega = omega_from_angle_rates(psi, psi_dot, theta_dot) (MODEL.md 1.3)."""
    rng = np.random.default_rng(4)
    h = 1e-6
    for x, mode, E, e in pose_bank[::2]:
        psi, theta = poses.angles_from_e(e)
        pd, td = rng.normal(size=(2, len(E)))
        v = rng.normal(size=E.shape) * 10.0
        om = poses.omega_from_angle_rates(psi, pd, td)
        model = velocity_model(inverse_kinematics(x, E, e, mode), x)
        qd = joint_rates(model, v, om)
        fd = _fd_rates(x, mode, lambda s: E + s * v, lambda s: poses.e_from_angles(psi + s * pd, theta + s * td), h)
        scale = np.maximum(np.max(np.abs(fd), axis=-1, keepdims=True), 1.0)
        np.testing.assert_allclose(qd / scale, fd / scale, rtol=0, atol=1e-7)


def test_pure_translation_moves_each_crank_by_its_own_coordinate(pose_bank):
    """v along u moves only rho_u among the cranks, at rate v_u / (-p_u cos rho_u) (Eq 5)."""
    for x, mode, E, e in pose_bank[::5]:
        sol = inverse_kinematics(x, E, e, mode)
        model = velocity_model(sol, x)
        p = np.array([x[6], x[7], x[8]])
        for k in range(3):
            v = np.zeros(3)
            v[k] = 1.0
            qd = joint_rates(model, v, np.zeros(3))
            expected = np.zeros((len(E), 3))
            expected[:, k] = 1.0 / (-p[k] * np.cos(sol.rho[:, k]))
            np.testing.assert_allclose(qd[:, :3], expected, rtol=1e-12, atol=1e-15)


def test_spin_about_e_gives_zero_joint_rates(pose_bank):
    rng = np.random.default_rng(5)
    for x, mode, E, e in pose_bank:
        model = velocity_model(inverse_kinematics(x, E, e, mode), x)
        qd = joint_rates(model, np.zeros(3), 2.5 * e)
        np.testing.assert_allclose(qd, 0.0, atol=1e-12)
        # adding spin to any twist changes nothing
        v, om = rng.normal(size=(2,) + E.shape)
        np.testing.assert_allclose(
            joint_rates(model, v, om + 3.0 * e), joint_rates(model, v, om), rtol=1e-9, atol=1e-12
        )


def test_twist_from_joint_rates_inverts_joint_rates(pose_bank):
    rng = np.random.default_rng(6)
    for x, mode, E, e in pose_bank:
        model = velocity_model(inverse_kinematics(x, E, e, mode), x)
        v = rng.normal(size=E.shape) * 5.0
        om = rng.normal(size=E.shape)
        om -= np.sum(om * e, axis=-1, keepdims=True) * e  # omega orthogonal to e
        qd = joint_rates(model, v, om)
        v2, om2 = mechanism.twist_from_joint_rates(model, qd)
        np.testing.assert_allclose(v2, v, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(om2, om, rtol=1e-8, atol=1e-8)
        # and from arbitrary joint rates: the twist it returns has no spin and maps back
        q = rng.normal(size=(len(E), 5)) * 0.1
        v3, om3 = mechanism.twist_from_joint_rates(model, q)
        np.testing.assert_allclose(np.sum(om3 * e, axis=-1), 0.0, atol=1e-10)
        np.testing.assert_allclose(joint_rates(model, v3, om3), q, rtol=1e-8, atol=1e-10)


def test_velocity_model_block_structure(pose_bank):
    """A = [I 0; J_AV  J_sigma J_AS^-1 J_AP], B = [J_LV 0; J_rho J_delta] (MODEL.md 7.4)."""
    x, mode, E, e = pose_bank[7]
    sol = inverse_kinematics(x, E, e, mode)
    J = jacobians(sol, x)
    model = velocity_model(sol, x)
    assert model.A.shape == (len(E), 5, 6) and model.B.shape == (len(E), 5, 5)
    np.testing.assert_array_equal(model.A[:, :3, :3], np.broadcast_to(np.eye(3), (len(E), 3, 3)))
    np.testing.assert_array_equal(model.A[:, :3, 3:], 0.0)
    np.testing.assert_array_equal(model.B[:, :3, 3:], 0.0)
    np.testing.assert_array_equal(model.A[:, 3:, :3], J["J_AV"])
    np.testing.assert_array_equal(model.B[:, :3, :3], J["J_LV"])
    np.testing.assert_array_equal(model.B[:, 3:, :3], J["J_rho"])
    np.testing.assert_array_equal(model.B[:, 3:, 3:], J["J_delta"])
    np.testing.assert_allclose(model.A[:, 3:, 3:], J["J_sigma"] @ np.linalg.inv(J["J_AS"]) @ J["J_AP"], rtol=1e-12)
