"""What moves the screw at the isthmus (model §22.2): the built robot, the registration, the deflection.

The tool's tip is commanded to each isthmus I_j along e_j = -u_j. Per sample (22.4) the hole passes I_j + D_j with
D = D_robot + D_registration + D_deflection:

* **robot**: a built robot (model §20.2): its parameters and zero offsets off by deviations drawn once per sample
  (uniform on [-T, T] by default, T of 20.1; or, calibrated, normal with the identification's covariance, 21.4), its
  encoders and lost motion drawn afresh at every screw; the tip of the exact FK at the commanded joints, minus I_j;
* **registration**: the navigation's error of the patient frame, one rigid motion per docking and sample:
  t ~ N(0, sigma_t^2/3 I), omega ~ N(0, sigma_r^2/3 I) (rad) about c, the centroid of the docking's entry points:
  D = t + omega x (I_j - c);
* **deflection**: the thrust F_t along +e_j through the compliance of 15.4, D = F_t C_E e_j, the same in every sample.

Random numbers, in this order from ``numpy.random.default_rng(seed)``: the per-sample robot deviations ``(N, 41)``,
the per-screw encoder and lost-motion deviations ``(N, J, 10)``, the registration translations ``(N, K, 3)``, then
rotations ``(N, K, 3)``: the same seed gives the same samples, in either path below.

Two paths compute the robot's displacements: :func:`robot_displacements_reference` (the NumPy reference, one sample at
a time, what the tests read) and :func:`robot_displacements` (every sample at once, in chunks: what the command runs).
They are equal sample by sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.monte_carlo import POSE_INDEX, pose_draws, pose_joint_errors, robot_draws, split
from arcube.accuracy.sources import N_SOURCES
from arcube.model.mechanism import forward_kinematics, inverse_kinematics

__all__ = [
    "CHUNK",
    "Draws",
    "RobotModel",
    "deflection",
    "draw",
    "registration",
    "robot_displacements",
    "robot_displacements_reference",
]

CHUNK = 20_000
"""Samples x screws evaluated at once by :func:`robot_displacements` (about 30 MB of temporaries)."""


@dataclass(frozen=True)
class RobotModel:
    """The robot the controller believes (``design`` ``(27,)``, ``mode`` ``(4,)``) and how the built one departs from
    it: tolerances ``T`` ``(41,)`` of every source (mm, deg) and their distribution, or, for a calibrated robot, the
    covariance ``(31, 31)`` of the first 31 sources (the identification's; the encoders and lost motion keep their T)."""

    design: NDArray[np.float64]
    mode: NDArray[np.float64]
    T: NDArray[np.float64]
    distribution: str = "uniform"
    covariance: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class Draws:
    """The random numbers of N samples: ``per_robot`` ``(N, 41)`` (mm, deg), ``per_pose`` ``(N, J, 10)`` (deg),
    ``t`` ``(N, K, 3)`` mm and ``omega`` ``(N, K, 3)`` rad, K the dockings."""

    per_robot: NDArray[np.float64]
    per_pose: NDArray[np.float64]
    t: NDArray[np.float64]
    omega: NDArray[np.float64]


def draw(
    rng: np.random.Generator,
    robot: RobotModel,
    n: int,
    screws: int,
    dockings: int,
    sigma_t_mm: float,
    sigma_r_deg: float,
) -> Draws:
    """The draws of ``n`` samples (module docstring for the order)."""
    if robot.covariance is None:
        per_robot = robot_draws(rng, robot.T, n, robot.distribution)
    else:
        from arcube.calibrate.budget import correlated_draws

        per_robot = np.zeros((n, N_SOURCES))
        per_robot[:, : robot.covariance.shape[0]] = correlated_draws(rng, robot.covariance, n)
    per_pose = pose_draws(rng, robot.T, n, screws, "uniform" if robot.covariance is not None else robot.distribution)
    t = rng.standard_normal((n, dockings, 3)) * (sigma_t_mm / np.sqrt(3.0))
    omega = rng.standard_normal((n, dockings, 3)) * (np.deg2rad(sigma_r_deg) / np.sqrt(3.0))
    return Draws(per_robot, per_pose, t, omega)


def _commanded(
    robot: RobotModel, I: NDArray[np.float64], e: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """(q_cmd ``(J, 5)`` rad, assembly ``(J, 3)``, reached ``(J,)``): the nominal IK at the isthmus poses."""
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(robot.design, I, e, robot.mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    return q, sol.assembly, np.asarray(sol.reachable) & np.all(np.isfinite(q), axis=-1)


def _tips(x: NDArray[np.float64], q: NDArray[np.float64], assembly: NDArray[np.float64]) -> NDArray[np.float64]:
    with np.errstate(invalid="ignore", divide="ignore"):
        fk = forward_kinematics(x, q[..., :3], q[..., 3:], assembly)
    return np.where(fk.valid[..., None], fk.E, np.inf)


def robot_displacements_reference(robot: RobotModel, I: ArrayLike, e: ArrayLike, draws: Draws) -> NDArray[np.float64]:
    """D_robot ``(N, J, 3)`` mm, one sample at a time (the reference); +inf where the built robot cannot be assembled at
    a screw, NaN where the nominal design does not reach it."""
    I_a, e_a = np.asarray(I, dtype=float), np.asarray(e, dtype=float)
    q_cmd, assembly, reached = _commanded(robot, I_a, e_a)
    dp, dq0 = split(draws.per_robot)
    out = np.empty((dp.shape[0], I_a.shape[0], 3))
    for i in range(dp.shape[0]):
        dq = dq0[i][None, :] + pose_joint_errors(draws.per_pose[i])
        out[i] = _tips(robot.design + dp[i], q_cmd + dq, assembly) - I_a
    return np.where(reached[None, :, None], out, np.nan)


def robot_displacements(robot: RobotModel, I: ArrayLike, e: ArrayLike, draws: Draws) -> NDArray[np.float64]:
    """D_robot ``(N, J, 3)`` mm as :func:`robot_displacements_reference`, every sample at once (in chunks of
    :data:`CHUNK` samples x screws)."""
    I_a, e_a = np.asarray(I, dtype=float), np.asarray(e, dtype=float)
    q_cmd, assembly, reached = _commanded(robot, I_a, e_a)
    dp, dq0 = split(draws.per_robot)
    n, J = dp.shape[0], I_a.shape[0]
    out = np.empty((n, J, 3))
    step = max(1, CHUNK // max(J, 1))
    for lo in range(0, n, step):
        hi = min(n, lo + step)
        dq = dq0[lo:hi, None, :] + pose_joint_errors(draws.per_pose[lo:hi])
        out[lo:hi] = _tips(robot.design + dp[lo:hi, None, :], q_cmd[None] + dq, assembly[None]) - I_a
    return np.where(reached[None, :, None], out, np.nan)


def registration(draws: Draws, I: ArrayLike, docking: ArrayLike, centres: ArrayLike) -> NDArray[np.float64]:
    """D_registration ``(N, J, 3)`` mm: t + omega x (I_j - c) with the rigid motion of screw j's docking
    (``docking`` ``(J,)`` indices into the K ``centres`` ``(K, 3)``)."""
    k = np.asarray(docking, dtype=np.intp)
    arm = np.asarray(I, dtype=float) - np.asarray(centres, dtype=float)[k]  # (J, 3)
    return draws.t[:, k, :] + np.cross(draws.omega[:, k, :], arm[None])


def deflection(
    robot: RobotModel, I: ArrayLike, e: ArrayLike, thrust_N: float, stiffness_Nm_per_rad: ArrayLike
) -> NDArray[np.float64]:
    """D_deflection ``(J, 3)`` mm: F_t C_E e_j with C_E = J_E K^-1 J_E^T (model §15.4; K in N mm/rad), at the
    nominal design; NaN where it does not reach the screw."""
    from arcube.evaluation.performance import forward_jacobian

    e_a = np.asarray(e, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        J_E, _ = forward_jacobian(robot.design, I, e_a, robot.mode)
    k = np.broadcast_to(np.asarray(stiffness_Nm_per_rad, dtype=float), (5,)) * 1000.0
    C = np.einsum("...ik,k,...jk->...ij", J_E, 1.0 / k, J_E)  # mm/N
    return float(thrust_N) * np.einsum("...ij,...j->...i", C, e_a)


assert POSE_INDEX.size == 10  # the encoders and lost motions of the five actuators
