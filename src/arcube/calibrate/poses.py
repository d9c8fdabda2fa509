"""Which poses to measure (model §21.3): :func:`poses`.

Candidates: the plan's points and its approach lines (:func:`arcube.evaluation.standoff.approach_lines`,
``PoseSettings.points`` per trajectory each), and around each of them ``around`` random poses: the tip
moved uniformly in the box +-``radius_mm`` on each axis, the axis tilted by angles uniform in
+-``radius_deg`` about the two directions perpendicular to it (:func:`~arcube.evaluation.performance.spin_free_basis`).
A candidate is kept when the nominal design reaches it with the guards of model §8.2
(:data:`arcube.options.GUARDED_OPTIONS`, whose single-assembly guard is taken over all the candidates
together, so that every pose has the same assembly mode; with the z dyad guard too when the design file
gives c_z, the length the z dyad was built with).

Choice: greedy D-optimality on the scaled identification Jacobian J_c ``(6, n)`` of each candidate (the
weighted residuals of :mod:`arcube.calibrate.model` w.r.t. the n unknowns the candidates can identify,
at the nominal values). Each step adds the candidate that most increases log det(M + J_c^T J_c) with
M = 1e-9 I + the sum over the chosen; by the matrix determinant lemma the increase is
log det(I_6 + J_c M^-1 J_c^T), computed for every candidate at once from M^-1/2 (one n x n eigen-
decomposition per step, no n x n determinant per candidate). The axis rows are first projected on the plane
perpendicular to the axis (:func:`tip_and_tilt_rows`: 5 rows per pose, the same J^T J).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.calibrate.design_file import (
    StartDesign,
    design_digest,
    load_design,
    signs_of,
)
from arcube.calibrate.identifiability import (
    Identifiability,
    identifiability,
    observability,
)
from arcube.calibrate.measurements import Measurements, write_measurements
from arcube.calibrate.model import (
    DOF_PER_MEASUREMENT,
    N_UNKNOWNS,
    UNKNOWNS,
    Problem,
    model_pose,
    scales,
    unknown_values,
)
from arcube.calibrate.settings import MAX_CANDIDATES, PoseSettings
from arcube.errors import InputError
from arcube.evaluation.performance import spin_free_basis
from arcube.evaluation.reference import evaluate_task
from arcube.evaluation.standoff import approach_lines
from arcube.evaluation.task import build_task
from arcube.model.mechanism import format_mode, inverse_kinematics
from arcube.options import GUARDED_OPTIONS, Options

RIDGE = 1e-9
"""The 1e-9 I of log det(J^T J + 1e-9 I) (model §21.3)."""


@dataclass(frozen=True)
class PoseSelection:
    """K chosen poses, how observable they make the unknowns, and a random choice of K for comparison."""

    measurements: Measurements  # the poses: joints to command (deg), E and e nominal, ids "1".."K", design digest
    random: (
        Measurements  # K candidates drawn at random (seeded), the same columns: what the chosen ones are compared with
    )
    o1: float  # O1 of the chosen poses
    condition_number: float
    o1_random: float  # O1 of K candidates drawn at random (seeded)
    condition_number_random: float
    identifiability: Identifiability  # over all the candidates, at the nominal values
    scale: NDArray[np.float64]  # (31,) typical sizes
    candidates: int  # candidate poses reached with the guards
    drawn: int  # candidate poses drawn (plan points, approach lines and the random ones around them)
    settings: PoseSettings
    mode: NDArray[np.float64]  # (4,)

    def summary(self) -> dict[str, Any]:
        """What ``calibrate poses`` prints: O1 and the condition number, chosen against random, and which
        unknowns no pose can identify."""
        ident = self.identifiability
        return {
            "poses": len(self.measurements),
            "candidates": self.candidates,
            "drawn": self.drawn,
            "mode": format_mode(self.mode),
            "O1": self.o1,
            "condition_number": self.condition_number,
            "O1_random": self.o1_random,
            "condition_number_random": self.condition_number_random,
            "not_identifiable": {
                UNKNOWNS[k]: [UNKNOWNS[i] for i, _ in ident.confounded_with(k, self.scale)]
                for k in np.flatnonzero(~ident.identifiable)
            },
        }


def candidate_poses(
    entry: ArrayLike,
    target: ArrayLike,
    settings: PoseSettings,
    anatomy: Any = None,
    rng: np.random.Generator | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(E, e) ``(C, 3)`` each: the plan's points and approach-line points, then ``around`` random poses around each
    (module doc), C = 2 T points (1 + around) for T trajectories."""
    rng = np.random.default_rng(settings.seed) if rng is None else rng
    task = build_task(entry, target, settings.points)
    E_a, e_a = approach_lines(entry, target, anatomy, settings.points, settings.standoff)
    E0, e0 = np.concatenate([task.E, E_a]), np.concatenate([task.e, e_a])
    n = settings.around
    dE = rng.uniform(-settings.radius_mm, settings.radius_mm, (len(E0), n, 3))
    tilt = np.tan(np.deg2rad(rng.uniform(-settings.radius_deg, settings.radius_deg, (len(E0), n, 2))))
    b = spin_free_basis(e0)  # (B, 3, 2)
    e1 = e0[:, None, :] + np.einsum("bij,bkj->bki", b, tilt)
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    return np.concatenate([E0, (E0[:, None, :] + dE).reshape(-1, 3)]), np.concatenate([e0, e1.reshape(-1, 3)])


