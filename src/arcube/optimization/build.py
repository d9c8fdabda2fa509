"""From a run's config to its fitness model: options, anatomy, tasks (the same for a new run, a
resume, an in-memory run and a report)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube import interrupts
from arcube.errors import InputError
from arcube.coerce import engine_name, mode_signs
from arcube.evaluation.task import build_task
from arcube.io.trajectories import validate_points
from arcube.model.design import PARAM_NAMES
from arcube.optimization.problem import DEFAULT_BOUNDS, FitnessModel, TaskData, VariableSpace
from arcube.optimization.settings import RunSettings

if TYPE_CHECKING:
    from arcube.optimization.run_config import RunConfig

__all__ = ["ANATOMY_FILES", "anatomy_file", "build_model", "check_engine", "load_run_anatomies", "stl_roundtrip"]


ANATOMY_FILES = "anatomy.stl"
"""The anatomy a run uses, copied into its folder (patient frame): ``anatomy.stl`` for the first
patient, ``anatomy_<i>.stl`` for patient i > 0."""


def anatomy_file(i: int) -> str:
    """File name of patient i's anatomy in a run folder."""
    return ANATOMY_FILES if i == 0 else f"anatomy_{i}.stl"


SWEEP_MM = 0.5
"""Tip spacing (mm) at which the search checks a docking's whole drilling line, standoff to target, once its coarse points
pass (:func:`sweep_tasks`): the resolution of model §17.2, at which the drilling program checks the same line."""


def sweep_points(start: np.ndarray, end: np.ndarray, coarse: int, spacing: float = SWEEP_MM) -> int:
    """Points per line of a sweep of the lines ``start`` -> ``end`` (``(T, 3)`` mm): (coarse - 1) m + 1, the smallest such
    count that puts consecutive points at most ``spacing`` apart on the longest line; the coarse points are among them."""
    longest = float(np.max(np.linalg.norm(np.asarray(end) - np.asarray(start), axis=-1), initial=0.0))
    return (coarse - 1) * max(1, int(np.ceil(longest / ((coarse - 1) * spacing)))) + 1


def sweep_tasks(
    patient: int, setup: int, label: str, S: np.ndarray, A: np.ndarray, B: np.ndarray, coarse: int
) -> list[TaskData]:
    """A docking's drilling lines at the program's resolution (model §17.2): the approach S_j -> A_j (replacing its
    coarse line) and the drill A_j -> B_j (role ``sweep``: reach, guards and clearances, no eta_G), each sampled every
    :data:`SWEEP_MM` or less with the coarse points among the samples."""
    drill = build_task(A, B, sweep_points(A, B, coarse))
    n = sweep_points(S, A, coarse)
    approach = build_task(S, A, n)
    direction = np.repeat(drill.e.reshape(-1, drill.n_points, 3)[:, 0], n, axis=0)
    return [
        TaskData(patient, setup, f"{label} approach", approach.E, direction, role="approach"),
        TaskData(patient, setup, f"{label} sweep", drill.E, drill.e, role="sweep"),
    ]


def envelope_file(i: int) -> str:
    """File name of patient i's skin-mesh envelope (model §19.5) in a run folder."""
    return f"envelope_{i}.stl"


def run_envelopes(cfg: RunConfig, run_dir: Any = None, skins: tuple[Any, ...] | None = None) -> tuple[Any, ...]:
    """Per patient (or docking), the envelope of the whole patient (model §19.5) its config records (() without one);
    a skin mesh is read from the run folder, or given as ``skins`` (one mesh list per patient)."""
    import json

    from arcube.evaluation.envelope import Envelope

    if not any("envelope" in p for p in cfg.patients):
        return ()
    out = []
    for i, p in enumerate(cfg.patients):
        record = json.loads(p["envelope"])
        skin: Any = ()
        if record.get("skin"):
            if skins is not None:
                skin = skins[i]
            elif run_dir is not None:
                from arcube.io.meshes import read_meshes

                path = Path(run_dir) / envelope_file(i)
                if not path.exists():
                    raise InputError(f"{run_dir}: the run's envelope file {path.name} is missing")
                skin = read_meshes([path], "patient")
            else:
                return ()  # validating a config: the skin is read with the run
        out.append(Envelope.from_record(record, skin))
    return tuple(out)


def load_run_anatomies(cfg: RunConfig, run_dir: Any) -> tuple[Any, ...]:
    """Per patient, the distance grids of the anatomy copied into the run folder (() without anatomy; None for a
    patient without one, in a cohort, model §19); the dockings of one plan share one file and one grid."""
    if not cfg.settings.anatomy and not any(p.get("anatomy") for p in cfg.patients):
        return ()
    from pathlib import Path

    from arcube.evaluation.anatomy import Anatomy
    from arcube.io.meshes import read_meshes

    if run_dir is None:
        return ()
    out: list[Any] = []
    loaded: dict[str, Any] = {}
    for i, p in enumerate(cfg.patients):
        if not cfg.own(i, "anatomy"):
            out.append(None)
            continue
        name = p.get("anatomy_file", anatomy_file(i))
        if name not in loaded:
            path = Path(run_dir) / name
            if not path.exists():
                raise InputError(f"{run_dir}: the run's anatomy file {path.name} is missing")
            loaded[name] = Anatomy.from_meshes(read_meshes([path], "patient"), str(path)).distance
        out.append(loaded[name])
    return tuple(out)


