"""Design studies: the same optimization over several seeds, to see how much the optimum depends on luck.

Study folder::

    study.toml         format, seeds, when and how it was started
    base_config.toml   the run config every seed shares (a normal config.toml; its seed is the first one)
    seed_<S>/          one optimization run folder per seed (config.toml, history.csv, checkpoint/, ...)
    study.csv          per seed: objective values, feasibility, generations, evaluations, wall time
    best_design.json   the best seed's best design (best_design_L.json too with --setups 2)
    summary.json       best / median / worst of the first objective, the best seed, the per-seed rows
    convergence.png    best eta_G against evaluations, one line per seed (log scale); drawn from the
                       files above by arcube.report.study.write_study_convergence, which arcube.study
                       and arcube.resume call once the study has finished (this layer draws nothing)

Every seed's folder is written (config and anatomy) before any seed runs, and each run checkpoints
as ``arcube optimize`` does, so an interrupted study is finished by :func:`resume_study`
(``arcube resume STUDY_DIR``): finished seeds are kept, the others resume from their checkpoints.
A run's result depends only on its config and seed, so the study's result does not depend on the
interruption, on the order the seeds ran in, or on how they were spread over processes.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import statistics
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from arcube.coerce import check_best_known
from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.io.inputs import what_is
from arcube.optimization import run as runmod
from arcube.optimization.folder import STUDY_FORMAT, STUDY_VERSION, is_study, read_study, seed_dir  # noqa: F401  (the folder's files)
from arcube.optimization.objectives import MAXIMIZED, summary_value
from arcube.optimization.run_config import RunConfig

__all__ = ["is_study", "read_study", "resume_study", "run_summary", "seed_dir", "start_study", "study_rows"]


def seed_config(base: RunConfig, seed: int) -> RunConfig:
    """The run config of one seed: the study's base config with this seed and its own run id."""
    return base.with_seed(seed)


def _prepare_seeds(study_dir: Path, base: RunConfig, seeds: list[int]) -> None:
    """Write the run folder of every seed that has none yet (config.toml and anatomy, nothing run)."""
    for seed in seeds:
        d = seed_dir(study_dir, seed)
        if not (d / "config.toml").exists():
            runmod.prepare(d, seed_config(base, seed))


