"""Monte Carlo of built robots (model §20.2, 20.4), with the exact closed-form FK.

The controller believes the nominal design p: at a plan pose X it commands q_cmd = IK_p(X) (in the
design's working mode). A built robot has parameters p + dp and zero offsets dq0 (drawn once per
robot), and at every pose an encoder error and a backlash (drawn afresh); its joints sit at
q = q_cmd + dq0 + dq_enc + dq_bl and its tool at FK_{p+dp}(q) in the assembly mode of the nominal
IK at X. Per robot and point: ``lateral`` = |P_perp dE|, ``axial`` = |e^T dE| (mm),
``axis`` = angle(e_real, e) (deg), dE = E_real - E.

Everything is batched over robots x points with :func:`arcube.model.mechanism.forward_kinematics`
(no Python loop over robots or points; robots go in chunks so that memory stays bounded). A robot
whose FK does not assemble at a point (the nominal assembly mode no longer closes) has an infinite
error there: it cannot drill that screw.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.sources import JOINT_COLUMN, N_SOURCES, PARAM_COLUMN, PER_ROBOT
from arcube.model.design import N_PARAMS
from arcube.model.mechanism import forward_kinematics

CHUNK_ROBOT_POINTS = 100_000
"""Robots x points evaluated at once (about 60 MB of temporaries)."""
PERCENTILES: tuple[float, ...] = (50.0, 95.0, 99.0)

_ROBOT_IDX = np.flatnonzero(PER_ROBOT)
POSE_INDEX: np.ndarray = np.flatnonzero(~PER_ROBOT)
"""Indices into SOURCE_NAMES of the sources drawn afresh at every pose (encoders, backlashes): the last axis of
:func:`pose_draws`."""


def standard_draws(rng: np.random.Generator, shape: tuple[int, ...], distribution: str) -> NDArray[np.float64]:
    """Deviations per unit of tolerance: uniform on [-1, 1], or normal with sigma 1/3 (model §20.1)."""
    if distribution == "uniform":
        return rng.uniform(-1.0, 1.0, shape)
    return rng.normal(0.0, 1.0 / 3.0, shape)


def robot_draws(rng: np.random.Generator, T: ArrayLike, n_robots: int, distribution: str) -> NDArray[np.float64]:
    """The per-robot deviations ``(N, n)`` (mm, deg) of the sources drawn once per robot (design parameters,
    docking, zero offsets); 0 in the columns of the per-pose sources."""
    T_ = np.asarray(T, dtype=float)
    out = np.zeros((n_robots, N_SOURCES))
    out[:, _ROBOT_IDX] = standard_draws(rng, (n_robots, _ROBOT_IDX.size), distribution) * T_[_ROBOT_IDX]
    return out


def pose_draws(
    rng: np.random.Generator, T: ArrayLike, n_robots: int, n_points: int, distribution: str
) -> NDArray[np.float64]:
    """The per-pose deviations ``(N, P, m)`` (deg) of the m sources of :data:`POSE_INDEX` (encoders, backlashes)."""
    return (
        standard_draws(rng, (n_robots, n_points, POSE_INDEX.size), distribution)
        * np.asarray(T, dtype=float)[POSE_INDEX]
    )


def pose_joint_errors(draws: ArrayLike) -> NDArray[np.float64]:
    """Joint errors ``(..., 5)`` rad from per-pose deviations ``(..., m)`` (deg, :func:`pose_draws`): each joint's
    encoder error plus its backlash."""
    d = np.asarray(draws, dtype=float)
    dq = np.zeros(d.shape[:-1] + (5,))
    for k, j in enumerate(JOINT_COLUMN[POSE_INDEX]):
        dq[..., j] += d[..., k]
    return np.deg2rad(dq)


def split(delta: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Source deviations ``(..., n)`` (mm, deg) -> (dp ``(..., 27)`` in design units (mm, deg), dq ``(..., 5)`` rad),
    the joint sources of one joint summed."""
    d = np.asarray(delta, dtype=float)
    dp = np.zeros(d.shape[:-1] + (N_PARAMS,))
    is_param = PARAM_COLUMN >= 0
    dp[..., PARAM_COLUMN[is_param]] = d[..., is_param]
    joint = np.deg2rad(d[..., ~is_param])
    dq = np.zeros(d.shape[:-1] + (5,))
    for k, j in enumerate(JOINT_COLUMN[~is_param]):  # zero offset + encoder + backlash of joint j
        dq[..., j] += joint[..., k]
    return dp, dq


