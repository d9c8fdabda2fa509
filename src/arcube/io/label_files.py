"""Label-map files decoded: 3D Slicer ``.seg.nrrd`` / ``.nrrd`` (pynrrd) and NIfTI (nibabel) -> :class:`LabelVolume`.

The file layer under :mod:`arcube.io.segmentations` (which documents the conventions and turns the
labels into surfaces): every check that needs only the file and its header (a regular file, its
size, the announced grid size before any voxel is read, the frame, a non-singular finite affine),
then the voxels as non-negative integer labels. Every problem is an :class:`~arcube.errors.InputError`
whose one-line message names the file.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import COORDINATE_LIMIT_MM, file_kind, short_repr

__all__ = [
    "LABEL_SUFFIXES",
    "MAX_LABELS",
    "MAX_SEGMENTATION_BYTES",
    "MAX_SEGMENTATION_VOXELS",
    "LabelVolume",
    "read_label_volume",
]

LABEL_SUFFIXES = (".seg.nrrd", ".nrrd", ".nii.gz", ".nii")
MAX_SEGMENTATION_VOXELS = 2**28
"""Largest grid, voxels (268 million: 512 x 512 x 1024, a whole-body CT at full resolution). Its
processing holds the labels, one sorted copy of them and, per segment, a cropped mask and its
float32 copy; a larger grid would need several GB of memory."""
MAX_SEGMENTATION_BYTES = 2**30
"""Largest file, and largest voxel data once decoded, bytes (1 GiB, as for mesh files): a 2 GB
volume is refused from its header, before its voxels are read."""
MAX_LABELS = 1000
"""Most distinct non-zero values of a plain label map (TotalSegmentator has 117, VerSe 28)."""

_SPACES = {"left-posterior-superior": "LPS", "lps": "LPS", "right-anterior-superior": "RAS", "ras": "RAS"}
_NRRD_ITEMSIZE = {  # NRRD type names (all spellings of the format) -> bytes per voxel
    **dict.fromkeys(("signed char", "int8", "int8_t", "uchar", "unsigned char", "uint8", "uint8_t"), 1),
    **dict.fromkeys(
        (
            "short",
            "short int",
            "signed short",
            "signed short int",
            "int16",
            "int16_t",
            "ushort",
            "unsigned short",
            "unsigned short int",
            "uint16",
            "uint16_t",
        ),
        2,
    ),
    **dict.fromkeys(
        ("int", "signed int", "int32", "int32_t", "uint", "unsigned int", "uint32", "uint32_t", "float"), 4
    ),
    **dict.fromkeys(
        (
            "longlong",
            "long long",
            "long long int",
            "signed long long",
            "signed long long int",
            "int64",
            "int64_t",
            "ulonglong",
            "unsigned long long",
            "unsigned long long int",
            "uint64",
            "uint64_t",
            "double",
        ),
        8,
    ),
}
_NIFTI_UNITS = {"mm": 1.0, "unknown": 1.0, "meter": 1000.0, "micron": 1e-3}
_MAX_NAME = 200
"""Longest segment name accepted, characters."""
_SEGMENT_KEY = re.compile(r"Segment([0-9]+)_(ID|Name|LabelValue|Layer)")


@dataclass
class LabelVolume:
    """A decoded label grid: layers (L, I, J, K) of non-negative integers, index -> world affine (4, 4) in
    ``space``, and the header's segments ``(name, label, layer)`` (None for a plain label map)."""

    layers: np.ndarray
    affine: np.ndarray
    space: str
    table: list[tuple[str, int, int]] | None


def _fail(path: Path, problem: str) -> InputError:
    return InputError(f"{path}: {problem}")


