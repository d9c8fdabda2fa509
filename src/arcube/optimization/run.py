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
import shutil
import math
import platform
import sys
import time
import tomllib
import uuid
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from arcube.model.design import PARAM_NAMES, Design
from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.optimization.algorithms import stop_reason
from arcube.optimization.checkpoint import (  # noqa: F401  (LOG_KEYS, digest: still importable from here)
    CHECKPOINT_FORMAT, FORMAT_VERSION, LOG_KEYS, Batch, EvalLog, _sha, digest, load_checkpoint, write_checkpoint,
)  # fmt: skip
from arcube.optimization.lock import LOCK_FILE, acquire, release
from arcube.optimization.loop import HISTORY_COLUMNS, Loop, describe, run_algorithm
from arcube.optimization.build import anatomy_file, build_model, check_engine
from arcube.optimization.executors import make_executor  # noqa: F401 (still importable from here)
from arcube.optimization.problem import FitnessModel
from arcube.optimization.settings import RunSettings

RUN_FORMAT = "arcube-optimize-run"


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for pkg in ("arcube", "pymoo", "numpy", "scipy", "cma", "numba"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out


# ----------------------------------------------------------------------------- config.toml
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        return repr(f) if math.isfinite(f) else ("nan" if math.isnan(f) else ("inf" if f > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(cfg: dict[str, Any]) -> str:
    """Tables of scalars/arrays and arrays of tables (enough for config.toml)."""
    lines: list[str] = []
    cfg = {k: v for k, v in cfg.items() if v is not None}
    for key, val in cfg.items():
        if not isinstance(val, (dict, list)) or (isinstance(val, list) and not (val and isinstance(val[0], dict))):
            lines.append(f"{key} = {_toml_value(val)}")
    for key, val in cfg.items():
        tables = [val] if isinstance(val, dict) else (val if isinstance(val, list) and val and isinstance(val[0], dict) else [])
        for tab in tables:
            lines += ["", f"[[{key}]]" if isinstance(val, list) else f"[{key}]"]
            lines += [f"{k} = {_toml_value(x)}" for k, x in tab.items() if x is not None]
    return "\n".join(lines) + "\n"


def read_config(run_dir: Path) -> tuple[dict[str, Any], bytes]:
    path = run_dir / "config.toml"
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: no such run folder")
    try:
        raw = path.read_bytes()
        cfg = tomllib.loads(raw.decode("utf-8"))
    except FileNotFoundError:
        raise InputError(f"{run_dir}: not an optimization run or study (no config.toml or study.toml)") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path}: unreadable config ({exc})") from None
    if cfg.get("format") != RUN_FORMAT or cfg.get("format_version") != FORMAT_VERSION:
        raise InputError(f"{path}: not an arcube optimize config (format {cfg.get('format')!r} version {cfg.get('format_version')!r})")
    try:
        check_engine(cfg["settings"]["engine_resolved"])
        build_model(cfg)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path}: incomplete or invalid config ({type(exc).__name__}: {exc})") from None
    return cfg, raw


# ----------------------------------------------------------------------------- history and outputs
def _fmt(v: float) -> str:
    return repr(float(v)) if math.isfinite(v) else ""


def reset_history(path: Path, keep_rows: int) -> None:
    rows: list[str] = []
    if path.exists() and keep_rows:
        rows = path.read_text(encoding="utf-8").splitlines()[1 : keep_rows + 1]
    atomic_write_text(path, "\n".join([",".join(HISTORY_COLUMNS), *rows]) + "\n")


def write_outputs(run_dir: Path, cfg: dict[str, Any], model: FitnessModel, algorithm: Any, info: dict[str, Any]) -> dict[str, Any]:
    """Write the best design(s), pareto.csv (multi-objective) and summary.json; returns the summary."""
    summary, designs, front = describe(cfg, model, algorithm, info)
    if model.space.per_patient:
        files = write_placements(run_dir, cfg, model, designs)
    else:
        Design.from_vector(designs[0]).to_json(run_dir / "best_design.json")
        files = {"best_design": "best_design.json"}
        if len(designs) == 2:
            Design.from_vector(designs[1]).to_json(run_dir / "best_design_L.json")
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


def placement_file(patient: int, setup: int = 0) -> str:
    """File name of one patient's complete design in a per-patient-docking run (patient 0-based)."""
    return f"best_design_p{patient + 1}{'_L' if setup else ''}.json"


def write_placements(run_dir: Path, cfg: dict[str, Any], model: FitnessModel, designs: list[np.ndarray]) -> dict[str, str]:
    """Per-patient docking: one complete design per patient (and side), and best_design.json = the shared
    design (placed for the first patient) with a ``placements`` list: each patient's m and mounting."""
    space, placements, files = model.space, [], {"best_design": "best_design.json"}
    own = [n for n in PARAM_NAMES if n in (*space.docked, *space.free_m)] or ["m_x", "m_y", "m_z"]
    for p, patient in enumerate(cfg["patients"]):
        for setup in range(space.setups):
            values = Design.from_vector(designs[space.slot(p, setup)]).to_dict()
            name = placement_file(p, setup)
            atomic_write_text(run_dir / name, json.dumps(values, indent=2) + "\n")
            files[name.removesuffix(".json")] = name
            entry = {"patient": p + 1, "trajectories": patient["source"], "file": name, **{n: values[n] for n in own}}
            placements.append(entry if space.setups == 1 else {**entry, "side": "L" if setup else "R"})
    shared = {**Design.from_vector(designs[0]).to_dict(), "placements": placements}
    atomic_write_text(run_dir / "best_design.json", json.dumps(shared, indent=2) + "\n")
    if space.setups == 2:  # the first patient's left side, where runs with two setups always put it
        Design.from_vector(designs[space.slot(0, 1)]).to_json(run_dir / "best_design_L.json")
        files["best_design_L"] = "best_design_L.json"
    return files


# ----------------------------------------------------------------------------- the run loop
def execute(run_dir: Path, cfg: dict[str, Any], cfg_raw: bytes, **kwargs: Any) -> dict[str, Any]:
    """Run (or resume) the optimization described by ``cfg`` in ``run_dir`` holding the folder's lock
    (:mod:`arcube.optimization.lock`); returns the summary. See :func:`_execute` for the arguments."""
    lock = acquire(run_dir)
    try:
        return _execute(run_dir, cfg, cfg_raw, **kwargs)
    finally:
        release(lock)


def _execute(run_dir: Path, cfg: dict[str, Any], cfg_raw: bytes, *, resume: bool = False, workers: int | None = None,
             dask: str | None = None, on_generation: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:  # fmt: skip
    """Run (or resume) the optimization described by ``cfg`` in ``run_dir``; returns the summary.

    ``on_generation`` gets each new generation's history row plus ``total``, this session's
    ``session_s`` (wall), ``eval_s`` (evaluation) and ``optimizer_s`` (pymoo's own time: inside
    the algorithm's step but not answering its batches); the rest of ``session_s`` is the run's
    own bookkeeping (setup, history, checkpoints, outputs).
    """
    s = cfg["settings"]
    settings = RunSettings.from_table(s)
    state, replay = load_checkpoint(run_dir, cfg, cfg_raw) if resume else (None, [])
    if state is None:
        state = {"format": CHECKPOINT_FORMAT, "format_version": FORMAT_VERSION, "run_id": cfg["run_id"], "config_sha256": _sha(cfg_raw),
                 "generation": 0, "elapsed_s": 0.0, "eval_s": 0.0, "sessions": 0, "chunks": [], "finished": False}  # fmt: skip
    done_gen, prior_s, prior_eval = int(state["generation"]), float(state["elapsed_s"]), float(state["eval_s"])
    state["sessions"] = int(state.get("sessions", 0)) + 1
    t0 = time.perf_counter()
    reset_history(run_dir / "history.csv", done_gen)
    model = build_model(cfg, run_dir)
    ex = cfg.get("executor", {})
    executor = make_executor(model, workers if workers is not None else int(ex.get("workers", 1)), dask if dask is not None else ex.get("dask") or None)
    log = EvalLog(executor, replay)
    every = settings.checkpoint_every
    budget = settings.population * settings.generations  # evaluations at most (the GA's own count at full length)
    hist = (run_dir / "history.csv").open("a", encoding="utf-8", newline="")
    loop: Loop | None = None

    def elapsed() -> float:
        return prior_s + time.perf_counter() - t0

    def generation(current: Loop, row: dict[str, Any]) -> None:
        nonlocal loop
        loop = current
        gen, n_eval = current.generation, current.algorithm.evaluator.n_eval
        row = {**row, "seconds": elapsed()}
        hist.write(",".join(str(row[c]) if c in ("generation", "evaluations") else _fmt(row[c]) for c in HISTORY_COLUMNS) + "\n")
        hist.flush()
        if gen % every == 0:
            state.update(elapsed_s=elapsed(), eval_s=prior_eval + log.eval_s, evaluations=n_eval)
            write_checkpoint(run_dir, state, log, gen)
        if on_generation is not None:
            on_generation({**row, "total": settings.generations, "total_evaluations": budget, "eval_s": log.eval_s,
                           "optimizer_s": current.algorithm_s - log.call_s, "session_s": time.perf_counter() - t0})  # fmt: skip

    try:
        loop = run_algorithm(model, settings, log, on_generation=generation, done_generation=done_gen)
        if log.replay:
            raise InputError("checkpoint does not replay: the run ended before the logged batches did (foreign checkpoint?)")
        gen, algo = loop.generation, loop.algorithm
        info = {"generations": gen, "evaluations": int(algo.evaluator.n_eval), "wall_s": elapsed(), "eval_s": prior_eval + log.eval_s,
                "stopped_by": stop_reason(loop.termination), "resumed": state["sessions"] - 1}  # fmt: skip
        summary = write_outputs(run_dir, cfg, model, algo, info)
        state.update(elapsed_s=elapsed(), eval_s=prior_eval + log.eval_s, evaluations=algo.evaluator.n_eval, finished=True)
        write_checkpoint(run_dir, state, log, gen)
        return summary
    except KeyboardInterrupt:
        if loop is not None and loop.generation > done_gen:
            state.update(elapsed_s=elapsed(), eval_s=prior_eval + log.eval_s)
            write_checkpoint(run_dir, state, log, loop.generation)
        raise
    finally:
        hist.close()
        executor.close()


def new_run_config(settings: dict[str, Any], bounds: dict[str, tuple[float, float]], design: Design, patients: list[dict[str, Any]],
                   executor: dict[str, Any]) -> dict[str, Any]:  # fmt: skip
    return {
        "format": RUN_FORMAT, "format_version": FORMAT_VERSION, "run_id": uuid.uuid4().hex,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "command": " ".join(sys.argv),
        "versions": versions(), "settings": settings,
        "bounds": {k: [float(lo), float(hi)] for k, (lo, hi) in bounds.items()},
        "design": design.to_dict(), "executor": executor, "patients": patients,
    }  # fmt: skip


def check_new_folder(run_dir: Path) -> None:
    """InputError unless ``run_dir`` is absent or an empty folder."""
    if run_dir.exists() and (not run_dir.is_dir() or any(run_dir.iterdir())):
        hint = " (it holds a run: use 'arcube resume')" if (run_dir / "config.toml").exists() else ""
        raise InputError.of("out", f"{run_dir}: exists and is not an empty folder{hint}")


def write_anatomy(run_dir: Path, cfg: dict[str, Any]) -> None:
    """Copy each patient's anatomy into the run folder (patient frame), so that resume and report need nothing else."""
    s = cfg["settings"]
    if not s.get("anatomy"):
        return
    from arcube.evaluation.anatomy import resolve_anatomy

    for i, spec in enumerate(s["trajectories"]):
        anatomy = resolve_anatomy(s["anatomy"], s.get("anatomy_frame", "LPS"), spec)
        anatomy.write_stl(run_dir / anatomy_file(i))
        cfg["patients"][i]["anatomy_source"] = anatomy.source


def start(run_dir: Path, cfg: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
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
            return _execute(run_dir, cfg, prepare(run_dir, cfg), **kwargs)
        except Exception:
            if not (run_dir / "checkpoint").exists():
                remove_folder(run_dir, created)
            raise
    finally:
        release(lock)


def prepare(run_dir: Path, cfg: dict[str, Any]) -> bytes:
    """Write a new run folder's anatomy files and config.toml (nothing run yet); returns the config's bytes.

    :func:`resume` runs such a folder from its first generation (it has no checkpoint)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    write_anatomy(run_dir, cfg)
    text = to_toml(cfg)
    atomic_write_text(run_dir / "config.toml", text)
    return text.encode("utf-8")


def remove_folder(path: Path, created: bool) -> None:
    """Empty ``path``; remove it too when this session ``created`` it (what an early bad input leaves)."""
    if path.is_dir():
        for child in path.iterdir():
            shutil.rmtree(child) if child.is_dir() else child.unlink()
        if created:
            path.rmdir()


def is_finished(run_dir: Path) -> bool:
    """True when the run folder holds a finished run (its checkpoint says so and summary.json exists)."""
    state_path = run_dir / "checkpoint" / "state.json"
    if state_path.exists() and (run_dir / "summary.json").exists():
        try:
            return json.loads(state_path.read_text(encoding="utf-8")).get("finished") is True
        except (OSError, ValueError):
            return False
    return False


def resume(run_dir: Path, **kwargs: Any) -> dict[str, Any] | None:
    """Continue a run from its checkpoint; None when it had already finished."""
    cfg, raw = read_config(run_dir)
    if is_finished(run_dir):
        return None
    old = cfg.get("versions", {})
    now = versions()
    changed = [f"{k} {old[k]} -> {now.get(k)}" for k in ("pymoo", "numpy", "cma") if k in old and old[k] != now.get(k)]
    if changed:
        sys.stderr.write(f"warning: versions changed since the run started ({', '.join(changed)}); the replay will check\n")
    return execute(run_dir, cfg, raw, resume=True, **kwargs)
