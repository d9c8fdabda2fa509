"""``arcube explore``: the interactive design explorer in the browser (or ``--html FILE``, a static scene)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import typer

from arcube.cli.common import (
    PATIENT,
    SELECTION,
    DESIGN,
    MODE,
    POINTS,
    TRAJECTORIES,
    FORCE,
    check_new_file,
    file_path,
    with_help,
    one_plan,
    options_of,
    plan_request,
    request_flags,
)
from arcube.cli.projection import Given, command, option
from arcube.errors import InputError

__all__ = ["register"]

FLAGS = [
    DESIGN,
    TRAJECTORIES,
    *[with_help(f, f.help.replace("[default: none]", "[default: default, as arcube design]")) for f in PATIENT],
    option("--port", "Port of the local web app. [default: 8080]", int, params=("port",)),
    option("--host", "Address to listen on (0.0.0.0: every interface). [default: 127.0.0.1]", params=("host",)),
    option(
        "--html",
        "Write a standalone static scene (HTML, opens offline) here instead of serving.",
        Path,
        params=("html",),
        parse=file_path("scene.html"),
    ),
    option(
        "--point",
        "Point along the lines shown first (per trajectory: approach points, then drill points).",
        int,
        params=("point",),
    ),
    option(
        "--save",
        "Default file of the app's 'Save design JSON' button. [default: design_explored.json]",
        Path,
        key="save_path",
    ),
    with_help(FORCE, "Replace the --html file if it exists (it is never replaced without it)."),
    POINTS,
    MODE,
    option("--no-guards", "Start without the guards of 'arcube design' (the paper's model).", bool),
    *SELECTION,
    *request_flags("body"),
]


def explore(given: Given) -> None:
    """Explore a design on a drilling plan in the browser: sliders, the robot coloured by clearance, live figures."""
    from arcube.explorer import explore as explore_api

    common = {**{k: given.get(k) for k in ("mode", "points", "point") if k in given}, **plan_request(given)}
    common.update(options=options_of(given, guarded=False), guarded=not given.get("no_guards"))
    design, plan = given.get("design", "paper"), one_plan(given)
    check_new_file(given, "html")
    if "html" in given:
        served = [given.flag(k) for k in ("port", "host", "save_path") if k in given]
        if served:  # a static scene serves nothing: those flags would be ignored
            raise InputError(f"--html writes a static scene, no app is served: leave {', '.join(served)} out")
        sys.stdout.write(f"{explore_api(design, plan, html=given.get('html'), **common)}\n")
        return
    serve = {k: given.get(k) for k in ("port", "host", "save_path") if k in given}
    app = explore_api(design, plan, block=False, **serve, **common)
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
    command(app, "explore", FLAGS, explore, help=explore.__doc__ or "")
