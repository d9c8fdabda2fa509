"""The HTML report of an optimization run folder (``arcube report RUN_DIR``).

What is read (everything defensively: the run format belongs to :mod:`arcube.optimization.run`):

* ``config.toml`` (required):
  - ``[[patients]]``: the exact trajectories the run optimized on (``source``, ``ids``,
    ``levels``, ``sides``, ``entry`` and ``target`` as lists of [x, y, z] mm). Each patient is
    reported: the first in ``report.html``, patient k in ``report_p<k>.html``, with its own design
    ``best_design_p<k>.json`` when the run docked per patient. Without it, ``settings.trajectories[0]`` is reloaded with the subset flags
    ``settings.side`` / ``levels`` / ``ids`` / ``transform``;
  - ``[settings]``: ``points`` (default 30), ``mode`` (signs, or ``"free"``: then the mode the
    optimizer picked, ``summary.json`` ``mode``), ``guarded`` (bool; ``guards`` in a folder of before), ``setups`` (1 or 2) and
    whatever else is shown in the run table;
* ``best_design.json`` (required; :meth:`arcube.model.design.Design.from_json`). With ``setups = 2``
  it is the right-side placement and ``best_design_L.json`` the left one: the main report covers
  the R trajectories and a second report ``report_L.html`` the L ones;
* ``history.csv`` (optional): columns generation, best_eta_G, mean_eta_G, feasible_fraction
  (:func:`arcube.report.figures.read_history`); missing -> no convergence plot, and a note;
  present but damaged (binary, a row wider than the header, text where a number belongs) -> InputError;
* ``summary.json`` (optional): shown in the run table;
* ``program/`` (optional): a drilling program of the first patient's design (program.csv,
  program.json), shown in ``report.html`` (:mod:`arcube.report.program_html`).

The design is re-evaluated here with the numpy reference engine (same numbers as the run's
engine, no JIT warm-up).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from arcube.coerce import check_best_known
from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.model.design import Design
from arcube.errors import InputError
from arcube.evaluation.result import evaluate_design
from arcube.options import GUARDED_OPTIONS, Options
from arcube.model.mechanism import parse_mode
from arcube.optimization.checkpoint import read_run_file
from arcube.optimization.folder import read_toml
from arcube.optimization.settings import table_placement
from arcube.report.figures import read_history
from arcube.report.html import write_evaluation_report
from arcube.request import with_design_c_z
from arcube.io import TrajectorySet, load_trajectories, select


def _read_toml(path: Path) -> dict[str, Any]:
    if not os.path.lexists(path):
        raise InputError(f"{path.parent}: not an optimization run (no config.toml)")
    return read_toml(path)[0]  # a regular file only: a FIFO put in its place is refused, not waited on


def _read_json(path: Path) -> dict[str, Any]:
    """summary.json as a dict; {} when absent (a run not finished); InputError when it is there but damaged."""
    if not os.path.lexists(path):
        return {}
    try:
        data = json.loads(read_run_file(path).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: damaged ({exc}); restore it, or delete it for a report without it") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: damaged (not a JSON object); restore it, or delete it for a report without it")
    return data


def _trajectories(cfg: dict[str, Any], settings: dict[str, Any], where: Path, index: int = 0) -> TrajectorySet:
    """Patient ``index``'s trajectories, as stored in the config (or the first one reloaded from its spec)."""
    patients = cfg.get("patients")
    try:
        if isinstance(patients, list) and patients:
            pat = patients[index]
            ids = [str(i) for i in pat["ids"]]
            n = len(ids)
            return TrajectorySet(
                ids=tuple(ids),
                levels=tuple(pat.get("levels", [""] * n)),
                sides=tuple(pat.get("sides", [""] * n)),
                entry=np.asarray(pat["entry"], float),
                target=np.asarray(pat["target"], float),
                source=str(pat.get("source", "run")),
            )
        specs = settings.get("trajectories") or []
        spec = specs[0] if isinstance(specs, list) and specs else specs
        if not spec:
            raise KeyError("patients / settings.trajectories")
        ts = load_trajectories(str(spec), transform=settings.get("transform"))
        subset = {k: settings.get(k) for k in ("side", "levels", "ids")}
        return select(ts, **subset) if any(v is not None for v in subset.values()) else ts
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{where}: cannot read the run's trajectories ({type(exc).__name__}: {exc})") from None


