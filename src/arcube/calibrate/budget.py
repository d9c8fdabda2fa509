"""The accuracy budget of a calibrated robot (model §21.4 with 20.2-20.4).

After calibration the controller believes the identified design p_id and zero offsets q0_id: at a
pose X it commands q_read = IK_{p_id}(X) - q0_id. The robot's parameters and zero offsets are then
off by the identification's errors, normal with its covariance Sigma_id (31 x 31, the unknowns of
:mod:`arcube.calibrate.model`, which are the first 31 error sources of :mod:`arcube.accuracy.sources`;
a non-identifiable unknown's error is 0: the identified ones have absorbed it); the encoders and the
lost motion keep their model §20.1 tolerances (uniform, drawn at every pose).

* First order (20.3 with a full covariance): RMS lateral = sqrt(trace(P_perp G_E Sigma G_E^T P_perp)),
  Sigma the 41 x 41 covariance of every source (Sigma_id, then the encoders' and backlashes'
  T^2 / 3 on the diagonal); RMS axis and axial likewise. The exact worst case of 20.3 is not defined
  for a normal (unbounded) distribution and is not reported.
* Monte Carlo (20.4): N robots draw their correlated deviations from Sigma_id (once per robot), the
  encoders and backlashes afresh at every point; the errors with the exact FK
  (:func:`arcube.accuracy.monte_carlo.exact_errors` at the identified design). Summary: the 95th
  percentile over robots of each robot's largest lateral (axis) error over the points.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.first_order import source_jacobians
from arcube.accuracy.monte_carlo import (
    CHUNK_ROBOT_POINTS,
    PERCENTILES,
    exact_errors,
    percentiles,
    pose_draws,
    pose_joint_errors,
    split,
)
from arcube.accuracy.sources import N_SOURCES, SOURCE_NAMES
from arcube.evaluation.performance import spin_free_basis
from arcube.evaluation.task import build_task
from arcube.model.mechanism import inverse_kinematics

_ENCODER = np.array([n.startswith("encoder_") for n in SOURCE_NAMES])
_BACKLASH = np.array([n.startswith("backlash_") for n in SOURCE_NAMES])


@dataclass(frozen=True)
class CalibratedBudget:
    """The budget on P points; per-point arrays NaN where the calibrated design does not reach the point."""

    where: str  # "plan" (the trajectories' points) or "measurements" (the measured poses)
    labels: tuple[str, ...]  # (P,) trajectory id (plan) or pose id / row (measurements) of each point
    point: NDArray[np.intp]  # (P,) index along its trajectory (0 for measured poses)
    E: NDArray[np.float64]  # (P, 3) mm
    e: NDArray[np.float64]  # (P, 3) unit
    lateral_rms_mm: NDArray[np.float64]  # (P,) first order
    axial_rms_mm: NDArray[np.float64]  # (P,)
    axis_rms_deg: NDArray[np.float64]  # (P,)
    lateral_mm: NDArray[np.float64]  # (P, 4) Monte Carlo p50, p95, p99, max over robots
    robot_lateral_max_mm: NDArray[np.float64]  # (N,) each robot's largest lateral error over the reached points
    robot_axis_max_deg: NDArray[np.float64]  # (N,)
    tolerances: NDArray[np.float64]  # (41,) T of the per-pose sources (encoders, backlashes), 0 elsewhere, deg

    @property
    def reachable(self) -> NDArray[np.bool_]:
        return np.isfinite(self.lateral_rms_mm)

    @property
    def summary(self) -> dict[str, float]:
        """Maxima over the reached points of the first-order RMS, and the Monte Carlo p95 of the per-robot maxima."""
        r = self.reachable
        return {
            "lateral_error_rms_mm": float(np.max(self.lateral_rms_mm[r])),
            "axial_error_rms_mm": float(np.max(self.axial_rms_mm[r])),
            "axis_error_rms_deg": float(np.max(self.axis_rms_deg[r])),
            "lateral_error_p95_mm": float(percentiles(self.robot_lateral_max_mm, [95.0])[0]),
            "axis_error_p95_deg": float(percentiles(self.robot_axis_max_deg, [95.0])[0]),
            "lateral_error_max_mm": float(np.max(self.robot_lateral_max_mm)),
        }

    def to_json(self) -> dict[str, Any]:
        return {
            "points": self.where,
            "count": len(self.labels),
            "reached": int(np.sum(self.reachable)),
            "robots": int(self.robot_lateral_max_mm.size),
            **self.summary,
        }


def source_covariance(
    cov_unknowns: ArrayLike, encoder_deg: float, backlash_arcmin: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(Sigma ``(41, 41)`` of every error source, T ``(41,)``): the unknowns' covariance (mm, deg) in the first 31
    rows and columns; each encoder's and backlash's uniform variance T^2 / 3 (deg^2) on the diagonal."""
    T = np.where(_ENCODER, encoder_deg, 0.0) + np.where(_BACKLASH, backlash_arcmin / 60.0, 0.0)
    S = np.diag(T**2 / 3.0)
    c = np.asarray(cov_unknowns, dtype=float)
    S[: c.shape[0], : c.shape[1]] = c
    return S, T


