"""Motor sizing along a program (model §18.3): per actuator the figures a motor supplier asks for.

From the torques of :mod:`arcube.motion.dynamics` (gravity, inertia, thrust; N m) and the rates
(rad/s) at the rows of a program on a uniform time grid, per actuator i:

* ``torque_peak_Nm``: max over the rows of |tau_i| + lateral_i, where lateral_i = F_l |P_perp J_E,i|
  on drill rows (the lateral force's worst direction, 18.2) and 0 elsewhere;
* ``torque_rms_Nm``: the RMS over time of that same magnitude (trapezoidal rule): the thermal load;
* ``speed_peak_deg_s``: max |q_dot_i|;
* ``power_peak_W``: max (|tau_i| + lateral_i) |q_dot_i|, the largest mechanical power;
* ``energy_J``: the integral of max(tau_i q_dot_i + lateral_i |q_dot_i|, 0) dt (no regeneration;
  the lateral force taken in the direction that costs work);
* ``torque_peak_gravity_Nm``: max |dV/dq_i| (what the weight alone asks);
* ``torque_peak_loads_only_Nm``: max of |thrust_i| + lateral_i (model §15.3's torque along the
  program: what the motor would be sized for without masses).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from arcube.motion.dynamics import ProgramTorques

__all__ = ["MOTOR_FIELDS", "motor_figures", "motor_table_rows", "motor_table_text"]

MOTOR_FIELDS: dict[str, str] = {
    "torque_peak_Nm": "peak torque, N m",
    "torque_rms_Nm": "RMS torque, N m",
    "speed_peak_deg_s": "peak speed, deg/s",
    "power_peak_W": "peak power, W",
    "energy_J": "energy per plan, J",
    "torque_peak_gravity_Nm": "peak gravity torque, N m",
    "torque_peak_loads_only_Nm": "peak torque without masses, N m",
}
"""The figures of each actuator in ``program.json``'s ``motors``, and what they are."""


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))) if len(t) > 1 else 0.0


def motor_figures(
    t_s: ArrayLike, q_dot_rad_s: ArrayLike, torques: ProgramTorques, joints: tuple[str, ...]
) -> dict[str, dict[str, float]]:
    """Per actuator (``joints``, q's order) the figures of model §18.3 (module docstring).

    ``t_s`` ``(n,)`` s, ``q_dot_rad_s`` ``(n, 5)`` rad/s, ``torques`` per row ``(n, 5)`` N m.
    """
    t = np.asarray(t_s, float)
    qd = np.asarray(q_dot_rad_s, float)
    tau, lat = torques.tau_Nm, torques.lateral_Nm
    size = np.abs(tau) + lat
    power = tau * qd + lat * np.abs(qd)
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    out: dict[str, dict[str, float]] = {}
    for i, name in enumerate(joints):
        rms = np.sqrt(_trapezoid(size[:, i] ** 2, t) / span) if span > 0 else float(size[0, i])
        out[name] = {
            "torque_peak_Nm": float(np.max(size[:, i])),
            "torque_rms_Nm": float(rms),
            "speed_peak_deg_s": float(np.degrees(np.max(np.abs(qd[:, i])))),
            "power_peak_W": float(np.max(size[:, i] * np.abs(qd[:, i]))),
            "energy_J": _trapezoid(np.maximum(power[:, i], 0.0), t),
            "torque_peak_gravity_Nm": float(np.max(np.abs(torques.gravity_Nm[:, i]))),
            "torque_peak_loads_only_Nm": float(np.max(np.abs(torques.thrust_Nm[:, i]) + lat[:, i])),
        }
    return out


def motor_table_rows(motors: dict[str, Any]) -> list[list[str]]:
    """The motor table as text rows: a header, then one row per actuator (for the CLI and the README)."""
    head = ["actuator", "peak N m", "RMS N m", "peak deg/s", "peak W", "energy J", "gravity N m", "no masses N m"]
    rows = [head]
    for name, f in motors.items():
        rows.append([name, *(f"{f[k]:.3g}" if f.get(k) is not None else "-" for k in MOTOR_FIELDS)])
    return rows


def motor_table_text(summary: dict[str, Any]) -> str:
    """The motor table of a program's summary as aligned text lines (empty without masses)."""
    motors = summary.get("motors")
    if not motors:
        return ""
    rows = motor_table_rows(motors)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))) for r in rows]
    mass = summary.get("masses", {}).get("moving_mass_kg")
    head = "motors (model §18.3" + (f"; moving mass {mass:.3g} kg" if mass is not None else "") + "):"
    return "\n".join([head, *lines]) + "\n"
