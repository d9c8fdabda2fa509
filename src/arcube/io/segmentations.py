"""Segmentations in (model §14.2): 3D Slicer ``.seg.nrrd`` and NIfTI label maps as closed surfaces.

A segmentation is a grid of integer labels. Each kept segment (a label value in a layer) becomes a
closed, outward-oriented triangle surface in the patient frame R_w of model §1.1 (x = patient's
right, y = superior, z = posterior; mm), which the anatomy then uses exactly like a mesh file.

**Geometry.** Voxel index i = (i, j, k) (i along the fastest axis of the file) is the *centre* of
its voxel, at world point ``origin + D @ i``; D (3, 3) holds one column per array axis (spacing
times direction cosine: oblique grids and either handedness are taken as they are). The world is
LPS or RAS and goes to the patient frame through ``PATIENT_FROM_LPS`` / ``PATIENT_FROM_RAS``
(:mod:`arcube.io.slicer`), so a point q of the file is ``P @ (origin + D @ i)``. A segment's binary
mask, cropped to its bounding box and padded by one empty voxel on every side (so that the surface
closes even where the segment touches the edge of the grid), is contoured at 0.5 by marching cubes
(scikit-image, Lewiner: topologically consistent cases): each vertex lies halfway between a voxel
centre inside the segment and one outside (within half a voxel edge of the segmented boundary), or,
in the cells that Lewiner's method resolves with an interior point, at the centre of a cell whose
corners lie on both sides: every vertex is within half a voxel diagonal of the boundary.
The vertices go through the full affine; when det(P D) < 0 (a mirrored grid) the faces are
reversed, so every surface faces outward in the patient frame and the mirror image is never taken
for the anatomy. Enclosed holes in a mask (background voxels not face-connected to the outside of
the segment) are filled first: a cavity cannot be reached and the anatomy takes solids without
cavities (:mod:`arcube.io.meshes`). Every surface then passes the closed-surface checks of
:mod:`arcube.io.meshes` (each directed edge matched, every shell of positive volume).

**.seg.nrrd** (``.nrrd``; pynrrd): ``space`` left-posterior-superior (LPS) or right-anterior-superior
(RAS), ``space directions`` and ``space origin`` (both required), ``space units`` mm when given. A
3-D array is one layer; a 4-D array has the layer axis first (``space directions`` ``none`` for it),
as Slicer writes overlapping segments. Segments come from the ``Segment<N>_Name``,
``Segment<N>_LabelValue`` (default 1) and ``Segment<N>_Layer`` (default 0, or N in a 4-D file, as
Slicer reads legacy files) fields; a file without them is a plain label map (below).
``Segmentation_ReferenceImageExtentOffset`` is the index of the stored box within the reference
image's grid; Slicer shifts ``space origin`` by it when saving, so that readers ignoring the field
place the voxels correctly: it is checked (three integers) but changes nothing here.

**NIfTI** (``.nii``, ``.nii.gz``; nibabel): the sform when its code is set (> 0), else the qform;
their world is RAS+. A file with neither code set is refused: NIfTI's fallback then is voxel sizes
alone, without orientation, so left and right would be a guess. Spatial units: mm (or ``unknown``,
read as mm as ITK and Slicer write it), m and um are converted. A 4-D image (beyond a trailing
size 1) is refused. Labels have no names: segment ``"5"`` is label value 5.

**Plain label maps** (NIfTI, NRRD without Segment fields): every non-zero value is a segment named by
its value. Values must be non-negative integers (float storage is accepted when every value is
integral), at most :data:`MAX_LABELS` distinct ones: more is an intensity image.

**Selection.** ``segments`` names segments by name, or by label value (an integer that is no
segment's name selects every segment with that value); default: every segment with a voxel. An
unknown name, or a selected segment without voxels, is an error listing the available segments.

**Limits.** A file of at most :data:`MAX_SEGMENTATION_BYTES` bytes, whose header announces at most
:data:`MAX_SEGMENTATION_VOXELS` voxels and :data:`MAX_SEGMENTATION_BYTES` bytes of voxel data: the
header is read and checked before the voxels are. Every problem is an :class:`~arcube.errors.InputError`
whose one-line message names the file.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube import interrupts
from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.io.label_files import (
    LABEL_SUFFIXES,
    MAX_LABELS,
    MAX_SEGMENTATION_BYTES,
    MAX_SEGMENTATION_VOXELS,
    LabelVolume,
    read_label_volume,
)
from arcube.io.slicer import PATIENT_FROM_LPS, PATIENT_FROM_RAS

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "MAX_LABELS",
    "MAX_SEGMENTATION_BYTES",
    "MAX_SEGMENTATION_VOXELS",
    "SEGMENTATION_SUFFIXES",
    "SegmentInfo",
    "Segmentation",
    "is_segmentation",
    "label_surface",
    "parse_segments",
    "read_segmentation",
    "read_segmentations",
]

SEGMENTATION_SUFFIXES = LABEL_SUFFIXES
_TO_PATIENT = {"LPS": PATIENT_FROM_LPS, "RAS": PATIENT_FROM_RAS}


def _fail(path: Path, problem: str) -> InputError:
    return InputError(f"{path}: {problem}")


@dataclass(frozen=True)
class SegmentInfo:
    """Provenance of one kept segment: where it came from, its size, and its surface's bounds.

    Attributes:
        file: the segmentation file. name: segment name (a NIfTI label's value as text).
        label: label value. layer: layer (0 for 3-D files). voxels: voxels carrying the label.
        lo, hi: bounds of the segment's surface in the patient frame, mm.
    """

    file: str
    name: str
    label: int
    layer: int
    voxels: int
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"file", "name", "label", "layer", "voxels", "bounds_mm": [lo, hi]}``."""
        return {
            "file": self.file,
            "name": self.name,
            "label": self.label,
            "layer": self.layer,
            "voxels": self.voxels,
            "bounds_mm": [list(self.lo), list(self.hi)],
        }


@dataclass(frozen=True)
class Segmentation:
    """The kept segments of one file: one closed mesh per segment (patient frame, mm), in the same order
    as ``segments``; ``index_to_patient`` (4, 4) maps a voxel index (i, j, k, 1) to the patient frame."""

    path: Path
    space: str
    shape: tuple[int, int, int]
    index_to_patient: np.ndarray
    meshes: tuple[trimesh.Trimesh, ...]
    segments: tuple[SegmentInfo, ...]


def is_segmentation(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` names a segmentation file by its suffix (``.seg.nrrd``, ``.nrrd``, ``.nii``, ``.nii.gz``)."""
    return os.fspath(path).lower().endswith(SEGMENTATION_SUFFIXES)


def parse_segments(segments: str | int | Iterable[str | int] | None) -> tuple[str, ...] | None:
    """A segment selection as a tuple of names/values: ``"C3,2"`` or ``["C3", 2]`` -> ``("C3", "2")``; None: all."""
    if segments is None:
        return None
    if isinstance(segments, (str, int)) and not isinstance(segments, bool):
        items = [s.strip() for s in str(segments).split(",")]
    else:
        try:  # each item may itself be a comma-separated list (a repeated command-line flag)
            items = [part.strip() for s in segments for part in str(s).split(",")]  # type: ignore[union-attr]
        except TypeError:
            raise InputError.of("segments", f"{short_repr(segments)}: expected names or label values") from None
    if not items or any(not s for s in items):
        raise InputError.of("segments", f"{short_repr(segments)}: an empty segment name")
    return tuple(dict.fromkeys(items))


def _counts(path: Path, volume: LabelVolume) -> dict[tuple[int, int], int]:
    """Voxels per (layer, non-zero label value)."""
    out: dict[tuple[int, int], int] = {}
    for layer, grid in enumerate(volume.layers):
        values, counts = np.unique(grid, return_counts=True)
        out.update({(layer, int(v)): int(c) for v, c in zip(values, counts) if v != 0})
    if volume.table is None and len(out) > MAX_LABELS:
        raise _fail(path, f"not a label map: {len(out)} distinct values (at most {MAX_LABELS}; an intensity image?)")
    return out


def _available(table: Sequence[tuple[str, int, int]], counts: dict[tuple[int, int], int]) -> str:
    shown = [
        f"{name} (label {label}{f', layer {layer}' if layer else ''}, {counts.get((layer, label), 0)} voxels)"
        for name, label, layer in table[:40]
    ]
    more = f", ... ({len(table)} in all)" if len(table) > 40 else ""
    return ", ".join(shown) + more


def _select(
    path: Path,
    table: list[tuple[str, int, int]],
    counts: dict[tuple[int, int], int],
    items: tuple[str, ...] | None,
    strict: bool,
) -> tuple[list[tuple[str, int, int]], set[str]]:
    """The kept segments and the selection items they matched (``strict``: every item must match here)."""
    if items is None:
        kept = [s for s in table if counts.get((s[2], s[1]), 0) > 0]
        if not kept:
            raise _fail(path, "no segment has a voxel (every label is 0)" if table else "no non-zero voxel")
        return kept, set()
    kept, matched = [], set()
    for item in items:
        hits = [s for s in table if s[0] == item]
        if not hits and re.fullmatch(r"[0-9]+", item):
            hits = [s for s in table if s[1] == int(item)]
        if not hits:
            if strict:
                raise _fail(path, f"no segment {item!r} (available: {_available(table, counts) or 'none'})")
            continue
        matched.add(item)
        for s in hits:
            if counts.get((s[2], s[1]), 0) == 0:
                raise _fail(path, f"segment {s[0]!r} (label {s[1]}) has no voxel: an empty mask")
            if s not in kept:
                kept.append(s)
    if not kept:
        raise _fail(
            path, f"none of the segments {', '.join(items)} is in it (available: {_available(table, counts) or 'none'})"
        )
    return kept, matched


def label_surface(mask: np.ndarray, index_to_patient: np.ndarray, start: Sequence[int] = (0, 0, 0)) -> trimesh.Trimesh:
    """The closed, outward surface of a binary mask, in the patient frame.

    Args:
        mask: (I, J, K) bool, the voxels of one segment (a crop of the grid starting at index ``start``).
        index_to_patient: (4, 4), grid index (i, j, k, 1) -> patient frame (mm); any non-singular affine.
        start: (3,) grid index of ``mask[0, 0, 0]``.

    Returns:
        A ``trimesh.Trimesh`` (not processed): marching cubes at 0.5 on the mask padded by one empty
        voxel, enclosed holes filled, faces reversed when the affine mirrors (det < 0).
    """
    import trimesh

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost
    from scipy import ndimage
    from skimage.measure import marching_cubes

    filled = np.pad(ndimage.binary_fill_holes(mask), 1).astype(np.float32)
    # "ascent": faces wind counter-clockwise seen from the side of values below the level (outside)
    verts, faces, _, _ = marching_cubes(filled, 0.5, gradient_direction="ascent")
    index = verts.astype(np.float64) + (np.asarray(start, dtype=np.float64) - 1.0)  # exact: k + 0.5 in float32
    points = np.einsum("ij,kj->ik", index, index_to_patient[:3, :3]) + index_to_patient[:3, 3]
    faces = np.asarray(faces, dtype=np.int64)
    if np.linalg.det(index_to_patient[:3, :3]) < 0:  # a mirrored grid turns outward faces inward: turn them back
        faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices=points, faces=np.ascontiguousarray(faces), process=False)


def _check_closed(path: Path, name: str, mesh: trimesh.Trimesh) -> None:
    """The checks :func:`arcube.io.meshes.read_mesh` applies to a mesh file."""
    from arcube.io.meshes import _signed_volume, _unmatched_edges, split_shells

    unmatched = _unmatched_edges(np.asarray(mesh.faces))
    if unmatched:
        raise _fail(path, f"segment {name!r}: its surface is not closed ({unmatched} unmatched edges)")
    for shell in split_shells(mesh):
        if _signed_volume(np.asarray(shell.vertices), np.asarray(shell.faces)) <= 0.0:
            raise _fail(path, f"segment {name!r}: a shell of its surface encloses no positive volume")


def _bounding_boxes(grid: np.ndarray, labels: Iterable[int]) -> dict[int, tuple[slice, ...]]:
    """Index box of each label value in ``grid`` (one pass when the values are small)."""
    from scipy import ndimage

    labels = list(labels)
    if grid.dtype.itemsize <= 4 and max(labels) <= 2**16:
        objects = ndimage.find_objects(grid, max_label=max(labels))
        return {v: objects[v - 1] for v in labels}
    out = {}
    for v in labels:
        idx = np.nonzero(grid == v)
        out[v] = tuple(slice(int(i.min()), int(i.max()) + 1) for i in idx)
    return out


def _surfaces(
    path: Path, volume: LabelVolume, kept: list[tuple[str, int, int]], counts: dict[tuple[int, int], int]
) -> Segmentation:
    to_patient = np.eye(4)
    to_patient[:3, :3] = _TO_PATIENT[volume.space]
    index_to_patient = to_patient @ volume.affine
    boxes = {
        layer: _bounding_boxes(volume.layers[layer], sorted({lab for _, lab, lay in kept if lay == layer}))
        for layer in sorted({s[2] for s in kept})
    }
    meshes, infos = [], []
    for name, label, layer in kept:
        box = boxes[layer][label]
        mesh = label_surface(volume.layers[layer][box] == label, index_to_patient, [s.start for s in box])
        _check_closed(path, name, mesh)
        lo, hi = mesh.bounds
        meshes.append(mesh)
        infos.append(
            SegmentInfo(
                os.fspath(path),
                name,
                label,
                layer,
                counts[(layer, label)],
                tuple(float(v) for v in lo),
                tuple(float(v) for v in hi),
            )
        )  # type: ignore[arg-type]
    return Segmentation(
        path, volume.space, tuple(volume.layers.shape[1:]), index_to_patient, tuple(meshes), tuple(infos)
    )


def _read_one(path: Path, items: tuple[str, ...] | None, strict: bool) -> tuple[Segmentation, set[str]]:
    volume = read_label_volume(path)
    counts = _counts(path, volume)
    table = volume.table if volume.table is not None else [(str(lab), lab, lay) for lay, lab in sorted(counts)]
    kept, matched = _select(path, table, counts, items, strict)
    return _surfaces(path, volume, kept, counts), matched


def read_segmentation(path: str | os.PathLike[str], segments: str | Iterable[str | int] | None = None) -> Segmentation:
    """Read a ``.seg.nrrd`` / ``.nrrd`` / ``.nii`` / ``.nii.gz`` label map as closed surfaces in the patient frame.

    Args:
        path: the file.
        segments: names or label values to keep (``"C3,C4"``, ``["C3", "2"]``); None: every segment with a voxel.

    Returns:
        A :class:`Segmentation`: one mesh and one :class:`SegmentInfo` per kept segment.

    Raises:
        InputError: one line naming the file: not a NRRD/NIfTI file, truncated, too large, an unsupported
            space, a singular or non-finite affine, a 4-D NIfTI image, not a label map, no voxel, an unknown
            or empty segment.
    """
    return _read_one(Path(path), parse_segments(segments), True)[0]


def read_segmentations(
    paths: Sequence[str | os.PathLike[str]], segments: str | Iterable[str | int] | None = None
) -> list[Segmentation]:
    """:func:`read_segmentation` for several files sharing one selection: each name or value must be in at
    least one file, and each file must keep at least one segment."""
    items = parse_segments(segments)
    if len(paths) == 1:
        return [read_segmentation(paths[0], items)]
    out, matched = [], set()
    for p in paths:
        seg, hits = _read_one(Path(p), items, False)
        out.append(seg)
        matched |= hits
    missing = [i for i in items or () if i not in matched]
    if missing:
        raise InputError(
            f"{', '.join(os.fspath(p) for p in paths)}: no segment {', '.join(map(repr, missing))} in any of them"
        )
    return out
