"""Label maps out: closed solids voxelized into a 3D Slicer ``.seg.nrrd`` or a NIfTI ``.nii`` / ``.nii.gz``.

So that the segmentation path (:mod:`arcube.io.segmentations`) can be tried without a scanner. Each
segment is a name, a label value and one or more closed solids in the patient frame (mm). A voxel
carries a segment's label when its *centre* lies inside one of the segment's solids; where the
solids of several segments overlap, the segment listed first wins (a label map holds one label per
voxel). The grid is axis-aligned with isotropic spacing ``spacing_mm``, covers every solid with a
margin of two voxels, and puts its voxel centres on multiples of the spacing in LPS.

* ``.seg.nrrd`` / ``.nrrd``: as 3D Slicer saves a segmentation: ``space`` left-posterior-superior,
  identity directions times the spacing, one layer, gzip; the ``Segmentation_*`` fields and per
  segment ``Segment<N>_ID``, ``_Name``, ``_Color``, ``_LabelValue``, ``_Layer`` (0), ``_Extent``
  (its voxels' index box), ``_Tags``.
* ``.nii`` / ``.nii.gz``: the same voxels and grid; the affine in RAS+ (so with −spacing on its
  first two diagonal entries), as both sform and qform with code 1 (scanner), units mm, intent
  ``label``. Label values only (NIfTI has no names).

Inside/outside: a ``trimesh.Trimesh`` by libigl's winding number (> 1/2 inside; exact for small
meshes, the fast approximation above 2000 faces); any other solid must have ``bounds`` ((2, 3):
lo, hi) and ``contains(points (N, 3)) -> (N,) bool`` (e.g. an exact box test). Writes are atomic
(:mod:`arcube.io.files`): on any error nothing is written.
"""

from __future__ import annotations

import gzip
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from arcube import interrupts
from arcube.errors import InputError
from arcube.io.files import atomic_write_bytes
from arcube.io.segmentations import MAX_SEGMENTATION_VOXELS
from arcube.io.slicer import PATIENT_FROM_LPS

__all__ = ["SegmentSolids", "voxelize", "write_segmentation"]

SegmentSolids = tuple[str, int, Sequence[Any]]
"""One segment to write: (name, label value >= 1, closed solids in the patient frame)."""

_CHUNK = 1 << 20  # query points per containment call (bounds the memory of the (N, 3) arrays)
_EXACT_FACES = 2000  # above this, libigl's fast winding number (the exact one is O(points x faces))
_PALETTE = (
    (0.89, 0.85, 0.72),
    (0.95, 0.55, 0.45),
    (0.50, 0.68, 0.85),
    (0.60, 0.80, 0.55),
    (0.85, 0.65, 0.85),
    (0.95, 0.80, 0.45),
    (0.55, 0.80, 0.80),
    (0.80, 0.60, 0.50),
)


def _bounds(solid: Any) -> np.ndarray:
    return np.asarray(solid.bounds, dtype=np.float64).reshape(2, 3)


def _contains(solid: Any, points: np.ndarray) -> np.ndarray:
    import trimesh

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost

    if isinstance(solid, trimesh.Trimesh):
        import igl

        v = np.ascontiguousarray(solid.vertices, dtype=np.float64)
        f = np.ascontiguousarray(solid.faces, dtype=np.int64)
        w = igl.winding_number(v, f, points) if len(f) <= _EXACT_FACES else igl.fast_winding_number(v, f, points)
        return np.asarray(w) > 0.5
    return np.asarray(solid.contains(points), dtype=bool)


def _check_segments(segments: Sequence[SegmentSolids], where: str) -> list[SegmentSolids]:
    segments = list(segments)
    if not segments:
        raise InputError(f"{where}: no segment to write")
    names, labels = set(), set()
    for name, label, solids in segments:
        if not isinstance(name, str) or not name.strip() or "\n" in name:
            raise InputError(f"{where}: segment name {name!r} must be one line of text")
        if isinstance(label, bool) or not isinstance(label, (int, np.integer)) or not 1 <= int(label) <= 32767:
            raise InputError(f"{where}: segment {name!r}: label value {label!r} must be an integer in 1..32767")
        if name in names or int(label) in labels:
            raise InputError(f"{where}: segment {name!r} (label {label}): names and label values must be unique")
        if not list(solids):
            raise InputError(f"{where}: segment {name!r} has no solid")
        names.add(name)
        labels.add(int(label))
    return segments


