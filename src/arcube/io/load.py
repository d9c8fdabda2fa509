"""One entry point for every trajectory format: CSV, 3D Slicer markups, or the bundled patient."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.slicer import read_markups
from arcube.io.inputs import short_repr
from arcube.io.trajectories import (
    TrajectorySet,
    apply_transform,
    read_csv,
    read_reference,
    read_transform,
    validate_points,
)

__all__ = ["load_plan", "load_trajectories"]


def load_trajectories(spec: str | os.PathLike[str], transform: str | os.PathLike[str] | None = None) -> TrajectorySet:
    """Load a trajectory set.

    Args:
        spec: a CSV path, a Slicer ``.mrk.json`` / ``.json`` file, a folder of ``.mrk.json``
            files, or the word ``"reference"`` (the bundled mean-patient CSV).
        transform: optional JSON rigid transform from the file's frame to the patient frame,
            applied after the Slicer coordinate-system conversion.

    Returns:
        The set, points in mm in the patient frame.
    """
    if not isinstance(spec, (str, os.PathLike)):
        raise InputError.of(
            "plan",
            f"must be a trajectory file or folder or 'reference', got {type(spec).__name__} (load_plan takes a TrajectorySet)",
        )
    if os.fspath(spec) == "reference":  # the word always means the bundled file; use ./reference for a path
        ts = read_reference()
    else:
        p = Path(spec)
        try:
            markups, exists = p.is_dir() or p.name.lower().endswith(".json"), p.exists()
        except OSError as exc:  # e.g. a name too long
            raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
        if markups:
            ts = read_markups(p)
        elif not exists:
            raise InputError(f"{p}: no such file")
        else:
            ts = read_csv(p)
    if transform is not None:
        ts = apply_transform(ts, read_transform(transform))
        # the moved points must still lie within the coordinate range of every reader
        labels = [
            f"{ts.source} trajectory {short_repr(tid)} (after the transform {os.fspath(transform)})" for tid in ts.ids
        ]
        validate_points(labels, ts.ids, ts.entry, ts.target)
    return ts


def load_plan(
    plan: TrajectorySet | str | os.PathLike[str],
    *,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[Any] | None = None,
    transform: str | os.PathLike[str] | None = None,
) -> TrajectorySet:
    """A plan as every command takes it: a :class:`TrajectorySet` (checked as a file's would be) or what
    :func:`load_trajectories` reads, then kept to ``side``, ``levels`` and ``ids`` (``"C3-C5"`` or
    ``["C3", "C4"]``, ``"1,3"`` or ``["1", "3"]``). ``transform`` applies to files only."""
    from arcube.io.trajectories import select

    if isinstance(plan, TrajectorySet):
        if len(plan) == 0:
            raise InputError.of("plan", f"{plan.source} has no trajectories")
        validate_points(
            [f"{plan.source} trajectory {i}" for i in plan.ids],
            plan.ids,
            np.asarray(plan.entry),
            np.asarray(plan.target),
        )
        ts = plan
    else:
        ts = load_trajectories(plan, transform=transform)
    return (
        select(ts, side=side, levels=levels, ids=ids)
        if (side is not None or levels is not None or ids is not None)
        else ts
    )
