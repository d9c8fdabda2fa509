"""A cohort file: the patients of one design job (``arcube design --cohort cohort.toml``, MODEL.md 19).

::

    [[patient]]
    name = "patient_a"                       # unique; used in file names and tables
    plan = "patient_a/plan.csv"              # CSV, .mrk.json or folder ("reference": the bundled patient)
    anatomy = ["patient_a/anatomy/C3.stl"]   # mesh or segmentation files, "default" or "none" [default: default]
    anatomy_frame = "LPS"                    # LPS (default), RAS or patient
    segments = ["C3", "C4"]                  # of segmentation files (names or label values) [default: all]
    envelope = "default"                     # the whole patient (MODEL.md 19.5): default, none or skin files
    table_z = -180.0                         # the table's top, mm, patient frame [default: below the skin]

Paths are relative to the cohort file. :func:`read_cohort` checks every entry before anything is
written (each file exists, each plan has trajectories, names are unique and fit in file names, no
unknown key) and refuses the first problem in one line naming the file and the entry.
``arcube patients --out DIR --count N`` writes such a file for its patients (:func:`arcube.patients.cohort.cohort_toml`).
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.optimization.config import PatientPlan

__all__ = ["COHORT_KEYS", "plans_as_cohort", "read_cohort"]

COHORT_KEYS = ("name", "plan", "anatomy", "anatomy_frame", "segments", "envelope", "table_z")
"""The keys of a ``[[patient]]`` entry (``name`` and ``plan`` required)."""
FRAMES = ("LPS", "RAS", "patient")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
WORDS = ("default", "none")


def _paths(value: Any, key: str, base: Path, where: str) -> tuple[str, ...]:
    """``"default"``, ``"none"``, one path or a list of paths -> the words, or absolute paths that exist."""
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not items or not all(isinstance(v, str) and v.strip() for v in items):
        raise InputError(f"{where}: {key} must be \"default\", \"none\" or a list of files, got {short_repr(value)}")
    items = [v.strip() for v in items]
    if any(v in WORDS for v in items):
        if len(items) != 1:
            raise InputError(f"{where}: {key} {short_repr(value)}: \"default\" and \"none\" stand alone (not with files)")
        return (items[0],)
    out = []
    for v in items:
        path = (base / v) if not os.path.isabs(v) else Path(v)
        if not path.exists():
            raise InputError(f"{where}: {key} file {v!r} does not exist ({path})")
        out.append(str(path.resolve()))
    return tuple(out)


def _entry(raw: Any, k: int, base: Path, source: Path) -> PatientPlan:
    where = f"{source}: patient {k + 1}"
    if not isinstance(raw, dict):
        raise InputError(f"{where}: expected a [[patient]] table, got {short_repr(raw)}")
    name = raw.get("name")
    if isinstance(name, str) and name:
        where = f"{source}: patient {k + 1} ({name})"
    unknown = [key for key in raw if key not in COHORT_KEYS]
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(COHORT_KEYS)})")
    for key in ("name", "plan"):
        if key not in raw:
            raise InputError(f"{where}: {key} is missing")
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"{where}: name must be 1-64 letters, digits, '_', '.' or '-' (it names files), got {short_repr(name)}")
    plan = raw["plan"]
    if not isinstance(plan, str) or not plan.strip():
        raise InputError(f"{where}: plan must be a file or folder name, got {short_repr(plan)}")
    if plan.strip() != "reference":
        path = base / plan if not os.path.isabs(plan) else Path(plan)
        if not path.exists():
            raise InputError(f"{where}: plan {plan!r} does not exist ({path})")
        plan = str(path.resolve())
    anatomy = _paths(raw.get("anatomy", "default"), "anatomy", base, where)
    frame = raw.get("anatomy_frame", "LPS")
    if frame not in FRAMES:
        raise InputError(f"{where}: anatomy_frame must be one of {', '.join(FRAMES)}, got {short_repr(frame)}")
    segments = raw.get("segments")
    if segments is not None:
        items = segments.split(",") if isinstance(segments, str) else segments
        if not isinstance(items, list) or not items or not all(isinstance(s, (str, int)) and not isinstance(s, bool) for s in items):
            raise InputError(f"{where}: segments must be names or label values, got {short_repr(segments)}")
        segments = tuple(str(s).strip() for s in items)
    envelope = _paths(raw["envelope"], "envelope", base, where) if "envelope" in raw else None
    table_z = raw.get("table_z")
    if table_z is not None and (isinstance(table_z, bool) or not isinstance(table_z, (int, float)) or not math.isfinite(table_z)):
        raise InputError(f"{where}: table_z must be a number of mm, got {short_repr(table_z)}")
    return PatientPlan(name, plan, () if anatomy == ("none",) else anatomy, frame, segments, envelope,
                       None if table_z is None else float(table_z))  # fmt: skip


def read_cohort(path: str | os.PathLike[str], *, side: str | None = None, levels: Any = None, ids: Any = None,
                transform: Any = None) -> list[PatientPlan]:  # fmt: skip
    """The patients of a cohort file, checked (module docstring); each plan is read, and after the run's
    selection (``side``, ``levels``, ``ids``) must keep a trajectory. InputError naming the file and the entry."""
    from arcube.io import load_trajectories, select

    source = Path(path)
    try:
        data = tomllib.loads(source.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError.of("cohort", f"{source}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError.of("cohort", f"{source}: cannot read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError.of("cohort", f"{source}: not valid TOML ({exc})") from None
    unknown = [k for k in data if k != "patient"]
    if unknown:
        raise InputError.of("cohort", f"{source}: unknown key {unknown[0]!r} (a cohort file holds [[patient]] tables only)")
    raw = data.get("patient")
    if not isinstance(raw, list) or not raw:
        raise InputError.of("cohort", f"{source}: no [[patient]] entries")
    base = source.resolve().parent
    patients = [_entry(r, k, base, source) for k, r in enumerate(raw)]
    seen: dict[str, int] = {}
    for k, p in enumerate(patients):
        if p.name in seen:
            raise InputError.of("cohort", f"{source}: patient {k + 1} ({p.name}): the name is already patient {seen[p.name] + 1}'s")
        seen[p.name] = k
    for k, p in enumerate(patients):
        where = f"{source}: patient {k + 1} ({p.name})"
        try:
            ts = load_trajectories(p.plan, transform)
            if side is not None or levels is not None or ids is not None:
                ts = select(ts, side=side, levels=levels, ids=ids)
        except InputError as exc:
            raise InputError.of("cohort", f"{where}: plan: {exc}") from None
        if not len(ts.ids):
            raise InputError.of("cohort", f"{where}: the plan has no trajectories")
    return patients


def plans_as_cohort(plans: Sequence[Any]) -> list[PatientPlan] | None:
    """Several ``--trajectories`` as a cohort of patients named after their files (None for one plan: it keeps the run's own
    settings, as every job before MODEL.md 19)."""
    names = []
    for k, plan in enumerate(plans):
        stem = Path(os.fspath(plan)).name.split(".")[0] if isinstance(plan, (str, os.PathLike)) else getattr(plan, "source", "")
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", str(stem))[:60] or f"patient_{k + 1}"
        names.append(stem if stem[0].isalnum() else f"p{stem}")
    if len(set(names)) != len(names):
        names = [f"patient_{k + 1}" for k in range(len(plans))]
    return [PatientPlan(n, p) for n, p in zip(names, plans)]
