"""``arcube design``: from a plan and a segmentation to a robot that meets every requirement.

One folder holds the job::

    design.toml        the requirements, the seeds, the standoff (what resume needs beside the study)
    study/             one optimization per seed (arcube study), all 27 parameters and the working mode free
    design.json        the chosen design (patient 1's placement; design_p<K>.json for patient K)
    summary.json       meets_requirements, mode (+,+,-,+), seed, every summary figure, the requirements
    requirements.csv   each requirement: limit, value, margin, pass/fail, where it is tightest
    report.html        the design on the plan with the anatomy (plotly)
    accuracy/          the accuracy budget of the chosen design as built (MODEL.md 20, class m unless --class):
                       arcube tolerance's folder (tolerance.json, CSVs, pictures)
    program/           the drilling program of a design that meets everything (MODEL.md 17): program.csv,
                       program.json; a design whose program is blocked does not meet the requirements
    design.xml         the MuJoCo model (when the z dyad closes with some c_z)

The best seed whose design meets every requirement when **re-evaluated by the NumPy reference**,
its drilling program included (a seed whose program is blocked gives way to the next),
is chosen; when none does, the best design found is written all the same and
:attr:`DesignResult.met` is False (the CLI exits with code 3 and names what was missed).
"""

from __future__ import annotations

import json
import math
import re
import shutil
import time
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.io import load_trajectories, select
from arcube.io.files import atomic_write_text
from arcube.model.design import Design
from arcube.model.mechanism import parse_mode
from arcube.optimization import run as runmod
from arcube.optimization import study as studymod
from arcube.optimization.config import build_config
from arcube.design_job.requirements import PROGRAM_FIGURES, Requirement, assess, design_options, program_rows, write_requirements_csv
from arcube.optimization.settings import RunSettings
from arcube.optimization.run_results import OptimizeResult
from arcube.io.json_values import finite

__all__ = ["DESIGN_FORMAT", "DesignResult", "design_settings", "finish_design", "is_design", "start_design"]

DESIGN_FORMAT = "arcube-design"
DESIGN_GENERATIONS = 100
"""The design job's default budget: population 400 x 100 generations = 40,000 evaluations per seed
(about 2 min on one core for one side of the reference plan; README "arcube design")."""
STUDY = "study"
PROGRAM = "program"
ACCURACY = "accuracy"


@dataclass(frozen=True)
class DesignResult:
    """What ``arcube design`` decided: whether the chosen design meets every requirement, the summary
    written to summary.json, and the requirement rows (requirements.csv)."""

    path: Path
    met: bool
    summary: dict[str, Any]
    rows: list[dict[str, Any]]

    @property
    def design(self) -> Design:
        """The chosen design (patient 1's placement)."""
        return Design.from_json(self.path / "design.json")

    @property
    def missed(self) -> list[dict[str, Any]]:
        """The requirement rows that fail."""
        return [r for r in self.rows if not r["passed"]]


def design_settings(reqs: Sequence[Requirement], settings: RunSettings | None = None, **fields: Any) -> RunSettings:
    """The optimization a design job runs: ``settings`` (budget, engine, anatomy, objective ...) with
    every parameter and the working mode free, the guards of 8.2, the clearance guards and the limits
    of ``reqs``, the standoff lines of MODEL.md 17.1 (20 mm unless set) and the envelope of the whole
    patient (MODEL.md 19.5: ``default`` unless set)."""
    from arcube.optimization.config import run_settings

    s = run_settings(settings, **fields)
    if not s.anatomy and any(r.name == "clearance" for r in reqs):  # before the guard below would blame its own field
        raise InputError.of("RunSettings.anatomy", "is needed by the clearance requirement (anatomy default, mesh files or a "
                                                   "segmentation); or drop the clearance requirement")  # fmt: skip
    maxima = {r.name: r.limit for r in reqs if r.kind == "max" and r.name not in PROGRAM_FIGURES}  # the program's: checked after
    options = design_options(reqs, s.options)
    envelope = s.envelope if "envelope" in s.model_fields_set else ("default",)
    if envelope == ("none",) and any(r.name == "envelope_clearance" for r in reqs):
        raise InputError.of("RunSettings.envelope", "is none, but the envelope_clearance requirement needs one (envelope default or a skin "
                                                    "mesh); or drop the requirement")  # fmt: skip
    return s.replace(free=["all", "mount", "L"], mode="free", guards=True, maxima={**s.maxima, **maxima}, options=options,
                     standoff=20.0 if s.standoff is None else s.standoff, envelope=envelope)  # fmt: skip


