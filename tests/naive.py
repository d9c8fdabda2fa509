"""The tests' INDEPENDENT oracles, written from MODEL.md (``/work/shared/spec/MODEL.md``, the docs site's model
pages), not from the code under test; every test imports them from here (``from naive import vec, get``).

* the parameter order and units (MODEL.md section 2) are restated by hand;
* the leg triads (MODEL.md 1.2) are written out from the table, not from ``poses.LEG_PERM``;
* :func:`oracle_config` builds the mechanism's points in 3-D (MODEL.md 3.1, 4.1, 5.1) from a pose
  and joint angles, and returns the closure residuals of every chain and the signed quantities
  that define the working and assembly modes (F, H, J_AS, det), each from its geometric
  definition (cross products of link vectors), not from the code's closed forms;
* the mounting rotation of MODEL.md 13.1 from elementary rotations (:func:`rotation`);
* the local condition number eta_L from NumPy's SVD of the Jacobians (:func:`svd_eta`);
* the moving mass of MODEL.md 18.1 summed by hand (:func:`mass_by_hand`);
* ``program.csv`` read back as text (:func:`read_program_csv`).

No function here calls into ``arcube`` except :func:`svd_eta`, which takes the Jacobians whose condition
numbers it computes from the code (the oracle is the SVD, not the matrices). The test inputs built with
these oracles (random designs, reachable poses, ...) are in :mod:`designs`; the comparison of two engines
field by field is in :mod:`compare`.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from arcube.evaluation.indices import JACOBIAN_NAMES
from arcube.model.mechanism import inverse_kinematics, jacobians

# ---------------------------------------------------------------------------------------------
# MODEL.md section 2, restated: name -> index, angles in degrees.
NAMES = (
    "m_x m_y m_z f_x f_y f_z p_x p_y p_z d_x d_y d_z c_x c_y t_x t_y r o_x o_y alpha_x alpha_y beta_x beta_y"
).split()
IDX = {n: i for i, n in enumerate(NAMES)}
ANGLES = {"o_x", "o_y", "alpha_x", "alpha_y", "beta_x", "beta_y"}

# MODEL.md 1.2: (u, v, w) triads of legs x, y, z, written out from the table.
X_HAT, Y_HAT, Z_HAT = np.eye(3)
TRIADS = np.array(
    [
        [X_HAT, Y_HAT, Z_HAT],  # leg x
        [Y_HAT, Z_HAT, X_HAT],  # leg y
        [Z_HAT, X_HAT, Y_HAT],  # leg z
    ]
)

ALL_MODES_ORACLE = np.array(
    [[a, b, c, d] for a in (1.0, -1.0) for b in (1.0, -1.0) for c in (1.0, -1.0) for d in (1.0, -1.0)]
)
"""The 16 working modes (4 signs each), written out (not from ``mechanism.ALL_MODES``)."""


def vec(values: dict[str, float]) -> np.ndarray:
    """A design vector (23,) from a name -> value mapping (mm, deg)."""
    return np.array([float(values[n]) for n in NAMES])


def get(x, name):
    """Parameter ``name`` of design array(s) ``x`` (..., 23); angles converted to radians."""
    v = np.asarray(x, dtype=float)[..., IDX[name]]
    return np.deg2rad(v) if name in ANGLES else v


def leg_pair(x, stem):
    """(..., 2) array of a per-leg parameter for legs x, y (e.g. stem 'c' -> c_x, c_y)."""
    return np.stack([get(x, f"{stem}_x"), get(x, f"{stem}_y")], axis=-1)


def leg_triple(x, stem):
    return np.stack([get(x, f"{stem}_x"), get(x, f"{stem}_y"), get(x, f"{stem}_z")], axis=-1)


def n_dir(phi, v_hat, w_hat):
    """Link direction n(phi) = sin(phi) v - cos(phi) w (MODEL.md 4.1), (..., 3)."""
    phi = np.asarray(phi, dtype=float)[..., None]
    return np.sin(phi) * v_hat - np.cos(phi) * w_hat


def e_of(psi, theta):
    """e = R_x(psi) R_y(theta) z by explicit rotation matrices (MODEL.md 1.3)."""
    cp, sp, ct, st = np.cos(psi), np.sin(psi), np.cos(theta), np.sin(theta)
    Rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    Ry = np.array([[ct, 0, st], [0, 1, 0], [-st, 0, ct]])
    return Rx @ Ry @ Z_HAT


def rotate(vectors, axis_angle):
    """Rodrigues rotation of ``vectors`` (..., 3) by rotation vectors ``axis_angle`` (..., 3)."""
    k = np.asarray(axis_angle, dtype=float)
    ang = np.linalg.norm(k, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        kh = np.where(ang > 0, k / np.where(ang > 0, ang, 1.0), 0.0)
    v = np.asarray(vectors, dtype=float)
    return (
        v * np.cos(ang)
        + np.cross(kh, v) * np.sin(ang)
        + kh * np.sum(kh * v, axis=-1, keepdims=True) * (1 - np.cos(ang))
    )


def wrap(a):
    """Wrap to (-pi, pi] for comparisons of angles."""
    return np.angle(np.exp(1j * np.asarray(a, dtype=float)))


def rotation(mount_deg) -> np.ndarray:
    """R = R_z(rz) R_y(ry) R_x(rx) (MODEL.md 13.1) from elementary rotations; ``mount_deg`` (rx, ry, rz) deg."""
    rx, ry, rz = np.radians(mount_deg)
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


# ---------------------------------------------------------------------------------------------
# The mechanism in 3-D.


def oracle_config(x, E, e, rho, delta, sigma):
    """Build the mechanism in 3-D in R_m (MODEL.md 3.1, 4.1, 5.1) and return its invariants.

    Shapes: x (..., 23), E (..., 3) in R_w, e (..., 3), rho (..., 3), delta, sigma (..., 2).
    """
    x = np.asarray(x, dtype=float)
    E_m = np.asarray(E, dtype=float) - np.stack([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")], axis=-1)
    e = np.asarray(e, dtype=float)
    rho = np.asarray(rho, dtype=float)
    f, p = leg_triple(x, "f"), leg_triple(x, "p")
    d, c, t = leg_pair(x, "d"), leg_pair(x, "c"), leg_pair(x, "t")
    o, al, be = leg_pair(x, "o"), leg_pair(x, "alpha"), leg_pair(x, "beta")
    r = get(x, "r")
    out = SimpleNamespace(D=[], Q=[], K=[], T=[], ub=[])
    for i in range(3):
        u_hat, v_hat, w_hat = TRIADS[i]
        P = -f[..., i, None] * u_hat
        Dp = P + p[..., i, None] * (-np.sin(rho[..., i, None]) * u_hat + np.cos(rho[..., i, None]) * w_hat)
        Q = E_m + r[..., None] * u_hat
        out.D.append(Dp)
        out.Q.append(Q)
        if i < 2:
            out.K.append(Dp + d[..., i, None] * n_dir(delta[..., i], v_hat, w_hat))
            out.T.append(Q + t[..., i, None] * n_dir(sigma[..., i], v_hat, w_hat))
            lam = sigma[..., i] + o[..., i]
            out.ub.append(np.cos(al[..., i, None]) * u_hat + np.sin(al[..., i, None]) * n_dir(lam, v_hat, w_hat))
    D = np.stack(np.broadcast_arrays(*out.D), axis=-2)
    Q = np.stack(np.broadcast_arrays(*out.Q), axis=-2)
    K = np.stack(np.broadcast_arrays(*out.K), axis=-2)
    T = np.stack(np.broadcast_arrays(*out.T), axis=-2)
    ub = np.stack(np.broadcast_arrays(*out.ub), axis=-2)
    u2 = TRIADS[:2, 0]  # (2, 3): x_hat, y_hat
    cross_u = lambda a, b: np.sum(np.cross(a, b) * u2, axis=-1)  # noqa: E731  (a x b) . u
    e_b = np.broadcast_to(e[..., None, :], ub.shape)
    return SimpleNamespace(
        E_m=E_m,
        D=D,
        Q=Q,
        K=K,
        T=T,
        ub=ub,
        # TLS: the distal chain is planar, so D_u and Q_u share their u coordinate.
        planar=np.sum((D - Q) * TRIADS[:, 0], axis=-1),
        # TMS: coupler closure |T - K| = c (in 3-D, so the planar offset also counts).
        Phi=np.sum((T - K) ** 2, axis=-1) - c**2,
        F=cross_u(K - D[..., :2, :], T - K),
        H=cross_u(T - Q[..., :2, :], T - K),
        s_F=cross_u(K - D[..., :2, :], T - K) / (d * c),
        s_H=cross_u(T - Q[..., :2, :], T - K) / (t * c),
        # RTS
        Gamma=np.sum(ub * e_b, axis=-1) - np.cos(be),
        J_AS=np.sum(np.cross(u2, ub) * e_b, axis=-1),
        det=np.linalg.det(np.stack([ub[..., 0, :], ub[..., 1, :], np.broadcast_to(e, ub[..., 0, :].shape)], axis=-1)),
        s_AS=np.sum(np.cross(u2, ub) * e_b, axis=-1) / (np.sin(al) * np.sin(be)),
        sin_beta=np.sin(be),
    )


def oracle_modes(cfg):
    """Working mode (sign F_x, sign F_y, -sign J_AS_x, -sign J_AS_y) and assembly (sign H, sign det)."""
    mode = np.concatenate([np.sign(cfg.F), -np.sign(cfg.J_AS)], axis=-1)
    asm = np.concatenate([np.sign(cfg.H), np.sign(cfg.det)[..., None]], axis=-1)
    return mode, asm


def transmission_sines(cfg):
    """The four transmission sines of MODEL.md 8.2, (..., 5): s_F (2), s_H (2)... packed as
    [s_F_x, s_F_y, s_H_x, s_H_y, s_AS_x, s_AS_y, s_AP]."""
    s_ap = cfg.det / (cfg.sin_beta[..., 0] * cfg.sin_beta[..., 1])
    return np.concatenate([cfg.s_F, cfg.s_H, cfg.s_AS, s_ap[..., None]], axis=-1)


# ---------------------------------------------------------------------------------------------
# Condition numbers (MODEL.md 8.3) by SVD.


def svd_eta(x, E, e, mode):
    """eta_L = max of the seven kappas, from numpy.linalg.cond of jacobians() (inf if singular)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(x, E, e, mode)
        J = jacobians(sol, x)
        ks = []
        for name in JACOBIAN_NAMES:
            M = np.nan_to_num(J[name], nan=0.0)
            s = np.linalg.svd(M, compute_uv=False)
            ks.append(np.where(s[..., -1] > 0, s[..., 0] / np.where(s[..., -1] > 0, s[..., -1], 1.0), np.inf))
    return np.max(np.stack(ks, axis=-1), axis=-1), sol


