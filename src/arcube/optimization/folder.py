"""The files of run and study folders: config.toml (written and read back), the file names, and the
folder's life (new or empty, finished, removed). Shared by the run loop, the study, the results and
the design job, so that each file name and format is written once.

Run folder: ``config.toml``, ``history.csv``, ``checkpoint/``, ``best_design.json`` (``best_design_L.json``,
``best_design_p<K>.json``), ``summary.json``, ``pareto.csv`` (see :mod:`arcube.optimization.run`).
Study folder: ``study.toml``, ``base_config.toml``, ``seed_<S>/`` (see :mod:`arcube.optimization.study`).
"""

from __future__ import annotations

import json
import math
import os
import platform
import shutil
import tomllib
from importlib import metadata
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import what_is
from arcube.model.design import Design
from arcube.optimization.build import build_model, check_engine
from arcube.optimization.checkpoint import FORMAT_VERSION, read_run_file
from arcube.optimization.run_config import RUN_FORMAT, RunConfig, executor_table

__all__ = [
    "RUN_FORMAT",
    "STUDY_FORMAT",
    "STUDY_VERSION",
    "check_new_folder",
    "is_finished",
    "is_study",
    "placement_file",
    "read_config",
    "read_study",
    "read_toml",
    "remove_folder",
    "seed_dir",
    "to_toml",
    "versions",
]


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for pkg in ("arcube", "pymoo", "numpy", "scipy", "cma", "numba"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out


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
    if isinstance(v, Mapping):  # an inline table (e.g. the tolerances' ``tol``)
        return "{" + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(cfg: dict[str, Any]) -> str:
    """Tables of scalars/arrays and arrays of tables (enough for config.toml)."""
    lines: list[str] = []
    cfg = {k: v for k, v in cfg.items() if v is not None}
    for key, val in cfg.items():
        if not isinstance(val, (dict, list)) or (isinstance(val, list) and not (val and isinstance(val[0], dict))):
            lines.append(f"{key} = {_toml_value(val)}")
    for key, val in cfg.items():
        tables = (
            [val]
            if isinstance(val, dict)
            else (val if isinstance(val, list) and val and isinstance(val[0], dict) else [])
        )
        for tab in tables:
            lines += ["", f"[[{key}]]" if isinstance(val, list) else f"[{key}]"]
            lines += [f"{k} = {_toml_value(x)}" for k, x in tab.items() if x is not None]
    return "\n".join(lines) + "\n"


def read_config(run_dir: Path) -> tuple[RunConfig, bytes]:
    """(the run's config, config.toml's bytes) of a run folder; InputError naming the file when it is not one
    or holds a bad setting."""
    path = run_dir / "config.toml"
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: no such run folder")
    if not os.path.lexists(path):
        raise InputError(f"{run_dir}: not an optimization run or study (no config.toml or study.toml)")
    table, raw = read_toml(path)
    return _validated(path, table), raw


def read_toml(path: Path) -> tuple[dict[str, Any], bytes]:
    """(parsed, bytes) of a run folder's TOML file (a regular file: :func:`read_run_file`); InputError naming it."""
    raw = read_run_file(path)
    try:
        return tomllib.loads(raw.decode("utf-8")), raw
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path}: unreadable ({exc})") from None


def _validated(path: Path, cfg: dict[str, Any]) -> RunConfig:
    """The run config a config.toml's tables describe, checked as far as a run needs (its engine, its model);
    InputError naming the file (and the [settings] key) otherwise."""
    if cfg.get("format") != RUN_FORMAT or cfg.get("format_version") != FORMAT_VERSION:
        raise InputError(
            f"{path}: not an arcube optimize config (format {cfg.get('format')!r} version {cfg.get('format_version')!r})"
        )
    try:
        config = RunConfig.from_toml(cfg)
        if config.design:  # the start design: a value that is not finite ran the whole run and failed at its end
            Design.from_dict(dict(config.design), source="[design]")
        check_engine(config.engine_resolved)
        build_model(config)
    except InputError as exc:  # a setting the file holds: name the file and its [settings] key, not RunSettings
        text = str(exc)
        if text.startswith("RunSettings."):
            text = "settings." + text[len("RunSettings.") :]
        raise InputError(f"{path}: {text}") from None
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: incomplete or invalid config ({type(exc).__name__}: {exc})") from None
    return config


def placement_file(patient: int, setup: int = 0) -> str:
    """File name of one patient's complete design in a per-patient-docking run (patient 0-based)."""
    return f"best_design_p{patient + 1}{'_L' if setup else ''}.json"


def check_new_folder(run_dir: Path) -> None:
    """InputError unless ``run_dir`` is absent or an empty folder (a file is named as one)."""
    if run_dir.exists() and not run_dir.is_dir():
        raise InputError.of("out", f"{run_dir}: is {what_is(run_dir)}, not a folder (give a new or empty folder)")
    if run_dir.exists() and any(run_dir.iterdir()):
        hint = " (it holds a run: use 'arcube resume')" if (run_dir / "config.toml").exists() else ""
        raise InputError.of("out", f"{run_dir}: exists and is not an empty folder{hint}")


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
            state = json.loads(read_run_file(state_path).decode("utf-8"))
        except (InputError, ValueError):  # not finished: the resume reads it again and says what is wrong
            return False
        return isinstance(state, dict) and state.get("finished") is True
    return False


STUDY_FORMAT = "arcube-study"


STUDY_VERSION = 1


def seed_dir(study_dir: Path, seed: int) -> Path:
    """The run folder of one seed."""
    return Path(study_dir) / f"seed_{seed}"


def is_study(path: Path) -> bool:
    """True when ``path`` holds a study (its ``study.toml``; one that is not a regular file, a FIFO, is then refused
    naming it when it is read, never taken for a missing one)."""
    return os.path.lexists(Path(path) / "study.toml")


def read_study(study_dir: Path, *, config: bool = False) -> tuple[dict[str, Any], RunConfig | None]:
    """(study.toml, the base config every seed shares) of a study folder; InputError when it is not one. The base
    config is read and checked as a run's (:func:`read_config`) only with ``config`` (what a resume needs); else
    None (a report or a study opened to be read evaluates nothing, on any machine)."""
    study_dir = Path(study_dir)
    if not study_dir.is_dir():
        raise InputError(f"{study_dir}: no such study or run folder")
    path = study_dir / "study.toml"
    if not os.path.lexists(path):
        raise InputError(f"{study_dir}: not a study (no study.toml)")
    study, _ = read_toml(path)  # first: a FIFO in its place is named as one
    if not os.path.lexists(study_dir / "base_config.toml"):
        raise InputError(f"{study_dir}: not a study (no base_config.toml)")
    base, _ = read_toml(study_dir / "base_config.toml")
    if study.get("format") != STUDY_FORMAT or study.get("format_version") != STUDY_VERSION:
        raise InputError(
            f"{path}: not an arcube study (format {study.get('format')!r} version {study.get('format_version')!r})"
        )
    seeds = study.get("seeds")
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) for s in seeds):
        raise InputError(f"{path}: no seeds list")
    odd = [s for s in seeds if isinstance(s, bool) or s < 0]
    if odd:
        raise InputError(f"{path}: seeds must be whole numbers >= 0, got {odd[0]!r}")
    if len(set(seeds)) != len(seeds):
        raise InputError(f"{path}: seed {next(s for s in seeds if seeds.count(s) > 1)} is listed twice")
    try:
        executor_table({"workers": study.get("workers", 1), "dask": study.get("dask", "")}, prefix="")
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    return study, _validated(study_dir / "base_config.toml", base) if config else None
