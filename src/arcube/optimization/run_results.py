"""What an optimization or a study leaves: a run (:class:`OptimizeResult`, in memory or in its
folder) and a study folder (:class:`Study`). Each gives the summary, the best design(s), the
history and the front; drawing them is the report's (:func:`arcube.write_report`)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import parse_decimal
from arcube.io.tables import read_table
from arcube.model.design import Design
from arcube.optimization.folder import placement_file, read_config, read_study, seed_dir
from arcube.optimization.run_config import RunConfig
from arcube.summary import Summary

__all__ = ["OptimizeResult", "RunSummary", "Study", "StudySummary"]

PathLike = str | os.PathLike[str]
S = TypeVar("S", bound=Summary)


class RunSummary(Summary):
    """The summary of an optimization run (``summary.json``, ``OptimizeResult.summary``); fields a run does not
    have (a single-objective run's front, a run without c_z ...) read None."""

    feasible: bool
    """Whether the best design meets every guard and limit."""
    eta_G: float
    """The best design's eta_G (model §8.3; over the run's tasks as ``aggregate`` says)."""
    dexterity_pct: dict[str, float]
    """Inverted condition number over the points, percent: ``min``, ``mean``, ``max``."""
    generations: int
    evaluations: int
    seed: int
    wall_s: float
    """Wall time of the run over all its sessions, s."""
    eval_s: float
    """Time spent evaluating designs, s."""
    stopped_by: str
    """What ended the run (``generations``, ``evaluations``, ``ftol`` ...)."""
    algorithm: str
    population: int
    engine: str
    """The evaluation engine used (``numba`` or ``numpy``)."""
    mode: str
    """The working mode of the best design (model §4.3, 5.3)."""
    setups: int
    aggregate: str
    free: list[str]
    """The free parameters."""
    violation: float
    """The best design's constraint violation (0: feasible)."""
    docking_violations: list[float] | None
    """Each docking's own violation V_k (model §19.3) of the best design, in the config's patient order (runs over
    dockings only; 0: the search calls that docking feasible)."""
    margin_shortfall_rad: float
    links_sum_mm: float
    bbox_volume_L: float
    clearance_min_mm: float | None
    self_clearance_min_mm: float | None
    envelope_clearance_min_mm: float | None
    tip_error_max_mm: float | None
    lateral_error_max_mm: float | None
    axial_error_max_mm: float | None
    axis_error_max_deg: float | None
    torque_max_Nm: float | None
    deflection_max_mm: float | None
    holding_torque_max_Nm: float | None
    moving_mass_kg: float | None
    lateral_error_wc_mm: float | None
    """Worst-case lateral error under the run's tolerances, mm (model §20.3); None unless an objective or limit."""
    lateral_error_rms_mm: float | None
    tolerance_class: str | None
    c_z: float | None
    """The run's z-dyad link, mm (model §19.1), when it has its own."""
    objectives: list[str]
    limits: list[list[Any]]
    """``[name, "max" | "min", value]`` per limit."""
    anatomy: list[str | None] | None
    """Each patient's anatomy source, None without anatomy."""
    tasks: list[dict[str, Any]]
    """One entry per task (patient, side, approach): its label and figures."""
    points: int
    files: dict[str, str]
    """The run folder's files by role."""
    resumed: int
    """Sessions after the first."""
    placement: str
    docking: str
    """``placement``'s name before 0.3 (kept for one release)."""
    front_size: int | None
    """Designs on the feasible front (multi-objective runs)."""
    compactness: str | None


class StudySummary(Summary):
    """The summary of a study (``summary.json`` of a study folder, ``Study.summary``): one optimization per seed."""

    format: str
    objective: str
    """The objective the seeds are ranked by (the run's first)."""
    seeds: list[int]
    feasible_seeds: int
    """Seeds whose best design meets every guard and limit."""
    best: float | None
    """The best seed's objective value (None: no seed feasible)."""
    median: float | None
    worst: float | None
    best_seed: int
    spread_pct: float | None
    """(worst - best) / best over the feasible seeds, percent."""
    wall_s: float
    """The seeds' wall times summed, s."""
    rows: list[dict[str, Any]]
    """One row per seed (study.csv's)."""


class OptimizeResult:
    """An optimization run: what :func:`arcube.optimize` returns, with or without a run folder.

    In memory (no ``out``) it holds the summary, designs, history and front; written to a folder it
    reads them from the folder's files when asked (``summary.json``, ``best_design*.json``,
    ``history.csv``, ``pareto.csv``, ``config.toml``), so that a folder opened with :meth:`load` and a
    run just finished look the same. :attr:`path` is the folder, or None in memory.
    """

    def __init__(
        self,
        path: PathLike | None = None,
        *,
        summary: dict[str, Any] | None = None,
        designs: list[Design] | None = None,
        history: dict[str, np.ndarray] | None = None,
        pareto: dict[str, np.ndarray] | None = None,
        config: RunConfig | None = None,
    ) -> None:
        if path is None and (summary is None or designs is None or history is None or config is None):
            raise InputError.of("path", "is required for a run that is not held in memory")
        self.path = None if path is None else Path(path)
        self._held = None if path is not None else (summary, designs, history, pareto, config)

    def __repr__(self) -> str:
        return f"OptimizeResult({'in memory' if self.path is None else str(self.path)!s})"

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, OptimizeResult) and other.path == self.path and (self.path is not None or other is self)
        )

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def load(cls, path: PathLike) -> OptimizeResult:
        """Open an existing run folder (InputError if it is not one)."""
        p = Path(path)
        if not (p / "config.toml").exists():
            raise InputError(f"{p}: not an optimization run (no config.toml)")
        return cls(p)

    @property
    def summary(self) -> RunSummary:
        """``summary.json``: feasible, eta_G, dexterity, generations, wall time, per-task details."""
        if self._held is not None:
            return RunSummary(self._held[0])
        return _read_summary(self.path, RunSummary, "run")

    @property
    def designs(self) -> list[Design]:
        """The best design of each slot: one complete design per patient (its own placement with
        per-patient docking, else the shared design for every patient); with two setups in memory,
        the left side's follow each patient's right side."""
        if self._held is not None:
            return self._held[1]
        cfg = read_config(self.path)[0]
        n = len(cfg.patients)
        if cfg.settings.placement == "per-patient" and n > 1:
            return [Design.from_json(self.path / placement_file(p)) for p in range(n)]  # each must exist
        return [Design.from_json(self.path / "best_design.json") for _ in range(n)]

    @property
    def best_design(self) -> Design:
        """The best design found (the first slot's: patient 1, right side)."""
        if self._held is not None:
            return self._held[1][0]
        return Design.from_json(self.path / "best_design.json")

    @property
    def history(self) -> dict[str, np.ndarray]:
        """One row per generation as columns (``history.csv``'s: generation, evaluations, best_eta_G, ...; NaN where empty)."""
        if self._held is not None:
            return self._held[2]
        return _read_columns(self.path / "history.csv")

    @property
    def pareto(self) -> dict[str, np.ndarray] | None:
        """The feasible front of a multi-objective run (``pareto.csv``'s columns), else None."""
        if self._held is not None:
            return self._held[3]
        path = self.path / "pareto.csv"
        return _read_columns(path) if path.exists() else None

    @property
    def config(self) -> RunConfig:
        """The run's configuration (what ``config.toml`` holds, or would hold in memory: :meth:`RunConfig.to_toml`)."""
        if self._held is not None:
            return self._held[4]
        return read_config(self.path)[0]


