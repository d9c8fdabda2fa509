"""Joint-space export: joint angles and rates along the drilling trajectories.

For drilling at a constant speed (mm/s) the tip moves from the entry toward the target,

    v = speed * (P_tg - P_in)/|P_tg - P_in| = -speed * e,    omega = 0

(the orientation is constant along a trajectory, model §1.4), and reaches point k at
t = s_k / speed, s_k = |E_k - E_0| the drilled length so far.

* rho, delta, sigma come from the IK (:func:`arcube.model.mechanism.inverse_kinematics`);
* (rho_dot, delta_dot) = B^-1 A (v, omega) (model §7.4, :func:`arcube.model.mechanism.joint_rates`);
* sigma_dot = J_AS^-1 J_AP omega (model §7.3), which is exactly 0 here: sigma depends on e
  only (RTS IK, model §5.2) and e is constant. It is still computed from the general relation
  so that the column means the same thing if a caller passes a path with omega != 0 later.

Actuator torques for the drilling loads (model §15.3, Options' thrust and lateral force): the
torque that holds the thrust F_t e alone, tau = -J_E^T (F_t e), signed, and the worst case of each
actuator over the lateral directions, F_t |e^T J_E,i| + F_l |P_perp J_E,i|; N·m.

With ``Options.outputs.holding_torque`` (``arcube joints`` with a mass flag) the rows also get the
holding torque of model §18.2, from the masses of ``Options.masses``: the signed torque that holds
the robot's weight, dV/dq (``tau_gravity_*_Nm``), each actuator's worst case with the drilling loads
|dV/dq_i - F_t e^T J_E,i| + F_l |P_perp J_E,i| (``hold_*_max_Nm``), their maximum and its actuator
(:data:`MASS_COLUMNS`, before ``reachable``).

Reachability is that of :func:`arcube.evaluation.evaluate_task` with the given options (guards
included); unreachable points have empty cells in the CSV and ``reachable=false``.
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model import frames
from arcube.model.design import Design, unpack
from arcube.evaluation.masses import holding_torque_of_solution
from arcube.evaluation.performance import ACTUATOR_NAMES, jacobians_of_solution, metrics_of_solution
from arcube.evaluation.reference import Options, evaluate_task
from arcube.io.files import atomic_write_text
from arcube.model.mechanism import DEFAULT_MODE, inverse_kinematics, joint_rates, velocity_model
from arcube.model.stages import rts
from arcube.evaluation.task import Task

JOINT_NAMES: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y", "sigma_x", "sigma_y")
"""Order of the last axis of :attr:`JointTrajectory.q_deg` and :attr:`JointTrajectory.q_dot_dps`."""

CSV_COLUMNS: tuple[str, ...] = (
    "trajectory",
    "k",
    "t_s",
    "x",
    "y",
    "z",
    *(f"{n}_deg" for n in JOINT_NAMES),
    *(f"{n}_dps" for n in JOINT_NAMES),
    *(f"tau_{n}_Nm" for n in ACTUATOR_NAMES),
    *(f"tau_{n}_max_Nm" for n in ACTUATOR_NAMES),
    "reachable",
)
MASS_COLUMNS: tuple[str, ...] = (
    *(f"tau_gravity_{n}_Nm" for n in ACTUATOR_NAMES),
    *(f"hold_{n}_max_Nm" for n in ACTUATOR_NAMES),
    "holding_torque_Nm",
    "holding_torque_actuator",
)
"""Columns of model §18.2 inserted before ``reachable`` when the trajectory has the holding torque."""


@dataclass(frozen=True)
class JointTrajectory:
    """Joint angles and rates at the P points of a task (trajectory-major order)."""

    ids: tuple[str, ...]  # (T,) trajectory ids
    trajectory: NDArray[np.intp]  # (P,) trajectory index of each point
    k: NDArray[np.intp]  # (P,) sample index along its trajectory
    t_s: NDArray[np.float64]  # (P,) time since the entry point, s
    E: NDArray[np.float64]  # (P, 3) drill tip in R_w, mm
    q_deg: NDArray[np.float64]  # (P, 7) angles in JOINT_NAMES order, deg (NaN where unreachable)
    q_dot_dps: NDArray[np.float64]  # (P, 7) rates, deg/s (NaN where unreachable)
    reachable: NDArray[np.bool_]  # (P,)
    speed_mm_s: float
    tau_thrust_Nm: NDArray[
        np.float64
    ]  # (P, 5) torques holding the thrust alone, ACTUATOR_NAMES order (NaN where unreachable)
    tau_max_Nm: NDArray[np.float64]  # (P, 5) worst case with the lateral force (model §15.3)
    tau_gravity_Nm: NDArray[np.float64] | None = None  # (P, 5) dV/dq (model §18.2), or None without masses
    hold_max_Nm: NDArray[np.float64] | None = None  # (P, 5) |dV/dq_i - F_t e^T J_E,i| + F_l |P_perp J_E,i|, or None

    @property
    def columns(self) -> tuple[str, ...]:
        """:data:`CSV_COLUMNS`, with :data:`MASS_COLUMNS` before ``reachable`` when the holding torque is there."""
        return CSV_COLUMNS if self.hold_max_Nm is None else (*CSV_COLUMNS[:-1], *MASS_COLUMNS, CSV_COLUMNS[-1])

    def to_csv(self) -> str:
        """CSV text with :attr:`columns`; empty cells where a value does not exist."""
        buf = io.StringIO()
        buf.write(",".join(self.columns) + "\n")
        for i in range(len(self.k)):
            ok = bool(self.reachable[i])
            joints = [
                _cell(v) if ok else ""
                for v in (*self.q_deg[i], *self.q_dot_dps[i], *self.tau_thrust_Nm[i], *self.tau_max_Nm[i])
            ]
            if self.hold_max_Nm is not None and self.tau_gravity_Nm is not None:
                hold = self.hold_max_Nm[i]
                best = int(np.argmax(hold)) if ok and np.all(np.isfinite(hold)) else -1
                joints += [_cell(v) if ok else "" for v in (*self.tau_gravity_Nm[i], *hold)]
                joints += [_cell(hold[best]), ACTUATOR_NAMES[best]] if best >= 0 else ["", ""]
            row = [
                self.ids[int(self.trajectory[i])],
                str(int(self.k[i])),
                _cell(self.t_s[i]),
                *(_cell(v) for v in self.E[i]),
                *joints,
                "true" if ok else "false",
            ]
            buf.write(",".join(row) + "\n")
        return buf.getvalue()

    def write_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`to_csv` atomically; returns the path."""
        out = Path(path)
        atomic_write_text(out, self.to_csv())
        return out


