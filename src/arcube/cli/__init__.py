"""Command-line interface: ``arcube <command>``, a thin shell over the library (:mod:`arcube.api`).

One small module per command (parse, call the library, print); every command registers itself
on :data:`app`. Every error a user can cause ends as one line ``error: <what and where>`` on
stderr and exit code 2, with no traceback (see :func:`main`).
"""

from __future__ import annotations

import os
import re
import sys
import warnings
from typing import Any

import typer

from arcube import __version__, interrupts
from arcube.cli import (
    breach,
    calibrate,
    demo,
    design,
    dock,
    evaluate,
    explore,
    export,
    joints,
    optimize,
    patients,
    program,
    report,
    resume,
    study,
    tolerance,
)
from arcube.cli.projection import REGISTRY
from arcube.errors import InputError
from arcube.optimization.executors import worker_processes

__all__ = ["app", "main"]

app = typer.Typer(
    name="arcube",
    help="Kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"arcube {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", help="Print the version and exit.", callback=_version, is_eager=True
    ),
) -> None:
    """Kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot."""


for _module in (
    evaluate,
    optimize,
    resume,
    study,
    design,
    dock,
    breach,
    report,
    joints,
    patients,
    demo,
    export,
    explore,
    program,
    tolerance,
    calibrate,
):
    _module.register(app)


MULTI_VALUE_OPTIONS = frozenset(f.name for flags in REGISTRY.values() for f in flags if f.spread)
"""Options that take several values after one flag (``--anatomy a.stl b.stl``)."""


def expand_multi_value(argv: list[str]) -> list[str]:
    """``--anatomy a b --x`` -> ``--anatomy a --anatomy b --x``: click takes one value per flag."""
    out: list[str] = []
    current: str | None = None
    for token in argv:
        if token == "--":
            current = None
            out.append(token)
        elif token.startswith("-"):
            name = token.split("=", 1)[0]
            current = name if name in MULTI_VALUE_OPTIONS and "=" not in token else None
            out.append(token)
        elif current is not None and out and out[-1] != current:
            out += [current, token]
        else:
            out.append(token)
    return out


PATH_OPTIONS = frozenset(f.name for flags in REGISTRY.values() for f in flags if f.path)
"""Options naming a file or folder: an empty value would silently mean the current folder."""


def _check_empty_paths(args: list[str]) -> None:
    for i, token in enumerate(args):
        name, eq, value = token.partition("=")
        if name in PATH_OPTIONS and (
            (eq and not value.strip()) or (not eq and i + 1 < len(args) and not args[i + 1].strip())
        ):
            raise InputError(f"{name}: empty path (give a file or folder name)")


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``arcube`` script: one-line errors and exit code 2 on bad input; Ctrl-C: one
    line and exit code 130, SIGTERM: one line and 143, also when a dependency swallowed the interrupt
    (:mod:`arcube.interrupts`). The command's worker processes stop with it, however it ends
    (:func:`arcube.optimization.executors.worker_processes`)."""
    previous = None
    try:
        previous = interrupts.arm()
        with worker_processes():
            _run(argv)
    except KeyboardInterrupt:
        _interrupted()
    finally:
        interrupts.disarm(previous)


def _interrupted() -> None:
    """``error: interrupted`` and exit code 130 (Ctrl-C), ``error: terminated`` and 143 (SIGTERM)."""
    message, code = interrupts.ending()
    sys.stderr.write(message.decode())
    sys.exit(code)


def _show_warning(show: Any) -> Any:
    """``warnings.showwarning`` that prints an old name's warning as one line with the user's flags
    (``warning: --tolerance is now --ftol ...``) and leaves every other warning to ``show``."""
    from arcube.errors import RenamedWarning

    def show_warning(
        message: Any, category: Any, filename: str, lineno: int, file: Any = None, line: Any = None
    ) -> None:
        if issubclass(category, RenamedWarning):
            from arcube.cli.projection import flag_message

            sys.stderr.write(f"warning: {flag_message(InputError(str(message)))}\n")
        else:
            show(message, category, filename, lineno, file, line)

    return show_warning


def _main_with_grid_bar(command: Any, args: list[str]) -> Any:
    """The command, with a bar while an anatomy's distance grids are built (:class:`arcube.cli.common.GridBar`)."""
    from arcube.cli.common import GridBar
    from arcube.progress import GRIDS, listening

    bar = GridBar()
    try:
        with listening(GRIDS, bar):
            return command.main(args=args, prog_name="arcube", standalone_mode=False)
    finally:
        bar.close()


def _run(argv: list[str] | None) -> None:
    command = typer.main.get_command(app)
    args = expand_multi_value(list(sys.argv[1:] if argv is None else argv))
    try:
        _check_empty_paths(args)
        with warnings.catch_warnings():
            if not os.environ.get("ARCUBE_DEBUG"):
                # numbers are checked where they matter (finite, in range); NumPy's and matplotlib's overflow
                # warnings on extreme values would only precede the one line that says what is wrong
                warnings.simplefilter("ignore", RuntimeWarning)
            warnings.showwarning = _show_warning(warnings.showwarning)
            code = _main_with_grid_bar(command, args)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        sys.stderr.write("error: aborted\n")
        sys.exit(130)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        if interrupts.pending() and not isinstance(
            exc, SystemExit
        ):  # what a swallowed interrupt became (ImportError, ...)
            _interrupted()
        _error(exc)
    if (
        code == 130 or interrupts.pending()
    ):  # typer turns Ctrl-C (and SIGTERM, raised as Ctrl-C) into Exit(130), returned (not raised) without standalone mode
        _interrupted()
    if isinstance(code, int) and code:
        sys.exit(code)


def _error(exc: BaseException) -> None:
    """One line and the exit code for an exception that ended a command."""
    if isinstance(exc, SystemExit):
        raise exc
    if isinstance(exc, typer.TyperException):
        if type(exc).__name__ == "NoArgsIsHelpError":
            sys.stdout.write(exc.format_message() + "\n")
            sys.exit(0)
        sys.stderr.write(f"error: {_one_line(exc.format_message())}\n")
        sys.exit(2)
    if isinstance(exc, InputError):
        sys.stderr.write(f"error: {_one_line(str(exc))}\n")
        sys.exit(2)
    if isinstance(exc, OSError):
        # A file the user named cannot be read or written (permissions, missing folder, full disk).
        where = f"{exc.filename}: " if exc.filename else ""
        sys.stderr.write(f"error: {where}{_one_line(exc.strerror or str(exc))}\n")
        sys.exit(2)
    if not isinstance(exc, Exception) or os.environ.get("ARCUBE_DEBUG"):
        raise exc
    # a bug, not bad input: one line and a hint, the traceback only on request
    sys.stderr.write(
        f"error: internal error ({type(exc).__name__}: {_one_line(str(exc))[:300]}); "
        "rerun with ARCUBE_DEBUG=1 for the traceback and please report it\n"
    )
    sys.exit(1)


_LONG_NUMBER = re.compile(r"[0-9]{25,}")
_MAX_MESSAGE = 2000


def _one_line(text: str) -> str:
    """``text`` on one line, each run of more than 24 digits shortened (``999999999999...(300 digits)``:
    the value a user typed is recognisable without filling the terminal), at most 2000 characters."""
    line = _LONG_NUMBER.sub(lambda m: f"{m.group()[:12]}...({len(m.group())} digits)", " ".join(text.split()))
    return line if len(line) <= _MAX_MESSAGE else line[: _MAX_MESSAGE - 3] + "..."
