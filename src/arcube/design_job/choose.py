"""The design job's robot, chosen among its seeds by what it serves (model §19.6).

Every seed's robot is re-checked by the NumPy reference at every docking, first at the search's own placements: that
verdict beside the search's (each docking's violation V_k in the run's summary, model §19.3) gives the job's
``search_verdict_agreement``, met by the re-check over feasible in the search, over every docking of every seed. Then
every docking the re-check refuses is docked anew as ``arcube dock`` does it (the robot fixed, ``dock``'s budget and
starts: :mod:`arcube.design_job.redock`), and every docking met at the plan's points gets its drilling program, so that
the seeds are compared as ``dock`` would find them. The robot kept serves the most dockings, then has the smallest
worst eta_G over the dockings it serves, then comes first in the study's ranking (feasible seeds by objective).

Each seed's programs are built in a staging folder of its own (``.seeds/seed_<N>/``, the layout of the job's folder);
the chosen seed's are moved into place and the staging folder removed.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arcube.design_job.dockings import Docking
from arcube.design_job.outputs import PROGRAM, build_program
from arcube.design_job.requirements import PROGRAM_FIGURES, Requirement
from arcube.optimization import run as runmod
from arcube.optimization.run_results import OptimizeResult
from arcube.optimization.settings import RunSettings

__all__ = ["DOCKINGS", "STAGING", "SeedCheck", "agreement", "choose_seed", "docking_folder", "judge_seed"]

DOCKINGS = "dockings"
STAGING = ".seeds"
"""Where each seed's drilling programs are built before one seed is chosen (removed once the job's outputs are written)."""


def docking_folder(root: Path, d: Docking, dockings: Sequence[Docking]) -> Path:
    """Where a docking's program, accuracy budget, report and MuJoCo model go under ``root``: ``root`` itself when it is
    the only docking (the layout of a one-docking job, as before model §19), else ``root/dockings/<patient>_<side>``."""
    return root if len(dockings) == 1 else root / DOCKINGS / d.label


@dataclass
class SeedCheck:
    """One seed of the job, re-checked: its study row, run, settings, run summary, dockings, and where its programs are."""

    row: dict[str, Any]
    run: OptimizeResult
    s: RunSettings
    summary: dict[str, Any]
    dockings: list[Docking]
    root: Path
    """The folder its dockings' programs are built under (:func:`docking_folder`)."""

    @property
    def seed(self) -> int:
        return int(self.row["seed"])

    @property
    def served(self) -> int:
        """The dockings it meets (every requirement, the program included), its placements docked anew where needed."""
        return sum(d.met for d in self.dockings)

    @property
    def worst_eta(self) -> float:
        """The largest eta_G over the dockings it serves (+inf when it serves none)."""
        etas = [d.eta_G if d.eta_G is not None and math.isfinite(d.eta_G) else math.inf for d in self.dockings if d.met]
        return max(etas) if etas else math.inf


def search_feasible(summary: dict[str, Any], n: int) -> list[bool]:
    """Whether the search called each of a run's ``n`` dockings feasible: its own violation V_k is 0 (runs before this
    field: every docking as the run's best design, feasible or not)."""
    each = summary.get("docking_violations")
    if isinstance(each, list) and len(each) == n:
        return [v == 0.0 for v in each]
    return [bool(summary.get("feasible"))] * n


def _search_etas(summary: dict[str, Any], dockings: Sequence[Docking]) -> None:
    """Each docking's eta_G as the search left it (its plan's task in the run's summary)."""
    tasks = {t["label"]: t.get("eta_G") for t in summary.get("tasks", [])}
    for d in dockings:
        v = tasks.get(f"{d.name} {d.side}")
        d.eta_G = float(v) if isinstance(v, (int, float)) else None