def _read_summary(folder: Path, kind: type[S], what: str) -> S:
    """``folder``'s summary.json as a ``kind``; InputError when the ``what`` (run, study) has not finished or the file
    is not a summary."""
    path = folder / "summary.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{folder}: the {what} has not finished (no summary.json)") from None
    except ValueError as exc:  # not JSON, or not UTF-8
        raise InputError(f"{path}: unreadable ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: not a {what}'s summary (a JSON object)")
    return kind(data)


def _read_columns(path: Path) -> dict[str, np.ndarray]:
    """A CSV of numbers (and a few text columns) as name -> array; a column of numbers (empty cells
    NaN) as float, any other as text. Read as every CSV is (:mod:`arcube.io.tables`)."""
    if not path.exists():
        raise InputError(f"{path}: missing (the run has not written it)")
    table = read_table(path, pipes=False)
    out: dict[str, np.ndarray] = {}
    for j, key in enumerate(table.header):
        values = [cells[j] for _, cells in table.rows]
        parsed = [math.nan if v == "" else parse_decimal(v) for v in values]
        out[key] = np.array(parsed, dtype=float) if all(v is not None for v in parsed) else np.array(values)
    return out if table.rows else {}


@dataclass(frozen=True)
class Study:
    """A design study folder: one optimization run per seed (``seed_<S>/``), ``study.csv``, ``summary.json``."""

    path: Path

    @classmethod
    def load(cls, path: PathLike) -> Study:
        """Open an existing study folder (InputError if it is not one)."""
        read_study(Path(path))
        return cls(Path(path))

    @property
    def summary(self) -> StudySummary:
        """``summary.json``: objective, best / median / worst, best_seed, spread_pct, wall_s, one row per seed."""
        return _read_summary(self.path, StudySummary, "study")

    @property
    def table(self) -> dict[str, np.ndarray]:
        """``study.csv`` as columns: seed, feasible, objective_<name>..., eta_G, generations, evaluations, wall_s."""
        if not (self.path / "study.csv").exists():
            raise InputError(f"{self.path}: the study has not finished (no study.csv)")
        return _read_columns(self.path / "study.csv")

    @property
    def best_design(self) -> Design:
        """The best seed's best design."""
        return Design.from_json(self.path / "best_design.json")

    @property
    def runs(self) -> dict[int, OptimizeResult]:
        """Each seed's run (:class:`OptimizeResult`)."""
        seeds = read_study(self.path)[0]["seeds"]
        return {int(s): OptimizeResult(seed_dir(self.path, int(s))) for s in seeds}
