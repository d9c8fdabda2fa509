"""A design job's robot docked anew where its search's placement falls short (model §19.3, 19.6).

The search gives each docking a placement, found together with the robot under one budget. When the re-check of a
seed's robot misses a docking (a requirement at the plan's points, or its drilling program blocked between them), the
robot is not necessarily at fault: with the robot fixed, that docking is a six-variable problem of its own, which
:func:`arcube.design_job.dock.solve_docking` solves from several starts (the docking's own placement, every other
docking's carried onto its plan, random placements) and re-checks as the job does. Where it meets everything, the
docking takes that placement; the robot is unchanged.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from arcube.design_job.dock import DOCK_EVALUATIONS, DockingJob
from arcube.design_job.dockings import Docking, warm_starts
from arcube.design_job.outputs import PROGRAM
from arcube.design_job.requirements import Requirement
from arcube.model.robot import BuiltRobot
from arcube.optimization.config import PatientPlan, own_settings
from arcube.optimization.run_config import RunConfig
from arcube.optimization.settings import RunSettings

__all__ = ["DOCK_STARTS", "docking_patient", "redock", "redock_budget"]


def docking_patient(cfg: RunConfig, k: int) -> PatientPlan:
    """The patient of a run's config entry ``k`` (a docking of a design job): its name, its plan as the user gave it,
    and the settings that are its own (anatomy, envelope, ...)."""
    entry = cfg.patients[k]
    spec = cfg.trajectories[entry.get("plan_index", k)]
    own = {key: (tuple(v) if isinstance(v, list) else v) for key, v in own_settings(entry).items()}
    return PatientPlan(str(entry.get("name", f"patient_{k + 1}")), spec, **own)


SMALLEST_JOB = 2000
"""A job of fewer evaluations per seed (a quick look, a test) does not dock its robot anew: its robot is not worth it."""


def redock_budget(s: RunSettings) -> int:
    """The evaluations of one docking searched anew: ``arcube dock``'s own (:data:`~arcube.design_job.dock.DOCK_EVALUATIONS`,
    so that seeds are compared as ``dock`` would find them); 0 (not at all) below :data:`SMALLEST_JOB` evaluations per
    seed."""
    return 0 if s.population * s.generations < SMALLEST_JOB else DOCK_EVALUATIONS


DOCK_STARTS = 8
"""The search runs of one docking searched anew: ``arcube dock``'s default ``--starts``."""


def redock(
    cfg: RunConfig,
    dockings: list[Docking],
    which: Sequence[int],
    folders: Sequence[Path],
    s: RunSettings,
    reqs: Sequence[Requirement],
    seed: int,
    *,
    workers: int = 1,
    dask: str | None = None,
    say: Callable[[str], None] | None = None,
) -> list[int]:
    """Dock the robot anew at the dockings ``which`` (indices into ``dockings``, the entries of ``cfg``), each program
    into its folder of ``folders``; a docking met that way takes the new placement and rows. Returns the indices met."""
    from arcube.design_job.coverage import run_jobs, solve_only

    if not which or redock_budget(s) == 0:
        return []
    starts = warm_starts(dockings)
    jobs = []
    for k in which:
        d = dockings[k]
        robot = BuiltRobot(d.label, d.design, (starts[k], *(w for j, w in enumerate(starts) if j != k)))
        side = d.side if d.side in ("R", "L") else None
        jobs.append(
            DockingJob(
                robot,
                docking_patient(cfg, k),
                side,
                s,
                tuple(reqs),
                int(seed),
                DOCK_STARTS,
                redock_budget(s),
                str(folders[k]),
            )
        )
    if say is not None:
        say(f"docking the robot anew at {', '.join(dockings[k].label for k in which)} (the robot fixed)")
    met = []
    for k, outcome in zip(which, run_jobs(jobs, workers, dask, None, task=solve_only)):
        if outcome.met:
            dockings[k].design, dockings[k].rows, dockings[k].redocked = outcome.design, outcome.rows, True
            dockings[k].eta_G = outcome.eta_G
            met.append(k)
        else:  # the docking keeps its placement and rows; a program built on the way was another placement's
            shutil.rmtree(Path(folders[k]) / PROGRAM, ignore_errors=True)
    return met
