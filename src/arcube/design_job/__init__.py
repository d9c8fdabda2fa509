"""``arcube design``: the design job and its requirements, in one package.

* :mod:`~arcube.design_job.requirements`: the requirements of a buildable robot and their check by
  the NumPy reference (:func:`~arcube.design_job.requirements.assess`);
* :mod:`~arcube.design_job.job`: the job itself (a study over seeds, the choice, the program, the
  outputs) and its folder (:class:`~arcube.design_job.job.DesignResult`).
"""

from arcube.design_job.job import (
    DESIGN_FORMAT,
    DESIGN_GENERATIONS,
    STUDY,
    DesignResult,
    design_settings,
    finish_design,
    is_design,
    read_design,
    start_design,
)

__all__ = [
    "DESIGN_FORMAT",
    "DESIGN_GENERATIONS",
    "STUDY",
    "DesignResult",
    "design_settings",
    "finish_design",
    "is_design",
    "read_design",
    "start_design",
]