def voxelize(
    segments: Sequence[SegmentSolids], spacing_mm: float = 0.5, where: str = "segmentation"
) -> tuple[np.ndarray, np.ndarray]:
    """Label map of ``segments`` on an LPS-aligned grid.

    Args:
        segments: (name, label, solids) per segment, first listed wins where they overlap.
        spacing_mm: voxel size, mm (> 0).
        where: what error messages name (the output file).

    Returns:
        ``labels`` (I, J, K) uint8 or int16 (I along L, J along P, K along S) and ``index_to_lps``
        (4, 4): index (i, j, k, 1) -> LPS point of the voxel centre, mm.

    Raises:
        InputError: a bad spacing or segment, or a grid of more than MAX_SEGMENTATION_VOXELS voxels.
    """
    segments = _check_segments(segments, where)
    if not (isinstance(spacing_mm, (int, float)) and np.isfinite(spacing_mm) and spacing_mm > 0):
        raise InputError(f"{where}: spacing {spacing_mm!r} mm must be a positive number")
    h = float(spacing_mm)
    lps_from_patient = PATIENT_FROM_LPS.T
    boxes = {}  # id(solid) -> its LPS bounding box (lo, hi)
    for _, _, solids in segments:
        for solid in solids:
            lo, hi = _bounds(solid)
            corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
            lps = corners @ lps_from_patient.T
            boxes[id(solid)] = (lps.min(axis=0), lps.max(axis=0))
    first = np.floor(np.min([b[0] for b in boxes.values()], axis=0) / h).astype(np.int64) - 2
    last = np.ceil(np.max([b[1] for b in boxes.values()], axis=0) / h).astype(np.int64) + 2
    origin = first * h  # LPS centre of voxel (0, 0, 0)
    shape = last - first + 1
    if float(np.prod(shape, dtype=np.float64)) > MAX_SEGMENTATION_VOXELS:
        raise InputError(
            f"{where}: a {shape[0]} x {shape[1]} x {shape[2]} grid at {h:g} mm exceeds "
            f"{MAX_SEGMENTATION_VOXELS} voxels; use a larger spacing"
        )
    top = max(int(label) for _, label, _ in segments)
    labels = np.zeros(tuple(int(n) for n in shape), dtype=np.uint8 if top <= 255 else np.int16)
    patient_origin = PATIENT_FROM_LPS @ origin
    patient_step = PATIENT_FROM_LPS * h  # column a: patient step along axis a
    for _, label, solids in reversed(segments):  # earlier segments overwrite later ones
        for solid in solids:
            lo_s, hi_s = boxes[id(solid)]
            a0 = np.maximum(np.floor((lo_s - origin) / h).astype(np.int64), 0)
            a1 = np.minimum(np.ceil((hi_s - origin) / h).astype(np.int64), shape - 1)
            plane = int((a1[1] - a0[1] + 1) * (a1[2] - a0[2] + 1))
            step = max(1, _CHUNK // max(plane, 1))  # slabs of about _CHUNK points
            j = np.arange(a0[1], a1[1] + 1)[None, :, None, None] * patient_step[:, 1]
            k = np.arange(a0[2], a1[2] + 1)[None, None, :, None] * patient_step[:, 2]
            for i0 in range(int(a0[0]), int(a1[0]) + 1, step):
                i1 = min(i0 + step, int(a1[0]) + 1)
                i = np.arange(i0, i1)[:, None, None, None] * patient_step[:, 0]
                points = (patient_origin + i + j + k).reshape(-1, 3)
                inside = _contains(solid, points).reshape(i1 - i0, j.shape[1], k.shape[2])
                labels[i0:i1, a0[1] : a1[1] + 1, a0[2] : a1[2] + 1][inside] = label
    index_to_lps = np.eye(4)
    index_to_lps[:3, :3] = np.eye(3) * h
    index_to_lps[:3, 3] = origin
    return labels, index_to_lps


def _extent(labels: np.ndarray, label: int) -> str:
    idx = np.nonzero(labels == label)
    if not len(idx[0]):
        return "0 -1 0 -1 0 -1"
    return " ".join(f"{int(i.min())} {int(i.max())}" for i in idx)


def _nrrd_bytes(labels: np.ndarray, index_to_lps: np.ndarray, segments: Sequence[SegmentSolids]) -> bytes:
    import nrrd

    header: dict[str, Any] = {
        "type": "uint8" if labels.dtype == np.uint8 else "int16",
        "dimension": 3,
        "space": "left-posterior-superior",
        "sizes": np.array(labels.shape),
        "space directions": index_to_lps[:3, :3].T.copy(),
        "kinds": ["domain", "domain", "domain"],
        "encoding": "gzip",
        "space origin": index_to_lps[:3, 3].copy(),
        "Segmentation_MasterRepresentation": "Binary labelmap",
        "Segmentation_ContainedRepresentationNames": "Binary labelmap|",
        "Segmentation_ReferenceImageExtentOffset": "0 0 0",
    }
    for n, (name, label, _) in enumerate(segments):
        r, g, b = _PALETTE[n % len(_PALETTE)]
        header.update(
            {
                f"Segment{n}_ID": f"Segment_{int(label)}",
                f"Segment{n}_Name": name,
                f"Segment{n}_NameAutoGenerated": "0",
                f"Segment{n}_Color": f"{r:g} {g:g} {b:g}",
                f"Segment{n}_ColorAutoGenerated": "0",
                f"Segment{n}_LabelValue": str(int(label)),
                f"Segment{n}_Layer": "0",
                f"Segment{n}_Extent": _extent(labels, int(label)),
                f"Segment{n}_Tags": "|",
            }
        )
    out = io.BytesIO()
    nrrd.write(out, labels, header, index_order="F")
    return out.getvalue()


def _nifti_bytes(labels: np.ndarray, index_to_lps: np.ndarray, compress: bool) -> bytes:
    import nibabel

    ras_from_lps = np.diag([-1.0, -1.0, 1.0, 1.0])
    affine = ras_from_lps @ index_to_lps
    img = nibabel.Nifti1Image(labels, affine)
    img.set_sform(affine, code=1)
    img.set_qform(affine, code=1)
    img.header.set_xyzt_units("mm")
    img.header.set_intent("label")
    data = img.to_bytes()
    return gzip.compress(data, mtime=0) if compress else data


def write_segmentation(
    segments: Sequence[SegmentSolids], path: str | os.PathLike[str], spacing_mm: float = 0.5
) -> Path:
    """Voxelize ``segments`` (:func:`voxelize`) and write them as a label map; the format follows the suffix.

    Args:
        segments: (name, label, solids) per segment (patient frame, mm; first listed wins on overlaps).
        path: ``.seg.nrrd`` or ``.nrrd`` (3D Slicer segmentation, LPS), ``.nii`` or ``.nii.gz`` (NIfTI, RAS).
        spacing_mm: voxel size, mm.

    Returns:
        The path written.

    Raises:
        InputError: unknown suffix, bad segments or spacing, a segment without a voxel (too thin for the
            spacing), an unwritable path; nothing is written then.
    """
    target = Path(path)
    name = target.name.lower()
    if not name.endswith((".nrrd", ".nii", ".nii.gz")):
        raise InputError(f"{target}: unknown segmentation format (expected .seg.nrrd, .nrrd, .nii or .nii.gz)")
    labels, index_to_lps = voxelize(segments, spacing_mm, str(target))
    present = set(np.unique(labels).tolist())
    for seg_name, label, _ in segments:
        if int(label) not in present:
            raise InputError(
                f"{target}: segment {seg_name!r} has no voxel at {spacing_mm:g} mm (thinner than a voxel, "
                "or covered by segments listed before it)"
            )
    data = (
        _nrrd_bytes(labels, index_to_lps, segments)
        if name.endswith(".nrrd")
        else _nifti_bytes(labels, index_to_lps, name.endswith(".gz"))
    )
    try:
        atomic_write_bytes(target, data)
    except OSError as exc:
        raise InputError(f"{target}: cannot write ({exc.strerror or exc})") from None
    return target