class Errors(NamedTuple):
    """Errors of built robots at plan points, each ``(N, P)``; +inf where the robot's FK does not assemble."""

    lateral_mm: NDArray[np.float64]
    axial_mm: NDArray[np.float64]
    axis_deg: NDArray[np.float64]


def exact_errors(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, q_cmd: ArrayLike, assembly: ArrayLike, dp: ArrayLike, dq: ArrayLike
) -> Errors:
    """Errors of model §20.2 for robots p + dp at joints q_cmd + dq, with the exact FK.

    Args:
        params: the nominal design ``(27,)`` (mm, deg).
        E, e: the plan poses ``(P, 3)`` in R_w; ``q_cmd`` ``(P, 5)`` rad their nominal IK,
            ``assembly`` ``(P, 3)`` its assembly mode.
        dp: parameter deviations ``(N, 27)`` (mm, deg); dq: joint deviations ``(N, P, 5)`` rad.
    """
    x = np.asarray(params, dtype=float)
    q = np.asarray(q_cmd, dtype=float)[None] + np.asarray(dq, dtype=float)
    fk = forward_kinematics(
        x + np.asarray(dp, dtype=float)[:, None, :], q[..., :3], q[..., 3:], np.asarray(assembly, dtype=float)[None]
    )
    E_a, e_a = np.asarray(E, dtype=float), np.asarray(e, dtype=float)
    dE = fk.E - E_a
    along = np.sum(dE * e_a, axis=-1)
    lateral = np.linalg.norm(dE - along[..., None] * e_a, axis=-1)
    cross = np.linalg.norm(np.cross(fk.e, e_a), axis=-1)
    axis = np.rad2deg(np.arctan2(cross, np.sum(fk.e * e_a, axis=-1)))
    bad = ~fk.valid | ~np.isfinite(lateral) | ~np.isfinite(axis)
    inf = np.inf
    return Errors(np.where(bad, inf, lateral), np.where(bad, inf, np.abs(along)), np.where(bad, inf, axis))


def monte_carlo(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    q_cmd: ArrayLike,
    assembly: ArrayLike,
    T: ArrayLike,
    n_robots: int,
    distribution: str = "uniform",
    seed: int = 1,
) -> tuple[Errors, NDArray[np.float64]]:
    """N built robots at the P plan poses: (errors ``(N, P)`` each, per-robot deviations ``(N, n)``).

    The generator (``numpy.random.default_rng(seed)``) draws the per-robot deviations of all N robots
    first, then the per-pose ones chunk by chunk of robots: the same seed, N and P give the same robots.
    """
    rng = np.random.default_rng(seed)
    P = np.asarray(E).shape[0]
    per_robot = robot_draws(rng, T, n_robots, distribution)
    dp, dq0 = split(per_robot)
    out = [np.empty((n_robots, P)) for _ in range(3)]
    step = max(1, CHUNK_ROBOT_POINTS // max(P, 1))
    for lo in range(0, n_robots, step):
        hi = min(n_robots, lo + step)
        dq_pose = pose_joint_errors(pose_draws(rng, T, hi - lo, P, distribution))
        err = exact_errors(params, E, e, q_cmd, assembly, dp[lo:hi], dq0[lo:hi, None, :] + dq_pose)
        for o, a in zip(out, err):
            o[lo:hi] = a
    return Errors(*out), per_robot


def percentiles(a: ArrayLike, q: ArrayLike, axis: int = 0) -> NDArray[np.float64]:
    """Percentiles ``q`` (NumPy's default, linear interpolation) of ``a`` along ``axis``, where +inf counts as the
    largest value: an interpolation that touches it is +inf (NumPy's would be NaN). Result: ``q`` first."""
    s = np.sort(np.asarray(a, dtype=float), axis=axis)
    s = np.moveaxis(s, axis, 0)
    n = s.shape[0]
    pos = np.asarray(q, dtype=float) / 100.0 * (n - 1)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, n - 1)
    frac = (pos - lo).reshape(pos.shape + (1,) * (s.ndim - 1))
    a_lo, a_hi = s[lo], s[hi]
    with np.errstate(invalid="ignore"):
        v = a_lo + frac * (a_hi - a_lo)
    return np.where(np.isinf(a_hi) & (frac > 0.0) | np.isinf(a_lo), np.inf, v)
