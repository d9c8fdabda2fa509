"""Actuator torques along a program (model §18.2): gravity + inertia + the drilling thrust, per row.

    tau = dV/dq + M(q) q_ddot + c(q, q_dot) - J_E^T f

**How the inertia term is computed.** Every moving body of 18.1 (:mod:`arcube.evaluation.mass_bodies`) is
a uniform rod between end points a, b, whose kinetic energy m (|v_a|^2 + v_a.v_b + |v_b|^2) / 6 is
exactly that of three point masses: m/6 at a, m/6 at b and 2m/3 at the midpoint (Simpson's rule;
a point mass has a = b). For point masses x_k(q) Lagrange's equations read

    d/dt dT/dq_dot - dT/dq = sum_k m_k J_k^T x_k_ddot

with J_k = dx_k/dq, so M q_ddot + c needs no derivative of M: only each point's acceleration along
the program, taken here as the central second difference of its position over the rows (the
program's time grid, step dt), and its Jacobian at the row. The drill motor adds the inertia of its
radius, I_r = m rho_m^2 / 4 about axes across e, turning with omega perp e (|omega| = |e_dot|):
T_r = I_r |e_dot|^2 / 2 gives I_r J_e^T e_ddot. Gravity enters the same way, with x_ddot - g:
tau = sum_k m_k J_k^T (x_k_ddot - g) + I_r J_e^T e_ddot - J_E^T f (kg mm/rad x mm/s^2 -> 1e-6 N m).

The program starts and ends at rest, so the rows before the first and after the last mirror their
neighbours (x(-dt) = x(dt)): the second difference there is 2 (x_1 - x_0) / dt^2.

The force f = F_t e (the thrust, ``Loads.thrust_N``) acts on drill rows only; the lateral force
has no direction along a program and is added by the sizing figures (:mod:`arcube.motion.motors`)
as each actuator's worst case F_l |P_perp J_E,i| (``lateral_Nm``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.arrays import Floats
from arcube.evaluation.mass_bodies import MassModel, bodies_of_solution
from arcube.evaluation.performance import jacobians_of_solution
from arcube.model import frames
from arcube.model.design import unpack
from arcube.model.mechanism import inverse_kinematics

__all__ = ["ProgramTorques", "program_torques"]

_CHUNK = 1024
"""Rows per block: the bodies' Jacobians take about 15 kB per row."""


class ProgramTorques(NamedTuple):
    """Actuator torques per row ``(n, 5)`` in N m (positive along q_i, JOINTS order), and their parts."""

    tau_Nm: Floats  # gravity + inertia - J_E^T f
    gravity_Nm: Floats  # dV/dq
    inertia_Nm: Floats  # M q_ddot + c
    thrust_Nm: Floats  # -J_E^T f (zero off the drill rows)
    lateral_Nm: Floats  # F_l |P_perp J_E,i| on drill rows, else 0 (sizing only, 18.3)


def _points(
    params: Floats,
    E: Floats,
    e: Floats,
    mode: Floats,
    model: MassModel,
) -> tuple[Floats, ...]:
    """Point masses of the rows: positions ``(m, 3 K, 3)``, Jacobians ``(m, 3 K, 3, 5)``, masses ``(3 K,)``, and
    e ``(m, 3)``, J_e, J_E ``(m, 3, 5)`` in R_w."""
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, mode)
        J_E, J_e = jacobians_of_solution(sol, params)
        b = bodies_of_solution(sol, params, model, (J_E, J_e))
    mid, J_mid = b.com, b.J_com
    x = np.concatenate([b.ends[..., 0, :], b.ends[..., 1, :], mid], axis=-2)
    J = np.concatenate([b.J_ends[..., 0, :, :], b.J_ends[..., 1, :, :], J_mid], axis=-3)
    m = np.asarray(b.mass[(0,) * (b.mass.ndim - 1)], float)
    w = np.concatenate([m / 6.0, m / 6.0, 2.0 * m / 3.0])
    e_w = frames.directions_to_world(unpack(params), sol.e)
    return x, J, w, e_w / np.linalg.norm(e_w, axis=-1, keepdims=True), J_e, J_E


def _rows_with_neighbours(s: int, stop: int, n: int) -> NDArray[np.intp]:
    """Rows s-1 .. stop (inclusive) of n, the rows before 0 and after n-1 mirrored (rest at both ends)."""
    idx = np.arange(s - 1, stop + 1)
    idx = np.where(idx < 0, -idx, idx)
    idx = np.where(idx > n - 1, 2 * (n - 1) - idx, idx)
    return np.clip(idx, 0, n - 1)


def program_torques(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike,
    dt: float,
    drilling: ArrayLike,
    model: MassModel,
    thrust_N: float = 30.0,
    lateral_N: float = 10.0,
) -> ProgramTorques:
    """The actuator torques along a program's rows (module docstring).

    Args:
        params: the design ``(27,)``.
        E: the rows' tip and axis ``(n, 3)`` in the patient frame (mm), on a time grid of step ``dt`` (s).
        e: see ``E``.
        mode: the working mode ``(4,)``.
        drilling: ``(n,)`` bool, the rows of drill segments (the thrust acts there).
        model: the mass model (18.1); thrust_N, lateral_N: F_t and F_l (N, 15.3).
    """
    p = np.asarray(params, float)
    E, e = np.asarray(E, float), np.asarray(e, float)
    drill = np.asarray(drilling, bool)
    n = len(E)
    g_mm = 1000.0 * np.asarray(model.gravity, float)
    radial = model.m_motor_kg * model.motor_radius_mm**2 / 4.0
    out = {k: np.zeros((n, 5)) for k in ProgramTorques._fields}
    for s in range(0, n, _CHUNK):
        stop = min(s + _CHUNK, n)
        idx = _rows_with_neighbours(s, stop, n)
        x, J, w, e_w, J_e, J_E = _points(p, E[idx], e[idx], mode, model)
        acc = (x[:-2] - 2.0 * x[1:-1] + x[2:]) / (dt * dt)  # point accelerations, mm/s^2
        e_acc = (e_w[:-2] - 2.0 * e_w[1:-1] + e_w[2:]) / (dt * dt)
        J, J_e, J_E, e_w = J[1:-1], J_e[1:-1], J_E[1:-1], e_w[1:-1]
        inertia = np.einsum("k,rkij,rki->rj", w, J, acc) + radial * np.einsum("rij,ri->rj", J_e, e_acc)
        gravity = -np.einsum("k,rkij,i->rj", w, J, g_mm)
        axial = np.einsum("ri,rij->rj", e_w, J_E)  # e^T J_E,i (mm/rad)
        lateral = np.linalg.norm(J_E - e_w[:, :, None] * axial[:, None, :], axis=-2)
        on = drill[s:stop, None]
        out["inertia_Nm"][s:stop] = inertia * 1e-6
        out["gravity_Nm"][s:stop] = gravity * 1e-6
        out["thrust_Nm"][s:stop] = np.where(on, -thrust_N * axial / 1000.0, 0.0)
        out["lateral_Nm"][s:stop] = np.where(on, lateral_N * lateral / 1000.0, 0.0)
    out["tau_Nm"] = out["gravity_Nm"] + out["inertia_Nm"] + out["thrust_Nm"]
    return ProgramTorques(**out)
