"""What an optimization or a study leaves: a run folder (:class:`Run`), a study folder
(:class:`Study`), or a run held in memory (:class:`OptimizeResult`). Each gives the summary, the
best design(s), the history and the front."""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.model.design import Design

__all__ = ["OptimizeResult", "Run", "Study"]

PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class OptimizeResult:
    """An optimization run held in memory (what :func:`optimize` returns without ``out``): the same
    summary, designs, history and front a run folder's files hold."""

    summary: dict[str, Any]
    """What ``summary.json`` holds (``files`` empty)."""
    designs: list[Design]
    """The best design of each slot (one per setup, and per patient with per-patient docking)."""
    history: dict[str, np.ndarray]
    """One row per generation, as columns (``history.csv``'s)."""
    pareto: dict[str, np.ndarray] | None
    """The feasible front (multi-objective runs, ``pareto.csv``'s columns), else None."""
    config: dict[str, Any]
    """What ``config.toml`` would hold."""

    @property
    def best_design(self) -> Design:
        """The best design found (the first slot's: patient 1, right side)."""
        return self.designs[0]


@dataclass(frozen=True)
class Run:
    """An optimization run folder (``config.toml``, ``history.csv``, ``best_design.json``, ``summary.json``)."""

    path: Path

    @classmethod
    def load(cls, path: PathLike) -> Run:
        """Open an existing run folder (InputError if it is not one)."""
        p = Path(path)
        if not (p / "config.toml").exists():
            raise InputError(f"{p}: not an optimization run (no config.toml)")
        return cls(p)

    @property
    def summary(self) -> dict[str, Any]:
        """``summary.json``: feasible, eta_G, dexterity, generations, wall time, per-task details."""
        try:
            return json.loads((self.path / "summary.json").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{self.path}: the run has not finished (no summary.json)") from None

    @property
    def best_design(self) -> Design:
        """The best design found (right-side placement when the run had two setups)."""
        return Design.from_json(self.path / "best_design.json")

    @property
    def designs(self) -> list[Design]:
        """One complete design per patient (its own placement with per-patient docking, else the shared
        design for every patient); with two setups, the right-side ones."""
        from arcube.optimization import run as runmod

        cfg = runmod.read_config(self.path)[0]
        n = len(cfg["patients"])
        if cfg["settings"].get("docking", "shared") == "per-patient" and n > 1:
            return [Design.from_json(self.path / runmod.placement_file(p)) for p in range(n)]  # each must exist
        return [Design.from_json(self.path / "best_design.json") for _ in range(n)]

    @property
    def history(self) -> dict[str, np.ndarray]:
        """``history.csv`` as columns: generation, evaluations, best_eta_G, ... (NaN where empty)."""
        return _read_columns(self.path / "history.csv")

    @property
    def pareto(self) -> dict[str, np.ndarray] | None:
        """``pareto.csv`` as columns (multi-objective runs), else None."""
        path = self.path / "pareto.csv"
        return _read_columns(path) if path.exists() else None

    def write_report(self, anatomy: Any = None, anatomy_frame: str = "LPS", best_known: float | None = None) -> Path:
        """Write ``report.html`` (and PNGs; ``report_p<K>.html`` for each further patient) into the run folder; returns its path.

        ``anatomy``: None (the run's own, copied into its folder), ``"none"``, ``"default"`` or mesh
        files in ``anatomy_frame``, as :func:`evaluate` takes it. ``best_known``: an eta_G drawn as
        a reference line on the convergence plot.
        """
        from arcube.report.run_report import write_run_report

        override = None
        if anatomy is not None:
            from arcube.optimization import run as runmod

            plans = runmod.read_config(self.path)[0]["settings"].get("trajectories") or ["reference"]
            override = [resolve_anatomy(anatomy, anatomy_frame, plan) or "none" for plan in plans]  # each patient's own
        return write_run_report(self.path, anatomy=override, best_known=best_known)


def _read_columns(path: Path) -> dict[str, np.ndarray]:
    """A CSV of numbers (and a few text columns) as name -> array; numeric columns as float."""
    try:
        with path.open(encoding="utf-8", newline="") as fh:
            rows = list(csv.DictReader(fh))
    except FileNotFoundError:
        raise InputError(f"{path}: missing (the run has not written it)") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})") from None
    if not rows:
        return {}
    out: dict[str, np.ndarray] = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        try:
            out[key] = np.array([float(v) if v != "" else np.nan for v in values])
        except ValueError:
            out[key] = np.array(values)
    return out


@dataclass(frozen=True)
class Study:
    """A design study folder: one optimization run per seed (``seed_<S>/``), ``study.csv``, ``summary.json``."""

    path: Path

    @classmethod
    def load(cls, path: PathLike) -> Study:
        """Open an existing study folder (InputError if it is not one)."""
        from arcube.optimization import study as studymod

        studymod.read_study(Path(path))
        return cls(Path(path))

    @property
    def summary(self) -> dict[str, Any]:
        """``summary.json``: objective, best / median / worst, best_seed, spread_pct, wall_s, one row per seed."""
        try:
            return json.loads((self.path / "summary.json").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{self.path}: the study has not finished (no summary.json)") from None

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
    def runs(self) -> dict[int, Run]:
        """Each seed's :class:`Run`."""
        from arcube.optimization import study as studymod

        seeds = studymod.read_study(self.path)[0]["seeds"]
        return {int(s): Run(studymod.seed_dir(self.path, int(s))) for s in seeds}
