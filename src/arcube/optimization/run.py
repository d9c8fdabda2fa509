"""Optimization runs: run folder, history, executors and the run loop.

Run folder::

    config.toml      everything needed to rerun (settings, seed, bounds, start design, the
                     trajectories' coordinates, versions)
    history.csv      one row appended per generation
    checkpoint/      state.json + evals_GGGGGG.npz (allow_pickle=False), written atomically
    best_design.json (best_design_L.json with --setups 2), summary.json, pareto.csv (nsga2);
                     with per-patient docking best_design.json also lists each patient's placement
                     and best_design_p<K>.json holds patient K's complete design

Checkpoint and bit-identical resume: see :mod:`arcube.optimization.checkpoint` (the evaluation log,
replayed on resume).
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from arcube.model.design import PARAM_NAMES, Design
from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.optimization.algorithms import stop_reason
from arcube.optimization.checkpoint import (
    CHECKPOINT_FORMAT,
    FORMAT_VERSION,
    EvalLog,
    _sha,
    load_checkpoint,
    write_checkpoint,
)
from arcube.optimization.lock import LOCK_FILE, acquire, release
from arcube.optimization.loop import HISTORY_COLUMNS, Loop, Observer, Progress, describe, observed
from arcube.optimization.build import anatomy_file, build_model, envelope_file
from arcube.optimization.folder import (  # noqa: F401  (the folder's files, used here and by callers of this module)
    RUN_FORMAT,
    check_new_folder,
    is_finished,
    placement_file,
    read_config,
    remove_folder,
    to_toml,
    versions,
)
from arcube.optimization.executors import make_executor
from arcube.optimization.problem import FitnessModel
from arcube.optimization.run_config import RunConfig
from arcube.optimization.run_results import OptimizeResult


# ----------------------------------------------------------------------------- config.toml
# ----------------------------------------------------------------------------- history and outputs
def _fmt(v: float) -> str:
    return repr(float(v)) if math.isfinite(v) else ""


def reset_history(path: Path, keep_rows: int) -> None:
    rows: list[str] = []
    if path.exists() and keep_rows:
        rows = path.read_text(encoding="utf-8").splitlines()[1 : keep_rows + 1]
    atomic_write_text(path, "\n".join([",".join(HISTORY_COLUMNS), *rows]) + "\n")


def write_outputs(
    run_dir: Path, cfg: RunConfig, model: FitnessModel, algorithm: Any, info: dict[str, Any]
) -> dict[str, Any]:
    """Write the best design(s), pareto.csv (multi-objective) and summary.json; returns the summary."""
    summary, designs, front = describe(cfg, model, algorithm, info)
    if model.space.per_patient:
        files = write_placements(run_dir, cfg, model, designs, summary.get("c_z"), summary.get("mode"))
    else:
        run_design(designs[0], summary).to_json(run_dir / "best_design.json")
        files = {"best_design": "best_design.json"}
        if len(designs) == 2:
            run_design(designs[1], summary).to_json(run_dir / "best_design_L.json")
            files = {"best_design_R": "best_design.json", "best_design_L": "best_design_L.json"}
    summary["files"] = files
    if front is not None:
        atomic_write_text(run_dir / "pareto.csv", front_csv(front))
        files["pareto"] = "pareto.csv"
    atomic_write_text(run_dir / "summary.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary


def front_csv(rows: list[dict[str, Any]]) -> str:
    """pareto.csv's text: one row per front design (floats written exactly)."""
    buf = io.StringIO()
    cols = list(rows[0]) if rows else ["eta_G", "links_sum_mm", "bbox_volume_L", *PARAM_NAMES]
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    w.writerows([{k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows])
    return buf.getvalue()


def run_design(vector: np.ndarray, summary: dict[str, Any]) -> Design:
    """The design of one slot ``(27,)`` with the run's working mode (the one it chose, with ``--mode free``) and its
    c_z when it has one (model §19.1): a design file carries what it needs to be used."""
    extras = {k: summary[k] for k in ("c_z", "mode") if summary.get(k) is not None}
    return Design.from_vector(vector).with_extras(**extras)


def write_placements(
    run_dir: Path,
    cfg: RunConfig,
    model: FitnessModel,
    designs: list[np.ndarray],
    c_z: float | None = None,
    mode: str | None = None,
) -> dict[str, str]:
    """Per-patient docking: one complete design per patient (and side), and best_design.json = the shared
    design (placed for the first patient) with a ``placements`` list: each patient's m and mounting.
    ``c_z`` (model §19.1) and ``mode``: the run's, in every file when given."""
    space, placements, files = model.space, [], {"best_design": "best_design.json"}
    own = [n for n in PARAM_NAMES if n in (*space.docked, *space.free_m)] or ["m_x", "m_y", "m_z"]
    extra = {k: v for k, v in (("c_z", c_z), ("mode", mode)) if v is not None}
    for p, patient in enumerate(cfg.patients):
        for setup in range(space.setups):
            values = Design.from_vector(designs[space.slot(p, setup)]).to_dict()
            name = placement_file(p, setup)
            atomic_write_text(run_dir / name, json.dumps({**values, **extra}, indent=2) + "\n")
            files[name.removesuffix(".json")] = name
            entry = {"patient": p + 1, "trajectories": patient["source"], "file": name, **{n: values[n] for n in own}}
            if "name" in patient:  # a docking of one robot (model §19)
                entry = {**entry, "name": patient["name"], "side": patient["side"]}
            placements.append(entry if space.setups == 1 else {**entry, "side": "L" if setup else "R"})
    shared = {**Design.from_vector(designs[0]).to_dict(), **extra, "placements": placements}
    atomic_write_text(run_dir / "best_design.json", json.dumps(shared, indent=2) + "\n")
    if space.setups == 2:  # the first patient's left side, where runs with two setups always put it
        Design.from_vector(designs[space.slot(0, 1)]).with_extras(**extra).to_json(run_dir / "best_design_L.json")
        files["best_design_L"] = "best_design_L.json"
    return files


# ----------------------------------------------------------------------------- the run loop
def execute(run_dir: Path, config: tuple[RunConfig, bytes], **kwargs: Any) -> dict[str, Any]:
    """Run (or resume) the optimization ``config`` describes (the run's config and config.toml's bytes) in ``run_dir``
    holding the folder's lock (:mod:`arcube.optimization.lock`); returns the summary. See :func:`_execute`."""
    lock = acquire(run_dir)
    try:
        return _execute(run_dir, config, **kwargs)
    finally:
        release(lock)


class _History(Observer):
    """Appends each generation's row to history.csv (flushed: a killed run keeps its rows)."""

    def __init__(self, path: Path) -> None:
        self.file = path.open("a", encoding="utf-8", newline="")

    def generation(self, loop: Loop, row: dict[str, Any], timing: dict[str, float]) -> None:
        self.file.write(
            ",".join(str(row[c]) if c in ("generation", "evaluations") else _fmt(row[c]) for c in HISTORY_COLUMNS)
            + "\n"
        )
        self.file.flush()


class _Checkpoint(Observer):
    """Writes a checkpoint every ``every`` generations (and remembers the last generation seen)."""

    def __init__(
        self, run_dir: Path, state: dict[str, Any], log: EvalLog, every: int, prior_s: float, prior_eval: float
    ) -> None:
        self.run_dir, self.state, self.log, self.every = run_dir, state, log, every
        self.prior_s, self.prior_eval, self.t0, self.generation_seen = prior_s, prior_eval, time.perf_counter(), 0

    def elapsed(self) -> float:
        """Wall time of the run over all its sessions, s."""
        return self.prior_s + time.perf_counter() - self.t0

    def write(self, generation: int, **fields: Any) -> None:
        """A checkpoint at ``generation`` with the run's timing (and ``fields``) in its state."""
        self.state.update(elapsed_s=self.elapsed(), eval_s=self.prior_eval + self.log.eval_s, **fields)
        write_checkpoint(self.run_dir, self.state, self.log, generation)

    def generation(self, loop: Loop, row: dict[str, Any], timing: dict[str, float]) -> None:
        self.generation_seen = loop.generation
        if loop.generation % self.every == 0:
            self.write(loop.generation, evaluations=loop.algorithm.evaluator.n_eval)


def _execute(
    run_dir: Path,
    config: tuple[RunConfig, bytes],
    *,
    resume: bool = False,
    workers: int | None = None,
    dask: str | None = None,
    on_generation: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) the optimization ``config`` describes (the run's config, config.toml's bytes) in ``run_dir``;
    returns the summary.

    ``on_generation`` gets each new generation's history row and timing (:class:`~arcube.optimization.loop.Observer`).
    """
    cfg, cfg_raw = config
    settings = cfg.settings
    state, replay = load_checkpoint(run_dir, cfg, cfg_raw) if resume else (None, [])
    if state is None:
        state = {
            "format": CHECKPOINT_FORMAT,
            "format_version": FORMAT_VERSION,
            "run_id": cfg.run_id,
            "config_sha256": _sha(cfg_raw),
            "generation": 0,
            "elapsed_s": 0.0,
            "eval_s": 0.0,
            "sessions": 0,
            "chunks": [],
            "finished": False,
        }
    done_gen, prior_s, prior_eval = int(state["generation"]), float(state["elapsed_s"]), float(state["eval_s"])
    state["sessions"] = int(state.get("sessions", 0)) + 1
    reset_history(run_dir / "history.csv", done_gen)
    model = build_model(cfg, run_dir, settings=settings)
    ex = cfg.executor
    executor = make_executor(
        model,
        workers if workers is not None else int(ex.get("workers", 1)),
        dask if dask is not None else ex.get("dask") or None,
    )
    log = EvalLog(executor, replay)
    history = _History(run_dir / "history.csv")
    checkpoint = _Checkpoint(run_dir, state, log, settings.checkpoint_every, prior_s, prior_eval)
    observers: list[Observer] = [history, checkpoint, *([Progress(on_generation)] if on_generation is not None else [])]
    try:
        loop = observed(model, settings, log, observers, done_generation=done_gen, prior_s=prior_s)
        if log.replay:
            raise InputError(
                "checkpoint does not replay: the run ended before the logged batches did (foreign checkpoint?)"
            )
        gen, algo = loop.generation, loop.algorithm
        info = {
            "generations": gen,
            "evaluations": int(algo.evaluator.n_eval),
            "wall_s": checkpoint.elapsed(),
            "eval_s": prior_eval + log.eval_s,
            "stopped_by": stop_reason(loop.termination),
            "resumed": state["sessions"] - 1,
        }
        summary = write_outputs(run_dir, cfg, model, algo, info)
        checkpoint.write(gen, evaluations=algo.evaluator.n_eval, finished=True)
        return summary
    except KeyboardInterrupt:
        if checkpoint.generation_seen > done_gen:
            checkpoint.write(checkpoint.generation_seen)
        raise
    finally:
        history.file.close()
        executor.close()


class _Rows(Observer):
    """Keeps each generation's row in memory."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []

    def generation(self, loop: Loop, row: dict[str, Any], timing: dict[str, float]) -> None:
        self.rows.append(row)


def run_in_memory(
    cfg: RunConfig, anatomies: tuple[Any, ...], on_generation: Callable[[dict[str, Any]], None] | None = None
) -> OptimizeResult:
    """Run ``cfg`` with nothing written (``anatomies``: each patient's distance grids, as the run
    folder's ``anatomy.stl`` gives them): the same designs, summary and history as a run folder's."""
    settings = cfg.settings
    skins = None
    if any(json.loads(p["envelope"]).get("skin") for p in cfg.patients if "envelope" in p):
        from arcube.io.meshes import read_meshes

        skins = tuple(tuple(read_meshes(list(settings.envelope), settings.anatomy_frame)) for _ in cfg.patients)
    model = build_model(cfg, anatomies=anatomies, settings=settings, skins=skins)
    ex = cfg.executor
    executor = make_executor(model, int(ex.get("workers", 1)), ex.get("dask") or None)
    log, rows = EvalLog(executor, [], keep=False), _Rows()
    t0 = time.perf_counter()
    try:
        loop = observed(model, settings, log, [rows, *([Progress(on_generation)] if on_generation is not None else [])])
    finally:
        executor.close()
    info = {
        "generations": loop.generation,
        "evaluations": int(loop.algorithm.evaluator.n_eval),
        "wall_s": time.perf_counter() - t0,
        "eval_s": log.eval_s,
        "stopped_by": stop_reason(loop.termination),
        "resumed": 0,
    }
    summary, designs, front = describe(cfg, model, loop.algorithm, info)
    history = {c: np.array([float(r[c]) for r in rows.rows]) for c in HISTORY_COLUMNS}
    pareto = None if front is None else {k: np.array([r.get(k) for r in front]) for k in (front[0] if front else {})}
    return OptimizeResult(
        summary=summary, designs=[run_design(d, summary) for d in designs], history=history, pareto=pareto, config=cfg
    )


def write_anatomy(run_dir: Path, cfg: RunConfig) -> RunConfig:
    """Copy each patient's anatomy into the run folder (patient frame), so that resume and report need nothing else;
    returns the config with each docking's record naming its file. A patient's own anatomy (a cohort's, model §19) is
    that entry's; the dockings of one plan share one file."""
    from arcube.evaluation.anatomy import resolve_anatomy

    written: dict[int, tuple[str, str]] = {}
    patients = [cfg.patient(i) for i in range(len(cfg.patients))]
    for i, p in enumerate(patients):
        spec_anatomy = cfg.own(i, "anatomy")
        if not spec_anatomy:
            continue
        plan = p.get("plan_index", i)
        if plan in written:  # another docking of the same plan
            p["anatomy_file"], p["anatomy_source"] = written[plan]
            continue
        anatomy = resolve_anatomy(
            list(spec_anatomy),
            cfg.own(i, "anatomy_frame"),
            cfg.trajectories[plan],
            segments=cfg.own(i, "segments"),
        )
        anatomy.write_stl(run_dir / anatomy_file(i))
        p["anatomy_source"] = anatomy.source
        if "plan_index" in p:
            p["anatomy_file"] = anatomy_file(i)
            written[plan] = (p["anatomy_file"], anatomy.source)
    return cfg.with_patients(patients)


def write_envelopes(run_dir: Path, cfg: RunConfig) -> None:
    """Copy a skin-mesh envelope (model §19.5) into the run folder (patient frame), beside its record in config.toml."""
    if not any(json.loads(p["envelope"]).get("skin") for p in cfg.patients if "envelope" in p):
        return
    from arcube.io.meshes import read_meshes, write_stl

    for i, p in enumerate(cfg.patients):
        if "envelope" in p and json.loads(p["envelope"]).get("skin"):
            meshes = read_meshes(list(cfg.own(i, "envelope")), cfg.own(i, "anatomy_frame"))
            write_stl(meshes, run_dir / envelope_file(i))


def start(run_dir: Path, cfg: RunConfig, **kwargs: Any) -> dict[str, Any]:
    """Create the run folder (anatomy files, config.toml, empty history.csv) and run.

    The folder's lock is taken before anything is written: of two runs started into one folder at
    once, one runs and the other is refused, and the refused one removes nothing. A run that stops
    on a bad input or an unexpected error before its first checkpoint (e.g. an unreachable dask
    scheduler) leaves nothing behind: the folder was absent or empty, and is so again (Ctrl-C
    leaves it resumable)."""
    check_new_folder(run_dir)
    created = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    lock = acquire(run_dir)
    try:
        if any(p.name != LOCK_FILE for p in run_dir.iterdir()):  # another run started and finished here meanwhile
            raise InputError.of("out", f"{run_dir}: exists and is not an empty folder (another run wrote it)")
        try:
            return _execute(run_dir, prepare(run_dir, cfg), **kwargs)
        except Exception:
            if not (run_dir / "checkpoint").exists():
                remove_folder(run_dir, created)
            raise
    finally:
        release(lock)


def prepare(run_dir: Path, cfg: RunConfig) -> tuple[RunConfig, bytes]:
    """Write a new run folder's anatomy files and config.toml (nothing run yet); returns the config as the folder
    holds it (its dockings naming their anatomy files) and config.toml's bytes.

    :func:`resume` runs such a folder from its first generation (it has no checkpoint)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg = write_anatomy(run_dir, cfg)
    write_envelopes(run_dir, cfg)
    text = to_toml(cfg.to_toml())
    atomic_write_text(run_dir / "config.toml", text)
    return cfg, text.encode("utf-8")


def resume(run_dir: Path, **kwargs: Any) -> dict[str, Any] | None:
    """Continue a run from its checkpoint; None when it had already finished."""
    cfg, raw = read_config(run_dir)
    if is_finished(run_dir):
        return None
    old = cfg.versions
    now = versions()
    changed = [f"{k} {old[k]} -> {now.get(k)}" for k in ("pymoo", "numpy", "cma") if k in old and old[k] != now.get(k)]
    if changed:
        sys.stderr.write(
            f"warning: versions changed since the run started ({', '.join(changed)}); the replay will check\n"
        )
    return execute(run_dir, (cfg, raw), resume=True, **kwargs)