def _mode(settings: dict[str, Any], summary: dict[str, Any], where: Path, chosen: str | None = None) -> np.ndarray:
    """The run's working mode: config.toml's, or with ``free`` the one the optimizer chose (summary.json's, else
    the best design file's ``chosen``)."""
    text = str(settings.get("mode", DEFAULT_MODE_TEXT))
    if text.strip().lower() == "free":
        text = str(summary.get("mode") or chosen or "")
        if not text:
            raise InputError(
                f"{where}: the run chose its working mode (mode free), and neither summary.json nor best_design.json "
                "records it"
            )
    try:
        return parse_mode(text)
    except ValueError as exc:
        raise InputError(f"{where}: mode: {exc}") from None


def _run_info(cfg: dict[str, Any], settings: dict[str, Any], summary: dict[str, Any]) -> dict[str, Any]:
    info: dict[str, Any] = {"run_id": cfg.get("run_id"), "created": cfg.get("created")}
    for key in (
        "algorithm",
        "population",
        "generations",
        "seed",
        "points",
        "mode",
        "guarded",
        "guards",  # a folder's before 0.3
        "setups",
        "aggregate",
        "engine_resolved",
    ):
        if key in settings:
            info[key] = settings[key]
    if "free" in settings:
        info["free variables"] = ", ".join(settings["free"]) if len(settings["free"]) < 23 else "all 23"
    for key in (
        "generations",
        "evaluations",
        "stopped_by",
        "feasible",
        "eta_G",
        "wall_s",
        "links_sum_mm",
        "bbox_volume_L",
    ):
        if key in summary:
            info[f"result: {key}"] = summary[key]
    if "rerun" in cfg:
        info["rerun"] = cfg["rerun"]
    return {k: v for k, v in info.items() if v is not None}


def write_run_report(
    run_dir: str | os.PathLike[str], anatomy: Any = None, best_known: float | None = None, anatomy_frame: str = "LPS"
) -> Path:
    """Write ``run_dir/report.html`` (and its PNGs) for an optimization run; returns its path.

    ``anatomy``: None (the run's own, copied into its folder); an :class:`~arcube.evaluation.anatomy.Anatomy`
    or ``"none"``, or a list of those, one per patient; or what :func:`arcube.evaluate` takes
    (``"default"``, mesh files in ``anatomy_frame``), resolved for each patient's plan.
    ``best_known``: an eta_G drawn as a reference line on the convergence plot.
    Raises :class:`InputError` (one line) when the folder is not a readable run.
    """
    run = Path(run_dir)
    if not run.is_dir():
        raise InputError(f"{run}: no such run folder")
    cfg = _read_toml(run / "config.toml")
    settings = cfg.get("settings") if isinstance(cfg.get("settings"), dict) else {}
    summary = _read_json(run / "summary.json")
    if not (run / "best_design.json").exists():
        raise InputError(f"{run}: no best_design.json yet (the run has not written its result)")
    best = Design.from_json(run / "best_design.json")  # a bad design file stops the report before any work
    try:
        points = int(settings.get("points", 30))
    except (TypeError, ValueError):
        raise InputError(f"{run / 'config.toml'}: settings.points is not an integer") from None
    if points < 2:
        raise InputError(f"{run / 'config.toml'}: settings.points must be at least 2, got {points}")
    check_best_known(best_known)
    signs = _mode(settings, summary, run / "config.toml", best.mode)
    options, _, limits = _run_body(run, settings)
    # the run's own engine: a design the optimizer left on a clearance limit is judged by the same search
    engine = _run_engine(settings)
    info = _run_info(cfg, settings, summary)
    n_patients = len(cfg["patients"]) if isinstance(cfg.get("patients"), list) and cfg["patients"] else 1
    if n_patients > 1:
        info["note: patients"] = (
            f"{n_patients} patients in the run: this report shows the first; report_p2.html ... the others"
            + (", each with its own placement (per-patient docking)" if (run / "best_design_p2.json").exists() else "")
        )
    history: Path | None = run / "history.csv"
    if not history.exists():  # type: ignore[union-attr]
        info["note: history"] = "no convergence plot (the run folder has no history.csv)"
        history = None
    else:  # a damaged history is a damaged run folder: said, not drawn around
        try:
            read_history(history)  # type: ignore[arg-type]
        except InputError as exc:
            raise InputError(
                f"{exc} (a damaged run folder: restore history.csv, or delete it for a report without the convergence plot)"
            ) from None
    two_sides = settings.get("setups") == 2 and (run / "best_design_L.json").exists()  # per-patient runs write it too
    if two_sides:
        info["note: setups"] = "two placements: this report covers the R trajectories; report_L.html the L ones"
    if anatomy is not None and not (
        isinstance(anatomy, (list, tuple)) and anatomy and not isinstance(anatomy[0], (str, os.PathLike))
    ):
        if not (isinstance(anatomy, str) and anatomy == "none"):
            from arcube.evaluation.anatomy import resolve_anatomy

            plans = settings.get("trajectories") or ["reference"]
            anatomy = [resolve_anatomy(anatomy, anatomy_frame, plan) or "none" for plan in plans]  # each patient's own
    pareto = run / "pareto.csv"
    main = run / "report.html"
    program = (
        run / "program" if (run / "program" / "program.json").is_file() else None
    )  # the first patient's (a design job's)
    for i in range(n_patients):
        ts = _trajectories(cfg, settings, run / "config.toml", i)
        stem = "report" if i == 0 else f"report_p{i + 1}"
        given = anatomy[min(i, len(anatomy) - 1)] if isinstance(anatomy, (list, tuple)) else anatomy
        patient_anatomy = (
            _run_anatomy(run, settings, i) if given is None else (None if isinstance(given, str) else given)
        )
        sides = [("R", ""), ("L", "_L")] if two_sides else [(None, "")]
        per_patient = table_placement(settings) == "per-patient" and n_patients > 1
        for side, suffix in sides:
            path = run / (f"best_design_p{i + 1}{suffix}.json" if per_patient else f"best_design{suffix}.json")
            if not path.exists():
                raise InputError(f"{run}: {path.name} is missing (the run's design for patient {i + 1})")
            design = _with_run_c_z(Design.from_json(path), settings, run / "config.toml")
            plan = select(ts, side=side) if side else ts
            patient_info = info if i == 0 else {**info, "patient": f"{i + 1} of {n_patients} ({ts.source})"}
            mine = with_design_c_z(options, design)  # the design's c_z (model §19.1), as arcube evaluate takes it
            write_evaluation_report(
                evaluate_design(design, plan, points, signs, mine, engine, anatomy=patient_anatomy),
                run / f"{stem}{suffix}.html",
                history_csv=history,
                run_info=patient_info,
                pareto_csv=pareto if pareto.exists() and i == 0 and not suffix else None,
                limits=limits,
                best_known=best_known,
                program=program if i == 0 and not suffix else None,
            )
    return main


