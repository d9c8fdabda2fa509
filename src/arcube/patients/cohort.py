"""Cohorts of virtual patients on disk: CSV + drawn parameters + default anatomy per patient, and their checks."""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.io.files import atomic_write_files
from arcube.io.inputs import short_repr
from arcube.io.trajectories import TrajectorySet, read_csv
from arcube.patients.anatomy_segments import anatomy_suffix, write_anatomy_as
from arcube.patients.virtual import TECHNIQUES, check_patient, format_check, generate_patient, write_patient

__all__ = [
    "COHORT_FILE",
    "MAX_PATIENTS",
    "NarrowPedicle",
    "WrittenPatients",
    "cohort_toml",
    "narrow_pedicles",
    "narrow_summary",
    "patient_files",
    "patient_name",
    "patient_paths",
    "write_patients",
]

MAX_PATIENTS = 10_000
"""The most patients one call writes (each is three or four files)."""


def write_patients(
    mean: bool,
    seed: int | None,
    technique: str,
    count: int,
    out: Path,
    *,
    anatomy_format: str = "stl",
    anatomy_spacing_mm: float = 0.5,
    beside: Callable[[Path], str] | None = None,
) -> WrittenPatients:
    """Generate, write and check the patients; return one check text per patient (a list) whose ``narrow`` lists
    the pedicles narrower than the default screw (:func:`narrow_pedicles`; ``arcube patients`` warns of them).

    Args:
        mean: the mean patient (every parameter at its published mean).
        seed: seed of patient 0; patient k uses ``seed + k`` so each file can be regenerated
            on its own from the seed stored in its JSON.
        technique: pedicle, roy-camille, magerl or an.
        count: number of patients K (>= 1).
        out: K = 1: the CSV path (``*.csv``; any other path is a folder, created, that receives ``patient_000.csv``);
            K > 1: a folder (created) receiving ``patient_000.csv`` ... ``patient_{K-1}.csv``, and ``cohort.toml``
            (every patient of the folder, for ``arcube design --cohort``, named by :func:`patient_name`: ``seed7`` ...).
            Each CSV gets its drawn parameters beside it as ``<stem>.json`` and its default
            anatomy (model §14.2, :mod:`arcube.patients.anatomy`) as ``<stem>.anatomy.stl``
            (binary STL, patient frame, one closed shell per box). All of these files are written, or
            none (they are made in a staging folder and put in place together; a file of the same name is
            replaced, a folder or device where one goes is refused before anything is written).
        anatomy_format: ``stl`` (default), ``seg.nrrd`` (3D Slicer segmentation, LPS) or ``nii.gz``
            (NIfTI label map, RAS): the anatomy file is then ``<stem>.anatomy.seg.nrrd`` or
            ``<stem>.anatomy.nii.gz``, one segment per vertebra and one for soft tissue
            (:mod:`arcube.patients.anatomy_segments`).
        anatomy_spacing_mm: voxel size of a label-map anatomy, mm (> 0).

    A folder's ``cohort.toml`` records in its leading comment how many pedicles of its plans are narrower than the
    default screw (0 included), and which (:func:`narrow_summary`).
    """
    anatomy_suffix(anatomy_format)
    if anatomy_format != "stl" and (
        isinstance(anatomy_spacing_mm, bool)
        or not isinstance(anatomy_spacing_mm, (int, float))
        or not 0 < anatomy_spacing_mm < float("inf")
    ):
        raise InputError.of("anatomy_spacing_mm", f"{anatomy_spacing_mm!r}: expected a positive number of mm")
    if mean and seed is not None:
        raise InputError.of("mean", "excludes a seed: the mean patient has no random draws (give one or the other)")
    if not mean and seed is None:
        raise InputError.of("seed", "is missing: give a seed for random patients, or ask for the mean patient")
    if technique not in TECHNIQUES:
        raise InputError.of("technique", f"{short_repr(technique)}: expected one of {', '.join(TECHNIQUES)}")
    if mean and count > 1:
        raise InputError.of("count", f"{count} for the mean patient would write identical patients")
    if seed is not None and seed < 0:
        raise InputError.of("seed", f"{seed}: expected a non-negative integer")
    paths = patient_paths(out, count)
    # Every file is made in a staging folder beside the output first; only when every patient is written
    # (and its anatomy read back by the envelope's writer) do they all go into place, as one output.
    parent = paths[0].parent
    made = [a for a in (*reversed(parent.parents), parent) if not a.exists()]
    try:  # the path given is named, not the staging folder beside it
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{parent.name or 'patients'}.", suffix=".tmp", dir=parent))
    except OSError as exc:
        _remove_made(made)
        blocker = next((p for p in (parent, *parent.parents) if p.exists() and not p.is_dir()), None)
        why = f"{blocker} is a file, not a folder" if blocker is not None else exc.strerror or str(exc)
        raise InputError.of("out", f"{out}: cannot write in {parent} ({why})") from None
    try:
        texts, entries, narrow = _stage_patients(
            paths, stage, mean, seed, technique, anatomy_format, anatomy_spacing_mm, beside
        )
        if (
            paths[0].parent == out
        ):  # a folder of patients: the cohort file of one design job for all of them (model §19)
            (stage / COHORT_FILE).write_text(cohort_toml(entries, narrow))
            texts.append(
                f"# {out / COHORT_FILE}: the cohort of these {len(entries)} patient(s), for arcube design --cohort {out / COHORT_FILE}"
            )
        staged = sorted(stage.iterdir(), key=lambda f: f.stat().st_mtime_ns)  # the order they were made in
        atomic_write_files({parent / f.name: f.read_bytes() for f in staged})
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        _remove_made(made)
        if isinstance(exc, InputError) and str(stage) in str(exc):  # the file it was making, not the staging folder
            raise InputError(str(exc).replace(str(stage), str(parent)), param=exc.param) from None
        raise
    shutil.rmtree(stage, ignore_errors=True)
    return WrittenPatients(texts, narrow)


