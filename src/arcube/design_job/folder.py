"""A design job's folder, read strictly: ``design.toml`` (its requirements, seeds and held-out cohort) and the study's
``summary.json``. A damaged file is one line naming it (:class:`~arcube.errors.InputError`), never a traceback."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from arcube.design_job.requirements import Requirement
from arcube.errors import InputError

__all__ = ["DESIGN_FORMAT", "STUDY", "is_design", "read_design", "read_study_summary"]

DESIGN_FORMAT = "arcube-design"
STUDY = "study"


def is_design(path: Path) -> bool:
    """Whether ``path`` holds a design job (design.toml)."""
    return (Path(path) / "design.toml").is_file()


def read_design(out: Path) -> tuple[dict[str, Any], list[Requirement]]:
    """design.toml and its requirements (InputError if it is not a design folder)."""
    path = Path(out) / "design.toml"
    try:
        meta = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path}: not a readable design job ({exc})") from None
    if meta.get("format") != DESIGN_FORMAT:
        raise InputError(f"{path}: not an arcube design job")
    from arcube.design_job.requirements import REQUIREMENTS

    raw = meta.get("requirements")
    if not isinstance(raw, list):
        raise InputError(
            f"{path}: requirements is {'missing' if raw is None else 'not a list'} (expected [[name, min|max, limit], ...])"
        )
    reqs = []
    for k, item in enumerate(raw, start=1):
        ok = isinstance(item, list) and len(item) == 3 and item[0] in REQUIREMENTS and item[1] in ("min", "max")
        if not ok or isinstance(item[2], bool) or not isinstance(item[2], (int, float)) or not math.isfinite(item[2]):
            raise InputError(
                f"{path}: requirement {k} is not [name, min|max, limit] with a known name and a finite limit: {item!r:.80}"
            )
        reqs.append(Requirement(str(item[0]), str(item[1]), float(item[2])))
    seeds = meta.get("seeds")
    if (
        not isinstance(seeds, list)
        or not seeds
        or not all(isinstance(x, int) and not isinstance(x, bool) for x in seeds)
    ):
        raise InputError(f"{path}: seeds is not a list of integers")
    return meta, reqs


def read_study_summary(out: Path) -> dict[str, Any]:
    """The study's summary.json of a design folder, checked: an object with the objective and one row per seed
    (seed, feasible, violation); one line naming the file when it is damaged."""
    from arcube.io.inputs import load_json

    path = Path(out) / STUDY / "summary.json"
    study = load_json(path)
    rows = study.get("rows") if isinstance(study, dict) else None
    if (
        not isinstance(study, dict)
        or not isinstance(study.get("objective"), str)
        or not isinstance(rows, list)
        or not rows
    ):
        raise InputError(
            f"{path}: not a study summary (an object with the objective and its rows); run 'arcube resume' on a folder "
            "whose study/ holds its seeds, or design anew"
        )
    for k, r in enumerate(rows, start=1):
        if not (
            isinstance(r, dict)
            and isinstance(r.get("seed"), int)
            and isinstance(r.get("feasible"), bool)
            and isinstance(r.get("violation"), (int, float))
        ):
            raise InputError(f"{path}: row {k} is not a seed's row (seed, feasible, violation)")
    return study
