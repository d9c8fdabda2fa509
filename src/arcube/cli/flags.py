"""The flag table: which command-line flag sets which setting, and the one place that turns a
library error about a setting into an error about its flag.

Library errors name what a Python caller wrote (``Loads.thrust_N must be >= 0, got -1.0``,
``points must be an integer >= 2``) and carry that name in ``InputError.param``; the CLI prints
the same message with the flag in its place (``--thrust must be >= 0, got -1.0``).

Also the flags of the mass model (MODEL.md 18.1), shared by ``evaluate``, ``optimize``, ``design``,
``joints`` and ``program``: :data:`MASS_FLAGS` and :func:`given_masses`.
"""

from __future__ import annotations

from typing import Annotated, Any

import typer

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
    # MODEL.md 18.1 (arcube.options.Masses, and the plain model arcube.evaluation.bodies.MassModel)
    **{f"{cls}.{name}": flag for cls in ("Masses", "MassModel") for name, flag in (
        ("wall_mm", "--wall"), ("density_kg_m3", "--density"), ("m_delta_kg", "--m-delta"), ("m_motor_kg", "--m-motor"),
        ("gravity", "--gravity"))},
    "MassModel.link_radius_mm": "--link-radius", "MassModel.motor_length_mm": "--motor-length",
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


# ----------------------------------------------------------------------------- the mass model's flags (MODEL.md 18.1)
WallOpt = Annotated[float | None, typer.Option("--wall", help="Wall of the links' tubes (MODEL.md 18.1), mm; default 2, < --link-radius.")]
DensityOpt = Annotated[float | None, typer.Option("--density", help="Density of the links' material, kg/m^3; default 2700 (aluminium).")]
MDeltaOpt = Annotated[float | None, typer.Option("--m-delta", help="Mass of each delta actuator (riding at D_x, D_y), kg; default 0.8.")]
MMotorOpt = Annotated[float | None, typer.Option("--m-motor", help="Mass of the drill motor, kg; default 1.5.")]
GravityOpt = Annotated[str | None, typer.Option("--gravity", help="Gravity in the patient frame, m/s^2, three numbers; default 0,0,-9.81 (prone, posterior up).")]
MASS_FLAGS: dict[str, str] = {"wall_mm": "--wall", "density_kg_m3": "--density", "m_delta_kg": "--m-delta", "m_motor_kg": "--m-motor",
                              "gravity": "--gravity"}  # fmt: skip
"""Each field of :class:`arcube.options.Masses` and its flag."""
_KEYWORDS = {"wall_mm": "wall", "density_kg_m3": "density", "m_delta_kg": "m_delta", "m_motor_kg": "m_motor", "gravity": "gravity"}
"""Each field's flat keyword of :func:`arcube.optimize` (``arcube.optimization.settings.FLAT_OPTIONS``)."""


def given_masses(wall: float | None, density: float | None, m_delta: float | None, m_motor: float | None,
                 gravity: str | None) -> dict[str, Any]:  # fmt: skip
    """The mass flags a user gave (None: not given), by :class:`arcube.options.Masses` field."""
    values = dict(zip(MASS_FLAGS, (wall, density, m_delta, m_motor, gravity)))
    return {name: value for name, value in values.items() if value is not None}


def mass_keywords(given: dict[str, Any], link_radius: float) -> dict[str, Any]:
    """The given mass flags as the flat keywords of :func:`arcube.optimize` and :func:`arcube.design`
    (``wall``, ``density``, ``m_delta``, ``m_motor``, ``gravity``), after checking them as :func:`masses_of`."""
    if given:
        masses_of(given, link_radius)
    return {_KEYWORDS[name]: value for name, value in given.items()}


def masses_of(given: dict[str, Any], link_radius: float) -> Any:
    """:class:`arcube.options.Masses` of the given flags (defaults for the others), checked against the
    link radius (``--wall`` < ``--link-radius``); InputError naming the flag."""
    from arcube.options import Body, Masses, Options, validated

    try:
        masses = validated(Masses, given)
        Options(body=Body(link_radius=link_radius), masses=masses).check_masses()
    except InputError as exc:
        raise InputError(flag_message(exc)) from None
    return masses
