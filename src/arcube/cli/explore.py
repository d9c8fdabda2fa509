"""``arcube explore``: the interactive design explorer in the browser (or ``--html FILE``, a static scene)."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, DesignOpt, IdsOpt, LevelsOpt, LinkRadiusOpt, ModeOpt, MotorLengthOpt, MotorRadiusOpt,
    PointsOpt, SideOpt, TrajOpt, radii,
)  # fmt: skip

__all__ = ["register"]


def explore(
    design: DesignOpt = "paper",
    trajectories: TrajOpt = "reference",
    anatomy: AnatomyOpt = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    port: Annotated[int, typer.Option("--port", help="Port of the local web app.")] = 8080,
    host: Annotated[str, typer.Option("--host", help="Address to listen on (0.0.0.0: every interface).")] = "127.0.0.1",
    html: Annotated[Path | None, typer.Option("--html", help="Write a standalone static scene (HTML, opens offline) here instead of serving.")] = None,
    point: Annotated[int | None, typer.Option("--point", help="Point along the lines shown first (per trajectory: approach points, then drill points).")] = None,
    save: Annotated[Path, typer.Option("--save", help="Default file of the app's 'Save design JSON' button.")] = Path("design_explored.json"),
    points: PointsOpt = 30,
    mode: ModeOpt = "+,+,+,+",
    no_guards: Annotated[bool, typer.Option("--no-guards", help="Start without the guards of 'arcube design' (the paper's model).")] = False,
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    link_radius: LinkRadiusOpt = 8.0,
    actuator_radius: ActuatorRadiusOpt = 25.0,
    motor_radius: MotorRadiusOpt = 20.0,
    motor_length: MotorLengthOpt = 120.0,
) -> None:
    """Explore a design on a drilling plan in the browser: sliders, the robot coloured by clearance, live figures."""
    from arcube.explore import explore as explore_api

    common = dict(anatomy=anatomy, anatomy_frame=anatomy_frame, mode=mode, points=points, side=side, levels=levels, ids=ids,
                  radii=radii(link_radius, actuator_radius, motor_radius, motor_length), guards=not no_guards, point=point)  # fmt: skip
    if html is not None:
        sys.stdout.write(f"{explore_api(design, trajectories, html=html, **common)}\n")
        return
    app = explore_api(design, trajectories, port=port, host=host, save_path=save, block=False, **common)
    sys.stdout.write(f"explorer: {app.url}  (Ctrl-C stops it)\n")
    sys.stdout.flush()
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        sys.stderr.write("stopped\n")
    finally:
        app.stop()


def register(app: typer.Typer) -> None:
    """Add the ``explore`` command to ``app``."""
    app.command("explore")(explore)