def _remove_made(made: list[Path]) -> None:
    """Remove the folders a write made (parents first in ``made``), deepest first, while nothing went into them."""
    for folder in reversed(made):
        try:
            folder.rmdir()
        except OSError:
            break


def patient_paths(out: Path, count: int) -> list[Path]:
    """The plan CSVs :func:`write_patients` writes for ``count`` patients at ``out``: ``out`` itself (one patient,
    a ``*.csv`` path), else ``out/patient_000.csv`` ...; InputError for an ``out`` that cannot hold them."""
    if count < 1:
        raise InputError.of("count", f"{count}: expected at least 1")
    if count > MAX_PATIENTS:
        raise InputError.of("count", f"{count}: at most {MAX_PATIENTS} patients in one folder")
    if out.suffix.lower() == ".json":  # the parameters go to <stem>.json; a folder so named is a mistake too
        raise InputError.of("out", f"{out}: the CSV path must not end in .json (the parameters go there)")
    if not out.is_dir() and out.suffix.lower() == ".csv":
        if count == 1:
            return [out]
        raise InputError.of("out", f"{out}: a .csv path holds one patient; give a folder for {count}")
    if out.exists() and not out.is_dir():
        raise InputError.of("out", f"{out}: exists and is not a folder (needed for more than one patient)")
    width = max(3, len(str(count - 1)))
    return [out / f"patient_{k:0{width}d}.csv" for k in range(count)]


def patient_files(out: Path, count: int, anatomy_format: str = "stl") -> list[Path]:
    """Every file :func:`write_patients` writes (without what ``beside`` adds): each patient's CSV, its parameters
    JSON and its anatomy, and a folder's ``cohort.toml``."""
    paths = patient_paths(out, count)
    suffix = anatomy_suffix(anatomy_format)
    files = [f for p in paths for f in (p, p.with_suffix(".json"), p.with_suffix(suffix))]
    return files + ([out / COHORT_FILE] if paths[0].parent == out else [])


