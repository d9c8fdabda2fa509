"""Command-line interface: ``arcube <command>``.

Every error a user can cause ends as one line ``error: <what and where>`` on stderr and exit
code 2, with no traceback (see :func:`main`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.errors import InputError

app = typer.Typer(
    name="arcube",
    help="Kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)



@app.callback()
def _root() -> None:
    """Kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot."""


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


@app.command()
def evaluate(
    design: DesignOpt = "paper",
    trajectories: TrajOpt = "reference",
    points: PointsOpt = 30,
    mode: ModeOpt = "+,+,+,+",
    guards: GuardsOpt = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object (per-point results and summary).")] = False,
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    transform: TransformOpt = None,
    engine: EngineOpt = "auto",
    report: Annotated[Path | None, typer.Option("--report", help="Also write a self-contained HTML report (plots, 3D mechanism) here.")] = None,
) -> None:
    """Evaluate a design on drilling trajectories: reachability, condition numbers, dexterity."""
    from arcube import report_text
    from arcube.evaluate_cmd import run_evaluation

    result = run_evaluation(
        design=design, trajectories=trajectories, points=points, mode=mode, guards=guards,
        side=side, levels=levels, ids=ids, transform=transform, engine=engine,
    )  # fmt: skip
    if report is not None:
        from arcube.report_cli import write_report_for_evaluation

        write_report_for_evaluation(result, report)
    if as_json:
        sys.stdout.write(json.dumps(result.to_json(), allow_nan=False) + "\n")
    else:
        report_text.print_evaluation(result)
        if report is not None:
            typer.echo(f"report: {report}")


def _register_subcommands() -> None:
    """Commands that live beside their subsystem register themselves here."""
    from arcube import demo, patients_cli, report_cli
    from arcube.optimize import cli as optimize_cli

    for module in (patients_cli, optimize_cli, report_cli, demo):
        module.register(app)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``arcube`` script: one-line errors and exit code 2 on bad input."""
    _register_subcommands()
    command = typer.main.get_command(app)
    try:
        command.main(args=argv, prog_name="arcube", standalone_mode=False)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        sys.stderr.write("error: aborted\n")
        sys.exit(130)
    except typer.TyperException as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":
            sys.stdout.write(exc.format_message() + "\n")
            sys.exit(0)
        sys.stderr.write(f"error: {_one_line(exc.format_message())}\n")
        sys.exit(2)
    except InputError as exc:
        sys.stderr.write(f"error: {_one_line(str(exc))}\n")
        sys.exit(2)
    except OSError as exc:
        # A file the user named cannot be read or written (permissions, missing folder, full disk).
        where = f"{exc.filename}: " if exc.filename else ""
        sys.stderr.write(f"error: {where}{_one_line(exc.strerror or str(exc))}\n")
        sys.exit(2)
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)


def _one_line(text: str) -> str:
    return " ".join(text.split())