def stl_roundtrip(anatomy: Any) -> Any:
    """The distance grids of ``anatomy`` as a run folder's ``anatomy.stl`` gives them (float32
    coordinates, merged vertices), built in memory: an in-memory run equals a folder run."""
    import io

    import trimesh

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost

    from arcube.evaluation.anatomy import Anatomy
    from arcube.io.meshes import _stl_bytes

    data = _stl_bytes(*anatomy.vertices_faces(), "arcube anatomy, mm, frame=patient")
    loaded = trimesh.load(io.BytesIO(data), file_type="stl", force="mesh", process=False)
    mesh = trimesh.Trimesh(
        vertices=np.asarray(loaded.vertices, dtype=np.float64),
        faces=np.asarray(loaded.faces, dtype=np.int64),
        process=False,
    )
    mesh.merge_vertices()
    mesh = trimesh.Trimesh(vertices=np.asarray(mesh.vertices) @ np.eye(3), faces=np.asarray(mesh.faces), process=False)
    return Anatomy.from_meshes([mesh], anatomy.source).distance


def _points(i: int, pat: Any) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(entry, target ``(T, 3)`` mm, sides) of a run's ``[[patients]]`` table ``i``, checked as a plan file's are
    (a config.toml edited by hand: an infinite point ran the whole run and failed writing its summary)."""
    where = f"[[patients]] {i + 1} ({pat.get('name', pat.get('source', '?'))})"
    try:
        entry, target = np.array(pat["entry"], float), np.array(pat["target"], float)
        ids, sides = [str(v) for v in pat["ids"]], [str(v) for v in pat["sides"]]
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{where}: entry, target, ids and sides must be lists ({type(exc).__name__}: {exc})") from None
    if (
        entry.ndim != 2
        or entry.shape[1:] != (3,)
        or target.shape != entry.shape
        or not len(ids) == len(entry) == len(sides)
    ):
        raise InputError(f"{where}: entry and target must be one [x, y, z] per trajectory id")
    validate_points([f"{where} trajectory {t}" for t in ids], ids, entry, target)
    return entry, target, sides


def build_model(
    cfg: RunConfig,
    run_dir: Any = None,
    anatomies: tuple[Any, ...] | None = None,
    settings: RunSettings | None = None,
    skins: tuple[Any, ...] | None = None,
) -> FitnessModel:
    """The fitness model a config describes (the same for a new run and a resume); the anatomy is read
    from the run folder (None: not loaded, for validating a config), or given as ``anatomies``;
    ``settings``: other settings than the config's (a docking's own)."""
    rs = settings if settings is not None else cfg.settings
    mode = None if rs.mode == "free" else mode_signs(rs.mode)
    # configs written before model §13 have 23 parameters: the four additions are then 0
    bounds = {**DEFAULT_BOUNDS, **cfg.bounds}
    base = np.array([float(cfg.design.get(n, 0.0)) for n in PARAM_NAMES])
    # configs written before --docking existed shared one placement among patients
    space = VariableSpace(
        base=base,
        free=rs.free,
        bounds=bounds,
        setups=rs.setups,
        mode=mode,
        patients=len(cfg.patients),
        placement=rs.placement,
        base_c_z=cfg.design.get("c_z"),
    )
    tasks: list[TaskData] = []
    fine: list[TaskData] = []
    for i, pat in enumerate(cfg.patients):
        entry, target, sides = _points(i, pat)
        groups = (
            [("", np.ones(len(sides), bool))]
            if space.setups == 1
            else [(sd, np.array([x == sd for x in sides])) for sd in ("R", "L")]
        )
        for setup, (side, keep) in enumerate(groups):
            task = build_task(entry[keep], target[keep], rs.points)
            label = (
                f"{pat['source']}{' ' + side if side else ''}" if "name" not in pat else f"{pat['name']} {pat['side']}"
            )
            tasks.append(TaskData(i, setup, label, task.E, task.e))
            fine.append(tasks[-1])
            if "standoff" in pat:  # model §17.1: the line from each standoff S_j to its entry A_j
                S = np.array(pat["standoff"], float)[keep]
                approach = build_task(S, entry[keep], rs.points)
                direction = np.repeat(task.e.reshape(-1, rs.points, 3)[:, 0], rs.points, axis=0)
                tasks.append(TaskData(i, setup, f"{label} approach", approach.E, direction, role="approach"))
                fine.extend(sweep_tasks(i, setup, label, S, entry[keep], target[keep], rs.points))
    return FitnessModel(
        space=space,
        tasks=tuple(tasks),
        n_patients=len(cfg.patients),
        options=rs.evaluation_options(),
        engine=cfg.engine_resolved,
        aggregate=rs.aggregate,
        anatomies=load_run_anatomies(cfg, run_dir) if anatomies is None else anatomies,
        envelopes=run_envelopes(cfg, run_dir, skins),
        margin_deg=rs.margin,
        by_docking=rs.dockings is not None,
        docking_plans=tuple((np.array(p["entry"], float), np.array(p["target"], float)) for p in cfg.patients)
        if rs.dockings is not None
        else (),
        objectives=rs.run_objectives,
        fine_tasks=tuple(fine) if any(t.role == "approach" for t in tasks) else (),
        limits=tuple((str(n), str(k), float(v)) for n, k, v in rs.limits),
        accuracy=rs.accuracy_settings(),
    )


def check_engine(name: str) -> str:
    """The resolved engine ('numba' or 'numpy'); InputError if unknown or unavailable."""
    resolved = engine_name(name)
    if resolved == "numba":
        try:
            import arcube.evaluation.kernel  # noqa: F401, PLC0415
        except ImportError as exc:
            raise InputError.of("engine", f"numba: the compiled kernel is not available ({exc})") from None
    return resolved
