"""A virtual patient's default anatomy (model §14.2) as a segmentation: one segment per vertebra, one for soft tissue.

The boxes of :mod:`arcube.patients.anatomy` grouped as a spine segmentation would be: segment
``C3`` ... ``C7`` (label values 3 ... 7, VerSe's numbering of the cervical vertebrae) holds the level's
body and posterior arch, segment ``soft tissue`` (label :data:`SOFT_TISSUE_LABEL`) the five
soft-tissue boxes. Bone is listed first, so where the slab overlaps a vertebra the voxel is bone
(:mod:`arcube.io.segmentation_writer`); the union of all segments is the union of the boxes, so
the forbidden region is the same as the STL's, up to the voxel size.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.patients.anatomy import Box, DefaultAnatomy, default_anatomy_layout
from arcube.patients.virtual import LEVELS

__all__ = ["ANATOMY_FORMATS", "SOFT_TISSUE_LABEL", "anatomy_segments", "anatomy_suffix", "write_anatomy_as"]

ANATOMY_FORMATS = ("stl", "seg.nrrd", "nii.gz")
"""File formats of a virtual patient's default anatomy: binary STL (patient frame), 3D Slicer segmentation, NIfTI."""
SOFT_TISSUE_LABEL = 100  # beyond VerSe's vertebra labels (1-28)
VERTEBRA_LABELS = {lv: int(lv[1:]) for lv in LEVELS}  # VerSe: C1..C7 = 1..7


@dataclass(frozen=True)
class _BoxSolid:
    """A box as a solid for the voxelizer: bounds and an exact point-in-box test."""

    box: Box

    @property
    def bounds(self) -> np.ndarray:
        corners = self.box.corners()
        return np.array([corners.min(axis=0), corners.max(axis=0)])

    def contains(self, points: np.ndarray) -> np.ndarray:
        inside = np.ones(len(points), dtype=bool)
        for axis, half in zip(self.box.rotation.T, self.box.half_extents):  # per axis: (N, 3) @ (3, 3) is slow
            inside &= np.abs(points @ axis - float(self.box.centre @ axis)) <= half
        return inside


def anatomy_segments(layout: DefaultAnatomy) -> list[tuple[str, int, list[Any]]]:
    """(name, label, solids) per segment: ``C3`` ... ``C7`` (body and arch, labels 3-7), then ``soft tissue``."""
    segments: list[tuple[str, int, list[Any]]] = []
    for lv in LEVELS:
        bones = [_BoxSolid(b) for b in layout.boxes if b.kind == "bone" and b.name.split()[0] == lv]
        segments.append((lv, VERTEBRA_LABELS[lv], bones))
    soft = [_BoxSolid(b) for b in layout.boxes if b.kind == "soft tissue"]
    segments.append(("soft tissue", SOFT_TISSUE_LABEL, soft))
    return segments


def anatomy_suffix(anatomy_format: str) -> str:
    """The suffix of an anatomy file beside a patient's CSV: ``.anatomy.stl``, ``.anatomy.seg.nrrd``, ``.anatomy.nii.gz``."""
    if anatomy_format not in ANATOMY_FORMATS:
        raise InputError.of("anatomy_format", f"{anatomy_format!r}: expected one of {', '.join(ANATOMY_FORMATS)}")
    return f".anatomy.{anatomy_format}"


def write_anatomy_as(
    params: dict[str, Any],
    path: str | os.PathLike[str],
    anatomy_format: str = "stl",
    spacing_mm: float = 0.5,
    **layout: float,
) -> DefaultAnatomy:
    """Write the default anatomy of ``params`` to ``path`` as STL (one shell per box, patient frame) or as a
    label map (``seg.nrrd``: LPS; ``nii.gz``: RAS; voxels of ``spacing_mm``); ``layout`` goes to
    :func:`~arcube.patients.anatomy.default_anatomy_layout` (skin_mm, corridor_width_mm, corridor_margin_mm).

    Returns:
        The layout written.
    """
    from arcube.io.meshes import write_stl
    from arcube.io.segmentation_writer import write_segmentation

    anatomy_suffix(anatomy_format)
    anatomy = default_anatomy_layout(params, **layout)
    if anatomy_format == "stl":
        write_stl(anatomy.meshes(), path, frame="patient")
    else:
        write_segmentation(anatomy_segments(anatomy), Path(path), spacing_mm)
    return anatomy
