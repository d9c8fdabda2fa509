"""Masses, gravity and the holding torque (MODEL.md 18.1-18.2): oracles written from the spec.

* dV/dq (the code: analytic, through the forward Jacobian of 15.1) against central differences of
  an INDEPENDENT potential energy: q -> the forward kinematics (MODEL.md 5.5, 13) in the design's
  assembly mode -> the mechanism's points rebuilt here by hand (naive.oracle_config; the z-dyad
  elbow by the law of cosines; the spherical links' 13 points by Rodrigues rotations about the
  arcs' normals, not by slerp) -> the 18.1 mass model restated from MODEL.md -> V = -sum m g . c;
  for random and paper designs, several working modes, with a mounting rotation and a tool offset,
  with the z dyad open and closed;
* the masses by hand (one crank; the paper's whole moving mass);
* batch = loop; gravity +z vs -z flips the sign (and V is linear in g); zero masses give zero torque,
  and the holding torque then is 15.3's ``torque``; NaN where the IK fails; bad input raises.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import arcube
from arcube.errors import InputError
from arcube.evaluation.mass_bodies import BODY_NAMES, MassModel, bodies_of_solution, body_masses_kg
from arcube.evaluation.masses import (
    gravity_torque_Nm,
    holding_torque,
    moving_mass_kg,
    potential_energy_J,
)
from arcube.evaluation.performance import ACTUATOR_NAMES, metrics_of_solution
from arcube.evaluation.task import build_task
from arcube.model.mechanism import forward_kinematics, inverse_kinematics
from arcube.options import Guards, Loads, Masses, Options

from designs import MASS_CASES, PAPER, placed_case
from naive import DENSITY, L_MOTOR, LAMBDA, M_DELTA, M_MOTOR, mass_by_hand, oracle_config, rotate, rotation, vec

G_DOWN = np.array([0.0, 0.0, -9.81])


def _arc(v1, v2, phi, n=12):
    """n + 1 unit vectors from v1 toward v2 (angle phi apart), by rotations about v1 x v2."""
    axis = np.cross(v1, v2)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    return np.stack([rotate(v1, axis * (k * phi / n)[..., None]) for k in range(n + 1)], axis=-2)


def _oracle_V(x, E, e, rho, delta, sigma, c_z=None, g=G_DOWN):
    """V (J) of the 18.1 mass model at the pose (E, e) in R_w with joints (rho, delta, sigma), by hand."""
    x23, R, L = x[:23], rotation(x[23:26]), x[26]
    m = x23[:3]
    C_w = E + L * e
    C_m = (C_w - m) @ R  # R^T (C - m), rows
    e_m = e @ R
    cfg = oracle_config(x23, C_m + m, e_m, rho, delta, sigma)  # points in R_m (E_m = C_m)
    f, p, d = x23[3:6], x23[6:9], x23[9:12]
    c, t, r = x23[12:14], x23[14:16], x23[16]
    al, be = np.radians(x23[19:21]), np.radians(x23[21:23])
    eye = np.eye(3)
    P = -f[:, None] * eye
    D, Q, K, T, ub = cfg.D, cfg.Q, cfg.K, cfg.T, cfg.ub
    S = np.zeros(np.shape(E))  # sum m c in R_m, kg mm
    for u in range(3):
        S += LAMBDA * p[u] * (P[u] + D[..., u, :]) / 2
        S += LAMBDA * math.sqrt(2) * r * (Q[..., u, :] + Q[..., (u + 1) % 3, :]) / 2
    for u in range(2):
        S += LAMBDA * d[u] * (D[..., u, :] + K[..., u, :]) / 2
        S += LAMBDA * c[u] * (K[..., u, :] + T[..., u, :]) / 2
        S += LAMBDA * t[u] * (Q[..., u, :] + T[..., u, :]) / 2
        S += M_DELTA * D[..., u, :]
        u_hat = np.broadcast_to(eye[u], ub[..., u, :].shape)
        for v1, v2, phi in ((u_hat, ub[..., u, :], al[u]), (ub[..., u, :], e_m, be[u])):
            pts = C_m[..., None, :] + r * _arc(v1, v2, phi)
            chord = 2 * r * math.sin(phi / 24)
            S += LAMBDA * chord * np.sum(pts[..., :-1, :] + pts[..., 1:, :], axis=-2) / 2
    # z dyad (MODEL.md 6 and 14.1): elbow on the z x (Q - D) side where it closes, else on D_z -> Q_z.
    cz = d[2] if c_z is None else c_z
    Dz, Qz = D[..., 2, :], Q[..., 2, :]
    span = np.linalg.norm(Qz - Dz, axis=-1, keepdims=True)
    along = (d[2] ** 2 - cz**2 + span**2) / (2 * span)
    closes = (span <= d[2] + cz) & (span >= abs(d[2] - cz))
    u1 = (Qz - Dz) / span
    with np.errstate(invalid="ignore"):
        J = Dz + along * u1 + np.sqrt(d[2] ** 2 - along**2) * np.cross(eye[2], u1)
    S += np.where(
        closes, LAMBDA * d[2] * (Dz + J) / 2 + LAMBDA * cz * (J + Qz) / 2, LAMBDA * (d[2] + cz) * (Dz + Qz) / 2
    )
    S += M_MOTOR * (C_m + (r + L_MOTOR / 2) * e_m)
    M = mass_by_hand(x23, cz)
    S_w = M * m + S @ R.T
    return -(S_w @ g) / 1000, closes[..., 0]


def _fd_gravity(x, E, e, mode, c_z=None, g=G_DOWN, h=1e-6):
    """Central differences of the oracle V through the forward kinematics, (n, 5) N m."""
    sol = inverse_kinematics(x, E, e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    out = []
    for j in range(5):
        Vs = []
        for s in (h, -h):
            qq = q.copy()
            qq[:, j] += s
            fk = forward_kinematics(x, qq[:, :3], qq[:, 3:], sol.assembly)
            assert fk.valid.all()
            Vs.append(_oracle_V(x, fk.E, fk.e, qq[:, :3], qq[:, 3:], fk.sigma, c_z, g)[0])
        out.append((Vs[0] - Vs[1]) / (2 * h))
    return np.stack(out, axis=-1)


MAX_ERR: list[float] = []


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index", "c_z"), MASS_CASES)
def test_gravity_torque_matches_central_differences_of_V_through_the_fk(seed, mount, L, mode_index, c_z):
    x, E, e, mode = placed_case(seed, mount, L, mode_index)
    opts = Options(guards=Guards(c_z=c_z))
    tau = gravity_torque_Nm(x, E, e, mode, opts)
    assert tau.shape == (len(E), 5)
    fd = _fd_gravity(x, E, e, mode, c_z)
    err = np.abs(tau - fd)
    MAX_ERR.append(float(err.max()))
    assert np.all(err <= 1e-6 + 1e-7 * np.abs(fd).max()), err.max()
    assert np.abs(fd).max() > 0.1  # the test means something: N m-sized torques
    # the code's V is the oracle's at the same poses (absolute, with the mounting point's constant)
    sol = inverse_kinematics(x, E, e, mode)
    V_or, closes = _oracle_V(x, E, e, sol.rho, sol.delta, sol.sigma, c_z)
    np.testing.assert_allclose(potential_energy_J(x, E, e, mode, opts), V_or, rtol=1e-12, atol=1e-9)


def test_z_dyad_both_open_and_closed_are_covered():
    """The cases above exercise the dyad's elbow (closed) and the fallback D_z -> Q_z (open)."""
    states = set()
    for seed, mount, L, mode_index, c_z in MASS_CASES:
        x, E, e, mode = placed_case(seed, mount, L, mode_index)
        sol = inverse_kinematics(x, E, e, mode)
        states |= set(_oracle_V(x, E, e, sol.rho, sol.delta, sol.sigma, c_z)[1].tolist())
    assert states == {True, False}