def start_study(
    study_dir: Path,
    base: RunConfig,
    seeds: list[int],
    *,
    workers: int = 1,
    dask: str | None = None,
    best_known: float | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    on_generation: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Create the study folder, one run folder per seed, run them all; returns the study summary.

    ``base`` is a run config (:func:`arcube.optimization.config.build_config`); its seed is replaced
    by each of ``seeds``. With ``workers > 1`` that many seeds run at once, each in its own process;
    with ``dask`` each seed is a task on the scheduler's workers (which must see the study folder).
    ``on_seed(seed, run_summary)`` is called as each seed finishes, ``on_generation`` with each
    generation's history row when the seeds run one after another in this process. ``best_known``
    (an eta_G) is recorded in study.toml for the convergence figure. A study that
    stops on a bad input before any seed has a checkpoint leaves nothing behind.
    """
    study_dir = Path(study_dir)
    if study_dir.exists() and not study_dir.is_dir():
        raise InputError.of("out", f"{study_dir}: is {what_is(study_dir)}, not a folder (give a new or empty folder)")
    if study_dir.exists() and any(study_dir.iterdir()):
        hint = " (it holds a study: use 'arcube resume')" if is_study(study_dir) else ""
        raise InputError.of("out", f"{study_dir}: exists and is not an empty folder{hint}")
    _check_parallel(workers, dask)
    check_best_known(best_known)
    created = not study_dir.exists()
    try:
        study_dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(study_dir / "base_config.toml", runmod.to_toml(base.to_toml()))
        study = {
            "format": STUDY_FORMAT,
            "format_version": STUDY_VERSION,
            "study_id": uuid.uuid4().hex,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "command": " ".join(sys.argv),
            "seeds": list(seeds),
            "workers": int(workers),
            "dask": dask or "",
            "best_known": best_known,
        }
        atomic_write_text(study_dir / "study.toml", runmod.to_toml(study))
        _prepare_seeds(study_dir, base, seeds)
        return _run(study_dir, seeds, workers, dask, on_seed, on_generation)
    except InputError:
        if not any((seed_dir(study_dir, s) / "checkpoint").exists() for s in seeds):
            runmod.remove_folder(study_dir, created)
        raise


def resume_study(
    study_dir: Path,
    *,
    workers: int | None = None,
    dask: str | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    on_generation: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Finish an interrupted study (finished seeds are kept, the others resume); returns its summary.

    ``workers`` / ``dask`` override how the study started (the result does not depend on them)."""
    study_dir = Path(study_dir)
    study, base = read_study(study_dir, config=True)
    seeds = [int(s) for s in study["seeds"]]
    if dask is None and workers is None:
        workers, dask = study.get("workers", 1), study.get("dask") or None  # checked by read_study
    workers = 1 if workers is None else workers
    _check_parallel(workers, dask)
    for seed in seeds:  # refuse a corrupt or foreign run folder before running anything
        d = seed_dir(study_dir, seed)
        if (d / "config.toml").exists():
            cfg, raw = runmod.read_config(d)
            own = seed_config(base, seed)
            if (cfg.settings, cfg.design, cfg.bounds) != (own.settings, own.design, own.bounds):
                raise InputError(
                    f"{d / 'config.toml'}: not seed {seed} of this study (its settings, design or bounds differ from "
                    f"{study_dir / 'base_config.toml'}'s): a run of another study; move it out to run the seed anew"
                )
            runmod.load_checkpoint(d, cfg, raw)
    _prepare_seeds(study_dir, base, seeds)
    return _run(study_dir, seeds, workers, dask, on_seed, on_generation)


def _check_parallel(workers: int, dask: str | None) -> None:
    if workers < 1:
        raise InputError.of("workers", f"must be at least 1, got {workers}")
    if dask and workers > 1:
        raise InputError.of("workers", "and dask exclude each other (the Dask cluster has its own workers)")
    if dask:
        from arcube.optimization.executors import check_dask_address

        check_dask_address(dask)


def _run_seed(run_dir: str, parent_pid: int | None = None) -> dict[str, Any]:
    """Run (or finish) one seed's folder in this process; returns its summary (picklable: a process or dask task).

    ``parent_pid``: the study's process, for a seed run in a child process. When it is gone (killed),
    the run stops at its next generation with a checkpoint, as on Ctrl-C, so that no orphan keeps
    writing into a folder that ``arcube resume`` will run again."""
    path = Path(run_dir)
    alone: list[bool] = []  # set when the parent is gone

    def orphaned(row: dict[str, Any]) -> None:
        if os.getppid() != parent_pid:
            alone.append(True)
            raise KeyboardInterrupt

    try:
        runmod.resume(path, workers=1, on_generation=orphaned if parent_pid is not None else None)
    except KeyboardInterrupt:
        if alone:  # the checkpoint is written and the files closed; the pool's pipes lead nowhere: leave now
            os._exit(1)
        raise
    return run_summary(path)


def _run(
    study_dir: Path,
    seeds: list[int],
    workers: int,
    dask: str | None,
    on_seed: Callable[[int, dict[str, Any]], None] | None,
    on_generation: Callable[[dict[str, Any]], None] | None,
) -> dict[str, Any]:
    pending = [s for s in seeds if not runmod.is_finished(seed_dir(study_dir, s))]
    for seed in seeds:
        if seed not in pending and on_seed is not None:
            on_seed(seed, run_summary(seed_dir(study_dir, seed)))
    if pending and dask:
        _run_dask(study_dir, pending, dask, on_seed)
    elif pending and workers > 1 and len(pending) > 1:
        _run_processes(study_dir, pending, workers, on_seed)
    else:
        for seed in pending:
            runmod.resume(seed_dir(study_dir, seed), workers=1, on_generation=on_generation)
            if on_seed is not None:
                on_seed(seed, run_summary(seed_dir(study_dir, seed)))
    return finish(study_dir, seeds)


def _run_processes(
    study_dir: Path, pending: list[int], workers: int, on_seed: Callable[[int, dict[str, Any]], None] | None
) -> None:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = multiprocessing.get_context("spawn")  # no fork under threads (progress bar)
    with ProcessPoolExecutor(min(workers, len(pending)), mp_context=ctx) as pool:
        futures = {pool.submit(_run_seed, str(seed_dir(study_dir, s)), os.getpid()): s for s in pending}
        try:
            for fut in as_completed(futures):
                summary = fut.result()
                if on_seed is not None:
                    on_seed(futures[fut], summary)
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # the running seeds write their checkpoints on the interrupt
            raise


def _run_dask(
    study_dir: Path, pending: list[int], address: str, on_seed: Callable[[int, dict[str, Any]], None] | None
) -> None:
    from arcube.optimization.executors import connect_dask

    client = connect_dask(address)
    try:
        futures = {client.submit(_run_seed, str(seed_dir(study_dir, s).resolve()), pure=False): s for s in pending}
        for fut, seed in futures.items():  # in seed order (distributed's as_completed wants a default client)
            summary = fut.result()
            if on_seed is not None:
                on_seed(seed, summary)
    finally:
        client.close()


# ----------------------------------------------------------------------------- results
def _ranked_value(summary: dict[str, Any], name: str) -> float:
    """The first objective as minimized (clearance negated); +inf for an infeasible or missing result."""
    value = summary_value(summary, name)
    if value is None or not summary.get("feasible") or not math.isfinite(value):
        return math.inf
    return -value if name in MAXIMIZED else value


def run_summary(run_dir: Path) -> dict[str, Any]:
    """A finished run's summary.json."""
    return json.loads((Path(run_dir) / "summary.json").read_text(encoding="utf-8"))


def study_rows(study_dir: Path, summaries: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per seed from its run's summary: seed, run, feasible, objective_<name>..., eta_G, violation, generations, evaluations, wall_s, eval_s."""
    rows = []
    for seed, s in summaries.items():
        d = seed_dir(study_dir, seed)
        names = s.get("objectives") or ["eta_G"]
        row: dict[str, Any] = {"seed": seed, "run": d.name, "feasible": bool(s["feasible"])}
        row |= {f"objective_{n}": summary_value(s, n) for n in names}
        row |= {
            "eta_G": s["eta_G"],
            "violation": s["violation"],
            "generations": s["generations"],
            "evaluations": s["evaluations"],
            "wall_s": s["wall_s"],
            "eval_s": s["eval_s"],
        }
        rows.append(row)
    return rows


def finish(study_dir: Path, seeds: list[int]) -> dict[str, Any]:
    """Write study.csv, best_design.json and summary.json from the finished seeds; returns the summary.

    The figure (convergence.png) is the report layer's: :func:`arcube.report.study.write_study_convergence`."""
    summaries = {seed: run_summary(seed_dir(study_dir, seed)) for seed in seeds}
    rows = study_rows(study_dir, summaries)
    first = next(k for k in rows[0] if k.startswith("objective_"))
    name = first.removeprefix("objective_")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(
        [{k: ("" if v is None else repr(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]
    )
    atomic_write_text(study_dir / "study.csv", buf.getvalue())
    # the first objective, then (when no seed is feasible) the least violation, then the seed
    ranked = sorted(rows, key=lambda r: (_ranked_value(summaries[r["seed"]], name), float(r["violation"]), r["seed"]))
    best_seed = ranked[0]["seed"]
    for src in sorted(seed_dir(study_dir, best_seed).glob("best_design*.json")):  # _L, _p<K>: what the run wrote
        atomic_write_text(study_dir / src.name, src.read_text(encoding="utf-8"))
    values = [_ranked_value(summaries[r["seed"]], name) for r in ranked]
    finite = [v for v in values if math.isfinite(v)]
    sign = -1.0 if name in MAXIMIZED else 1.0

    def shown(v: float) -> float | None:
        return sign * v if math.isfinite(v) else None

    summary = {
        "format": STUDY_FORMAT,
        "objective": name,
        "seeds": seeds,
        "feasible_seeds": len(finite),
        "best": shown(values[0]),
        "median": shown(statistics.median(values)) if values else None,
        "worst": shown(values[-1]),
        "best_seed": best_seed,
        "spread_pct": 100.0 * (finite[-1] - finite[0]) / abs(finite[0]) if len(finite) > 1 and finite[0] else None,
        "wall_s": round(sum(float(r["wall_s"]) for r in rows), 3),
        "rows": rows,
    }
    atomic_write_text(study_dir / "summary.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary
