"""A cohort file: the patients of one design job (``arcube design --cohort cohort.toml``, model §19).

::

    [[patient]]
    name = "patient_a"                       # unique; used in file names and tables
    plan = "patient_a/plan.csv"              # CSV, .mrk.json or folder ("reference": the bundled patient)
    anatomy = ["patient_a/anatomy/C3.stl"]   # mesh or segmentation files, "default" or "none" [default: default]
    anatomy_frame = "LPS"                    # LPS (default), RAS or patient
    segments = ["C3", "C4"]                  # of segmentation files (names or label values) [default: all]
    envelope = "default"                     # the whole patient (model §19.5): default, none or skin files
    table_z = -180.0                         # the table's top, mm, patient frame [default: below the skin]

Paths are relative to the cohort file. :func:`read_cohort` checks every entry before anything is
written (each file exists, each plan has trajectories, names are unique and fit in file names, no
unknown key) and refuses the first problem in one line naming the file and the entry.
``arcube patients --out DIR --count N`` writes such a file for its patients (:func:`arcube.patients.cohort.cohort_toml`).
"""

from __future__ import annotations

import os
import re
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator, Field, field_validator

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.optimization.config import PatientPlan
from arcube.validation import Settings

__all__ = ["COHORT_KEYS", "CohortPatient", "plans_as_cohort", "read_cohort"]

_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
WORDS = ("default", "none")


def _files(value: Any) -> Any:
    """One path or word as a list of one; a list as it is (each item checked by the field's type)."""
    return [value] if isinstance(value, str) else value