def candidate_jacobians(
    start: StartDesign, E: ArrayLike, e: ArrayLike, mode: ArrayLike, sigma_mm: float, sigma_deg: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(q_read ``(C, 5)`` deg: the joints to command, IK - q0; assembly ``(C, 3)``; J ``(C, 6, 31)`` the scaled
    identification Jacobian at the nominal values) of poses the design reaches in working mode ``mode``."""
    x, q0 = start.vector, start.q0_deg
    sol = inverse_kinematics(x, E, e, mode)
    q_read = np.rad2deg(np.concatenate([sol.rho, sol.delta], axis=-1)) - q0
    asm = np.asarray(sol.assembly, dtype=float)
    pose = model_pose(x, q0, q_read, asm)
    p = Problem(
        x,
        unknown_values(x, q0),
        scales(x),
        q_read,
        np.asarray(E, float),
        np.asarray(e, float),
        asm,
        sigma_mm,
        float(np.deg2rad(sigma_deg)),
    )
    return q_read, asm, p.jacobian(pose)


def tip_and_tilt_rows(J: ArrayLike, e: ArrayLike) -> NDArray[np.float64]:
    """``(C, 5, n)``: the 3 tip rows of J ``(C, 6, n)`` and its 3 axis rows projected on the two directions
    perpendicular to the unit axes ``e`` ``(C, 3)``. The same J^T J (the derivative of a unit vector is
    perpendicular to it, so the dropped row is 0), at 5/6 of the cost."""
    A = np.asarray(J, dtype=float)
    b = spin_free_basis(e)  # (C, 3, 2)
    return np.concatenate([A[:, :3], np.swapaxes(b, -1, -2) @ A[:, 3:6]], axis=1)


def greedy_d_optimal(J: ArrayLike, count: int, ridge: float = RIDGE) -> NDArray[np.intp]:
    """Indices ``(count,)`` of the candidates chosen greedily, in order: each step the one (not yet chosen) that
    most increases log det(M + J_c^T J_c), M = ridge I + sum of the chosen J_c^T J_c; J ``(C, r, n)``.

    The increase is log det(I_r + B_c B_c^T) with B_c = J_c W, W W^T = M^-1 (M's eigen-decomposition), for
    all candidates in one matrix product per step; I_r + B_c B_c^T is positive definite: its log det is
    twice the sum of the logs of its Cholesky factor's diagonal."""
    A = np.ascontiguousarray(J, dtype=float)
    C, r, n = A.shape
    if count > C:
        raise ValueError(f"cannot choose {count} of {C} candidates")
    flat = A.reshape(C * r, n)
    M = ridge * np.eye(n)
    free = np.ones(C, bool)
    chosen = np.empty(count, dtype=np.intp)
    eye = np.eye(r)
    for step in range(count):
        w, V = np.linalg.eigh(M)
        B = (flat @ (V / np.sqrt(w))).reshape(C, r, n)
        L = np.linalg.cholesky(eye + B @ np.swapaxes(B, -1, -2))
        gain = np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
        best = int(np.argmax(np.where(free, gain, -np.inf)))
        chosen[step] = best
        free[best] = False
        M = M + A[best].T @ A[best]
    return chosen


def poses(
    design: Any,
    trajectories: Any,
    mode: ArrayLike | str | None = None,
    settings: PoseSettings | None = None,
    anatomy: Any = None,
    out: str | os.PathLike[str] | None = None,
) -> PoseSelection:
    """Choose the poses to measure (model §21.3).

    Args:
        design: the nominal design (Design, preset, design JSON plain or calibrated, 27 numbers). For a calibrated
            one the joint angles written are IK - q0 (what its controller commands).
        trajectories: the plan, a :class:`~arcube.io.trajectories.TrajectorySet` already selected (e.g. one side).
        mode: the working mode (default: the design file's, else +,+,+,+).
        settings: :class:`PoseSettings`.
        anatomy: an :class:`~arcube.evaluation.anatomy.Anatomy` (where the approach lines start), or None.
        out: if given, the poses CSV written atomically (the measurement file's columns, ``pose`` and ``design``).

    Raises:
        InputError: fewer reachable candidates than ``count``, too many candidates, or no candidate at all.
    """
    settings = PoseSettings() if settings is None else settings
    start = load_design(design)
    signs = signs_of(mode, start.mode)
    drawn = 2 * len(trajectories.ids) * settings.points * (1 + settings.around)
    if drawn > MAX_CANDIDATES:
        raise InputError.of(
            "PoseSettings.around",
            f"x points x trajectories gives {drawn:,} candidate poses (at most {MAX_CANDIDATES:,})",
        )
    rng = np.random.default_rng(settings.seed)
    E, e = candidate_poses(trajectories.entry, trajectories.target, settings, anatomy, rng)
    guards = GUARDED_OPTIONS.guards
    if start.c_z is not None:
        guards = guards.replace(z_dyad=True, c_z=start.c_z)
    with np.errstate(invalid="ignore", divide="ignore"):
        reach = np.asarray(evaluate_task(start.vector, E, e, signs, Options(guards=guards)).points.reachable)
        E, e = E[reach], e[reach]
        q_read, _, J = candidate_jacobians(start, E, e, signs, settings.sigma_mm, settings.sigma_deg)
    C = len(E)
    if C < settings.count:
        raise InputError.of(
            "PoseSettings.count",
            f"is {settings.count}, but the design reaches only {C} of the {drawn} candidate poses "
            f"with the guards in working mode {format_mode(signs)}",
        )
    ident = identifiability(J.reshape(-1, N_UNKNOWNS))
    cols = np.flatnonzero(ident.identifiable)
    least = cols.size // DOF_PER_MEASUREMENT + 1  # each pose gives 5 independent values (3 of the tip, 2 of the axis)
    if settings.count < least:
        raise InputError.of(
            "PoseSettings.count",
            f"is {settings.count}, but the {cols.size} identifiable unknowns need at least {least} "
            "poses (each gives 5 independent values); measure more, and some held out",
        )
    Jr = tip_and_tilt_rows(J[..., cols], e)
    chosen = greedy_d_optimal(Jr, settings.count)
    random = rng.choice(C, settings.count, replace=False)
    o1, cond = observability(Jr[chosen].reshape(-1, cols.size), settings.count)
    o1_r, cond_r = observability(Jr[random].reshape(-1, cols.size), settings.count)
    ids = tuple(str(i + 1) for i in range(settings.count))
    digest = design_digest(start.vector, start.q0_deg)
    meas = Measurements(q_read[chosen], E[chosen], e[chosen], ids, digest, "poses")
    rand = Measurements(q_read[random], E[random], e[random], ids, digest, "random poses")
    if out is not None:
        write_measurements(out, meas)
    return PoseSelection(meas, rand, o1, cond, o1_r, cond_r, ident, scales(start.vector), C, drawn, settings, signs)