def is_design(path: Path) -> bool:
    """Whether ``path`` holds a design job (design.toml)."""
    return (Path(path) / "design.toml").is_file()


def start_design(out: Path, plans: Sequence[Any], settings: RunSettings, reqs: Sequence[Requirement], seeds: Sequence[int], *,
                 workers: int = 1, dask: str | None = None, on_seed: Callable[[int, dict[str, Any]], None] | None = None,
                 on_generation: Callable[[dict[str, Any]], None] | None = None, on_stage: Callable[[str], None] | None = None) -> DesignResult:  # fmt: skip
    """Run the design job into ``out`` (absent or empty): the study, then the choice and the outputs
    (``on_stage`` is told each stage after the search, :func:`finish_design`)."""
    out = Path(out)
    runmod.check_new_folder(out)
    if settings.anatomy == () and any(r.name == "clearance" for r in reqs):
        raise InputError.of("anatomy", "is needed by the clearance requirement (default or mesh files); or drop it")
    on_program = [r.name for r in reqs if r.name in PROGRAM_FIGURES]
    if on_program and settings.setups != 1:
        raise InputError.of("requirements.max", f"{', '.join(on_program)}: judged on the drilling program, which a job with one placement "
                                                "per side (setups 2) does not build; design per side (side R, side L) instead")  # fmt: skip
    base = build_config(list(plans), settings.replace(seed=int(seeds[0])))  # validates everything before a file is written
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        meta = {"format": DESIGN_FORMAT, "format_version": 1, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                "seeds": [int(s) for s in seeds], "requirements": [[r.name, r.kind, r.limit] for r in reqs]}  # fmt: skip
        atomic_write_text(out / "design.toml", runmod.to_toml(meta))
        studymod.start_study(out / STUDY, base, list(seeds), workers=workers, dask=dask, on_seed=on_seed, on_generation=on_generation)
    except InputError:
        if not (out / STUDY).exists():
            runmod.remove_folder(out, created)
        raise
    return finish_design(out, on_stage)


def read_design(out: Path) -> tuple[dict[str, Any], list[Requirement]]:
    """design.toml and its requirements (InputError if it is not a design folder)."""
    path = Path(out) / "design.toml"
    try:
        meta = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path}: not a readable design job ({exc})") from None
    if meta.get("format") != DESIGN_FORMAT:
        raise InputError(f"{path}: not an arcube design job")
    return meta, [Requirement(str(n), str(k), float(v)) for n, k, v in meta["requirements"]]


def _patients(cfg: dict[str, Any], run_dir: Path) -> tuple[list[Any], list[Any], tuple[Any, ...]]:
    """Per patient of a run config: its plan (as the run selected it), its anatomy (or None), and the
    envelopes of the whole patient the run recorded (MODEL.md 19.5; () without)."""
    from arcube.optimization.build import run_envelopes

    s = RunSettings.from_config(cfg)
    plans, anatomies = [], []
    for spec, pat in zip(cfg["settings"]["trajectories"], cfg["patients"]):
        ts = load_trajectories(spec, s.transform)
        plans.append(select(ts, ids=",".join(pat["ids"])))
        anatomies.append(resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec, segments=s.segments) if s.anatomy else None)
    return plans, anatomies, run_envelopes(cfg, run_dir)