def _segment_list(value: Any) -> Any:
    """``"C3,C4"`` or a list of names and label values (integers) as a list of text."""
    if isinstance(value, str):
        return value.split(",")
    if isinstance(value, list):
        return [str(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    return value


Files = Annotated[tuple[Annotated[str, Field(min_length=1)], ...], BeforeValidator(_files), Field(min_length=1)]


class CohortPatient(Settings):
    """One ``[[patient]]`` table of a cohort file (paths as written: relative to the file)."""

    name: str
    """Unique; 1-64 letters, digits, '_', '.' or '-' (it names the docking folders and table rows)."""
    plan: Annotated[str, Field(min_length=1)]
    """The plan: CSV, .mrk.json or folder ("reference": the bundled patient)."""
    anatomy: Files = ("default",)
    """Mesh or segmentation files, "default" (the plan's default anatomy) or "none"."""
    anatomy_frame: Literal["LPS", "RAS", "patient"] = "LPS"
    """The frame of the anatomy files."""
    segments: Annotated[tuple[str, ...] | None, BeforeValidator(_segment_list)] = None
    """Segments of segmentation files to keep (names or label values); default every labelled segment."""
    envelope: Files | None = None
    """The whole patient (model §19.5): "default", "none" or skin files; default the run's."""
    table_z: Annotated[float, Field(allow_inf_nan=False)] | None = None
    """The table's top, mm, patient frame; default below the skin."""

    @field_validator("name")
    @classmethod
    def _name(cls, v: str) -> str:
        if not re.match(_NAME, v):
            raise ValueError(
                "must be 1-64 letters, digits, '_', '.' or '-' (it names files), starting with a letter or digit"
            )
        return v

    @field_validator("anatomy", "envelope")
    @classmethod
    def _words_alone(cls, v: tuple[str, ...] | None) -> tuple[str, ...] | None:
        if v is not None and len(v) > 1 and any(x.strip() in WORDS for x in v):
            raise ValueError('must be "default", "none" or a list of files, not both')
        return v

    @field_validator("segments")
    @classmethod
    def _segments(cls, v: tuple[str, ...] | None) -> tuple[str, ...] | None:
        if v is not None and (not v or not all(s.strip() for s in v)):
            raise ValueError("must be segment names or label values")
        return None if v is None else tuple(s.strip() for s in v)


COHORT_KEYS = tuple(CohortPatient.model_fields)
"""The keys of a ``[[patient]]`` entry (``name`` and ``plan`` required)."""


def _existing(value: str, key: str, base: Path, where: str, what: str = "cohort") -> str:
    """An absolute path that exists (relative ones to the cohort file's folder); InputError naming the entry."""
    path = (base / value) if not os.path.isabs(value) else Path(value)
    if not path.exists():
        raise InputError.of(what, f"{where}: {key} {value!r} does not exist ({path})")
    return str(path.resolve())


def _entry(raw: Any, k: int, base: Path, source: Path, what: str = "cohort") -> PatientPlan:
    where = f"{source}: patient {k + 1}"
    if not isinstance(raw, dict):
        raise InputError.of(what, f"{where}: expected a [[patient]] table, got {short_repr(raw)}")
    if isinstance(raw.get("name"), str) and raw["name"]:
        where = f"{source}: patient {k + 1} ({raw['name']})"
    unknown = [key for key in raw if key not in COHORT_KEYS]
    if unknown:
        raise InputError.of(what, f"{where}: unknown key {unknown[0]!r} (known: {', '.join(COHORT_KEYS)})")
    missing = [key for key in ("name", "plan") if key not in raw]
    if missing:
        raise InputError.of(what, f"{where}: {missing[0]} is missing")
    try:
        p = CohortPatient(**raw)
    except InputError as exc:
        raise InputError.of(what, f"{where}: {str(exc).removeprefix('CohortPatient.')}") from None
    plan = p.plan.strip() if p.plan.strip() == "reference" else _existing(p.plan, "plan", base, where, what)
    anatomy = (
        p.anatomy
        if p.anatomy[0] in WORDS
        else tuple(_existing(v, "anatomy file", base, where, what) for v in p.anatomy)
    )
    envelope = p.envelope
    if envelope is not None and envelope[0] not in WORDS:
        envelope = tuple(_existing(v, "envelope file", base, where, what) for v in envelope)
    return PatientPlan(
        p.name, plan, () if anatomy == ("none",) else anatomy, p.anatomy_frame, p.segments, envelope, p.table_z
    )


def plan_key(ts: Any) -> bytes:
    """A plan's geometry (every entry and target point, in order), for telling one patient given twice."""
    return (
        np.ascontiguousarray(ts.entry, dtype=float).tobytes() + np.ascontiguousarray(ts.target, dtype=float).tobytes()
    )


def _given_twice(first: str) -> str:
    return f"the same trajectories (every entry and target) as {first}: one patient given twice; a cohort's patients are different people"


def read_cohort(
    path: str | os.PathLike[str],
    *,
    side: str | None = None,
    levels: Any = None,
    ids: Any = None,
    transform: Any = None,
    what: str = "cohort",
) -> list[PatientPlan]:
    """The patients of a cohort file, checked (module docstring); each plan is read, and after the run's
    selection (``side``, ``levels``, ``ids``) must keep a trajectory; two patients with the same plan (every entry and
    target) are refused. InputError naming the file and the entry, and the setting ``what`` (the file's flag)."""
    from arcube.io import load_trajectories, select

    source = Path(path)
    try:
        data = tomllib.loads(source.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError.of(what, f"{source}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError.of(what, f"{source}: cannot read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError.of(what, f"{source}: not valid TOML ({exc})") from None
    unknown = [k for k in data if k != "patient"]
    if unknown:
        raise InputError.of(what, f"{source}: unknown key {unknown[0]!r} (a cohort file holds [[patient]] tables only)")
    raw = data.get("patient")
    if not isinstance(raw, list) or not raw:
        raise InputError.of(what, f"{source}: no [[patient]] entries")
    base = source.resolve().parent
    patients = [_entry(r, k, base, source, what) for k, r in enumerate(raw)]
    seen: dict[str, int] = {}
    for k, p in enumerate(patients):
        if p.name in seen:
            raise InputError.of(
                what, f"{source}: patient {k + 1} ({p.name}): the name is already patient {seen[p.name] + 1}'s"
            )
        seen[p.name] = k
    geometry: dict[bytes, int] = {}
    for k, p in enumerate(patients):
        where = f"{source}: patient {k + 1} ({p.name})"
        try:
            ts = load_trajectories(p.plan, transform)
            j = geometry.setdefault(plan_key(ts), k)
            if j != k:
                raise InputError(_given_twice(f"patient {j + 1} ({patients[j].name})"))
            if side is not None or levels is not None or ids is not None:
                ts = select(ts, side=side, levels=levels, ids=ids)
        except InputError as exc:
            raise InputError.of(what, f"{where}: plan: {exc}") from None
        if not len(ts.ids):
            raise InputError.of(what, f"{where}: the plan has no trajectories")
    return patients


def plans_as_cohort(plans: Sequence[Any]) -> list[PatientPlan] | None:
    """Several ``--trajectories`` as a cohort of patients named after their files (``patient_1`` ... where two names
    clash); two plans with the same trajectories (every entry and target) are one patient given twice: InputError
    naming ``plan``."""
    names = []
    for k, plan in enumerate(plans):
        stem = (
            Path(os.fspath(plan)).name.split(".")[0]
            if isinstance(plan, (str, os.PathLike))
            else getattr(plan, "source", "")
        )
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", str(stem))[:60] or f"patient_{k + 1}"
        names.append(stem if stem[0].isalnum() else f"p{stem}")
    if len(set(names)) != len(names):
        names = [f"patient_{k + 1}" for k in range(len(plans))]
    if len(plans) > 1:
        from arcube.io.load import load_plan

        geometry: dict[bytes, int] = {}
        for k, plan in enumerate(plans):
            j = geometry.setdefault(plan_key(load_plan(plan)), k)
            if j != k:
                raise InputError.of(
                    "plan", f"{_shown(plan)} (plan {k + 1}): {_given_twice(f'plan {j + 1} ({_shown(plans[j])})')}"
                )
    return [PatientPlan(n, p) for n, p in zip(names, plans)]


def _shown(plan: Any) -> str:
    return os.fspath(plan) if isinstance(plan, (str, os.PathLike)) else str(getattr(plan, "source", "") or "a plan")


def docking_count(plans: Sequence[Any] | None, cohort: Any, side: str | None = None, per_patient: bool = False) -> int:
    """How many dockings a design job of ``plans`` (or a ``cohort`` file) makes: each patient's sides (one per patient
    ``per_patient``), after ``side``. For a progress line's time left only: 1 where a plan cannot be read (the job
    itself then says why)."""
    from arcube.io import load_trajectories, select

    try:
        entries = read_cohort(cohort, side=side) if cohort is not None else [PatientPlan("", p) for p in plans or []]
        sides = [
            set(select(load_trajectories(e.plan), side=side).sides) if side else set(load_trajectories(e.plan).sides)
            for e in entries
        ]
    except InputError:
        return 1
    return max(sum(1 if per_patient else len(s) for s in sides if s), 1)