def _stage_patients(
    paths: list[Path],
    stage: Path,
    mean: bool,
    seed: int | None,
    technique: str,
    anatomy_format: str,
    anatomy_spacing_mm: float,
    beside: Callable[[Path], str] | None,
) -> tuple[list[str], list[dict[str, Any]], list[NarrowPedicle]]:
    """Write each patient's files into ``stage`` under the names of ``paths``; the check texts name ``paths``.
    Also returns the cohort file's entries and the pedicles narrower than the default screw."""
    suffix = anatomy_suffix(anatomy_format)
    texts: list[str] = []
    entries: list[dict[str, Any]] = []
    narrow: list[NarrowPedicle] = []
    for k, path in enumerate(paths):
        ts, params = generate_patient(None if mean else seed + k, technique)  # type: ignore[operator]
        staged = stage / path.name
        anatomy_path = path.with_suffix(suffix)
        # the anatomy first: a label map can fail (spacing too coarse or too fine) before the CSV exists
        layout = write_anatomy_as(params, staged.with_suffix(suffix), anatomy_format, anatomy_spacing_mm)
        json_path = path.with_suffix(".json")
        write_patient(ts, params, staged)
        frame = {
            "stl": "patient frame",
            "seg.nrrd": f"LPS label map, {anatomy_spacing_mm:g} mm voxels",
            "nii.gz": f"RAS label map, {anatomy_spacing_mm:g} mm voxels",
        }[anatomy_format]
        # The check re-reads the written file, so it sees the 3-decimal points a user gets (and the pedicles'
        # widths and heights that arcube breach reads).
        back = read_csv(staged)
        check = format_check(check_patient(back, params))
        narrow += narrow_pedicles(back, patient_name(params), path)
        # what a higher layer writes beside the plan (its envelope; it reads the anatomy back on the way)
        more = "" if beside is None else beside(staged).replace(str(stage), str(path.parent))
        texts.append(
            f"# {path} (parameters: {json_path}; default anatomy: {anatomy_path}, {frame}{more})\n"
            f"# {layout.summary()}\n{check}"
        )
        entries.append(
            {
                "name": patient_name(params),
                "plan": path.name,
                "anatomy": [anatomy_path.name],
                "anatomy_frame": COHORT_FRAMES[anatomy_format],
            }
        )
    return texts, entries, narrow


def patient_name(params: dict[str, Any]) -> str:
    """A virtual patient's name in a cohort file: what makes it the patient it is, ``seed<S>`` (``mean`` for the mean
    patient), after its technique when that is not the pedicle screw (``magerl_seed<S>``). Two cohorts that share a
    name share that patient: a design job refuses such a held-out cohort (model §19.6)."""
    base = "mean" if params.get("seed") is None else f"seed{params['seed']}"
    return base if params.get("technique", "pedicle") == "pedicle" else f"{params['technique']}_{base}"


COHORT_FILE = "cohort.toml"
"""The cohort file ``arcube patients`` writes into a folder of patients."""
COHORT_FRAMES = {"stl": "patient", "seg.nrrd": "LPS", "nii.gz": "RAS"}
"""The frame a cohort entry names for each anatomy format (the STL is written in the patient frame)."""


