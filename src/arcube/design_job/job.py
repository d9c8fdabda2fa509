"""``arcube design``: from a plan and a segmentation (or a cohort of patients) to one robot that meets every requirement.

One folder holds the job::

    design.toml        the requirements, the seeds, the standoff (what resume needs beside the study)
    study/             one optimization per seed (arcube study): the robot's 22 parameters (c_z among them,
                       model §19.1), each docking's placement m and mounting angles, and the working mode free
    design.json        the robot: the first docking's complete design (27 parameters, c_z, mode: what every
                       command reads) and ``dockings``, each docking's patient, side, m and mounting angles
    dockings/<patient>_<side>/
                       design.json (that docking's complete design), requirements.csv (its own table); with
                       several dockings also report.html, accuracy/, program/ and design.xml (its MuJoCo model)
    summary.json       meets_requirements, mode, seed, the robot, every docking's figures, the requirements
    requirements.csv   each requirement: limit, value, margin, pass/fail, the docking and where it is tightest
    report.html        one docking: the design on the plan with the anatomy (plotly), under the verdict and the
                       requirements; several: every docking of the robot side by side, with its patient
    accuracy/          (one docking) the accuracy budget of the chosen design as built (model §20, class m unless
                       --class): arcube tolerance's folder (tolerance.json, CSVs, pictures)
    program/           (one docking) the drilling program of a design that meets everything (model §17):
                       program.csv, program.json; a design whose program is blocked does not meet the requirements
    design.xml         (one docking) the MuJoCo model (when the z dyad closes)

The dockings (model §19.1) are one per patient and side by default (``dockings per-side``: a plan's R
trajectories one docking, its L ones another), or one per patient. The best seed whose robot meets
every requirement at every docking when **re-evaluated by the NumPy reference**, every docking's
drilling program included (a seed whose program is blocked gives way to the next), is chosen; when
none does, the best robot found is written all the same and :attr:`DesignResult.met` is False (the
CLI exits with code 3 and names what was missed, at which docking).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arcube.design_job.outputs import (
    ACCURACY,
    PROGRAM,
    accuracy_budget,
    breach_check,
    breach_risk,
    closing_c_z,
    docking_evaluation,
)
from arcube.design_job.dockings import (
    PLACEMENT,
    ROBOT_NAMES,
    Docking,
    assess_dockings,
    docking_entry,
    merge_rows,
    run_dockings,
)
from arcube.design_job.choose import (
    DOCKINGS,
    STAGING,
    SeedCheck,
    agreement,
    choose_seed,
    docking_folder,
    judge_seed,
    settle_programs,
)
from arcube.design_job.folder import DESIGN_FORMAT, STUDY, is_design, read_design, read_study_summary
from arcube.design_job.held_out import VALIDATION, check_held_out, coverage_fields, coverage_html, validate
from arcube.design_job.requirements import (
    DOCKING_KEYS,
    PROGRAM_FIGURES,
    Requirement,
    design_settings,
    write_requirements_csv,
)
from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.model.design import Design
from arcube.model.robot import write_docking
from arcube.optimization import run as runmod
from arcube.optimization import study as studymod
from arcube.optimization.config import build_config
from arcube.optimization.run_results import OptimizeResult
from arcube.design_job.summaries import DesignSummary
from arcube.optimization.settings import RunSettings
from arcube.io.json_values import finite

__all__ = [
    "DESIGN_FORMAT",
    "DesignResult",
    "design_settings",
    "finish_design",
    "is_design",
    "read_design",
    "seed_dockings",
    "start_design",
]

DESIGN_GENERATIONS = 100
"""The design job's default budget: population 400 x 100 generations = 40,000 evaluations per seed
(about 2 min on one core for one side of the reference plan; README "arcube design")."""


@dataclass(frozen=True)
class DesignResult:
    """What ``arcube design`` decided: whether the chosen robot meets every requirement at every docking, the
    summary written to summary.json, and the requirement rows (requirements.csv: per requirement, the docking
    where it is tightest)."""

    path: Path
    met: bool
    summary: DesignSummary
    rows: list[dict[str, Any]]

    @property
    def design(self) -> Design:
        """The chosen design at its first docking (design.json, or with several dockings the first one's file)."""
        first = self.summary.get("dockings") or []
        if len(first) > 1:
            return Design.from_json(self.path / DOCKINGS / first[0]["label"] / "design.json")
        return Design.from_json(self.path / "design.json")

    @property
    def dockings(self) -> dict[str, Design]:
        """Each docking's complete design, by ``<patient>_<side>``."""
        return {
            d["label"]: Design.from_json(self.path / DOCKINGS / d["label"] / "design.json")
            for d in self.summary.get("dockings", [])
        }

    @property
    def missed(self) -> list[dict[str, Any]]:
        """The requirement rows that fail (each names its docking)."""
        return [r for r in self.rows if not r["passed"]]


def start_design(
    out: Path,
    plans: Sequence[Any],
    settings: RunSettings,
    reqs: Sequence[Requirement],
    seeds: Sequence[int],
    *,
    workers: int = 1,
    dask: str | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    on_generation: Callable[[dict[str, Any]], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
    validate: str | os.PathLike[str] | None = None,
) -> DesignResult:
    """Run the design job into ``out`` (absent or empty): the study, then the choice and the outputs. ``plans``: the
    trajectory sets, or :class:`~arcube.optimization.config.PatientPlan` (a cohort's patients, named, each with its own
    anatomy and envelope); ``on_stage`` is told each stage after the search (:func:`finish_design`); ``validate``: a
    held-out cohort file (its patients must not share a name with the training ones), docked by the robot chosen."""
    from arcube.design_job.cohort import plans_as_cohort
    from arcube.optimization.config import PatientPlan

    out = Path(out)
    runmod.check_new_folder(out)
    patients = list(plans) if all(isinstance(p, PatientPlan) for p in plans) else plans_as_cohort(list(plans))
    _check_anatomies(patients, settings, reqs)
    on_program = [r.name for r in reqs if r.name in PROGRAM_FIGURES]
    if on_program and settings.setups != 1:
        raise InputError.of(
            "requirements.max",
            f"{', '.join(on_program)}: judged on the drilling program, which a job with one placement "
            "per side (setups 2) does not build; design per side (side R, side L) instead",
        )
    held_out = check_held_out(validate, patients, settings) if validate is not None else None
    base = build_config(
        list(patients), settings.replace(seed=int(seeds[0]))
    )  # validates everything before a file is written
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        meta = {
            "format": DESIGN_FORMAT,
            "format_version": 1,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "seeds": [int(s) for s in seeds],
            "requirements": [[r.name, r.kind, r.limit] for r in reqs],
            **({"validate": held_out} if held_out is not None else {}),
        }
        atomic_write_text(out / "design.toml", runmod.to_toml(meta))
        studymod.start_study(
            out / STUDY, base, list(seeds), workers=workers, dask=dask, on_seed=on_seed, on_generation=on_generation
        )
    except (InputError, Exception):
        if not any((studymod.seed_dir(out / STUDY, int(sd)) / "checkpoint").exists() for sd in seeds):
            runmod.remove_folder(out, created)
        raise
    return finish_design(out, on_stage, workers, dask)


def _check_anatomies(patients: Sequence[Any], settings: RunSettings, reqs: Sequence[Requirement]) -> None:
    """InputError when the clearance requirement has no anatomy to clear (the run's, or a cohort patient's own)."""
    if not any(r.name == "clearance" for r in reqs):
        return
    if settings.anatomy == () and all(p.anatomy is None for p in patients):
        raise InputError.of("anatomy", "is needed by the clearance requirement (default or mesh files); or drop it")
    for p in patients:
        if (p.anatomy if p.anatomy is not None else settings.anatomy) == ():
            raise InputError.of(
                "cohort",
                f"patient {p.name}: anatomy none, but the clearance requirement needs one (give its anatomy, "
                "or drop the clearance requirement)",
            )


def seed_dockings(out: Path, seed: int) -> tuple[OptimizeResult, RunSettings, dict[str, Any], list[Docking]]:
    """One seed of a design folder: its run, settings, summary and dockings (each with the run's design for it, not yet
    re-checked: :func:`~arcube.design_job.dockings.assess_dockings`)."""
    run = OptimizeResult(studymod.seed_dir(Path(out) / STUDY, seed))
    cfg = runmod.read_config(run.path)[0]
    summary = run.summary
    return run, cfg.settings, summary, run_dockings(cfg, run, summary["mode"])


def finish_design(
    out: Path, on_stage: Callable[[str], None] | None = None, workers: int = 1, dask: str | None = None
) -> DesignResult:
    """Choose the robot, re-evaluate every docking with the NumPy reference, build every docking's program and write
    the outputs; ``on_stage`` is told each stage ("checking seed 2 with the NumPy reference", "building the drilling
    program", ...). With a held-out cohort (design.toml's ``validate``), the robot chosen is then docked on it
    (:mod:`arcube.design_job.coverage`, over ``workers`` or ``dask``) into ``validation/``.

    Seed by seed in the study's ranking, the robot is re-checked at every docking; where a docking falls short (at the
    plan's points, or its program blocked), the robot is docked there anew with its parameters fixed
    (:func:`arcube.design_job.redock.redock`). The robot chosen is the first that meets every requirement at every
    docking; when there is none, the one that meets the most dockings (model §19.6: coverage first, then the worst
    met docking's eta_G), its programs built."""
    out = Path(out)
    say = on_stage or (lambda text: None)
    meta, reqs = read_design(out)
    study = read_study_summary(out)
    # feasible seeds by objective, then the others by violation (the study's own ranking): the order of the ties
    order = sorted(
        study["rows"],
        key=lambda r: (
            not r["feasible"],
            r.get(f"objective_{study['objective']}") or math.inf,
            r["violation"],
            r["seed"],
        ),
    )
    shutil.rmtree(out / STAGING, ignore_errors=True)  # an interrupted finish's: built again
    checks = []
    for row in order:
        run, s, summary, dockings = seed_dockings(out, int(row["seed"]))
        check = SeedCheck(row, run, s, summary, dockings, out / STAGING / f"seed_{row['seed']}")
        say(
            f"checking seed {row['seed']}'s robot with the NumPy reference"
            + (f" at {len(dockings)} dockings" if len(dockings) > 1 else "")
        )
        assess_dockings(dockings, reqs, s)
        judge_seed(check, reqs, say, workers, dask)
        checks.append(check)
    chosen = choose_seed(checks)
    settle_programs(out, chosen)
    row, run, s, summary, dockings = chosen.row, chosen.run, chosen.s, chosen.summary, chosen.dockings
    for d in dockings:  # model §22.4: the breach Monte Carlo, on the chosen robot only
        say(
            f"the breach probability of seed {row['seed']}'s robot"
            + (f" at docking {d.label}" if len(dockings) > 1 else "")
        )
        d.breach, breach_rows = breach_check(docking_folder(out, d, dockings), d, s, reqs)
        d.rows = [*d.rows, *breach_rows]
    met = all(d.met for d in dockings)
    held_out = validate(out, meta, dockings, reqs, s, say, workers, dask) if meta.get("validate") else None
    say("writing the report, the accuracy budget (the model, 20) and the MuJoCo model")
    seeds = {"search_verdict_agreement": agreement(checks), "seeds_served": {str(c.seed): c.served for c in checks}}
    return _write_outputs(out, met, int(row["seed"]), run, s, summary, dockings, held_out, seeds)


def _docking_summary(d: Docking) -> dict[str, Any]:
    """One docking's line of summary.json: who, where, met, and the figures of model §19.4's table."""
    rows = {r["requirement"]: r for r in d.rows}

    def value(name: str) -> Any:
        r = rows.get(name)
        return None if r is None or not math.isfinite(r["value"]) else r["value"]

    from arcube.design_job.coverage import binding_fields, docking_verdict

    return {
        **docking_verdict(d.label, d.name, d.side, d.rows),
        "trajectories": list(d.plan.ids),
        **docking_entry(d),
        **{key: value(name) for name, key in DOCKING_KEYS.items()},
        "breach_probability": d.breach.get("breach_probability"),
        **binding_fields(d.rows),
        "folder": f"{DOCKINGS}/{d.label}",
    }


def _worst_breach(dockings: Sequence[Docking]) -> dict[str, Any]:
    """The breach figures (model §22) of the docking where the breach probability is largest, with its name."""
    judged = [d for d in dockings if isinstance(d.breach.get("breach_probability"), float)]
    if not judged:
        return dockings[0].breach
    worst = max(judged, key=lambda d: d.breach["breach_probability"])
    return {**worst.breach, **({} if len(dockings) == 1 else {"docking": worst.label})}


def _write_outputs(
    out: Path,
    met: bool,
    seed: int,
    run: OptimizeResult,
    s: RunSettings,
    summary: dict[str, Any],
    dockings: list[Docking],
    held_out: dict[str, Any] | None = None,
    seeds: dict[str, Any] | None = None,
) -> DesignResult:
    from arcube.export.mjcf import export_mjcf
    from arcube.report import write_report

    first = dockings[0].design
    entries = [docking_entry(d, points=True) for d in dockings]
    full = first.to_file_dict()
    # model §19.1 / issue 30: one docking, its complete design (what every command reads, as before); several, the
    # robot's 22 parameters, its mode and the dockings (each docking's complete design: dockings/<patient>_<side>/design.json)
    robot = full if len(dockings) == 1 else {k: v for k, v in full.items() if k not in PLACEMENT}
    robot = {**robot, "c_z": first.c_z_mm, "dockings": entries}
    atomic_write_text(out / "design.json", json.dumps(robot, indent=2) + "\n")
    from arcube.report.design_job import design_preface

    one = len(dockings) == 1
    evaluations, accuracies, mujoco = [], [], "design.xml"
    for d in dockings:
        folder = docking_folder(out, d, dockings)
        (out / DOCKINGS / d.label).mkdir(parents=True, exist_ok=True)
        write_docking(d.design, out / DOCKINGS / d.label / "design.json", d.name, d.side, d.plan)
        write_requirements_csv(
            out / DOCKINGS / d.label / "requirements.csv", [{**r, "docking": d.label} for r in d.rows]
        )
        ev = docking_evaluation(d, s)
        evaluations.append(ev)
        # the perfect robot's lateral error beside it: the run's figure (one docking), else this docking's requirement row
        perfect = (
            summary.get("lateral_error_max_mm")
            if one
            else next((r["value"] for r in d.rows if r["requirement"] == "lateral_error"), None)
        )
        accuracies.append(
            {
                **accuracy_budget(folder, d.design, d.plan, summary["mode"], s, perfect),
                **({} if one else {"docking": d.label}),
            }
        )
        c_z = d.design.c_z if d.design.c_z is not None else closing_c_z(d.design, d.plan, s, summary)
        try:
            xml = export_mjcf(
                d.design.with_extras(c_z=c_z),  # the design's own c_z, else the one that closes its z dyad
                d.plan,
                points=s.points,
                mode=d.design.mode,
                options=s.options,
                anatomy=d.anatomy,
                envelope=d.envelope,
            )
            atomic_write_text(folder / "design.xml", xml)
        except InputError as exc:  # an open z dyad (a design that misses the z-dyad requirement): the summary says so
            mujoco = f"not written: {exc}" if one else mujoco
        if not one:
            program = folder / PROGRAM if (folder / PROGRAM / "program.json").exists() else None
            mine = {
                **summary,
                "seed": seed,
                "meets_requirements": d.met,
                "accuracy": accuracies[-1],
                "breach": d.breach,
            }
            preface = design_preface(mine, d.rows, d.design, c_z=d.design.c_z, folder=folder)
            write_report(
                ev,
                folder / "report.html",
                program=program,
                preface=preface,
                title=f"AR-CUBE docking: patient {d.name}, side {d.side}",
                risk=breach_risk(d.breach),
            )
    rows = merge_rows(dockings)
    robot_values = {**first.to_dict(), "c_z": first.c_z_mm}
    # the accuracy as built of the docking where it is worst (each docking's own: in its folder's accuracy/)
    accuracy = max(
        accuracies,
        key=lambda a: a.get("lateral_error_p95_mm") if isinstance(a.get("lateral_error_p95_mm"), float) else -math.inf,
    )
    result = {
        "meets_requirements": met,
        "seed": seed,
        "mode": summary["mode"],
        "objective": summary["objectives"][0] if summary.get("objectives") else "eta_G",
        "aggregate": s.aggregate,
        "docking_mode": s.dockings,
        "missed": [r["requirement"] for r in rows if not r["passed"]],
        "missed_at": {r["requirement"]: r["docking"] for r in rows if not r["passed"]},
        "robot": {n: robot_values[n] for n in ROBOT_NAMES},
        "dockings": [_docking_summary(d) for d in dockings],
        "requirements": [{k: v for k, v in r.items()} for r in rows],
        **{k: v for k, v in summary.items() if k not in ("files", "tasks", "objectives", "limits", "resumed")},
        "accuracy": accuracy,
        **coverage_fields(dockings, held_out),
        "breach": _worst_breach(dockings),
        "redocked": [d.label for d in dockings if d.redocked],
        **(seeds or {}),
        "files": {
            "design": "design.json",
            "requirements": "requirements.csv",
            "report": "report.html",
            "study": STUDY,
            "dockings": DOCKINGS,
            **({"validation": VALIDATION, "coverage": "coverage.html"} if held_out is not None else {}),
            **({"mujoco": mujoco} if one else {}),
            **({"accuracy": ACCURACY} if (out / ACCURACY / "tolerance.json").exists() else {}),
            **({"program": PROGRAM} if (out / PROGRAM / "program.json").exists() else {}),
        },
    }
    etas = [ev.summary.get("eta_G") for ev in evaluations]
    if result.get("eta_G") is None and all(isinstance(v, float) and math.isfinite(v) for v in etas):
        # the run's robot missed somewhere and was docked anew (redocked): its eta_G is the NumPy reference's, over the dockings
        result["eta_G"] = max(etas) if s.aggregate != "mean" else sum(etas) / len(etas)
    if one:
        program = out / PROGRAM if (out / PROGRAM / "program.json").exists() else None
        write_report(
            evaluations[0],
            out / "report.html",
            program=program,
            preface=design_preface(result, rows, first, c_z=first.c_z, folder=out),
            risk=breach_risk(dockings[0].breach),
        )
    else:
        from arcube.report.dockings import write_dockings_report

        write_dockings_report(
            out / "report.html",
            dockings,
            evaluations,
            rows,
            met,
            extra=coverage_html(result, held_out),
            accuracies=accuracies,
        )
    if held_out is not None:
        from arcube.report.coverage import write_coverage_report

        write_coverage_report(
            out / "coverage.html", {**result, **result["training"]}, held_out, held_out_link=f"{VALIDATION}/"
        )
    write_requirements_csv(out / "requirements.csv", rows)
    atomic_write_text(out / "summary.json", json.dumps(finite(result), indent=2, allow_nan=False) + "\n")
    return DesignResult(out, met, DesignSummary(result), rows)
