"""Masses, gravity and the holding torque (model §18.1-18.2): the NumPy reference.

* :func:`moving_mass_kg`: the moving mass per design ``(..., 27)`` -> ``(...)`` kg;
* :func:`potential_energy_J`: V = -sum_b m_b g . c_b at poses ``(...)``, J (positions in R_w, so V
  includes the constant -M g . m of the mounting point);
* :func:`gravity_torque_Nm`: dV/dq ``(..., 5)`` N m, positive along q_i, the torque actuator i
  applies to hold the robot's weight;
* :func:`holding_torque`: per actuator |tau_i|max = |dV/dq_i - F_t e^T J_E,i| + F_l |P_perp J_E,i|
  (N m), its maximum ``holding_torque_Nm`` and the actuator that attains it (index into
  :data:`arcube.evaluation.performance.ACTUATOR_NAMES`, -1 where NaN).

Inputs broadcast over leading axes like the tip metrics: ``params`` ``(..., 27)`` (or the paper's
``(..., 23)``), ``E``, ``e`` ``(..., 3)`` in the patient frame R_w (mm), ``mode`` ``(..., 4)``, e.g.
designs ``params[:, None, :]`` against the P points of a plan ``E[None, :, :]`` -> ``(D, P)``. The
``*_of_solution`` forms take an IK solution (and the forward Jacobians) already at hand. Settings:
an :class:`arcube.options.Options` (``masses``, ``body``, ``loads``, ``guards.c_z``) or a plain
:class:`arcube.evaluation.mass_bodies.MassModel` (which may have zero density).

**What is counted** (model §18.1, :mod:`arcube.evaluation.mass_bodies`): the moving links of 14.1 as
thin-walled tubes (cranks, four-bar input, coupler and output links, the z dyad, the platform
triangle, the four spherical links as 12 chords each), the two delta actuators as point masses at
D_x, D_y, the drill motor (solid cylinder, H -> H + L_m e). Not counted: frame_u, the rho actuators
at P_u (on the base), rotor inertias, the tool E -> H. The moving mass is a design quantity: every
length is fixed by the design (the dyad's links are d_z and c_z whether or not it closes; a chord of a
spherical link spans 1/12 of alpha_u or beta_u, which the IK fixes exactly), so

    M = lambda [p_x + p_y + p_z + d_x + d_y + c_x + c_y + t_x + t_y + d_z + c_z + 3 sqrt2 r
                + 24 r sum_u (sin(alpha_u / 24) + sin(beta_u / 24))] + 2 m_delta + m_motor.

**How dV/dq is computed** (analytically, no finite differences): dV/dq = -(1/1000) sum_b m_b
J_b^T g, with J_b the Jacobian (mm/rad) of body b's centre of mass, the mean of its two end points'
Jacobians. Those come from the forward Jacobian of 15.1 (J_E, J_e, omega perp e), the crank and input
link rotations about their own joint axes, and the passive RTS/TMS angle rate sigma_dot_u =
-(u_beta . e_dot) / J_AS,u from differentiating Eq 4 (see :mod:`arcube.evaluation.mass_bodies`). Every
body of the closed chain is thus moved exactly as the forward kinematics moves it. N mm -> N m: /1000.

**Ambiguities of model §18 resolved here:**

* the z dyad where it does not close (the default, unchecked): both its rods lie on D_z -> Q_z as
  14.1 draws it, with the built links' masses lambda d_z, lambda c_z (not lambda |Q_z - D_z|); the
  elbow where it closes is 14.1's (sign +1); c_z = ``Guards.c_z`` (d_z when None);
* the sign of the thrust term: f = F_t e on the tool at E and tau = dV/dq - J_E^T f, so the thrust
  enters as -F_t e^T J_E,i inside the absolute value, as in 18.2; the lateral term is added as its
  worst case over the directions across e (|a + F_l l^T P_perp J_E,i| <= |a| + F_l |P_perp J_E,i|);
* units: gravity in m/s^2 in R_w, positions in mm -> V in J after /1000; torques in N m.

With zero masses (or zero gravity) the holding torque is model §15.3's ``torque``.

The evaluation computes it per point with ``Outputs.holding_torque`` (:func:`arcube.evaluation.reference.evaluate_task`:
``holding_torque_Nm``, ``holding_torque_actuator``, summary ``holding_torque_max``); the compiled kernel
collapses the same sum over bodies into a few terms (:mod:`arcube.evaluation.kernel._masses`), held equal
to this reference by tests/test_kernel_masses.py.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.evaluation.mass_bodies import MassModel, body_masses_kg, bodies_of_solution
from arcube.evaluation.performance import check_force, jacobians_of_solution
from arcube.model import frames
from arcube.model.design import unpack
from arcube.model.mechanism import DEFAULT_MODE, IKSolution, inverse_kinematics
from arcube.options import Options

__all__ = [
    "HoldingTorque",
    "MassModel",
    "gravity_torque_Nm",
    "gravity_torque_of_solution",
    "holding_torque",
    "holding_torque_of_solution",
    "moving_mass_kg",
    "potential_energy_J",
]


def moving_mass_kg(
    params: ArrayLike, options: Options | MassModel | None = None, c_z: ArrayLike | None = None
) -> NDArray[np.float64]:
    """The moving mass (kg) of each design ``(..., 27)`` -> ``(...)`` (model §18.1, 18.3 ``moving_mass``);
    ``c_z`` ``(...)``: each design's own z-dyad link (mm; None: the options')."""
    return np.sum(body_masses_kg(params, options, c_z), axis=-1)


def _solve(params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike) -> IKSolution:
    with np.errstate(invalid="ignore", divide="ignore"):
        return inverse_kinematics(params, E, e, mode)


def potential_energy_J(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options | MassModel | None = None,
) -> NDArray[np.float64]:
    """V = -sum_b m_b g . c_b ``(...)`` in J at poses (E, e) in working mode ``mode``; NaN where the IK fails."""
    model = MassModel.of(options)
    sol = _solve(params, E, e, mode)
    with np.errstate(invalid="ignore", divide="ignore"):
        b = bodies_of_solution(sol, params, model)
    weight = np.einsum("...b,...bi->...i", b.mass, b.com)  # kg mm
    return -np.einsum("...i,i->...", weight, np.asarray(model.gravity, dtype=float)) / 1000.0


def gravity_torque_of_solution(
    sol: IKSolution,
    params: ArrayLike,
    options: Options | MassModel | None = None,
    jacobians: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    c_z: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """dV/dq ``(..., 5)`` N m at the poses of ``sol``; ``jacobians`` = (J_E, J_e) if at hand; ``c_z``: each
    design's own z-dyad link (mm; None: the model's)."""
    model = MassModel.of(options)
    with np.errstate(invalid="ignore", divide="ignore"):
        b = bodies_of_solution(sol, params, model, jacobians, c_z)
    J_weight = np.einsum("...b,...bij->...ij", b.mass, b.J_com)  # sum_b m_b J_b, kg mm/rad, (..., 3, 5)
    return -np.einsum("...ij,i->...j", J_weight, np.asarray(model.gravity, dtype=float)) / 1000.0


def gravity_torque_Nm(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options | MassModel | None = None,
) -> NDArray[np.float64]:
    """dV/dq ``(..., 5)`` N m (positive along q_i) at poses (E, e) in R_w; NaN where the IK fails."""
    return gravity_torque_of_solution(_solve(params, E, e, mode), params, options)


class HoldingTorque(NamedTuple):
    """model §18.2 at each point; NaN (and -1 for the actuator) where the forward Jacobian is NaN."""

    holding_torque_Nm: NDArray[np.float64]  # (...) max_i |tau_i|max
    holding_torque_actuator: NDArray[np.int64]  # (...) index into ACTUATOR_NAMES, -1 where NaN
    per_actuator_Nm: NDArray[np.float64]  # (..., 5) |dV/dq_i - F_t e^T J_E,i| + F_l |P_perp J_E,i|
    gravity_Nm: NDArray[np.float64]  # (..., 5) dV/dq


def holding_torque_of_solution(
    sol: IKSolution,
    params: ArrayLike,
    options: Options | None = None,
    masses: MassModel | None = None,
    jacobians: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    c_z: ArrayLike | None = None,
) -> HoldingTorque:
    """The holding torque (model §18.2) at the poses of an IK solution.

    ``options`` gives the loads (``Options.loads``: thrust F_t, lateral bound F_l) and, unless
    ``masses`` is given, the mass model. ``jacobians`` = (J_E, J_e) of 15.1 if at hand. ``c_z``: each
    design's own z-dyad link (mm, broadcasting as the poses; None: the mass model's).
    """
    opts = Options() if options is None else options
    model = MassModel.of(opts if masses is None else masses)
    F_t = check_force(opts.loads.thrust_N, "thrust_N")
    F_l = check_force(opts.loads.lateral_force_N, "lateral_N")
    J_E, J_e = jacobians_of_solution(sol, params) if jacobians is None else jacobians
    tau_g = gravity_torque_of_solution(sol, params, model, (J_E, J_e), c_z)
    e_w = frames.directions_to_world(unpack(params), sol.e)
    e_w = e_w / np.linalg.norm(e_w, axis=-1, keepdims=True)
    axial = np.einsum("...i,...ij->...j", e_w, J_E)  # e^T J_E,i, mm/rad
    lateral = np.linalg.norm(J_E - e_w[..., :, None] * axial[..., None, :], axis=-2)  # |P_perp J_E,i|
    per = np.abs(tau_g - F_t * axial / 1000.0) + F_l * lateral / 1000.0
    bad = np.any(~np.isfinite(per), axis=-1)
    safe = np.where(bad[..., None], 0.0, per)
    return HoldingTorque(
        holding_torque_Nm=np.where(bad, np.nan, np.max(safe, axis=-1)),
        holding_torque_actuator=np.where(bad, -1, np.argmax(safe, axis=-1)).astype(np.int64),
        per_actuator_Nm=np.where(bad[..., None], np.nan, per),
        gravity_Nm=tau_g,
    )


def holding_torque(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options | None = None,
    masses: MassModel | None = None,
) -> HoldingTorque:
    """:func:`holding_torque_of_solution` at poses (E, e) in R_w, e.g. designs ``(D, 1, 27)`` x points ``(P, 3)``."""
    return holding_torque_of_solution(_solve(params, E, e, mode), params, options, masses)
