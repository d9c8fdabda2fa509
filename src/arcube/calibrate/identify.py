"""Identification of a built robot from tracker measurements (model §21.2, 21.4): :func:`identify`.

1. The robot's assembly mode: the one whose nominal FK at the joint readings is nearest the measured
   poses in most rows (:func:`arcube.calibrate.model.robot_assembly`); a row where the nominal FK does
   not close in it is refused.
2. A seeded fraction (``IdentifySettings.holdout``) of the rows is held out; the rest are fitted.
3. Identifiability: QR with column pivoting of the scaled Jacobian of the fitted rows at the nominal
   values (:mod:`arcube.calibrate.identifiability`); the unknowns it cannot tell apart stay nominal.
4. Levenberg-Marquardt (``scipy.optimize.least_squares(method="lm")``, the analytic Jacobian of
   :mod:`arcube.model.sensitivity`) from the nominal values, on the identifiable unknowns.
5. Standard deviations from sigma_hat^2 (J^T J)^-1 at the solution, sigma_hat^2 = (sum of squared
   weighted residuals) / (5 N_fit - n): a measurement carries 5 independent values (3 of the tip, 2 of
   the unit axis), so this is the residual variance per degree of freedom; sigma_hat ~ 1 when the
   residuals are at the tracker's noise level.

Too few measurements: fewer than n_s / 5 + 1 fitted rows, n_s the number of unknowns the model can
identify near these joint readings (the rank of the Jacobian at the readings jittered by +-5 deg, so
that a small set does not pass by its own low rank), is refused: the fit needs more independent values
than unknowns, and sigma_hat needs one more.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from arcube.calibrate.budget import calibrated_budget
from arcube.calibrate.design_file import design_digest, load_design, signs_of
from arcube.calibrate.identifiability import identifiability, observability
from arcube.calibrate.measurements import Measurements, read_measurements
from arcube.calibrate.model import (
    DOF_PER_MEASUREMENT,
    N_UNKNOWNS,
    Problem,
    make_problem,
    model_pose,
)
from arcube.calibrate.result import Calibration, Residuals, pose_errors
from arcube.calibrate.settings import IdentifySettings
from arcube.errors import InputError
from arcube.model.design import Design

JITTER_DEG = 5.0
"""Joint jitter of the poses on which the number of identifiable unknowns is counted, deg."""
MIN_JITTERED = 64
"""Fewest jittered poses that count is taken on."""


def _subset(p: Problem, rows: NDArray[np.intp]) -> Problem:
    return Problem(
        p.design, p.u0, p.scale, p.q_read[rows], p.E[rows], p.e[rows], p.assembly[rows], p.sigma_mm, p.sigma_rad
    )


def identifiable_count(p: Problem) -> int:
    """How many unknowns the model can identify near the rows' joint readings: the rank of the scaled
    Jacobian at the readings jittered by +-:data:`JITTER_DEG` (fixed seed), at least :data:`MIN_JITTERED` poses."""
    rng = np.random.default_rng(20240521)
    reps = max(1, math.ceil(MIN_JITTERED / max(len(p.q_read), 1)))
    q = np.repeat(p.q_read, reps, axis=0) + rng.uniform(-JITTER_DEG, JITTER_DEG, (len(p.q_read) * reps, 5))
    asm = np.repeat(p.assembly, reps, axis=0)
    x, q0 = p.state(np.zeros(N_UNKNOWNS))
    with np.errstate(invalid="ignore", divide="ignore"):
        pose = model_pose(x, q0, q, asm)
    jp = Problem(p.design, p.u0, p.scale, q, pose.E, pose.e, asm, p.sigma_mm, p.sigma_rad)
    J = jp.jacobian(pose)[pose.valid].reshape(-1, N_UNKNOWNS)
    return identifiability(J).rank


class _Cached:
    """fun and jac of least_squares share one FK evaluation per point."""

    def __init__(self, p: Problem, idx: NDArray[np.intp]) -> None:
        self.p, self.idx, self.z, self.pose = p, idx, None, None

    def _at(self, zi: NDArray[np.float64]) -> Any:
        if self.z is None or not np.array_equal(zi, self.z):
            z = np.zeros(N_UNKNOWNS)
            z[self.idx] = zi
            with np.errstate(invalid="ignore", divide="ignore"):
                self.pose = self.p.pose(z)
            self.z = zi.copy()
        return self.pose

    def fun(self, zi: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.p.residuals(self._at(zi)).reshape(-1)

    def jac(self, zi: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.p.jacobian(self._at(zi))[..., self.idx].reshape(-1, len(self.idx))


def _holdout(n: int, fraction: float, seed: int) -> NDArray[np.bool_]:
    """``(n,)`` True for the fitted rows: round(fraction n) rows, chosen by ``default_rng(seed)``, are held out."""
    fitted = np.ones(n, bool)
    fitted[np.random.default_rng(seed).permutation(n)[: round(fraction * n)]] = False
    return fitted


NOT_MEASURED = 0.01
"""Measurements whose RMS residual against the nominal design is below this many tracker noises are not measurements:
a real robot measured by a real tracker is off by its errors and the noise (the poses file given as its own readings
matched to 1e-13 mm)."""


FIT_LIMIT = 10.0
"""Largest sigma_hat accepted (the fitted residuals in the tracker's noise): beyond it the rows are no measurements
of this robot (angles in the wrong unit, another robot, a mistyped row). The held-out rows are reported, not judged:
few measurements predict them poorly without any being wrong."""


def _check_fit(
    meas: Measurements,
    settings: IdentifySettings,
    r: NDArray[np.float64],
    valid: NDArray[np.bool_],
    fitted: NDArray[np.bool_],
    s2: float,
) -> None:
    """InputError when the identified model does not explain the fitted measurements (naming the worst row), or cannot
    assemble at a held-out one: ``r`` ``(N, 6)`` weighted residuals at the solution, ``valid`` ``(N,)`` where it
    assembles, ``s2`` sigma_hat^2 of the fitted rows."""
    noise = f"IdentifySettings.sigma_mm {settings.sigma_mm:g}, IdentifySettings.sigma_deg {settings.sigma_deg:g}"
    with np.errstate(invalid="ignore"):
        per_row = np.sqrt(np.sum(r * r, axis=-1) / DOF_PER_MEASUREMENT)  # (N,) each measurement's, in the noise
    if not math.sqrt(s2) <= FIT_LIMIT:
        i = int(np.flatnonzero(fitted)[np.argmax(per_row[fitted])])
        raise InputError(
            f"{meas.source}: the calibrated model misses the fitted measurements by {math.sqrt(s2):.3g} times the "
            f"tracker's noise ({noise}; at most {FIT_LIMIT:g} is a fit; the worst, {per_row[i]:.3g} times, is "
            f"{meas.where(i)}): joint angles in the wrong unit (deg), rows of another robot or mistyped rows, or a "
            "tracker noisier than that (give its noise)"
        )
    if not np.all(valid):  # the fitted rows assemble (checked with convergence): a held-out one does not
        raise InputError(
            f"{meas.where(int(np.flatnonzero(~valid)[0]))}: held out, and the calibrated robot cannot take its joint "
            "angles: a wrong row, or one of another robot"
        )


def identify(
    design: Any,
    measurements: Measurements | str | os.PathLike[str],
    mode: ArrayLike | str | None = None,
    settings: IdentifySettings | None = None,
    trajectories: Any = None,
    out: str | os.PathLike[str] | None = None,
) -> Calibration:
    """Identify the built robot's parameters and zero offsets from measurements (model §21.2, 21.4).

    Args:
        design: the nominal design: a :class:`~arcube.model.design.Design`, preset, design JSON (plain or
            calibrated: a calibrated one's q0_* are the nominal zero offsets, its c_z is kept), or 27 numbers.
        measurements: a :class:`Measurements` or a measurement CSV (:mod:`arcube.calibrate.measurements`).
        mode: the design's working mode (``"+,+,+,-"``); default: the design file's, else +,+,+,+. It is
            recorded in design.json and used by the budget's IK.
        settings: :class:`IdentifySettings` (tracker noise, holdout, seed, budget).
        trajectories: a :class:`~arcube.io.trajectories.TrajectorySet` (already selected, e.g. one side):
            the calibrated robot's accuracy budget is computed on its points; None: on the measured poses.
        out: if given, the output folder (new or empty) written all or nothing: design.json,
            calibration.json, residuals.csv, calibration.html (:func:`arcube.calibrate.output.write_calibration`).

    Raises:
        InputError: a bad file or row (named), too few measurements, or a fit that fails.
    """
    settings = IdentifySettings() if settings is None else settings
    start = load_design(design)
    meas = measurements if isinstance(measurements, Measurements) else read_measurements(measurements)
    signs = signs_of(mode, start.mode)
    full = make_problem(
        start.vector, start.q0_deg, meas.q_deg, meas.E, meas.e, settings.sigma_mm, settings.sigma_deg, where=meas.where
    )
    n_rows = len(meas)
    fitted = _holdout(n_rows, settings.holdout, settings.seed)
    fit = _subset(full, np.flatnonzero(fitted))
    n_fit = int(fitted.sum())
    n_model = identifiable_count(fit) if n_fit else N_UNKNOWNS
    if DOF_PER_MEASUREMENT * n_fit <= n_model:
        need = n_model // DOF_PER_MEASUREMENT + 1
        raise InputError(
            f"{meas.source}: {n_fit} fitted measurements ({n_rows} rows, {n_rows - n_fit} held out) are too few for the "
            f"{n_model} unknowns the model can identify: each gives 5 independent values (3 of the tip, 2 of the axis); "
            f"fit at least {need} (IdentifySettings.holdout sets how many are held out)"
        )

    digest = design_digest(start.vector, start.q0_deg)
    # A calibrated design refines itself from measurements taken at the poses of the design it was calibrated
    # from (whose digest its file does not keep): only a plain design's poses must be its own.
    if meas.design is not None and meas.design != digest and not start.calibrated:
        raise InputError(
            f"{meas.source}: measured at poses chosen for another design (digest {meas.design}, this design's is {digest}); "
            "identify with the design the poses were chosen for"
        )
    with np.errstate(invalid="ignore", divide="ignore"):
        pose0 = full.pose(np.zeros(N_UNKNOWNS))
        r0 = full.residuals(pose0)[fitted]
    rms0 = float(np.sqrt(np.nanmean(r0 * r0)))
    if rms0 < NOT_MEASURED:
        raise InputError(
            f"{meas.source}: the rows match the nominal design to {rms0:.1e} of the tracker's noise (sigma_mm "
            f"{settings.sigma_mm:g}, sigma_deg {settings.sigma_deg:g}): these are the poses to measure, not measurements "
            "(fill in E and e with the tracker's readings)"
        )
    J0 = full.jacobian(pose0)[fitted].reshape(-1, N_UNKNOWNS)
    ident = identifiability(J0)
    idx = np.flatnonzero(ident.identifiable)
    o1, cond = observability(J0[:, idx], n_fit)

    f = _Cached(fit, idx)
    sol = scipy.optimize.least_squares(
        f.fun,
        np.zeros(idx.size),
        jac=f.jac,
        method="lm",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=200 * (idx.size + 1),
    )
    z = np.zeros(N_UNKNOWNS)
    z[idx] = sol.x
    with np.errstate(invalid="ignore", divide="ignore"):
        pose1 = full.pose(z)
    if sol.status <= 0 or not np.all(pose1.valid[fitted]):
        raise InputError(
            f"{meas.source}: the identification did not converge ({sol.message}); check the measurements "
            "(units, rows of another robot) and the design"
        )
    x_id, _ = full.state(z)
    try:
        Design.from_vector(x_id)
    except InputError as exc:
        raise InputError(
            f"{meas.source}: the identified parameters are not a robot ({exc}); check the measurements"
        ) from None

    Jf = full.jacobian(pose1)[fitted][..., idx].reshape(-1, idx.size)
    r_all = full.residuals(pose1)
    r = r_all[fitted]
    dof = DOF_PER_MEASUREMENT * n_fit - idx.size
    s2 = float(np.sum(r * r) / dof)
    _check_fit(meas, settings, r_all, pose1.valid, fitted, s2)
    _, sv, Vt = np.linalg.svd(Jf, full_matrices=False)
    cov_z = s2 * (Vt.T / sv**2) @ Vt
    cov = np.zeros((N_UNKNOWNS, N_UNKNOWNS))
    cov[np.ix_(idx, idx)] = cov_z * np.outer(full.scale[idx], full.scale[idx])

    before, after = pose_errors(meas.E, meas.e, pose0.E, pose0.e), pose_errors(meas.E, meas.e, pose1.E, pose1.e)
    budget = calibrated_budget(x_id, cov, signs, settings, trajectories, meas)
    result = Calibration(
        settings=settings,
        start=start,
        mode=signs,
        measurements=meas,
        fitted=fitted,
        assembly=full.assembly,
        identifiability=ident,
        scale=full.scale,
        u_nominal=full.u0,
        u_identified=full.u0 + z * full.scale,
        covariance=cov,
        sigma_hat=math.sqrt(s2),
        dof=dof,
        residuals=Residuals(*before, *after),
        o1=o1,
        condition_number=cond,
        n_model=n_model,
        solver={"status": int(sol.status), "message": str(sol.message), "evaluations": int(sol.nfev)},
        budget=budget,
    )
    if out is not None:
        from arcube.calibrate.output import write_calibration

        write_calibration(result, out)
    return result