def finish_design(out: Path, on_stage: Callable[[str], None] | None = None) -> DesignResult:
    """Choose the design, re-evaluate it with the NumPy reference and write the outputs; ``on_stage`` is
    told each stage ("checking seed 2 with the NumPy reference", "building the drilling program", ...)."""
    out = Path(out)
    say = on_stage or (lambda text: None)
    _, reqs = read_design(out)
    study = json.loads((out / STUDY / "summary.json").read_text(encoding="utf-8"))
    # feasible seeds by objective, then the others by violation (the study's own ranking)
    order = sorted(study["rows"], key=lambda r: (not r["feasible"], r.get(f"objective_{study['objective']}") or math.inf, r["violation"], r["seed"]))
    chosen = None
    for row in order:
        run = OptimizeResult(studymod.seed_dir(out / STUDY, int(row["seed"])))
        cfg = runmod.read_config(run.path)[0]
        s = RunSettings.from_config(cfg)
        plans, anatomies, envelopes = _patients(cfg, run.path)
        summary = run.summary
        designs = [d.to_vector() for d in run.designs]
        say(f"checking seed {row['seed']}'s design with the NumPy reference")
        rows = assess(designs, parse_mode(summary["mode"]), plans, anatomies, reqs, options=s.evaluation_options(), envelopes=envelopes,
                      points=s.points, standoff_mm=float(s.standoff or 0.0), accuracy=s.accuracy_settings())  # fmt: skip
        met = bool(row["feasible"] and all(r["passed"] for r in rows))
        if met and s.setups == 1:  # with one placement per side (--setups 2), program each side with arcube program
            say(f"building the drilling program of seed {row['seed']}'s design")
            built = _program_rows(out, run.designs[0], plans[0], anatomies[0], summary["mode"], s, reqs, envelopes[0] if envelopes else None)
            rows = [*rows, *built]
            met = all(r["passed"] for r in built)
        if chosen is None or (met and not chosen[-1]):
            chosen = (row, run, cfg, s, plans, anatomies, envelopes, summary, rows, met)
        if met or not row["feasible"]:
            break  # met; or the infeasible seeds after the first cannot do better than the best one
        # a seed met at the sampled points whose program is blocked (a failed build writes nothing): try the next
    assert chosen is not None
    row, run, cfg, s, plans, anatomies, envelopes, summary, rows, met = chosen
    say("writing the report, the accuracy budget (MODEL.md 20) and the MuJoCo model")
    return _write_outputs(out, met, int(row["seed"]), run, cfg, s, plans, anatomies, summary, rows, envelopes)


def _program_rows(out: Path, design: Design, plan: Any, anatomy: Any, mode: str, s: RunSettings, reqs: Sequence[Requirement],
                  envelope: Any = None) -> list[dict[str, Any]]:  # fmt: skip
    """Build the drilling program of the chosen design (MODEL.md 17, patient 1) into ``out/program`` with
    the design's clearances and standoff; its requirement rows: the program (met, or the blocked segment
    named), then ``torque_peak`` / ``power_peak`` when required (MODEL.md 18.3, from its motor figures)."""
    from arcube.motion import program
    from arcube.report.program import timeline_png

    # a dropped clearance requirement leaves no margin, but a program never passes through the patient or itself
    limits = {"clearance": 0.0, "self_clearance": 0.0, "envelope_clearance": 0.0,
              **{r.name: r.limit for r in reqs if r.name in ("clearance", "self_clearance", "envelope_clearance")}}  # fmt: skip
    shutil.rmtree(out / PROGRAM, ignore_errors=True)  # ours: a resumed job (or the next seed tried) builds it again
    started = time.perf_counter()
    row: dict[str, Any] = {"requirement": "program", "kind": "min", "limit": 1.0, "unit": "feasible", "where": {}, "part": ""}
    try:
        prog = program(design, plan, out / PROGRAM, options=s.options, anatomy=anatomy, envelope=envelope, mode=mode, standoff_mm=float(s.standoff or 0.0),
                       masses=True, **limits)  # fmt: skip
        timeline_png(prog, out / PROGRAM / "program.png")
    except InputError as exc:
        return [{**row, "value": 0.0, "margin": -1.0, "passed": False, "part": str(exc)}, *program_rows(reqs, None)]
    summary = prog.summary
    built = {**row, "value": 1.0, "margin": 0.0, "passed": True, "part": f"total {summary['total_s']:.1f} s, built in {time.perf_counter() - started:.0f} s"}
    return [built, *program_rows(reqs, summary.get("motors"))]