def _cell(v: float) -> str:
    f = float(v) + 0.0  # + 0.0 turns -0.0 into 0.0
    return repr(f) if math.isfinite(f) else ""


def joint_trajectory(
    design: Design | ArrayLike,
    task: Task,
    speed_mm_s: float,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(),
    anatomy: Any = None,
) -> JointTrajectory:
    """Joint angles (deg) and rates (deg/s) for drilling the task's trajectories at ``speed_mm_s``.

    ``design``: a :class:`Design` or a ``(27,)`` (or ``(23,)``) vector (mm, deg); ``mode``: ``(4,)`` working-mode
    signs; ``anatomy``: the distance grids (:class:`arcube.evaluation.sdf.AnatomyDistance`) that the
    clearance guard of ``options`` measures against. Raises ValueError if the speed is not a finite
    positive number.
    """
    if not (math.isfinite(speed_mm_s) and speed_mm_s > 0.0):
        raise ValueError(f"speed must be a finite positive number of mm/s, got {speed_mm_s}")
    params = design.to_vector() if isinstance(design, Design) else np.asarray(design, dtype=float)
    # model §21.4: a calibrated design's controller commands the actuated angles less its zero offsets
    q0_deg = np.concatenate([design.q0, np.zeros(2)]) if isinstance(design, Design) else np.zeros(7)
    signs = np.asarray(mode, dtype=float)
    reachable = np.asarray(evaluate_task(params, task.E, task.e, signs, options, anatomy).points.reachable, dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, task.E, task.e, signs)
        # the tip moves against e (e points from the tip to the motor); with omega = 0 the centre C
        # moves with it, and the velocity model takes the twist in mechanism coordinates (model §13)
        v = frames.directions_to_mechanism(unpack(params), -speed_mm_s * task.e)
        omega = np.zeros_like(v)
        q_dot = joint_rates(velocity_model(sol, params), v, omega)  # (P, 5): rho_dot, delta_dot, rad/s
        j_ap_omega = np.einsum("...ij,...j->...i", rts.J_AP(sol.e, sol.u_beta), omega)
        sigma_dot = j_ap_omega / rts.J_AS_diag(sol.e, sol.u_beta)  # J_AS is diagonal: σ̇_u = (J_AP ω)_u / J_AS,u
        J_E, J_e = jacobians_of_solution(sol, params)
        e_w = frames.directions_to_world(unpack(params), sol.e)
        tau = -np.einsum("...ij,...i->...j", J_E, options.loads.thrust_N * e_w) / 1000.0  # N·mm -> N·m
        worst = metrics_of_solution(sol, params, options.loads, (J_E, J_e)).torque_per_actuator_Nm
        hold = (
            holding_torque_of_solution(sol, params, options, jacobians=(J_E, J_e))
            if options.outputs.holding_torque
            else None
        )
    q = np.concatenate([sol.rho, sol.delta, sol.sigma], axis=-1)
    rates = np.concatenate([q_dot, sigma_dot], axis=-1)
    first = np.flatnonzero(task.k == 0)  # entry point of each trajectory (trajectory-major order)
    s = np.linalg.norm(task.E - task.E[first][task.trajectory], axis=-1)
    keep = reachable[:, None]
    return JointTrajectory(
        ids=task.ids,
        trajectory=task.trajectory,
        k=task.k,
        t_s=s / speed_mm_s,
        E=task.E,
        q_deg=np.where(keep, np.rad2deg(q) - q0_deg, np.nan),
        q_dot_dps=np.where(keep, np.rad2deg(rates), np.nan),
        reachable=reachable,
        speed_mm_s=float(speed_mm_s),
        tau_thrust_Nm=np.where(keep, tau, np.nan),
        tau_max_Nm=np.where(keep, worst, np.nan),
        tau_gravity_Nm=None if hold is None else np.where(keep, hold.gravity_Nm, np.nan),
        hold_max_Nm=None if hold is None else np.where(keep, hold.per_actuator_Nm, np.nan),
    )
