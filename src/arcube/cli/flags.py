"""The flag table: which command-line flag sets which setting, and the one place that turns a
library error about a setting into an error about its flag.

Library errors name what a Python caller wrote (``Loads.thrust_N must be >= 0, got -1.0``,
``points must be an integer >= 2``) and carry that name in ``InputError.param``; the CLI prints
the same message with the flag in its place (``--thrust must be >= 0, got -1.0``).
"""

from __future__ import annotations

from arcube.errors import InputError

FLAGS: dict[str, str] = {
    # arcube.evaluate / arcube.optimize keywords and plan selection
    "points": "--points", "mode": "--mode", "engine": "--engine", "side": "--side", "levels": "--levels", "ids": "--ids",
    "transform": "--transform", "out": "--out", "plan": "--trajectories", "workers": "--workers", "dask": "--dask",
    "seed": "--seed", "seeds": "--seeds", "anatomy": "--anatomy", "anatomy_frame": "--anatomy-frame", "c_z": "--c-z",
    "speed": "--speed", "best_known": "--best-known", "at": "--at", "technique": "--technique", "count": "--count",
    "mean": "--mean", "encoder_deg": "--encoder-deg", "thrust_N": "--thrust", "lateral_N": "--lateral-force",
    "stiffness_Nm_per_rad": "--actuator-stiffness",
    # arcube.Options groups (MODEL.md 8.2, 14, 15)
    "Guards.clearance_mm": "--clearance", "Guards.self_clearance_mm": "--self-clearance",
    "Guards.rho_max_deg": "--guards", "Guards.min_transmission_deg": "--guards", "Guards.kappa_max": "--guards",
    "Body.link_radius": "--link-radius", "Body.actuator_radius": "--actuator-radius", "Body.motor_radius": "--motor-radius",
    "Body.motor_length": "--motor-length", "BodyRadii.link": "--link-radius", "BodyRadii.actuator": "--actuator-radius",
    "BodyRadii.motor": "--motor-radius", "BodyRadii.motor_length": "--motor-length",
    "Loads.encoder_deg": "--encoder-deg", "Loads.thrust_N": "--thrust", "Loads.lateral_force_N": "--lateral-force",
    "Loads.actuator_stiffness": "--actuator-stiffness",
    # arcube.RunSettings
    **{f"RunSettings.{name}": f"--{name.replace('_', '-')}" for name in (
        "algorithm", "population", "generations", "tolerance", "points", "mode", "setups", "margin", "seed", "engine",
        "aggregate", "compactness", "checkpoint_every", "eliminate_duplicates", "design_from", "free", "bounds", "side",
        "levels", "ids", "transform", "anatomy", "anatomy_frame", "objectives", "docking")},
    "RunSettings.maxima": "--max", "RunSettings.minima": "--min", "RunSettings.standoff": "--standoff",
    "requirements.min": "--min", "requirements.max": "--max",
    # arcube.program (MODEL.md 17)
    "ProgramLimits.standoff_mm": "--standoff", "ProgramLimits.approach_speed": "--approach-speed", "ProgramLimits.feed": "--feed",
    "ProgramLimits.retract_speed": "--retract-speed", "ProgramLimits.max_joint_speed_deg": "--max-joint-speed",
    "ProgramLimits.max_joint_accel_deg": "--max-joint-accel", "ProgramLimits.max_tip_speed": "--max-tip-speed",
    "ProgramLimits.tool_radius": "--tool-radius", "ProgramLimits.dt": "--dt", "ProgramLimits.clearance": "--clearance",
    "ProgramLimits.self_clearance": "--self-clearance", "ProgramLimits.kappa_max": "--kappa-max", "Planner.seed": "--seed",
    "Planner.time_s": "--plan-time", "order": "--order",
    # arcube.explore
    "port": "--port", "point": "--point",
}  # fmt: skip
"""Setting (as :class:`~arcube.errors.InputError` names it) -> the flag that sets it."""


def flag_message(exc: InputError) -> str:
    """The error's message with the setting it names replaced by its flag (unchanged if none)."""
    text = str(exc)
    param = getattr(exc, "param", None)
    flag = FLAGS.get(param) if param else None
    if flag is not None and text.startswith(param):
        return flag + text[len(param):]
    return text