def judge_seed(
    check: SeedCheck,
    reqs: Sequence[Requirement],
    say: Callable[[str], None],
    workers: int,
    dask: str | None,
) -> None:
    """Re-check a seed whose dockings' rows hold the re-check at the search's placements: record that verdict
    (:attr:`Docking.met_at_search`), dock anew where it misses, build the programs, dock anew where a program is blocked."""
    from arcube.design_job.redock import redock

    dockings, s = check.dockings, check.s
    _search_etas(check.summary, dockings)
    for d, ok in zip(dockings, search_feasible(check.summary, len(dockings))):
        d.search_feasible = ok
    if s.setups != 1:  # one placement per side (--setups 2): programmed by arcube program, not here
        for d in dockings:
            d.met_at_search = d.met
        return
    cfg = runmod.read_config(check.run.path)[0]
    folders = [docking_folder(check.root, d, dockings) for d in dockings]
    for d in dockings:
        if not d.met:
            d.met_at_search = False
    redone = set(
        redock(
            cfg,
            dockings,
            [k for k, d in enumerate(dockings) if not d.met],
            folders,
            s,
            reqs,
            check.seed,
            workers=workers,
            dask=dask,
            say=say,
        )  # fmt: skip
    )
    for k, d in enumerate(dockings):
        if d.met and k not in redone:
            programs(check, reqs, say, [d])
            if d.met_at_search is None:
                d.met_at_search = d.met
    blocked = {k: d.rows for k, d in enumerate(dockings) if not d.met and k not in redone and _at_points(d)}
    for k in blocked:
        dockings[k].rows = [r for r in dockings[k].rows if r["requirement"] not in ("program", *PROGRAM_FIGURES)]
    again = redock(cfg, dockings, list(blocked), folders, s, reqs, check.seed, workers=workers, dask=dask, say=say)
    for k, rows in blocked.items():
        if k not in again:
            dockings[k].rows = rows  # its own placement: met at the plan's points, its program blocked


def _at_points(d: Docking) -> bool:
    """Met at the plan's points and approach lines: every row but the program's passes."""
    return all(r["passed"] for r in d.rows if r["requirement"] not in ("program", *PROGRAM_FIGURES))


def programs(
    check: SeedCheck, reqs: Sequence[Requirement], say: Callable[[str], None], which: Sequence[Docking]
) -> None:
    """Build the drilling program of the dockings ``which`` of a seed (their rows gain the program's)."""
    for d in which:
        say(
            f"building the drilling program of seed {check.seed}'s robot"
            + (f" at docking {d.label}" if len(check.dockings) > 1 else "")
        )
        d.rows = [*d.rows, *build_program(docking_folder(check.root, d, check.dockings), d, check.s, reqs)]


def agreement(checks: Sequence[SeedCheck]) -> float | None:
    """``search_verdict_agreement``: of the dockings the search called feasible (every docking of every seed), the
    fraction the re-check met at the search's own placement; None when the search called none feasible."""
    pairs = [(d.search_feasible, d.met_at_search) for c in checks for d in c.dockings]
    feasible = [bool(met) for ok, met in pairs if ok]
    return sum(feasible) / len(feasible) if feasible else None


def choose_seed(checks: Sequence[SeedCheck]) -> SeedCheck:
    """The seed kept: the most dockings served, then the smallest worst eta_G over them, then the study's ranking
    (``checks`` in that order)."""
    return min(enumerate(checks), key=lambda ic: (-ic[1].served, ic[1].worst_eta, ic[0]))[1]


def settle_programs(out: Path, chosen: SeedCheck) -> None:
    """Move the chosen seed's programs from its staging folder into the job's folders; remove the staging folder."""
    for d in chosen.dockings:
        final = docking_folder(out, d, chosen.dockings) / PROGRAM
        shutil.rmtree(final, ignore_errors=True)
        staged = docking_folder(chosen.root, d, chosen.dockings) / PROGRAM
        if staged.exists():
            final.parent.mkdir(parents=True, exist_ok=True)
            staged.rename(final)
    shutil.rmtree(out / STAGING, ignore_errors=True)