def test_link_masses_by_hand():
    x = vec(PAPER)
    masses = body_masses_kg(x)
    assert masses.shape == (len(BODY_NAMES),) == (65,)
    # one crank: lambda p_x, lambda = 2700 pi (8^2 - 6^2) mm^2 = 0.23750 kg/m
    assert LAMBDA * 1000 == pytest.approx(0.2375044, rel=1e-6)
    assert masses[BODY_NAMES.index("crank_x")] == pytest.approx(LAMBDA * 134.099, rel=1e-13)
    chord = 2 * 70.4466 * math.sin(math.radians(62.1208) / 24)  # 1/12 of beta_y's arc
    assert masses[BODY_NAMES.index("spherical_beta_y/7")] == pytest.approx(LAMBDA * chord, rel=1e-13)
    assert masses[BODY_NAMES.index("drill_motor")] == M_MOTOR and masses[BODY_NAMES.index("actuator_D_y")] == M_DELTA
    # the whole moving mass of Table 2, by hand
    assert float(moving_mass_kg(x)) == pytest.approx(mass_by_hand(x), rel=1e-13)
    assert float(moving_mass_kg(x)) == pytest.approx(3.4887, abs=1e-4)
    # the settings reach the model: a thinner wall, a heavier motor, c_z
    opts = Options(masses=Masses(wall_mm=1.0, m_motor_kg=2.0), guards=Guards(c_z=90.0))
    lam1 = DENSITY * math.pi * (0.008**2 - 0.007**2) / 1000
    want = (mass_by_hand(x, 90.0) - 2 * M_DELTA - M_MOTOR) / LAMBDA * lam1 + 2 * M_DELTA + 2.0
    assert float(moving_mass_kg(x, opts)) == pytest.approx(want, rel=1e-13)
    # per design, broadcast
    xs = np.stack([x, x * np.r_[np.ones(6), 1.1 * np.ones(17)]])
    assert moving_mass_kg(xs).shape == (2,)


