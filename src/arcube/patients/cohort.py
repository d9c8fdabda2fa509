"""Cohorts of virtual patients on disk: CSV + drawn parameters + default anatomy per patient, and their checks."""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.io.files import atomic_write_files
from arcube.io.inputs import short_repr
from arcube.io.trajectories import read_csv
from arcube.patients.anatomy_segments import anatomy_suffix, write_anatomy_as
from arcube.patients.virtual import TECHNIQUES, check_patient, format_check, generate_patient, write_patient

__all__ = [
    "COHORT_FILE",
    "MAX_PATIENTS",
    "cohort_toml",
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
) -> list[str]:
    """Generate, write and check the patients; return one check text per patient.

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
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{parent.name or 'patients'}.", suffix=".tmp", dir=parent))
    try:
        texts, entries = _stage_patients(
            paths, stage, mean, seed, technique, anatomy_format, anatomy_spacing_mm, beside
        )
        if (
            paths[0].parent == out
        ):  # a folder of patients: the cohort file of one design job for all of them (model §19)
            (stage / COHORT_FILE).write_text(cohort_toml(entries))
            texts.append(
                f"# {out / COHORT_FILE}: the cohort of these {len(entries)} patient(s), for arcube design --cohort {out / COHORT_FILE}"
            )
        staged = sorted(stage.iterdir(), key=lambda f: f.stat().st_mtime_ns)  # the order they were made in
        atomic_write_files({parent / f.name: f.read_bytes() for f in staged})
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        for folder in reversed(made):  # the folders this call made, if nothing went into them
            try:
                folder.rmdir()
            except OSError:
                break
        if isinstance(exc, InputError) and str(stage) in str(exc):  # the file it was making, not the staging folder
            raise InputError(str(exc).replace(str(stage), str(parent)), param=exc.param) from None
        raise
    shutil.rmtree(stage, ignore_errors=True)
    return texts


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
) -> tuple[list[str], list[dict[str, Any]]]:
    """Write each patient's files into ``stage`` under the names of ``paths``; the check texts name ``paths``."""
    suffix = anatomy_suffix(anatomy_format)
    texts: list[str] = []
    entries: list[dict[str, Any]] = []
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
        # The check re-reads the written file, so it sees the 3-decimal points a user gets.
        check = format_check(check_patient(read_csv(staged), params))
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
    return texts, entries


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


def cohort_toml(entries: list[dict[str, Any]]) -> str:
    """A cohort file's text (``arcube design --cohort``): one ``[[patient]]`` table per entry, paths relative to the file."""
    lines = [
        "# arcube cohort: the patients of one design job (arcube design --cohort cohort.toml); paths relative to this file"
    ]
    for e in entries:
        lines += ["", "[[patient]]", *(f"{k} = {json.dumps(v)}" for k, v in e.items())]
    return "\n".join(lines) + "\n"
