"""The first-order breach probability (model §22 linearized as §20.3), and what it takes to reach a target.

The Monte Carlo of :mod:`arcube.pedicles.monte_carlo` answers "how likely is this screw to breach"; the inverse
questions ("what registration would bring it to 1 %?") need that answer for many settings at once, so here the offset
of the hole at the isthmus is taken as a 2-D normal, delta_j ~ N(mu_j, S_j) in the isthmus plane (w_j, h_j):

* **robot**: delta = P G_E eps to first order (G_E the derivatives of the tip by every error source at the isthmus
  pose, :func:`arcube.accuracy.first_order.source_jacobians`), eps with variances sigma_i^2 = T_i^2/3 (uniform) or
  T_i^2/9 (normal), independent; for a calibrated robot the first 31 sources (parameters, zero offsets) with the
  identification's covariance C: S_robot = P G C G^T P^T + sum over the encoders and lost motions;
* **registration**: t ~ N(0, sigma_t^2/3 I), omega ~ N(0, sigma_r^2/3 I) about the docking's centroid c: D = t + omega x
  a (a = I_j - c) has covariance sigma_t^2/3 I + sigma_r^2/3 (|a|^2 I - a a^T);
* **deflection**: the mean, mu = P F_t C_E e (the same as the Monte Carlo's, exactly).

P = [w_j^T; h_j^T] projects onto the isthmus plane. P(breach) = P((delta_w/a')^2 + (delta_h/b')^2 > 1)
(:func:`outside_ellipse`): in whitened coordinates u = L^-1 (z - m) ~ N(0, I), the ray from the mean in direction
theta leaves the unit disk at radii found in closed form, and the standard normal mass along it is
exp(-rho^2 / 2) between them: the probability is one integral over theta, periodic, which the trapezoid rule with
:data:`ANGLES` angles gives to rounding for any covariance that is not degenerate to a line. It is checked against
the Monte Carlo (tests, and benchmarks/breach_first_order.py): the robot's errors are uniform and its kinematics not
linear, so the two agree within the Monte Carlo's interval where the normal and linear pictures hold.

:func:`what_it_takes`: per level and for the worst screw, the largest registration r (r mm and r deg RMS together)
with P <= target for the robot as given, the largest screw diameter with P <= target at the given registration, and
the coarsest ISO 2768 class (or the calibration) that reaches it; bisection on the first-order P.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.pedicles.geometry import Pedicles
from arcube.pedicles.sources import RobotModel, deflection

__all__ = [
    "ANGLES",
    "CLASSES_COARSE_FIRST",
    "WHAT_IT_TAKES_COLUMNS",
    "Moments",
    "breach_first_order",
    "moments",
    "outside_ellipse",
    "what_it_takes",
]

ANGLES = 720
"""Directions of the integral over theta in :func:`outside_ellipse` (the trapezoid rule on a periodic integrand)."""
CLASSES_COARSE_FIRST = ("v", "c", "m", "f")
"""The ISO 2768 classes, coarsest first: the first that reaches a target is the cheapest robot that does."""
WHAT_IT_TAKES_COLUMNS = ("level", "worst_trajectory", "registration_needed", "screw_max_mm", "as_built")
"""The columns of what_it_takes.csv, as the issue names them (then ``p_breach``, ``p_first_order``, ``target``)."""
REGISTRATION_MAX = 10.0
"""The largest registration (mm and deg RMS) the search for the one needed looks at."""


class Moments:
    """The normal picture of each screw's offset at the isthmus: ``mean`` ``(J, 2)`` mm (the deflection) and the
    covariances ``(J, 2, 2)`` mm^2 of the robot and of a registration of 1 mm / 0 deg and 0 mm / 1 deg (each scales with
    the square of its RMS)."""

    def __init__(
        self,
        mean: NDArray[np.float64],
        robot: NDArray[np.float64],
        reg_t: NDArray[np.float64],
        reg_r: NDArray[np.float64],
    ) -> None:
        self.mean, self.robot, self.reg_t, self.reg_r = mean, robot, reg_t, reg_r

    def covariance(self, registration_mm: float, registration_deg: float, robot: bool = True) -> NDArray[np.float64]:
        """``(J, 2, 2)`` the offset's covariance with a registration of these RMS figures (and the robot's, unless
        ``robot`` is False)."""
        return (
            (self.robot if robot else 0.0)
            + registration_mm**2 * self.reg_t
            + math.radians(registration_deg) ** 2 * self.reg_r
        )


def _projector(p: Pedicles) -> NDArray[np.float64]:
    return np.stack([p.w, p.h], axis=-2)  # (J, 2, 3)


def robot_covariance(robot: RobotModel, p: Pedicles) -> NDArray[np.float64]:
    """``(J, 2, 2)`` mm^2: the first-order covariance of the robot's offset at each isthmus (module docstring); NaN
    where the nominal robot does not reach the isthmus pose."""
    from arcube.accuracy.first_order import source_jacobians
    from arcube.accuracy.sources import sigmas

    G_E, _, valid = source_jacobians(robot.design, p.isthmus, -p.u, robot.mode)  # (J, 3, n)
    G = np.einsum("jab,jbn->jan", _projector(p), G_E)  # (J, 2, n)
    if robot.covariance is None:
        var = sigmas(robot.T, robot.distribution) ** 2
        S = np.einsum("jan,n,jbn->jab", G, var, G)
    else:
        k = robot.covariance.shape[0]
        var = sigmas(robot.T, "uniform") ** 2  # the encoders and lost motion, as the Monte Carlo draws them
        S = np.einsum("jan,nm,jbm->jab", G[..., :k], robot.covariance, G[..., :k])
        S = S + np.einsum("jan,n,jbn->jab", G[..., k:], var[k:], G[..., k:])
    return np.where(valid[:, None, None], S, np.nan)


def moments(
    robot: RobotModel,
    p: Pedicles,
    docking: Sequence[str],
    thrust_N: float,
    stiffness_Nm_per_rad: Any,
) -> Moments:
    """The normal picture (:class:`Moments`) of each screw's offset; ``docking`` ``(J,)`` names each screw's docking
    (one registration per docking, about the centroid of its screws' entries, as the Monte Carlo draws it)."""
    names = list(dict.fromkeys(docking))
    index = np.array([names.index(d) for d in docking], dtype=np.intp)
    entries = p.isthmus - p.depth[:, None] * p.u
    centres = np.array([entries[index == k].mean(axis=0) for k in range(len(names))])
    a = p.isthmus - centres[index]  # (J, 3)
    P = _projector(p)
    eye = np.broadcast_to(np.eye(3), (len(p.ids), 3, 3))
    rot = (np.sum(a * a, axis=-1)[:, None, None] * np.eye(3) - a[:, :, None] * a[:, None, :]) / 3.0
    reg_t = np.einsum("jab,jbc,jdc->jad", P, eye / 3.0, P)
    reg_r = np.einsum("jab,jbc,jdc->jad", P, rot, P)
    with np.errstate(invalid="ignore"):
        mean = np.einsum("jab,jb->ja", P, deflection(robot, p.isthmus, -p.u, thrust_N, stiffness_Nm_per_rad))
    return Moments(mean, robot_covariance(robot, p), reg_t, reg_r)


def outside_ellipse(mean: ArrayLike, cov: ArrayLike, room: ArrayLike, angles: int = ANGLES) -> NDArray[np.float64]:
    """P(delta outside the ellipse (delta_w/a')^2 + (delta_h/b')^2 <= 1) for delta ~ N(mean, cov): ``mean`` ``(..., 2)``,
    ``cov`` ``(..., 2, 2)``, ``room`` ``(..., 2)`` = (a', b') > 0; ``(...)``. A covariance of 0 gives 0 or 1 (the mean
    inside or outside); NaN where the mean or the covariance is not finite."""
    m = np.asarray(mean, dtype=float) / np.asarray(room, dtype=float)
    scale = 1.0 / np.asarray(room, dtype=float)
    S = np.asarray(cov, dtype=float) * scale[..., :, None] * scale[..., None, :]
    bad = ~(np.all(np.isfinite(m), axis=-1) & np.all(np.isfinite(S), axis=(-2, -1)))
    m = np.where(bad[..., None], 0.0, m)
    S = np.where(bad[..., None, None], 0.0, S)
    # L with L L^T = S (a symmetric square root: well defined for a singular S too)
    vals, vecs = np.linalg.eigh(S)
    L = vecs * np.sqrt(np.maximum(vals, 0.0))[..., None, :]
    theta = np.arange(angles) * (2.0 * np.pi / angles)
    d = np.stack([np.cos(theta), np.sin(theta)], axis=-1)  # (A, 2)
    Ld = np.einsum("...ab,tb->...ta", L, d)  # (..., A, 2)
    A = np.sum(Ld * Ld, axis=-1)
    B = 2.0 * np.einsum("...a,...ta->...t", m, Ld)
    C = (np.sum(m * m, axis=-1) - 1.0)[..., None]
    inside = C < 0.0
    disc = B * B - 4.0 * A * C
    moving = A > 1e-300
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        root = np.sqrt(np.maximum(disc, 0.0))
        far = np.where(moving, (-B + root) / (2.0 * A), np.inf)
        near = np.where(moving, (-B - root) / (2.0 * A), np.inf)
        # from inside: the mass from 0 to where the ray leaves; from outside: between the two crossings, if ahead
        mass_in = 1.0 - np.exp(-0.5 * far * far)
        crosses = moving & (disc > 0.0) & (B < 0.0)
        mass_out = np.where(crosses, np.exp(-0.5 * near * near) - np.exp(-0.5 * far * far), 0.0)
    p_in = np.mean(np.where(inside, np.where(moving, mass_in, 1.0), mass_out), axis=-1)
    return np.where(bad, np.nan, np.clip(1.0 - p_in, 0.0, 1.0))


def breach_first_order(
    mom: Moments, p: Pedicles, registration_mm: float, registration_deg: float, robot: bool = True
) -> NDArray[np.float64]:
    """``(J,)`` the first-order P(breach) of every screw (1 where too wide, NaN where the robot does not reach it)."""
    room = np.where(p.too_wide[:, None], 1.0, p.room)
    out = outside_ellipse(mom.mean, mom.covariance(registration_mm, registration_deg, robot), room)
    return np.where(p.too_wide, 1.0, out)


def _bisect(f: Any, lo: float, hi: float, iterations: int = 40) -> float:
    """The largest x in [lo, hi] with f(x) true, f monotone (true then false), f(lo) true."""
    if f(hi):
        return hi
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) else (lo, mid)
    return lo