def test_bodies_have_the_design_lengths_at_poses():
    """Each rod's end points are as far apart as the length its mass counts; chords lie on the sphere."""
    x, E, e, mode = placed_case(44, (10.0, 80.0, 5.0), 150.0, 3)
    model = MassModel(c_z_mm=250.0)
    sol = inverse_kinematics(x, E, e, mode)
    b = bodies_of_solution(sol, x, model)
    lengths = np.linalg.norm(b.ends[..., 1, :] - b.ends[..., 0, :], axis=-1)
    want = body_masses_kg(x, model)[:62] / model.lambda_kg_per_mm
    closed = np.isfinite(b.J_ends[:, 9]).all(axis=(-3, -2, -1))
    np.testing.assert_allclose(lengths[closed, :62], np.broadcast_to(want, (closed.sum(), 62)), rtol=1e-9)
    C = E + x[26] * e
    on_sphere = np.linalg.norm(b.ends[:, 14:62] - C[:, None, None, :], axis=-1)
    np.testing.assert_allclose(on_sphere, x[16], rtol=1e-12)


def test_batch_equals_loop():
    d = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89).to_vector()
    plan = arcube.select(arcube.load_trajectories("reference"), side="R")
    task = build_task(plan.entry, plan.target, 30)
    E, e = task.E[::10], task.e[::10]
    xs = np.stack([d, d + np.r_[np.zeros(23), 0.0, 0.0, 0.0, 5.0], d + np.r_[np.zeros(23), 1.0, -1.0, 0.5, 0.0]])
    opts = Options(loads=Loads(thrust_N=25.0))
    batch = holding_torque(xs[:, None, :], E[None], e[None], options=opts)
    assert batch.holding_torque_Nm.shape == (3, len(E)) and batch.per_actuator_Nm.shape == (3, len(E), 5)
    for i in range(3):
        for k in range(len(E)):
            one = holding_torque(xs[i], E[k], e[k], options=opts)
            np.testing.assert_allclose(batch.per_actuator_Nm[i, k], one.per_actuator_Nm, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(batch.gravity_Nm[i, k], one.gravity_Nm, rtol=1e-12, atol=1e-12)
            assert batch.holding_torque_actuator[i, k] == one.holding_torque_actuator
    assert np.all(np.isfinite(batch.holding_torque_Nm))


def test_gravity_sign_and_linearity():
    x, E, e, mode = placed_case(11, (-135.0, -144.74, -67.63), 140.0, 5)
    down = gravity_torque_Nm(x, E, e, mode, Options(masses=Masses(gravity=(0.0, 0.0, -9.81))))
    up = gravity_torque_Nm(x, E, e, mode, Options(masses=Masses(gravity=(0.0, 0.0, 9.81))))
    np.testing.assert_allclose(up, -down, rtol=1e-12, atol=1e-12)
    assert np.abs(down).max() > 0.1
    parts = [gravity_torque_Nm(x, E, e, mode, Options(masses=Masses(gravity=tuple(row)))) for row in np.eye(3)]
    mixed = gravity_torque_Nm(x, E, e, mode, Options(masses=Masses(gravity=(1.0, -2.0, 3.0))))
    np.testing.assert_allclose(mixed, parts[0] - 2 * parts[1] + 3 * parts[2], rtol=1e-10, atol=1e-12)


def test_zero_masses_give_zero_torque_and_the_15_3_torque():
    x, E, e, mode = placed_case(None, (20.0, -35.0, 170.0), 60.0, 0)
    massless = MassModel(density_kg_m3=0.0, m_delta_kg=0.0, m_motor_kg=0.0)
    assert float(moving_mass_kg(x, massless)) == 0.0
    assert np.all(gravity_torque_Nm(x, E, e, mode, massless) == 0.0)
    opts = Options(loads=Loads(thrust_N=25.0, lateral_force_N=7.0))
    sol = inverse_kinematics(x, E, e, mode)
    perf = metrics_of_solution(sol, x, opts.loads)
    with pytest.raises(InputError, match="^loads must be an arcube.options.Loads"):  # not a load of before
        metrics_of_solution(sol, x, 25.0)
    weightless = Options(loads=opts.loads, masses=Masses(gravity=(0, 0, 0)))
    for hold in (holding_torque(x, E, e, mode, opts, masses=massless), holding_torque(x, E, e, mode, weightless)):
        np.testing.assert_allclose(hold.per_actuator_Nm, perf.torque_per_actuator_Nm, rtol=1e-12)
        np.testing.assert_allclose(hold.holding_torque_Nm, perf.torque_Nm, rtol=1e-12)
        np.testing.assert_array_equal(hold.holding_torque_actuator, perf.torque_actuator)
    # no drilling load: the holding torque is |dV/dq|
    still = holding_torque(x, E, e, mode, Options(loads=Loads(thrust_N=0.0, lateral_force_N=0.0)))
    np.testing.assert_allclose(still.per_actuator_Nm, np.abs(gravity_torque_Nm(x, E, e, mode)), rtol=1e-13)
    # thrust along +e: the thrust term is -F_t e^T J_E,i inside the absolute value (18.2)
    thrust = holding_torque(x, E, e, mode, Options(loads=Loads(thrust_N=30.0, lateral_force_N=0.0)))
    J_axial = np.stack([np.einsum("pi,pi->p", e, c) for c in np.moveaxis(_fd_tip(x, E, e, mode), -1, 0)], axis=-1)
    want = np.abs(thrust.gravity_Nm - 30.0 * J_axial / 1000)
    np.testing.assert_allclose(thrust.per_actuator_Nm, want, rtol=1e-5, atol=1e-6)


def _fd_tip(x, E, e, mode, h=1e-6):
    """dE/dq by central differences of the forward kinematics, (n, 3, 5) mm/rad."""
    sol = inverse_kinematics(x, E, e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    cols = []
    for j in range(5):
        step = np.zeros(5)
        step[j] = h
        a = forward_kinematics(x, (q + step)[:, :3], (q + step)[:, 3:], sol.assembly).E
        b = forward_kinematics(x, (q - step)[:, :3], (q - step)[:, 3:], sol.assembly).E
        cols.append((a - b) / (2 * h))
    return np.stack(cols, axis=-1)


def test_nan_where_the_ik_fails():
    x = vec(PAPER)
    E = np.array([[1000.0, 0.0, 0.0], [-150.0, -150.0, 100.0]])
    e = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    hold = holding_torque(x, E, e)
    assert np.isnan(hold.holding_torque_Nm[0]) and hold.holding_torque_actuator[0] == -1
    assert np.all(np.isnan(hold.per_actuator_Nm[0])) and np.all(np.isnan(hold.gravity_Nm[0]))
    assert ACTUATOR_NAMES[0] == "rho_x"


@pytest.mark.parametrize(
    "kwargs",
    [
        {"wall_mm": 8.0},
        {"wall_mm": -1.0},
        {"density_kg_m3": -1.0},
        {"m_motor_kg": float("nan")},
        {"gravity": (0.0, 9.81)},
        {"c_z_mm": 0.0},
        {"m_delta_kg": -0.1},
    ],
)
def test_bad_mass_model_raises(kwargs):
    with pytest.raises(InputError) as info:
        MassModel(**kwargs)
    assert "MassModel." in str(info.value) and "\n" not in str(info.value)
