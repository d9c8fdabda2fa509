"""arcube: kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot.

The public API (see :mod:`arcube.api`)::

    import arcube
    design = arcube.Design.paper()
    plan = arcube.load_trajectories("reference")
    ev = arcube.evaluate(design, plan)
    ev.summary["eta_G"]

Every error a user can cause raises :class:`InputError` with a one-line message.

The names below are imported on first use (PEP 562), so that ``import arcube`` itself stays light:
the ``arcube`` script installs its Ctrl-C handling (:mod:`arcube.interrupts`) before anything
heavy is imported, and Numba's cache folder is chosen (:mod:`arcube.caches`) before Numba loads.
"""

from __future__ import annotations

import importlib

from arcube import caches as _caches

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (a start-up cost of the arcube script)

__version__ = "0.2.0"

_caches.configure()

_SOURCES: dict[str, str] = {
    **dict.fromkeys(("OptimizeResult", "Planner", "Program", "ProgramLimits", "Study"), "arcube.api"),
    **dict.fromkeys(
        ("design", "evaluate", "joints", "optimize", "program", "resume", "study", "tolerance"), "arcube.api"
    ),
    "Request": "arcube.request",
    "RunConfig": "arcube.optimization.run_config",
    "RunSummary": "arcube.optimization.run_results",
    "StudySummary": "arcube.optimization.run_results",
    **dict.fromkeys(("DockSummary", "DesignSummary"), "arcube.design_job.summaries"),
    "EvaluationSummary": "arcube.evaluation.result",
    "ToleranceSummary": "arcube.accuracy.budget",
    **dict.fromkeys(("ToleranceResult", "ToleranceSettings"), "arcube.accuracy"),
    "InputError": "arcube.errors",
    "RunSettings": "arcube.optimization.settings",
    **dict.fromkeys(("GUARDED_OPTIONS", "Body", "Guards", "Loads", "Masses", "Options", "Outputs"), "arcube.options"),
    "Evaluation": "arcube.evaluation.result",
    "export_mjcf": "arcube.export.mjcf",
    **dict.fromkeys(
        ("TrajectorySet", "load_trajectories", "read_markups", "select", "write_csv", "write_markups"), "arcube.io"
    ),
    **dict.fromkeys(("PARAM_NAMES", "Design"), "arcube.model.design"),
    "generate_patient": "arcube.patients",
    "write_report": "arcube.report",
    "explore": "arcube.explorer",
    "ExplorerApp": "arcube.explorer.app",
    **dict.fromkeys(("DockResult", "dock"), "arcube.design_job.coverage"),
    "DesignResult": "arcube.design_job",
    "JointTrajectory": "arcube.export.joints",
    **dict.fromkeys(("BreachResult", "BreachSettings"), "arcube.pedicles"),
    "breach": "arcube.design_job.at_patient",
    "PointResults": "arcube.evaluation.reference",
    "TrajectorySummary": "arcube.evaluation.tables",
    "Resolved": "arcube.request",
    "BodyRadii": "arcube.model.body",
    "BreachSummary": "arcube.pedicles.monte_carlo",
}
"""Public name -> the module it comes from (``calibrate``, a subpackage, is imported as one)."""

if TYPE_CHECKING:
    from typing import Any

    from arcube import calibrate
    from arcube.accuracy import ToleranceResult, ToleranceSettings
    from arcube.api import (
        OptimizeResult,
        Planner,
        Program,
        ProgramLimits,
        Study,
        design,
        evaluate,
        joints,
        optimize,
        program,
        resume,
        study,
        tolerance,
    )
    from arcube.errors import InputError
    from arcube.evaluation.result import Evaluation
    from arcube.design_job import DesignResult
    from arcube.design_job.coverage import DockResult, dock
    from arcube.export.joints import JointTrajectory
    from arcube.design_job.at_patient import breach
    from arcube.pedicles import BreachResult, BreachSettings
    from arcube.pedicles.monte_carlo import BreachSummary
    from arcube.explorer import explore
    from arcube.explorer.app import ExplorerApp
    from arcube.export.mjcf import export_mjcf
    from arcube.io import TrajectorySet, load_trajectories, read_markups, select, write_csv, write_markups
    from arcube.model.design import PARAM_NAMES, Design
    from arcube.optimization.settings import RunSettings
    from arcube.options import GUARDED_OPTIONS, Body, Guards, Loads, Masses, Options, Outputs
    from arcube.patients import generate_patient
    from arcube.report import write_report
    from arcube.request import Request
    from arcube.evaluation.result import EvaluationSummary
    from arcube.optimization.run_config import RunConfig
    from arcube.optimization.run_results import RunSummary, StudySummary
    from arcube.accuracy.budget import ToleranceSummary
    from arcube.design_job.summaries import DesignSummary, DockSummary
    from arcube.evaluation.reference import PointResults
    from arcube.evaluation.tables import TrajectorySummary
    from arcube.request import Resolved
    from arcube.model.body import BodyRadii

__all__ = [
    "GUARDED_OPTIONS",
    "PARAM_NAMES",
    "Body",
    "BodyRadii",
    "BreachResult",
    "BreachSettings",
    "BreachSummary",
    "Design",
    "DesignResult",
    "DesignSummary",
    "DockResult",
    "DockSummary",
    "Evaluation",
    "EvaluationSummary",
    "ExplorerApp",
    "Guards",
    "InputError",
    "JointTrajectory",
    "Loads",
    "OptimizeResult",
    "Options",
    "Masses",
    "Outputs",
    "Planner",
    "PointResults",
    "Program",
    "ProgramLimits",
    "Request",
    "Resolved",
    "RunConfig",
    "RunSettings",
    "RunSummary",
    "ToleranceResult",
    "ToleranceSettings",
    "ToleranceSummary",
    "Study",
    "StudySummary",
    "TrajectorySet",
    "TrajectorySummary",
    "__version__",
    "breach",
    "calibrate",
    "design",
    "dock",
    "evaluate",
    "explore",
    "export_mjcf",
    "generate_patient",
    "joints",
    "load_trajectories",
    "optimize",
    "program",
    "read_markups",
    "resume",
    "select",
    "study",
    "tolerance",
    "write_csv",
    "write_markups",
    "write_report",
]


def _is_submodule(name: str) -> bool:
    """Whether ``arcube.<name>`` is a module or subpackage (found, not imported)."""
    import importlib.util  # here: it costs the script's start-up a few milliseconds before its Ctrl-C handler

    return importlib.util.find_spec(f"arcube.{name}") is not None


def __getattr__(name: str) -> Any:
    if name in _SOURCES:
        value: Any = getattr(importlib.import_module(_SOURCES[name]), name)
    elif not name.startswith("_") and _is_submodule(name):
        value = importlib.import_module(
            f"arcube.{name}"
        )  # a subpackage, as when this module imported them all (arcube.io, arcube.calibrate)
    else:
        raise AttributeError(f"module 'arcube' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)  # the public names only (not TYPE_CHECKING, importlib, the caches module ...)
