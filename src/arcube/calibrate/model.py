"""The identification model of model §21.2: unknowns, scales, weighted residuals and their Jacobian.

(E, e) = FK_p(q_read + dq0) (5.5 with 13.1-13.2), with the docking (m, mount) part of p. The n = 31
unknowns, in :data:`UNKNOWNS` order (the first 31 error sources of :mod:`arcube.accuracy.sources`):
the 26 design parameters that move the tool in design order (docking m_x m_y m_z, the 13 lengths,
the 6 angles, docking mount_rx mount_ry mount_rz, L) and the zero offsets ``q0_rho_x`` ..
``q0_delta_y``. d_z and c_z do not move the tool and are not unknowns. An unknown's value u is in
design units (mm, or deg for every angle and zero offset); the solver works on the scaled deviation
z = (u - u_nominal) / s with s the unknown's typical size (:func:`scales`).

Residuals per measurement i, 6 values: (E_meas - E_model) / sigma_E (3) and (e_meas - e_model) /
sigma_e (3), both e unit vectors, **sigma_e in radians** (the difference of two unit vectors is, to
first order, the angle between them in radians; MODEL gives sigma_e in degrees, converted here).
The three e residuals carry two degrees of freedom (the difference of unit vectors is orthogonal to
them to first order), so a measurement carries 5: 3 of the tip, 2 of the axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.sources import (
    IS_ANGLE,
    PARAM_COLUMN,
    SOURCE_NAMES,
    UNITS,
    tolerances,
)
from arcube.errors import InputError
from arcube.model.mechanism import forward_kinematics
from arcube.model.sensitivity import fk_derivatives

N_UNKNOWNS = 31
UNKNOWNS: tuple[str, ...] = SOURCE_NAMES[:N_UNKNOWNS]
"""The 31 unknowns: 26 design parameters (design order) then q0_rho_x .. q0_delta_y."""
UNKNOWN_UNITS: tuple[str, ...] = UNITS[:N_UNKNOWNS]
PARAM_INDEX: NDArray[np.intp] = PARAM_COLUMN[:26]
"""Index into the 27 design parameters of each of the 26 parameter unknowns."""
_PER_DEG = np.where(IS_ANGLE[:N_UNKNOWNS], np.pi / 180.0, 1.0)  # per rad -> per deg for the angle columns
DOCKING: frozenset[str] = frozenset({"m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz"})
KINDS: tuple[str, ...] = tuple(
    "docking" if n in DOCKING else "zero offset" if n.startswith("q0_") else "robot" for n in UNKNOWNS
)
"""``robot`` (20), ``docking`` (6) or ``zero offset`` (5), per unknown."""
DOF_PER_MEASUREMENT = 5
"""Independent residuals per measurement: 3 of the tip, 2 of the unit axis."""
SCALE_CLASS = "m"
"""ISO 2768-1 class whose tolerances are the typical sizes of the robot's unknowns (model §21.2)."""
SCALE_DOCKING_MM, SCALE_DOCKING_DEG, SCALE_Q0_DEG = 10.0, 5.0, 0.1
BAD_RESIDUAL = 1e4
"""Residual of a measurement whose FK does not assemble at trial parameters: the step is refused."""


def scales(design: ArrayLike) -> NDArray[np.float64]:
    """Typical size s ``(31,)`` of each unknown (mm or deg): its ISO 2768-1 class m tolerance for the design's
    nominal sizes (lengths, L, angles), 10 mm and 5 deg for the docking, 0.1 deg for a zero offset."""
    T = tolerances(design, SCALE_CLASS, q0_deg=SCALE_Q0_DEG, docking_mm=SCALE_DOCKING_MM, docking_deg=SCALE_DOCKING_DEG)
    return np.asarray(T[..., :N_UNKNOWNS], dtype=float)