def _with_run_c_z(design: Design, settings: dict[str, Any], where: Path) -> Design:
    """``design`` with the run's ``c_z`` when its file has none: a run written before c_z was the design's alone
    recorded ``--c-z`` in ``[settings]`` only (a run now writes it in its designs too)."""
    c_z = settings.get("c_z")
    if design.c_z is not None or c_z is None:
        return design
    try:
        return design.with_extras(c_z=float(c_z))
    except (InputError, TypeError, ValueError):
        raise InputError(f"{where}: settings.c_z is not a length in mm ({c_z!r})") from None


def _run_engine(settings: dict[str, Any]) -> str:
    """The run's own engine when this machine has it, else the NumPy reference."""
    from arcube.optimization.build import check_engine

    if settings.get("engine_resolved") != "numba":
        return "numpy"
    try:
        return check_engine("numba")
    except InputError:
        return "numpy"


def _run_body(run: Path, settings: dict[str, Any]) -> tuple[Options, Any, dict[str, float]]:
    """The run's evaluation options (guards, clearance guards, body radii, loads; body on), its first
    patient's anatomy (the copy in the run folder) and its --max / --min limits by name."""
    from arcube.optimization.settings import RunSettings

    guarded = settings.get("guarded", settings.get("guards")) is True  # guards: its key before 0.3
    try:
        table = {k: v for k, v in settings.items() if k != "guards"}
        options = RunSettings.from_table({**table, "guarded": guarded}).evaluation_options()
        options = options.replace(outputs=options.outputs.replace(clearances=True, tip_metrics=True))
    except (InputError, TypeError, ValueError):  # a hand-edited or older config: the guards alone
        options = GUARDED_OPTIONS if guarded else Options()
    limits = {
        str(lim[0]): float(lim[2]) for lim in settings.get("limits", []) if isinstance(lim, list) and len(lim) == 3
    }
    return options, _run_anatomy(run, settings, 0), limits


def _run_anatomy(run: Path, settings: dict[str, Any], index: int) -> Any:
    """Patient ``index``'s anatomy as the run copied it into its folder (None without one)."""
    from arcube.optimization.build import anatomy_file

    path = run / anatomy_file(index)
    if not (settings.get("anatomy") and path.exists()):
        return None
    from arcube.evaluation.anatomy import Anatomy
    from arcube.io.meshes import read_meshes

    return Anatomy.from_meshes(read_meshes([path], "patient"), str(path))
