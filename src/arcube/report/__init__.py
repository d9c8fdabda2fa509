"""Reporting layer: mechanism drawings, figures and the self-contained HTML report.

* :mod:`arcube.report.text`: the terminal tables of an evaluation;
* :mod:`arcube.report.figures`: matplotlib PNGs (the paper's Fig 4, optimizer convergence);
* :mod:`arcube.report.html`: one self-contained HTML file (plotly, with plotly.js embedded);
* :mod:`arcube.report.run_report`: the report of an optimization run folder;
* :mod:`arcube.report.study`: the convergence figure of a design-study folder;
* :mod:`arcube.report.program_html`: a drilling program's section of a report, read from its files
  (:mod:`~arcube.report.program_data`; playback :mod:`~arcube.report.program_scene`), and a program
  folder's own report (``arcube report PROGRAM_DIR``).

The layers below (model, io, evaluation, optimization) never import this one: a result does not
know its renderer. :func:`write_report` draws an :class:`~arcube.evaluation.result.Evaluation`.

Submodules are imported lazily so that ``import arcube.report`` stays cheap (plotly and
matplotlib load only when a report is written).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from arcube.errors import InputError

if TYPE_CHECKING:
    from arcube.evaluation.result import Evaluation
    from arcube.optimization.run_results import OptimizeResult

__all__ = [
    "REPORT_SUFFIXES",
    "check_report_path",
    "mechanism_points",
    "write_evaluation_report",
    "write_report",
    "write_run_report",
    "write_study_convergence",
]

REPORT_SUFFIXES = (".html", ".htm")
"""File endings of an HTML report (its PNGs are named from the stem)."""


REPORT_PNGS = ("_dexterity.png", "_convergence.png", "_pareto.png")
"""The PNGs a report may write beside its HTML file (``report.html`` -> ``report_dexterity.png``, ...)."""


def check_report_path(path: str | os.PathLike[str], name: str = "path") -> Path:
    """``path`` as a :class:`Path`, checked before any work: :class:`InputError` naming ``name`` unless
    it ends in .html/.htm, its folder can be written, and it and its PNGs (:data:`REPORT_PNGS`) are
    regular files or absent (a report is several files: it is never written into a FIFO or a device,
    which would leave its PNGs beside them)."""
    from arcube.io.files import check_targets

    out = Path(path)
    if out.suffix.lower() not in REPORT_SUFFIXES:
        raise InputError(f"{name} {out}: the report file must end in .html")
    stem = out.with_suffix("")
    try:
        check_targets([out, *(stem.with_name(stem.name + png) for png in REPORT_PNGS)])
    except OSError as exc:
        raise InputError(f"{name} {out}: {exc.filename}: {exc.strerror}") from None
    _check_writable(out, name)
    return out


def _check_writable(out: Path, name: str) -> None:
    """InputError naming ``name`` unless a file can be created in ``out``'s folder, or, when the folder
    does not exist yet, in its nearest existing parent (a probe file, removed at once: nothing is created)."""
    import tempfile

    folder = out.parent
    existing = next((a for a in (folder, *folder.parents) if a.exists()), Path("."))
    try:
        if not existing.is_dir():
            raise NotADirectoryError(20, f"{existing} is a file, not a folder")
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise InputError(f"{name} {out}: cannot write in {existing} ({exc.strerror or exc})") from None


def write_report(
    evaluation: Evaluation | OptimizeResult,
    path: str | os.PathLike[str] | None = None,
    program: str | os.PathLike[str] | None = None,
    preface: str | None = None,
    title: str | None = None,
    risk: dict[str, float] | None = None,
    **run: Any,
) -> Path:
    """Write the self-contained HTML report of an evaluation (plots, 3D mechanism), or of an optimization
    run held in a folder, and its PNGs; returns the path.

    ``evaluation`` is what :func:`arcube.evaluate` returns; or what :func:`arcube.optimize` returns with a
    folder: its report is ``report.html`` in that folder (``path`` not given), with ``run``'s keywords
    ``anatomy``, ``anatomy_frame`` and ``best_known`` (:func:`~arcube.report.run_report.write_run_report`).
    ``program``: a program folder of the same
    design (program.csv, program.json) whose section (timeline, limits, motors, playback) the report
    adds; by default the ``program/`` beside a report written into an ``arcube design`` job's folder
    (one with design.toml). ``preface``: an HTML fragment put under the title (an ``arcube design`` job's
    verdict, requirements and budget, :func:`arcube.report.design_job.design_preface`); ``title``: the page's title;
    ``risk``: screw id -> P(breach), the colour of each screw in the 3D scene. Raises :class:`InputError` if ``path`` does not end in .html/.htm (the
    PNGs beside it are named from its stem) or the program's files are unreadable.
    """
    from arcube.optimization.run_results import OptimizeResult

    if isinstance(evaluation, OptimizeResult):
        if evaluation.path is None:
            raise InputError.of(
                "result", "is held in memory: only a run written to a folder (optimize with out=...) has a report"
            )
        if path is not None:
            raise InputError.of("path", "is the run folder's report.html for a run; give none")
        from arcube.report.run_report import write_run_report

        return write_run_report(evaluation.path, **run)
    if path is None:
        raise InputError.of("path", "is required (an .html file) for an evaluation's report")
    out = check_report_path(path)
    from arcube.report.html import write_evaluation_report

    if (
        program is None
        and (out.parent / "design.toml").is_file()
        and (out.parent / "program" / "program.json").is_file()
    ):
        program = out.parent / "program"
    return write_evaluation_report(evaluation, out, program=program, preface=preface, title=title, risk=risk)


def __getattr__(name: str) -> Any:
    if name == "mechanism_points":
        from arcube.model.body import mechanism_points

        return mechanism_points
    if name == "write_evaluation_report":
        from arcube.report.html import write_evaluation_report

        return write_evaluation_report
    if name == "write_run_report":
        from arcube.report.run_report import write_run_report

        return write_run_report
    if name == "write_study_convergence":
        from arcube.report.study import write_study_convergence

        return write_study_convergence
    raise AttributeError(f"module 'arcube.report' has no attribute {name!r}")