def first_order_rms(G_E: ArrayLike, G_e: ArrayLike, e: ArrayLike, Sigma: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """(lateral mm, axial mm, axis deg) RMS ``(...)`` for G ``(..., 3, 41)`` (per mm or deg), unit e ``(..., 3)``
    and the sources' covariance Sigma ``(41, 41)``: sqrt(trace(P G Sigma G^T P)) with P the projection."""
    GE, Ge, S = np.asarray(G_E, dtype=float), np.asarray(G_e, dtype=float), np.asarray(Sigma, dtype=float)
    b = spin_free_basis(e)
    bt = np.swapaxes(b, -1, -2)
    lat, ax = bt @ GE, bt @ Ge  # (..., 2, n)
    along = np.einsum("...i,...ij->...j", np.asarray(e, dtype=float), GE)[..., None, :]

    def rms(A: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.sqrt(np.maximum(np.einsum("...in,nm,...im->...", A, S, A), 0.0))

    return rms(lat), rms(along), np.rad2deg(rms(ax))


def correlated_draws(rng: np.random.Generator, cov: ArrayLike, n: int) -> NDArray[np.float64]:
    """``(n, k)`` draws of N(0, cov) for a symmetric positive semi-definite ``cov`` ``(k, k)`` (a singular one too)."""
    w, V = np.linalg.eigh(np.asarray(cov, dtype=float))
    A = V * np.sqrt(np.maximum(w, 0.0))
    return rng.standard_normal((n, len(w))) @ A.T


def budget_at(
    design: ArrayLike,
    cov_unknowns: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike,
    *,
    encoder_deg: float,
    backlash_arcmin: float,
    samples: int,
    seed: int,
    where: str,
    labels: tuple[str, ...],
    point: ArrayLike,
) -> CalibratedBudget | None:
    """The budget of the calibrated design ``(27,)`` with the unknowns' covariance ``(31, 31)`` at poses (E, e)
    ``(P, 3)`` in working mode ``mode``; None when it reaches none of them."""
    x = np.asarray(design, dtype=float)
    E_a = np.asarray(E, dtype=float)
    e_a = np.asarray(e, dtype=float)
    e_a = e_a / np.linalg.norm(e_a, axis=-1, keepdims=True)
    P = len(E_a)
    Sigma, T = source_covariance(cov_unknowns, encoder_deg, backlash_arcmin)
    with np.errstate(invalid="ignore", divide="ignore"):
        G_E, G_e, valid = source_jacobians(x, E_a, e_a, mode)
        lat, axial, axis = first_order_rms(G_E, G_e, e_a, Sigma)
    ok = valid & np.isfinite(lat) & np.isfinite(axis)
    if not ok.any():
        return None
    nan = np.full(P, np.nan)
    sol = inverse_kinematics(x, E_a[ok], e_a[ok], mode)
    q_cmd = np.concatenate([sol.rho, sol.delta], axis=-1)
    rng = np.random.default_rng(seed)
    per = np.zeros((samples, N_SOURCES))
    per[:, : np.shape(cov_unknowns)[0]] = correlated_draws(rng, cov_unknowns, samples)
    dp, dq0 = split(per)
    n_ok = int(ok.sum())
    lateral, axis_err = np.empty((samples, n_ok)), np.empty((samples, n_ok))
    step = max(1, CHUNK_ROBOT_POINTS // n_ok)
    for lo in range(0, samples, step):
        hi = min(samples, lo + step)
        dq = dq0[lo:hi, None, :] + pose_joint_errors(pose_draws(rng, T, hi - lo, n_ok, "uniform"))
        err = exact_errors(x, E_a[ok], e_a[ok], q_cmd, sol.assembly, dp[lo:hi], dq)
        lateral[lo:hi], axis_err[lo:hi] = err.lateral_mm, err.axis_deg
    per_point = np.full((P, 4), np.nan)
    per_point[ok, :3] = percentiles(lateral, PERCENTILES, axis=0).T
    per_point[ok, 3] = np.max(lateral, axis=0)
    return CalibratedBudget(
        where=where,
        labels=labels,
        point=np.asarray(point, dtype=np.intp),
        E=E_a,
        e=e_a,
        lateral_rms_mm=np.where(ok, lat, nan),
        axial_rms_mm=np.where(ok, axial, nan),
        axis_rms_deg=np.where(ok, axis, nan),
        lateral_mm=per_point,
        robot_lateral_max_mm=np.max(lateral, axis=1),
        robot_axis_max_deg=np.max(axis_err, axis=1),
        tolerances=T,
    )


def calibrated_budget(
    design: ArrayLike,
    cov_unknowns: ArrayLike,
    mode: ArrayLike,
    settings: Any,
    trajectories: Any = None,
    measurements: Any = None,
) -> CalibratedBudget | None:
    """The budget on a plan's points (``trajectories``, sampled at ``settings.points`` per trajectory) or, without
    one, on the measured poses. The identified zero offsets do not enter: the controller subtracts them from the IK
    and the robot's real offsets add them back, up to the identification's error (in the covariance)."""
    kw = {
        "encoder_deg": settings.encoder_deg,
        "backlash_arcmin": settings.backlash_arcmin,
        "samples": settings.samples,
        "seed": settings.seed,
    }
    if trajectories is not None:
        task = build_task(trajectories.entry, trajectories.target, settings.points, ids=tuple(trajectories.ids))
        labels = tuple(task.ids[t] for t in task.trajectory)
        return budget_at(design, cov_unknowns, task.E, task.e, mode, where="plan", labels=labels, point=task.k, **kw)
    m = measurements
    labels = m.pose if m.pose is not None else tuple(str(r) for r in (m.rows or range(1, len(m) + 1)))
    return budget_at(
        design, cov_unknowns, m.E, m.e, mode, where="measurements", labels=tuple(labels), point=np.zeros(len(m)), **kw
    )
