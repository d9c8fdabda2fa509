"""``arcube joints``: joint angles and rates along the trajectories, as CSV (:func:`arcube.joints`)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from arcube.cli.common import (
    ENGINE,
    FORCE,
    OUT,
    PLAN,
    check_replace,
    file_out,
    masses_given,
    one_plan,
    options_of,
    plan_request,
    request_flags,
)
from arcube.cli.projection import Given, command, option
from arcube.errors import InputError

__all__ = ["register"]

CSV_OUT = file_out(OUT, "Output CSV file (written atomically).", "joints.csv", required=True)
SPEED = option("--speed", "Drilling speed along each trajectory, mm/s. [default: 1]", float, params=("speed",))
_UNUSED = ("options.guards.envelope_clearance_mm", "options.loads.encoder_deg", "options.loads.actuator_stiffness")
"""Option flags joints would take and ignore: no envelope (--envelope) to keep clear of, and no accuracy columns
(the encoders and the actuators' stiffness enter the accuracy of model §15, which joints does not write)."""
FLAGS = [
    CSV_OUT,
    FORCE,
    SPEED,
    *[f for f in PLAN if f is not ENGINE],
    *[f for f in request_flags("clearances", "body", "loads", "masses") if f.key not in _UNUSED],
]


def joints(given: Given) -> None:
    """Joint angles (deg) and rates (deg/s) for drilling each trajectory at --speed mm/s, as CSV. With any
    mass flag (e.g. --gravity 0,0,-9.81 for the defaults) also the holding torque of model §18.2 per row."""
    from arcube.api import joints as joints_api

    out: Path = given.get("out")
    if out.exists() and out.is_dir():
        raise InputError(f"{CSV_OUT.name} {out}: is a folder; give a CSV file path")
    check_replace(given)
    options = options_of(given)
    if masses_given(given):  # the columns of model §18.2 (arcube.export.joints.MASS_COLUMNS)
        options = options.check_masses().replace(outputs=options.outputs.replace(holding_torque=True))
    keys = ("speed", "points", "mode")
    jt = joints_api(
        given.get("design", "paper"),
        one_plan(given),
        options=options,
        **{k: given.get(k) for k in keys if k in given},
        **plan_request(given),
    )
    try:
        path = jt.write_csv(out)
    except OSError as exc:
        raise InputError(f"{CSV_OUT.name} {out}: cannot write ({exc.strerror or exc})") from None
    n_bad = int((~jt.reachable).sum())
    sys.stdout.write(f"{path}\n")
    if n_bad:
        sys.stderr.write(
            f"note: {n_bad} of {len(jt.reachable)} points are unreachable (empty cells, reachable=false)\n"
        )


def register(app: typer.Typer) -> None:
    """Add the ``joints`` command to ``app``."""
    command(app, "joints", FLAGS, joints, help=joints.__doc__ or "")