def cohort_toml(entries: list[dict[str, Any]], narrow: Sequence[NarrowPedicle] | None = None) -> str:
    """A cohort file's text (``arcube design --cohort``): one ``[[patient]]`` table per entry, paths relative to the file.

    ``narrow``: the pedicles of these patients narrower than the default screw (:func:`narrow_pedicles`); given (an
    empty list too), the leading comment says how many there are and which (:func:`narrow_summary`)."""
    lines = [
        "# arcube cohort: the patients of one design job (arcube design --cohort cohort.toml); paths relative to this file"
    ]
    if narrow is not None:
        lines.append(f"# {narrow_summary(narrow)}")
    for e in entries:
        lines += ["", "[[patient]]", *(f"{k} = {json.dumps(v)}" for k, v in e.items())]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class NarrowPedicle:
    """A pedicle of a written plan that is no wider (or no taller) than the default screw (model §22.3: the screw has
    no room there, and ``arcube breach`` flags it ``too_wide``). Lengths in mm, as written in the plan."""

    patient: str
    """The patient's name in a cohort file (:func:`patient_name`: ``seed57``)."""
    plan: Path
    """The plan CSV that holds the screw."""
    trajectory: str
    """The screw's trajectory id in the plan."""
    level: str
    side: str
    width_mm: float
    height_mm: float
    screw_mm: float
    """The default screw's diameter it is compared with."""

    def describe(self) -> str:
        """``seed57 C4 R (width 3.41 mm)``: the patient, level, side and the dimension(s) the screw does not fit."""
        sizes = [
            f"{what} {value:.2f}"
            for what, value in (("width", self.width_mm), ("height", self.height_mm))
            if value <= self.screw_mm
        ]
        return f"{self.patient} {self.level} {self.side} ({', '.join(sizes)} mm)"


class WrittenPatients(list[str]):
    """What :func:`write_patients` returns: one check text per patient (and one line naming a folder's cohort file),
    as a list; ``narrow`` holds the pedicles of the written plans narrower than the default screw."""

    def __init__(self, texts: Sequence[str] = (), narrow: Sequence[NarrowPedicle] = ()) -> None:
        super().__init__(texts)
        self.narrow: tuple[NarrowPedicle, ...] = tuple(narrow)


def narrow_pedicles(plan: TrajectorySet, patient: str, path: Path) -> list[NarrowPedicle]:
    """The screws of ``plan`` (as written and read back) whose pedicle is no wider or no taller than the default screw
    (:data:`arcube.patients.isthmus.DEFAULT_SCREW_MM`): those ``arcube breach`` flags ``too_wide`` unless given another
    screw. A plan without pedicle columns (the mean patient, lateral-mass screws) takes the levels' means: none."""
    from arcube.patients.isthmus import DEFAULT_SCREW_MM, isthmus_mean

    out = []
    for j, level in enumerate(plan.levels):
        # the widths and heights arcube breach takes: the plan's columns, the level's mean where a cell is empty
        mean = isthmus_mean(level)
        cells = plan.pedicle[j, :2] if plan.pedicle is not None else (math.nan, math.nan)
        width, height = (float(c) if math.isfinite(c) else m for c, m in zip(cells, mean))
        if min(width, height) <= DEFAULT_SCREW_MM:  # no room: a' = (W - d)/2 <= 0 or b' <= 0 (model §22.3)
            out.append(NarrowPedicle(patient, path, plan.ids[j], level, plan.sides[j], width, height, DEFAULT_SCREW_MM))
    return out


NARROW_SHOWN = 3
"""How many narrow pedicles :func:`narrow_summary` names before ``and N more``."""


def narrow_summary(narrow: Sequence[NarrowPedicle], shown: int = NARROW_SHOWN) -> str:
    """One line: ``1 pedicle narrower than the default 3.5 mm screw: seed57 C4 R (width 3.41 mm)``, the first ``shown``
    named and then ``and N more``; ``0 pedicles narrower than the default 3.5 mm screw`` when there is none."""
    from arcube.patients.isthmus import DEFAULT_SCREW_MM

    n = len(narrow)
    text = f"{n} pedicle{'' if n == 1 else 's'} narrower than the default {DEFAULT_SCREW_MM:g} mm screw"
    if not n:
        return text
    names = ", ".join(q.describe() for q in narrow[:shown])
    more = f" and {n - shown} more" if n > shown else ""
    return f"{text}: {names}{more}"