def _check_file(path: Path) -> None:
    """A regular file of at most MAX_SEGMENTATION_BYTES (stat only: a FIFO is never opened)."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise _fail(path, "no such file") from None
    except (OSError, ValueError) as exc:
        raise _fail(path, f"cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise _fail(path, f"is {file_kind(st.st_mode)}, not a regular file")
    if st.st_size > MAX_SEGMENTATION_BYTES:
        raise _fail(path, f"too large: {st.st_size} bytes (the limit is {MAX_SEGMENTATION_BYTES // 2**20} MiB)")


def _check_size(path: Path, shape: Sequence[int], itemsize: int) -> None:
    """Refuse, from the header, a grid of too many voxels or bytes (before anything is allocated)."""
    if any(int(n) < 1 for n in shape):
        raise _fail(path, f"grid size {' x '.join(str(int(n)) for n in shape)} has an empty axis")
    voxels = int(np.prod([int(n) for n in shape], dtype=object))
    text = " x ".join(str(int(n)) for n in shape)
    if voxels > MAX_SEGMENTATION_VOXELS:
        raise _fail(
            path,
            f"too large: {text} = {voxels} voxels (the limit is {MAX_SEGMENTATION_VOXELS}); "
            "crop the segmentation to the operated region",
        )
    if voxels * itemsize > MAX_SEGMENTATION_BYTES:
        raise _fail(
            path,
            f"too large: {text} voxels of {itemsize} bytes = {voxels * itemsize} bytes of voxel data "
            f"(the limit is {MAX_SEGMENTATION_BYTES // 2**20} MiB)",
        )


def _check_affine(path: Path, linear: np.ndarray, origin: np.ndarray, shape: Sequence[int]) -> None:
    """Finite, non-singular index -> world map whose grid corners stay within the coordinate limit."""
    if not (np.isfinite(linear).all() and np.isfinite(origin).all()):
        raise _fail(path, "the voxel-to-world matrix has non-finite (NaN or inf) entries")
    lengths = np.linalg.norm(linear, axis=0)
    if not (lengths > 1e-9).all():
        raise _fail(
            path, f"the voxel-to-world matrix is singular (voxel spacing {np.array2string(lengths, precision=4)} mm)"
        )
    if abs(float(np.linalg.det(linear / lengths))) < 1e-6:  # unit axes (nearly) coplanar
        raise _fail(path, "the voxel-to-world matrix is singular (its axis directions are coplanar)")
    corners = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)]) * (np.asarray(shape) - 1)
    extent = float(np.abs(corners @ linear.T + origin).max())
    if extent > COORDINATE_LIMIT_MM:
        raise _fail(
            path,
            f"the grid reaches {extent:g} mm from the origin, beyond ±{COORDINATE_LIMIT_MM:g} mm (a unit mistake?)",
        )


def _labels(path: Path, data: np.ndarray) -> np.ndarray:
    """``data`` as a non-negative integer array (floats only when every value is integral)."""
    kind = data.dtype.kind
    if kind == "b":
        return data.astype(np.uint8)
    if kind not in "uif":
        raise _fail(path, f"not a label map: voxel type {data.dtype} (expected integers)")
    if kind == "f":
        if not np.isfinite(data).all():
            raise _fail(path, "not a label map: it holds NaN or infinite values")
        if not (data == np.round(data)).all():
            raise _fail(path, "not a label map: it holds non-integer values (an intensity image or a probability map?)")
    low = data.min() if kind != "u" else 0
    if low < 0:
        raise _fail(path, f"not a label map: negative values (down to {low:g}; an intensity image?)")
    if kind == "f":
        data = data.astype(np.uint16 if float(data.max()) <= np.iinfo(np.uint16).max else np.int64)
    return data


def _read_nrrd(path: Path) -> LabelVolume:
    import nrrd

    with open(path, "rb") as fh:
        try:
            header = nrrd.read_header(fh)
        except Exception as exc:  # pynrrd raises NRRDError, ValueError, UnicodeDecodeError... on other files
            raise _fail(path, f"not a NRRD file ({' '.join(str(exc).split())[:160] or type(exc).__name__})") from None
        if "data file" in header or "datafile" in header:
            raise _fail(
                path, "detached voxel data ('data file') is not supported: save the segmentation as one .seg.nrrd"
            )
        dim = int(header.get("dimension", 0))
        sizes = [int(s) for s in np.atleast_1d(header.get("sizes", []))]
        if dim not in (3, 4) or len(sizes) != dim:
            raise _fail(path, f"a {dim}-D NRRD image: expected 3-D labels, or 4-D with the layer axis first")
        space_name = str(header.get("space", "")).strip()
        if not space_name:
            raise _fail(path, "no 'space' field: the anatomical frame (LPS or RAS) is unknown")
        space = _SPACES.get(space_name.lower())
        if space is None:
            raise _fail(
                path,
                f"space {space_name!r} is not supported (expected left-posterior-superior or right-anterior-superior)",
            )
        units = [str(u).strip().lower() for u in header.get("space units", [])]
        if any(u not in ("mm", "") for u in units):
            raise _fail(path, f"space units {' '.join(units)!r}: expected mm")
        directions = np.asarray(header.get("space directions", np.empty((0, 3))), dtype=float)
        if directions.shape != (dim, 3):
            raise _fail(path, "no 'space directions' for the three spatial axes")
        if dim == 4:
            if not np.isnan(directions[0]).all():
                raise _fail(
                    path,
                    "a 4-D image whose first axis is spatial: expected the layer axis first ('space directions: none ...')",
                )
            directions = directions[1:]
        if "space origin" not in header:
            raise _fail(path, "no 'space origin' field")
        origin = np.asarray(header["space origin"], dtype=float).reshape(-1)
        if origin.shape != (3,):
            raise _fail(path, "'space origin' is not a 3-D point")
        linear = directions.T  # column a: world step along array axis a
        spatial = sizes[-3:]
        _check_affine(path, linear, origin, spatial)
        offset = header.get("Segmentation_ReferenceImageExtentOffset")
        if offset is not None and not re.fullmatch(r"\s*-?[0-9]+\s+-?[0-9]+\s+-?[0-9]+\s*", str(offset)):
            raise _fail(
                path, f"Segmentation_ReferenceImageExtentOffset {short_repr(str(offset))} is not three integers"
            )
        type_name = str(header.get("type", "")).strip().lower()
        if type_name not in _NRRD_ITEMSIZE:
            raise _fail(path, f"voxel type {type_name!r} is not a label type")
        _check_size(path, sizes, _NRRD_ITEMSIZE[type_name])
        if int(np.prod(spatial)) == 1:
            raise _fail(path, "holds a single voxel: an empty segmentation (no segment has voxels)")
        try:
            data = nrrd.read_data(header, fh, str(path), index_order="F")
        except Exception as exc:  # truncated or corrupt data: NRRDError, zlib.error, EOFError, ValueError
            raise _fail(
                path,
                f"cannot read the voxel data (truncated or corrupt: {' '.join(str(exc).split())[:160] or type(exc).__name__})",
            ) from None
    layers = _labels(path, np.asarray(data)).reshape([1] * (4 - dim) + sizes)
    affine = np.eye(4)
    affine[:3, :3], affine[:3, 3] = linear, origin
    return LabelVolume(layers, affine, space, _segment_table(path, header, dim, layers.shape[0]))


def _segment_table(path: Path, header: dict[str, Any], dim: int, n_layers: int) -> list[tuple[str, int, int]] | None:
    """The header's segments (name, label value, layer), in Segment<N> order; None without Segment fields."""
    indices = sorted({int(m.group(1)) for key in header if (m := _SEGMENT_KEY.fullmatch(str(key)))})
    if not indices:
        return None
    table = []
    for n in indices:
        name = str(header.get(f"Segment{n}_Name", header.get(f"Segment{n}_ID", f"Segment_{n}"))).strip()
        bad = next((i for i, ch in enumerate(name) if not ch.isprintable()), None)
        if bad is not None:  # a NUL or a line break would be copied into every message, mesh and report naming it
            raise _fail(
                path,
                f"Segment{n}_Name {short_repr(name[:60])} holds a control character (U+{ord(name[bad]):04X}) at position {bad}",
            )
        if len(name) > _MAX_NAME:
            raise _fail(path, f"Segment{n}_Name has {len(name)} characters (at most {_MAX_NAME})")
        values = []
        for key, default in (("LabelValue", 1), ("Layer", n if dim == 4 else 0)):
            text = str(header.get(f"Segment{n}_{key}", default)).strip()
            if not re.fullmatch(r"[0-9]+", text):
                raise _fail(path, f"Segment{n}_{key} {short_repr(text)} is not a non-negative integer")
            values.append(int(text))
        label, layer = values
        if label == 0:
            raise _fail(path, f"Segment{n}_LabelValue is 0, the background")
        if layer >= n_layers:
            raise _fail(path, f"Segment{n}_Layer {layer} does not exist (the file has {n_layers} layer(s))")
        table.append((name, label, layer))
    return table