def unknown_values(design: ArrayLike, q0_deg: ArrayLike) -> NDArray[np.float64]:
    """The unknowns' values ``(..., 31)`` of designs ``(..., 27)`` (mm, deg) and zero offsets ``(..., 5)`` (deg)."""
    x = np.asarray(design, dtype=float)
    return np.concatenate([x[..., PARAM_INDEX], np.asarray(q0_deg, dtype=float)], axis=-1)


def with_unknowns(design: ArrayLike, u: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(design ``(..., 27)``, q0 ``(..., 5)`` deg): ``design`` with its tool-moving parameters set from u ``(..., 31)``."""
    ua = np.asarray(u, dtype=float)
    x = np.array(np.broadcast_to(design, ua.shape[:-1] + (27,)), dtype=float)
    x[..., PARAM_INDEX] = ua[..., :26]
    return x, ua[..., 26:]


class Pose(NamedTuple):
    """Model poses and their derivatives w.r.t. the 31 unknowns (per mm or per deg); NaN where not valid."""

    E: NDArray[np.float64]  # (N, 3) mm
    e: NDArray[np.float64]  # (N, 3) unit
    dE: NDArray[np.float64]  # (N, 3, 31) mm per unit of each unknown
    de: NDArray[np.float64]  # (N, 3, 31) per unit of each unknown
    valid: NDArray[np.bool_]  # (N,) the FK assembles


def model_pose(design: ArrayLike, q0_deg: ArrayLike, q_read_deg: ArrayLike, assembly: ArrayLike) -> Pose:
    """FK_p(q_read + q0) in the given assembly modes ``(N, 3)`` and its derivatives w.r.t. the unknowns
    (:mod:`arcube.model.sensitivity`, analytic). ``q_read_deg`` ``(N, 5)``, ``q0_deg`` ``(5,)``."""
    q = np.deg2rad(np.asarray(q_read_deg, dtype=float) + np.asarray(q0_deg, dtype=float))
    d = fk_derivatives(design, q[..., :3], q[..., 3:], assembly)
    dE = np.concatenate([d.dE_dp[..., PARAM_INDEX], d.dE_dq], axis=-1) * _PER_DEG
    de = np.concatenate([d.de_dp[..., PARAM_INDEX], d.de_dq], axis=-1) * _PER_DEG
    return Pose(d.E, d.e, dE, de, d.valid)


ASSEMBLIES: NDArray[np.float64] = np.array([[a, b, c] for a in (1.0, -1.0) for b in (1.0, -1.0) for c in (1.0, -1.0)])
"""The 8 assembly modes (eps_H_x, eps_H_y, eps_P) of the FK."""


def robot_assembly(
    design: ArrayLike,
    q0_deg: ArrayLike,
    rows: tuple[ArrayLike, ArrayLike, ArrayLike],
    sigma_mm: float,
    sigma_rad: float,
    where: object = None,
) -> NDArray[np.float64]:
    """The robot's assembly mode at each row ``(N, 3)`` of ``rows`` = (joint readings ``(N, 5)`` deg, measured tips
    ``(N, 3)`` mm, measured axes ``(N, 3)``); InputError naming the first row where FK_p(q_read + q0) does not close
    in it (``where(i)`` names row i; else "measurement i+1").

    The measurements do not record how the robot was assembled, but a robot keeps one assembly mode: it
    cannot change it without passing through a singularity (the design job's single-assembly-mode guard,
    model §8.2, puts a whole plan in one). Per row, the mode whose nominal FK is nearest the measured
    pose (in the weighted norm of the residuals) is the robot's, except near the boundary between two
    modes, where the nominal FK of the wrong one can come nearer than the robot's errors; the mode most
    rows choose (ties: the first of :data:`ASSEMBLIES`) is taken for every row."""
    q_read, E, e = rows
    q = np.deg2rad(np.asarray(q_read, dtype=float) + np.asarray(q0_deg, dtype=float))
    with np.errstate(invalid="ignore", divide="ignore"):
        fk = forward_kinematics(design, q[None, :, :3], q[None, :, 3:], ASSEMBLIES[:, None, :])
        cost = np.sum((fk.E - E) ** 2, axis=-1) / sigma_mm**2 + np.sum((fk.e - e) ** 2, axis=-1) / sigma_rad**2
    closes = fk.valid & np.isfinite(cost)  # (8, N)
    cost = np.where(closes, cost, np.inf)
    nearest = np.argmin(cost, axis=0)
    votes = np.bincount(nearest[np.isfinite(np.min(cost, axis=0))], minlength=len(ASSEMBLIES))
    best = int(np.argmax(votes))
    if not closes[best].all():
        i = int(np.flatnonzero(~closes[best])[0])
        name = where(i) if callable(where) else f"measurement {i + 1}"
        raise InputError(
            f"{name}: the design cannot take these joint angles (its forward kinematics does not close there in the "
            "assembly mode of the other rows): angles of another robot, or in the wrong unit"
        )
    return np.broadcast_to(ASSEMBLIES[best], (q.shape[0], 3)).copy()


@dataclass(frozen=True)
class Problem:
    """The weighted least-squares problem of one set of measurements."""

    design: NDArray[np.float64]  # (27,) nominal design (mm, deg)
    u0: NDArray[np.float64]  # (31,) nominal unknowns (design units)
    scale: NDArray[np.float64]  # (31,) typical sizes s
    q_read: NDArray[np.float64]  # (N, 5) joint readings, deg
    E: NDArray[np.float64]  # (N, 3) measured tips, mm
    e: NDArray[np.float64]  # (N, 3) measured unit axes
    assembly: NDArray[np.float64]  # (N, 3) assembly modes
    sigma_mm: float
    sigma_rad: float

    def state(self, z: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(design ``(27,)``, q0 ``(5,)`` deg) at scaled deviations z ``(31,)``."""
        return with_unknowns(self.design, self.u0 + np.asarray(z, dtype=float) * self.scale)

    def pose(self, z: ArrayLike) -> Pose:
        x, q0 = self.state(z)
        return model_pose(x, q0, self.q_read, self.assembly)

    def residuals(self, pose: Pose) -> NDArray[np.float64]:
        """``(N, 6)`` weighted residuals; :data:`BAD_RESIDUAL` where the FK does not assemble."""
        r = np.concatenate([(self.E - pose.E) / self.sigma_mm, (self.e - pose.e) / self.sigma_rad], axis=-1)
        return np.where(pose.valid[:, None] & np.isfinite(r), r, BAD_RESIDUAL)

    def jacobian(self, pose: Pose) -> NDArray[np.float64]:
        """``(N, 6, 31)`` derivatives of the residuals w.r.t. the scaled unknowns z; 0 where not valid."""
        J = -np.concatenate([pose.dE / self.sigma_mm, pose.de / self.sigma_rad], axis=-2) * self.scale
        return np.where(pose.valid[:, None, None] & np.isfinite(J), J, 0.0)


def make_problem(
    design: ArrayLike,
    q0_deg: ArrayLike,
    q_read_deg: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    sigma_mm: float,
    sigma_deg: float,
    assembly: ArrayLike | None = None,
    where: object = None,
) -> Problem:
    """The problem at the nominal design and zero offsets; the assembly mode is :func:`robot_assembly`'s unless
    given (``where`` as there)."""
    x = np.asarray(design, dtype=float)
    q0 = np.asarray(q0_deg, dtype=float)
    q = np.asarray(q_read_deg, dtype=float)
    sigma_rad = float(np.deg2rad(sigma_deg))
    asm = (
        robot_assembly(x, q0, (q, E, e), sigma_mm, sigma_rad, where)
        if assembly is None
        else np.asarray(assembly, float)
    )
    return Problem(
        x,
        unknown_values(x, q0),
        scales(x),
        q,
        np.asarray(E, dtype=float),
        np.asarray(e, dtype=float),
        asm,
        float(sigma_mm),
        sigma_rad,
    )
