"""The design job's held-out cohort (model §19.6): checked before the search, docked by the robot chosen after it,
and the coverage of the training and held-out dockings in summary.json and the report."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from arcube.design_job.dockings import Docking, warm_starts
from arcube.design_job.requirements import Requirement
from arcube.errors import InputError
from arcube.optimization.settings import RunSettings

__all__ = ["VALIDATION", "check_held_out", "coverage_html", "coverage_fields", "validate"]

VALIDATION = "validation"
"""The folder of a design job where the held-out cohort's dockings go (``arcube dock``'s folder)."""


def check_held_out(validate: str | os.PathLike[str], patients: Sequence[Any], settings: RunSettings) -> str:
    """The held-out cohort file's absolute path, after reading it whole; InputError naming it when one of its patients
    has a training patient's name (a held-out patient is one the search never sees)."""
    from arcube.design_job.cohort import plan_key, read_cohort
    from arcube.io import load_trajectories

    held = read_cohort(
        validate,
        side=settings.side,
        levels=settings.levels,
        ids=settings.ids,
        transform=settings.transform,
        what="validate",
    )
    training = {p.name for p in patients}
    shared = [p.name for p in held if p.name in training]
    if shared:
        raise InputError.of(
            "validate",
            f"{validate}: patient {shared[0]!r} is also in the training cohort; a held-out patient is one the "
            "search never sees (leave it out of one of the cohorts)",
        )
    trained = {plan_key(load_trajectories(p.plan, settings.transform)): p.name for p in patients}
    for p in held:
        twin = trained.get(plan_key(load_trajectories(p.plan, settings.transform)))
        if twin is not None:
            raise InputError.of(
                "validate",
                f"{validate}: patient {p.name!r} has the trajectories of training patient {twin!r} (every entry and "
                "target); a held-out patient is one the search never sees (leave it out of one of the cohorts)",
            )
    return str(Path(validate).resolve())


def validate(
    out: Path,
    meta: dict[str, Any],
    dockings: Sequence[Docking],
    reqs: Sequence[Requirement],
    s: RunSettings,
    say: Callable[[str], None],
    workers: int,
    dask: str | None,
) -> dict[str, Any]:
    """Dock the chosen robot on the held-out cohort (model §19.6), which the search never saw, into ``validation/``
    (``arcube dock``'s folder); its summary."""
    from arcube.design_job.cohort import read_cohort
    from arcube.design_job.coverage import dock_patients
    from arcube.design_job.dock import DOCK_EVALUATIONS
    from arcube.model.robot import BuiltRobot

    patients = read_cohort(meta["validate"], side=s.side, levels=s.levels, ids=s.ids, transform=s.transform)
    robot = BuiltRobot(str(out / "design.json"), dockings[0].design, warm_starts(dockings))
    folder = out / VALIDATION
    shutil.rmtree(folder, ignore_errors=True)  # ours: a resumed job docks again
    say(f"docking the robot on the {len(patients)} held-out patients (never seen by the search)")
    done: list[bool] = []

    def progress(outcome: Any) -> None:
        done.append(outcome.met)
        say(
            f"held out: {sum(done)} of {len(done)} sides served; {outcome.label} {'served' if outcome.met else 'not served'}"
        )

    return dock_patients(
        robot,
        patients,
        folder,
        s,
        reqs,
        seed=int(meta["seeds"][0]),
        evaluations=DOCK_EVALUATIONS,
        workers=workers,
        dask=dask,
        on_docking=progress,
    ).summary


def coverage_fields(dockings: Sequence[Docking], held_out: dict[str, Any] | None) -> dict[str, Any]:
    """summary.json's coverage (model §19.6): ``training`` (the dockings the robot was designed on, met / all, with the
    95 % Wilson interval) and, with a held-out cohort, ``held_out`` (its docking's figures)."""
    from arcube.design_job.coverage import wilson

    keys = ("coverage", "coverage_low", "coverage_high", "sides", "met")
    met = sum(d.met for d in dockings)
    training = dict(zip(keys, (*wilson(met, len(dockings)), len(dockings), met)))
    return {"training": training, **({"held_out": {k: held_out[k] for k in keys}} if held_out is not None else {})}


def coverage_html(result: dict[str, Any], held_out: dict[str, Any] | None) -> str:
    """The coverage section of the dockings report: training (and held-out) coverage and the map of the sides."""
    from arcube.report.coverage import coverage_section

    return coverage_section({**result, **result["training"]}, held_out, held_out_link=f"{VALIDATION}/")