def _read_nifti(path: Path) -> LabelVolume:
    import nibabel

    try:
        img = nibabel.load(str(path))
    except Exception as exc:  # ImageFileError, gzip errors, OSError on short headers
        raise _fail(path, f"not a NIfTI file ({' '.join(str(exc).split())[:160] or type(exc).__name__})") from None
    if not isinstance(img, nibabel.Nifti1Image):  # Nifti2Image is a subclass
        raise _fail(path, f"not a NIfTI image ({type(img).__name__})")
    shape = tuple(int(s) for s in img.shape)
    if len(shape) > 3 and any(s != 1 for s in shape[3:]):
        raise _fail(path, f"a {len(shape)}-D image ({' x '.join(map(str, shape))}): expected one 3-D label map")
    shape = (shape + (1, 1, 1))[:3]
    sform, s_code = img.get_sform(coded=True)
    qform, q_code = img.get_qform(coded=True)
    if s_code > 0:
        affine = np.asarray(sform, dtype=float)
    elif q_code > 0:
        affine = np.asarray(qform, dtype=float)
    else:
        raise _fail(
            path,
            "neither sform nor qform is set (both codes 0): the image has no orientation, "
            "so left and right would be a guess",
        )
    unit = img.header.get_xyzt_units()[0]
    if unit not in _NIFTI_UNITS:
        raise _fail(path, f"spatial unit {unit!r} (expected mm, m or um)")
    affine = affine.copy()
    affine[:3] *= _NIFTI_UNITS[unit]
    _check_affine(path, affine[:3, :3], affine[:3, 3], shape)
    slope, inter = img.dataobj.slope, img.dataobj.inter
    scaled = not (slope in (1, None) or np.isnan(slope)) or not (inter in (0, None) or np.isnan(inter))
    _check_size(path, shape, 8 if scaled else img.get_data_dtype().itemsize)
    try:
        data = np.asanyarray(img.dataobj)
    except Exception as exc:  # truncated: OSError, EOFError, zlib.error
        raise _fail(
            path,
            f"cannot read the voxel data (truncated or corrupt: {' '.join(str(exc).split())[:160] or type(exc).__name__})",
        ) from None
    return LabelVolume(_labels(path, data).reshape((1,) + shape), affine, "RAS", None)


def read_label_volume(path: Path) -> LabelVolume:
    """The labels of a ``.seg.nrrd`` / ``.nrrd`` / ``.nii`` / ``.nii.gz`` file, checked (see the module docstring)."""
    _check_file(path)
    name = path.name.lower()
    if name.endswith(".nrrd"):
        return _read_nrrd(path)
    if name.endswith((".nii", ".nii.gz")):
        return _read_nifti(path)
    raise _fail(path, f"unknown segmentation format (expected {', '.join(LABEL_SUFFIXES)})")
