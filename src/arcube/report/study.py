"""The figure of a design-study folder: ``convergence.png``, best eta_G of every seed against evaluations.

It is drawn from the folder alone (``study.toml``, ``summary.json`` and each seed's ``history.csv``),
after :func:`arcube.optimization.study.start_study` or :func:`~arcube.optimization.study.resume_study`
has finished the study: the optimization layer writes data, this layer draws it (as pymoo's
``Result`` and its ``visualization``). :func:`arcube.study` and :func:`arcube.resume` call it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from arcube.errors import InputError
from arcube.optimization.study import read_study, seed_dir
from arcube.report.figures import History, read_history, study_convergence_png

__all__ = ["STUDY_CONVERGENCE", "write_study_convergence"]

STUDY_CONVERGENCE = "convergence.png"
"""The study folder's convergence figure."""


def write_study_convergence(study_dir: str | os.PathLike[str]) -> Path:
    """Draw ``STUDY_DIR/convergence.png`` of a finished study and return its path.

    One line per seed (the best seed, from ``summary.json``, drawn bold; a seed without a readable
    ``history.csv`` is left out) and the study's ``best_known`` eta_G as a line when it has one.
    Raises :class:`InputError` when the folder is not a study or the study has not finished.
    """
    study_dir = Path(study_dir)
    study, _ = read_study(study_dir)
    try:
        best_seed = json.loads((study_dir / "summary.json").read_text(encoding="utf-8"))["best_seed"]
    except FileNotFoundError:
        raise InputError(f"{study_dir}: the study has not finished (no summary.json)") from None
    histories: dict[int, History] = {}
    for seed in [int(s) for s in study["seeds"]]:
        try:
            histories[seed] = read_history(seed_dir(study_dir, seed) / "history.csv")
        except InputError:
            continue
    return study_convergence_png(
        histories, study_dir / STUDY_CONVERGENCE, best_seed=best_seed, best_known=study.get("best_known")
    )
