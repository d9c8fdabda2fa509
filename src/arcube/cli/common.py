"""Options shared by several commands (one definition, one help text)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.errors import InputError
from arcube.model.body import BodyRadii

DesignOpt = Annotated[str, typer.Option("--design", help="Design: a preset name (paper) or a design JSON file.")]
TrajOpt = Annotated[str, typer.Option("--trajectories", help="Trajectories: a CSV, a Slicer .mrk.json (file or folder), or 'reference'.")]
PointsOpt = Annotated[int, typer.Option("--points", help="Points per trajectory (N >= 2), both ends included.")]
ModeOpt = Annotated[str, typer.Option("--mode", help="Working mode: signs of TMS x, TMS y, RTS x, RTS y, e.g. --mode=-,+,+,-")]
GuardsOpt = Annotated[bool, typer.Option("--guards", help="Turn on the guards of MODEL.md 8.2 (all but z_dyad).")]
SideOpt = Annotated[str | None, typer.Option("--side", help="Keep trajectories of one side: R or L.")]
LevelsOpt = Annotated[str | None, typer.Option("--levels", help="Keep levels, e.g. C3-C5 or C3,C6.")]
IdsOpt = Annotated[str | None, typer.Option("--ids", help="Keep trajectory ids, e.g. 1,3,5.")]
TransformOpt = Annotated[Path | None, typer.Option("--transform", help="4x4 rigid transform (JSON) from the file's frame to the patient frame.")]
EngineOpt = Annotated[str, typer.Option("--engine", help="Evaluation engine: auto (numba if available), numba or numpy.")]
AnatomyOpt = Annotated[list[str] | None, typer.Option("--anatomy", help="Patient anatomy (MODEL.md 14.2): none, default (the plan's default anatomy), or mesh files FILE [FILE ...] (STL, OBJ, PLY).")]
AnatomyFrameOpt = Annotated[str, typer.Option("--anatomy-frame", help="Frame of the anatomy files: LPS (3D Slicer's default), RAS or patient.")]
ClearanceOpt = Annotated[float | None, typer.Option("--clearance", help="Guard: clearance to the anatomy >= MM (failure collision/patient).")]
SelfClearanceOpt = Annotated[float | None, typer.Option("--self-clearance", help="Guard: clearance between the robot's own parts >= MM (failure collision/self).")]
LinkRadiusOpt = Annotated[float, typer.Option("--link-radius", help="Radius of the links (MODEL.md 14.1), mm.")]
ActuatorRadiusOpt = Annotated[float, typer.Option("--actuator-radius", help="Radius of the actuators at P_u and D_u, mm.")]
MotorRadiusOpt = Annotated[float, typer.Option("--motor-radius", help="Radius of the drill motor, mm.")]
MotorLengthOpt = Annotated[float, typer.Option("--motor-length", help="Length of the drill motor beyond the holder H, mm.")]
EncoderOpt = Annotated[str, typer.Option("--encoder-deg", help="Position error bound of the actuators (MODEL.md 15.2), deg: one value, or five (rho_x,rho_y,rho_z,delta_x,delta_y).")]
ThrustOpt = Annotated[float, typer.Option("--thrust", help="Drilling thrust along the drill axis (MODEL.md 15.3), N.")]
LateralForceOpt = Annotated[float, typer.Option("--lateral-force", help="Largest lateral (skiving) force across the drill axis, N.")]
StiffnessOpt = Annotated[str, typer.Option("--actuator-stiffness", help="Torsional stiffness of the actuators (MODEL.md 15.4), N·m/rad: one value or five.")]


def plan_specs(trajectories: list[str] | None, more: list[str] | None, out: Path | None, folder: str) -> list[str]:
    """The trajectory sets given after ``--trajectories`` (several values allowed), with ``--out`` required."""
    if more and not trajectories:
        raise InputError(f"unexpected argument {more[0]!r} (trajectory sets go after --trajectories)")
    if out is None:
        raise InputError(f"--out DIR is required (the {folder} folder)")
    return [*(trajectories or []), *(more or [])]


def numbers(text: str, flag: str) -> float | list[float]:
    """One number or a comma-separated list of numbers (``--encoder-deg 0.01`` or ``0.01,0.01,0.02,0.01,0.01``)."""
    try:
        values = [float(v) for v in str(text).split(",")]
    except ValueError:
        raise InputError(f"{flag} {text!r}: expected one number or five comma-separated numbers") from None
    return values[0] if len(values) == 1 else values


def loads(encoder_deg: str, thrust: float, lateral_force: float, actuator_stiffness: str) -> dict[str, object]:
    """The MODEL.md 15 parameters of the command line, as keyword arguments of :func:`arcube.evaluate`
    and :func:`arcube.optimize`."""
    return {"encoder_deg": numbers(encoder_deg, "--encoder-deg"), "thrust": thrust, "lateral_force": lateral_force,
            "actuator_stiffness": numbers(actuator_stiffness, "--actuator-stiffness")}  # fmt: skip


def radii(link: float, actuator: float, motor: float, motor_length: float) -> BodyRadii:
    """The body radii of the flags (InputError on a bad value)."""
    return BodyRadii(link, actuator, motor, motor_length)


class RichBar:
    """A Rich progress bar on stderr, shown only on a terminal; subclasses give its columns and fields."""

    def __init__(self, enabled: bool, columns: tuple[Any, ...], **fields: Any) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        console = Console(stderr=True)
        self.enabled, self.task = enabled and console.is_terminal, None
        if self.enabled:
            title, *rest = columns
            self.progress = Progress(TextColumn(title), MofNCompleteColumn(), BarColumn(), *rest, console=console)
            self.task = self.progress.add_task(title, **fields)

    def __enter__(self) -> RichBar:
        if self.enabled:
            self.progress.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.enabled:
            self.progress.__exit__(*exc)
