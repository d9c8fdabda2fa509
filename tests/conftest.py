"""Shared fixtures and INDEPENDENT oracles for the kinematic-core tests.

Everything here is written from /work/shared/spec/MODEL.md, not from the code under test:

* the parameter order and units (MODEL.md section 2) are restated by hand;
* the leg triads (MODEL.md 1.2) are written out from the table, not from ``poses.LEG_PERM``;
* :func:`oracle_config` builds the mechanism's points in 3-D (MODEL.md 3.1, 4.1, 5.1) from a pose
  and joint angles, and returns the closure residuals of every chain and the signed quantities
  that define the working and assembly modes (F, H, J_AS, det), each from its geometric
  definition (cross products of link vectors), not from the code's closed forms.

The only calls into ``arcube`` in this file are the inverse kinematics used to *filter* random
poses (keep reachable ones); whether the IK is right is what the tests then check.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

_SRC = Path(__file__).resolve().parents[1] / "src"
if str(_SRC) not in sys.path:  # pragma: no cover - the venv normally has arcube installed
    sys.path.append(str(_SRC))

from arcube.model import mechanism  # noqa: E402

# ---------------------------------------------------------------------------------------------
# MODEL.md section 2, restated: name -> index, angles in degrees.
NAMES = (
    "m_x m_y m_z f_x f_y f_z p_x p_y p_z d_x d_y d_z c_x c_y t_x t_y r "
    "o_x o_y alpha_x alpha_y beta_x beta_y"
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

PAPER = {
    "m_x": 31.8694, "m_y": 11.9589, "m_z": 192.0769,
    "f_x": 123.1147, "f_y": 116.9719, "f_z": 56.7787,
    "p_x": 134.099, "p_y": 149.9886, "p_z": 99.8766,
    "d_x": 79.2596, "d_y": 99.9402, "d_z": 53.5671,
    "c_x": 139.8911, "c_y": 106.8319,
    "t_x": 70.9301, "t_y": 65.3946,
    "r": 70.4466,
    "o_x": -19.2229, "o_y": 43.2917,
    "alpha_x": 52.6402, "alpha_y": 66.446,
    "beta_x": 50.0038, "beta_y": 62.1208,
}  # fmt: skip
"""Table 2 of the paper, copied from MODEL.md section 2 (not from arcube.model.design)."""


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
# Random designs and reachable poses.


def random_design(rng) -> np.ndarray:
    """A random design (23,) with m != 0 and dimensions that reach a good share of poses."""
    vals = {}
    for ax in "xyz":
        vals[f"m_{ax}"] = rng.choice([-1.0, 1.0]) * rng.uniform(20.0, 150.0)
        vals[f"f_{ax}"] = rng.uniform(20.0, 80.0)
        vals[f"p_{ax}"] = rng.uniform(60.0, 140.0)
        vals[f"d_{ax}"] = rng.uniform(80.0, 180.0)
    for ax in "xy":
        vals[f"c_{ax}"] = rng.uniform(120.0, 220.0)
        vals[f"t_{ax}"] = rng.uniform(40.0, 100.0)
        vals[f"o_{ax}"] = rng.uniform(-180.0, 180.0)
        vals[f"alpha_{ax}"] = rng.uniform(40.0, 85.0)
        vals[f"beta_{ax}"] = rng.uniform(40.0, 85.0)
    vals["r"] = rng.uniform(50.0, 80.0)
    return vec(vals)


def candidate_poses(rng, x, n, arg_max=0.95):
    """n poses with the tip inside the TLS box (|Eq 1 argument| <= arg_max) and e uniform on S^2."""
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    m = np.stack([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
    arg = rng.uniform(-arg_max, arg_max, size=(n, 3))
    E = m + (p * arg - f - r)
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    return E, e


def reachable_poses(rng, x, mode, n, min_sine=0.1, max_batches=200):
    """n poses (E, e) that the IK reaches in working mode ``mode``, away from every singularity.

    Kept only where cos(rho_u) and all transmission sines exceed ``min_sine`` (computed by the
    oracle), so that finite differences and round trips are well conditioned.
    """
    Es, es = [], []
    count = 0
    for _ in range(max_batches):
        E, e = candidate_poses(rng, x, 4000)
        sol = mechanism.inverse_kinematics(x, E, e, mode)
        ok = np.asarray(sol.reachable)
        with np.errstate(invalid="ignore"):
            cfg = oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma)
            s = transmission_sines(cfg)
            ok &= np.all(np.abs(s) > min_sine, axis=-1) & np.all(np.cos(sol.rho) > min_sine, axis=-1)
        Es.append(E[ok])
        es.append(e[ok])
        count += int(ok.sum())
        if count >= n:
            break
    E, e = np.concatenate(Es)[:n], np.concatenate(es)[:n]
    assert E.shape[0] == n, f"could only find {E.shape[0]} of {n} reachable poses"
    return E, e


ALL_MODES_ORACLE = np.array([[a, b, c, d] for a in (1.0, -1.0) for b in (1.0, -1.0) for c in (1.0, -1.0) for d in (1.0, -1.0)])


@pytest.fixture
def rng():
    return np.random.default_rng(20240601)


@pytest.fixture(scope="session")
def designs():
    """Four random designs, each with m != 0, fixed seeds."""
    return [random_design(np.random.default_rng(seed)) for seed in (11, 22, 33, 44)]


@pytest.fixture(scope="session")
def paper_design():
    return vec(PAPER)


@pytest.fixture(scope="session")
def pose_bank(designs):
    """For every design and every one of the 16 working modes, 12 well-conditioned reachable poses.

    Returns a list of (design, mode, E (12, 3), e (12, 3)).
    """
    rng = np.random.default_rng(777)
    bank = []
    for x in designs:
        for mode in ALL_MODES_ORACLE:
            E, e = reachable_poses(rng, x, mode, 12)
            bank.append((x, mode, E, e))
    return bank


# ----------------------------------------------------------------------------- headless Chromium (browser tests)
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
CHROMIUM_SKIP = pytest.mark.skipif(
    not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()) and os.environ.get("CI") != "true",
    reason="headless Chromium not installed (apt-get install chromium chromium-driver)",
)
"""Skip a browser test when Chromium is missing, except on CI (CI=true), where that is a failure."""


def start_chromium(profile: Path, *args: str):  # noqa: ANN201 - a selenium driver
    """A headless Chromium driver with a fresh profile in ``profile``, the browser log kept, and ``args``
    added to the common ones; skips without selenium unless on CI."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        if os.environ.get("CI") == "true":
            raise
        pytest.skip("selenium not installed (pip install -e '.[test]')")
    assert os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER), f"{CHROMIUM} or {CHROMEDRIVER} is missing (CI=true: install chromium and chromium-driver)"
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run", *args, f"--user-data-dir={profile}"):  # fmt: skip
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