def _write_outputs(out: Path, met: bool, seed: int, run: OptimizeResult, cfg: dict[str, Any], s: RunSettings, plans: list[Any],
                   anatomies: list[Any], summary: dict[str, Any], rows: list[dict[str, Any]], envelopes: tuple[Any, ...] = ()) -> DesignResult:  # fmt: skip
    from arcube.evaluation.result import evaluate_design
    from arcube.export.mjcf import export_mjcf
    from arcube.report import write_report

    designs = run.designs
    designs[0].with_extras(mode=summary["mode"]).to_json(out / "design.json")  # a design file records its working mode
    for k, d in enumerate(designs[1:], start=2):
        d.to_json(out / f"design_p{k}.json")
    options = s.evaluation_options()
    options = options.replace(outputs=options.outputs.replace(clearances=True, tip_metrics=True, clearance_min_exact=True))
    ev = evaluate_design(designs[0], plans[0], s.points, parse_mode(summary["mode"]), options, "numpy", anatomy=anatomies[0],
                         envelope=envelopes[0] if envelopes else None)  # fmt: skip
    accuracy = _accuracy_budget(out, designs[0], plans[0], summary, s)
    mujoco = "design.xml"
    try:
        xml = export_mjcf(designs[0], plans[0], points=s.points, mode=summary["mode"], c_z=_closing_c_z(designs[0], plans[0], s, summary),
                          radii=s.options.radii, anatomy=anatomies[0], masses=s.options)  # fmt: skip
        atomic_write_text(out / mujoco, xml)
    except InputError as exc:
        mujoco = f"not written: {exc}"
    result = {
        "meets_requirements": met, "seed": seed, "mode": summary["mode"], "objective": summary["objectives"][0] if summary.get("objectives") else "eta_G",
        "missed": [r["requirement"] for r in rows if not r["passed"]],
        "requirements": [{k: v for k, v in r.items()} for r in rows],
        **{k: v for k, v in summary.items() if k not in ("files", "tasks", "objectives", "limits", "resumed")},
        "accuracy": accuracy,
        "files": {"design": "design.json", "requirements": "requirements.csv", "report": "report.html", "mujoco": mujoco, "study": STUDY,
                  **({"accuracy": ACCURACY} if (out / ACCURACY / "tolerance.json").exists() else {}),
                  **({"program": PROGRAM} if (out / PROGRAM / "program.json").exists() else {})},
    }  # fmt: skip
    from arcube.report.design_job import design_preface

    write_report(ev, out / "report.html", preface=design_preface(result, rows, designs[0], c_z=_design_c_z(out), folder=out))
    write_requirements_csv(out / "requirements.csv", rows)
    atomic_write_text(out / "summary.json", json.dumps(finite(result), indent=2, allow_nan=False) + "\n")
    return DesignResult(out, met, result, rows)


def _accuracy_budget(out: Path, design: Design, plan: Any, summary: dict[str, Any], s: RunSettings) -> dict[str, Any]:
    """The accuracy budget of the chosen design as built (MODEL.md 20, class ``s.tolerance_class``, m by default)
    on patient 1's plan, written to ``out/accuracy`` (arcube tolerance's folder); its figures for summary.json,
    beside the perfect robot's ``lateral_error`` (MODEL.md 15.2) so that figure never stands alone."""
    from arcube.accuracy import budget
    from arcube.evaluation.task import build_task
    from arcube.report.accuracy import write_budget

    shutil.rmtree(out / ACCURACY, ignore_errors=True)  # ours: a resumed job writes it again
    settings = s.accuracy_settings()
    task = build_task(plan.entry, plan.target, s.points, tuple(plan.ids))
    try:
        result = budget(design, task.E, task.e, summary["mode"], settings, [task.ids[i] for i in task.trajectory], task.k)
    except InputError as exc:
        return {"tolerance_class": settings.tolerance_class, "not_computed": str(exc)}
    write_budget(result, out / ACCURACY)
    return {"tolerance_class": settings.tolerance_class, "robots": settings.samples, "seed": settings.seed, **result.summary,
            "perfect_robot_lateral_error_mm": summary.get("lateral_error_max_mm"),
            "tighten_first": [{"source": n, "tolerance": t, "unit": u, "share": v} for n, t, u, v in result.ranked_sources()[:3]]}  # fmt: skip


def _design_c_z(out: Path) -> float | None:
    """The c_z design.json records (the z dyad's second link, MODEL.md 19), or None."""
    try:
        return Design.from_json(out / "design.json").c_z
    except (InputError, OSError):
        return None



def _closing_c_z(design: Design, plan: Any, s: RunSettings, summary: dict[str, Any]) -> float | None:
    """A z-dyad link c_z that closes the dyad at every point (the middle of the range the export names), or None (c_z = d_z)."""
    from arcube.export.mjcf import export_mjcf

    try:
        export_mjcf(design, plan, points=s.points, mode=summary["mode"])
        return None
    except InputError as exc:
        found = re.search(r"c_z in \[([0-9.eE+-]+), ([0-9.eE+-]+)\]", str(exc))
        if not found:
            raise
        lo, hi = float(found.group(1)), float(found.group(2))
        return 0.5 * (lo + hi)