def _one_screw(p: Pedicles, j: int) -> Pedicles:
    from dataclasses import replace

    take = slice(j, j + 1)
    return replace(
        p,
        ids=p.ids[take],
        levels=p.levels[take],
        sides=p.sides[take],
        **{k: getattr(p, k)[take] for k in ("isthmus", "u", "w", "h", "medial", "cranial", "width", "height")},
        depth=p.depth[take],
        screw=p.screw[take],
    )


def what_it_takes(
    mom: Moments,
    p: Pedicles,
    p_breach: NDArray[np.float64],
    status: Sequence[str],
    registration_mm: float,
    registration_deg: float,
    target: float,
    classes: dict[str, Moments] | None = None,
    calibrated: bool = False,
) -> list[dict[str, Any]]:
    """One row per level (then ``all``, the worst screw) of :data:`WHAT_IT_TAKES_COLUMNS`: the level's worst assessed
    screw by the Monte Carlo's ``p_breach``; ``registration_needed`` r (mm and deg RMS) with first-order P = target
    (None when even r = 0 exceeds it); ``screw_max_mm`` the largest screw with P <= target at the given registration
    (None when none); ``as_built`` ``calibration`` (a calibrated robot that reaches it), the coarsest class of
    ``classes`` (level -> :class:`Moments` of the robot built to it) that reaches it, or ``none``."""
    assessed = np.array([s == "assessed" for s in status])
    levels = list(dict.fromkeys(p.levels[j] for j in np.flatnonzero(assessed)))
    groups = [(lv, [j for j in np.flatnonzero(assessed) if p.levels[j] == lv]) for lv in levels]
    if assessed.any():
        groups.append(("all", list(np.flatnonzero(assessed))))
    rows = []
    for level, idx in groups:
        j = int(idx[int(np.argmax(p_breach[idx]))])
        one = _one_screw(p, j)
        sub = Moments(mom.mean[j : j + 1], mom.robot[j : j + 1], mom.reg_t[j : j + 1], mom.reg_r[j : j + 1])

        def ok(m: Moments, r_mm: float, r_deg: float, screw: Pedicles = one) -> bool:
            return bool(breach_first_order(m, screw, r_mm, r_deg)[0] <= target)

        p_now = float(breach_first_order(sub, one, registration_mm, registration_deg)[0])
        reg = None if not ok(sub, 0.0, 0.0) else _bisect(lambda r: ok(sub, r, r), 0.0, REGISTRATION_MAX)
        d_max = None
        widest = float(min(one.width[0], one.height[0]))
        if ok(sub, registration_mm, registration_deg, _with_screw(one, 1e-6)):
            d_max = _bisect(lambda d: ok(sub, registration_mm, registration_deg, _with_screw(one, d)), 1e-6, widest)
        as_built = "none"
        if calibrated and ok(sub, registration_mm, registration_deg):
            as_built = "calibration"
        elif classes:
            for name in CLASSES_COARSE_FIRST:
                if name in classes:
                    c = classes[name]
                    cm = Moments(c.mean[j : j + 1], c.robot[j : j + 1], c.reg_t[j : j + 1], c.reg_r[j : j + 1])
                    if ok(cm, registration_mm, registration_deg):
                        as_built = name
                        break
        rows.append(
            {
                "level": level,
                "worst_trajectory": p.ids[j],
                "p_breach": float(p_breach[j]),
                "registration_needed": reg,
                "screw_max_mm": d_max,
                "as_built": as_built,
                "p_first_order": p_now,
                "target": float(target),
            }
        )
    return rows


def _with_screw(p: Pedicles, d: float) -> Pedicles:
    from dataclasses import replace

    return replace(p, screw=np.full_like(p.screw, d))
