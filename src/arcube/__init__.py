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

from arcube.api import Run, Study, evaluate, optimize, resume, study
from arcube.errors import InputError
from arcube.evaluation.reference import GUARDED_OPTIONS, Options
from arcube.evaluation.result import Evaluation
from arcube.export.mjcf import export_mjcf
from arcube.io import TrajectorySet, load_trajectories, read_markups, select, write_csv, write_markups
from arcube.model.design import PARAM_NAMES, Design
from arcube.patients import generate_patient

__all__ = [
    "GUARDED_OPTIONS", "PARAM_NAMES", "Design", "Evaluation", "InputError", "Options", "Run", "Study", "TrajectorySet",
    "__version__", "evaluate", "export_mjcf", "generate_patient", "load_trajectories", "optimize", "read_markups", "resume", "select", "study",
    "write_csv", "write_markups",
]  # fmt: skip
