"""arcube: kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot.

The public API (see :mod:`arcube.api`)::

    import arcube
    design = arcube.Design.paper()
    plan = arcube.load_trajectories("reference")
    ev = arcube.evaluate(design, plan)
    ev.summary["eta_G"]

Every error a user can cause raises :class:`InputError` with a one-line message.
"""

from __future__ import annotations

__version__ = "0.2.0"

from arcube.api import OptimizeResult, Planner, Program, ProgramLimits, Study, design, evaluate, joints, optimize, program, resume, study, tolerance
from arcube.accuracy import ToleranceResult, ToleranceSettings
from arcube import calibrate
from arcube.errors import InputError
from arcube.optimization.settings import RunSettings
from arcube.options import GUARDED_OPTIONS, Body, Guards, Loads, Options, Outputs
from arcube.evaluation.result import Evaluation
from arcube.export.mjcf import export_mjcf
from arcube.io import TrajectorySet, load_trajectories, read_markups, select, write_csv, write_markups
from arcube.model.design import PARAM_NAMES, Design
from arcube.patients import generate_patient
from arcube.report import write_report
from arcube.explorer import explore  # noqa: E402 (after api: polish imports arcube.api lazily)
from arcube.options import Masses

__all__ = [
    "GUARDED_OPTIONS", "PARAM_NAMES", "Body", "Design", "Evaluation", "Guards", "InputError", "Loads", "OptimizeResult", "Options",
    "Masses", "Outputs", "Planner", "Program", "ProgramLimits", "RunSettings", "ToleranceResult", "ToleranceSettings", "Study", "TrajectorySet",
    "__version__", "calibrate", "design", "evaluate", "explore", "export_mjcf", "generate_patient", "joints", "load_trajectories", "optimize", "program", "read_markups", "resume", "select", "study", "tolerance",
    "write_csv", "write_markups", "write_report",
]  # fmt: skip
