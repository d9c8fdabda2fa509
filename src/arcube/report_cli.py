"""The ``report`` and ``joints`` commands; :func:`register` adds them to a Typer app.

* ``arcube report RUN_DIR``: writes RUN_DIR/report.html (+ PNGs) and prints its path;
* ``arcube joints --design D --trajectories T --speed 1.0 --out FILE.csv``: joint angles and
  rates along the trajectories (:mod:`arcube.joints`).

Bad input raises :class:`arcube.errors.InputError` (one line); the main CLI prints it as
``error: ...`` and exits with code 2.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from arcube.errors import InputError

if TYPE_CHECKING:
    from arcube.evaluate_cmd import EvaluationReport


def write_report_for_evaluation(report: EvaluationReport, path: str | os.PathLike[str]) -> Path:
    """HTML report of an ``arcube evaluate`` result (for ``--report FILE.html``); returns the path.

    Raises InputError if the path does not end in .html/.htm (the PNGs are named from its stem).
    """
    from arcube.report.html import write_evaluation_report

    out = Path(path)
    if out.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"--report {out}: the report file must end in .html")
    return write_evaluation_report(report, out)


def report(run_dir: Annotated[Path, typer.Argument(help="An optimization run folder (config.toml, best_design.json, history.csv).")]) -> None:
    """Write the HTML report of an optimization run (RUN_DIR/report.html) and print its path."""
    from arcube.report.run_report import write_run_report

    sys.stdout.write(f"{write_run_report(run_dir)}\n")


def joints(
    out: Annotated[Path, typer.Option("--out", help="Output CSV file (written atomically).")],
    design: Annotated[str, typer.Option("--design", help="Design: a preset name (paper) or a design JSON file.")] = "paper",
    trajectories: Annotated[str, typer.Option("--trajectories", help="Trajectories: a CSV, a Slicer .mrk.json (file or folder), or 'reference'.")] = "reference",
    speed: Annotated[float, typer.Option("--speed", help="Drilling speed along each trajectory, mm/s.")] = 1.0,
    points: Annotated[int, typer.Option("--points", help="Points per trajectory (N >= 2), both ends included.")] = 30,
    mode: Annotated[str, typer.Option("--mode", help="Working mode: signs of TMS x, TMS y, RTS x, RTS y, e.g. --mode=-,+,+,-")] = "+,+,+,+",
    guards: Annotated[bool, typer.Option("--guards", help="Turn on the guards of MODEL.md 8.2 (all but z_dyad) for 'reachable'.")] = False,
    side: Annotated[str | None, typer.Option("--side", help="Keep trajectories of one side: R or L.")] = None,
    levels: Annotated[str | None, typer.Option("--levels", help="Keep levels, e.g. C3-C5 or C3,C6.")] = None,
    ids: Annotated[str | None, typer.Option("--ids", help="Keep trajectory ids, e.g. 1,3,5.")] = None,
    transform: Annotated[Path | None, typer.Option("--transform", help="4x4 rigid transform (JSON) from the file's frame to the patient frame.")] = None,
) -> None:
    """Joint angles (deg) and rates (deg/s) for drilling each trajectory at --speed mm/s, as CSV."""
    from arcube.design import Design
    from arcube.evaluate_cmd import load_task, parse_mode_option
    from arcube.evaluation import GUARDED_OPTIONS, Options
    from arcube.joints import joint_trajectory

    if not (math.isfinite(speed) and speed > 0.0):
        raise InputError(f"--speed must be a finite positive number of mm/s, got {speed}")
    if out.exists() and out.is_dir():
        raise InputError(f"--out {out}: is a folder; give a CSV file path")
    signs = parse_mode_option(mode)
    d = Design.load(design)
    _, task = load_task(trajectories, points, side, levels, ids, transform)
    jt = joint_trajectory(d, task, speed, signs, GUARDED_OPTIONS if guards else Options())
    try:
        path = jt.write_csv(out)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    n_bad = int((~jt.reachable).sum())
    sys.stdout.write(f"{path}\n")
    if n_bad:
        sys.stderr.write(f"note: {n_bad} of {len(jt.reachable)} points are unreachable (empty cells, reachable=false)\n")


def register(app: typer.Typer) -> None:
    """Add ``report`` and ``joints`` to ``app``."""
    app.command("report")(report)
    app.command("joints")(joints)