# ---------------------------------------------------------------------------------------------
# Masses (MODEL.md 18.1 defaults and 14.1 radii, restated).

RHO_L, WALL, DENSITY, M_DELTA, M_MOTOR, L_MOTOR = 8.0, 2.0, 2700.0, 0.8, 1.5, 120.0
"""Link radius and wall (mm), density (kg/m^3), actuator and motor masses (kg), motor length (mm)."""
LAMBDA = DENSITY * math.pi * ((RHO_L / 1000) ** 2 - ((RHO_L - WALL) / 1000) ** 2) / 1000  # kg/mm


def mass_by_hand(x23, c_z=None):
    """The whole moving mass (kg) of design ``x23`` (23,): every link's length times LAMBDA, plus the two
    delta actuators and the drill motor; ``c_z`` (mm) the z dyad's coupler (None: d_z)."""
    p, d = x23[6:9], x23[9:12]
    c, t, r = x23[12:14], x23[14:16], x23[16]
    al, be = np.radians(x23[19:21]), np.radians(x23[21:23])
    cz = d[2] if c_z is None else c_z
    length = (
        p.sum()
        + d.sum()
        + cz
        + c.sum()
        + t.sum()
        + 3 * math.sqrt(2) * r
        + 24 * r * np.sum(np.sin(al / 24) + np.sin(be / 24))
    )
    return LAMBDA * length + 2 * M_DELTA + M_MOTOR


# ---------------------------------------------------------------------------------------------
# A program's CSV, read as text.


def read_program_csv(folder: Path) -> dict[str, np.ndarray]:
    """program.csv as the test reads it: text columns as str arrays, the others as float."""
    with open(folder / "program.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {
        k: np.array([r[k] for r in rows]) if k in ("segment", "trajectory") else np.array([float(r[k]) for r in rows])
        for k in rows[0]
    }
