"""Segmentations in (issue 33): .seg.nrrd and NIfTI label maps of analytic shapes, read back as surfaces.

Oracles, all independent of the reader under test:

* the shapes are analytic (two rotated boxes and a sphere in the patient frame) with exact signed
  distances (``box_signed_distance`` of the SDF module, ``|p - c| - R``);
* the label maps are made here, voxel by voxel, from the definition "voxel index i is the centre
  ``origin + D @ i`` of its voxel" and written with pynrrd / nibabel header fields set by hand
  (one NRRD is written byte by byte, without pynrrd);
* the frames are restated from MODEL.md 1.1 (x right, y superior, z posterior): LPS (l, p, s) ->
  (-l, s, p), RAS (r, a, s) -> (r, s, -a).

Bounds. Marching cubes at 0.5 on a binary mask puts every vertex halfway along a grid edge whose
ends lie on either side of the segmented boundary, or (Lewiner's interior points of ambiguous
cells) at the centre of a cell with corners on both sides, so every vertex is within half the
voxel diagonal (``HALF_DIAGONAL``) of the analytic surface. The converse holds on
the sphere and on box faces, not at box edges and corners, which marching cubes bevels (by up to
about 1.44 voxel there): those are left out of the converse and distance checks.
"""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import nibabel
import nrrd
import numpy as np
import pytest

from arcube.errors import InputError
from arcube.evaluation.anatomy import load_anatomy, resolve_anatomy
from arcube.evaluation.sdf import box_signed_distance
from arcube.io.segmentations import read_segmentation, read_segmentations

# MODEL.md 1.1 restated: patient point from an LPS / RAS point.
LPS_TO_PATIENT = np.array([[-1.0, 0, 0], [0, 0, 1], [0, 1, 0]])
RAS_TO_PATIENT = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
RAS_FROM_LPS = np.diag([-1.0, -1.0, 1.0])


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# The analytic anatomy (patient frame, mm): label -> shape.
BOX1 = (np.array([-14.0, 2.0, -3.0]), np.array([8.0, 6.0, 5.0]), _rotation(1))
BOX2 = (np.array([13.0, 6.0, 1.0]), np.array([5.0, 9.0, 4.0]), _rotation(2))
SPHERE = (np.array([0.0, -12.0, 14.0]), 7.5)
NAMES = {1: "C3 box", 2: "C4 box", 3: "ball"}


def sd_shape(label: int, p: np.ndarray) -> np.ndarray:
    """Exact signed distance (..., 3) -> (...) to the shape of ``label``."""
    if label == 1:
        return box_signed_distance(p, *BOX1)
    if label == 2:
        return box_signed_distance(p, *BOX2)
    return np.linalg.norm(p - SPHERE[0], axis=-1) - SPHERE[1]


def sd_all(p: np.ndarray) -> np.ndarray:
    return np.min([sd_shape(k, p) for k in (1, 2, 3)], axis=0)


# The grid: oblique (rotated) and anisotropic, in LPS; voxel (i, j, k) centred at ORIGIN + D @ (i, j, k).
SPACING = np.array([0.8, 1.0, 1.25])
HALF_DIAGONAL = 0.5 * float(np.linalg.norm(SPACING))
GRID_ROT = _rotation(7)
D_LPS = GRID_ROT @ np.diag(SPACING)
SHAPE = tuple(int(np.ceil(64.0 / s)) + 1 for s in SPACING)
ORIGIN_LPS = LPS_TO_PATIENT.T @ np.zeros(3) - D_LPS @ ((np.array(SHAPE) - 1) / 2.0)  # centred on the patient origin


def label_grid(d_lps: np.ndarray = D_LPS, origin_lps: np.ndarray = ORIGIN_LPS, shape=SHAPE) -> np.ndarray:
    """Labels (I, J, K) uint8 of the analytic shapes at the voxel centres of the grid."""
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), axis=-1).reshape(-1, 3)
    patient = (origin_lps + idx @ d_lps.T) @ LPS_TO_PATIENT.T
    labels = np.zeros(len(idx), dtype=np.uint8)
    for label in (1, 2, 3):
        labels[sd_shape(label, patient) <= 0] = label
    return labels.reshape(shape)


LABELS = label_grid()


def write_nrrd(
    path: Path,
    data: np.ndarray,
    d_world: np.ndarray,
    origin: np.ndarray,
    space: str = "left-posterior-superior",
    segments=((1, 0), (2, 0), (3, 0)),
    **extra,
) -> Path:
    """A .seg.nrrd: data (I, J, K) or (L, I, J, K), world step per axis = columns of d_world."""
    layered = data.ndim == 4
    header = {
        "type": "uint8",
        "dimension": data.ndim,
        "space": space,
        "sizes": np.array(data.shape),
        "space directions": np.vstack(([[np.nan] * 3] if layered else []) + [d_world.T]),
        "kinds": (["list"] if layered else []) + ["domain"] * 3,
        "encoding": "gzip",
        "space origin": origin,
    }
    for n, (label, layer) in enumerate(segments):
        header.update(
            {
                f"Segment{n}_ID": f"Segment_{label}",
                f"Segment{n}_Name": NAMES[label],
                f"Segment{n}_LabelValue": str(label),
                f"Segment{n}_Layer": str(layer),
            }
        )
    header.update(extra)
    nrrd.write(str(path), data, header, index_order="F")
    return path


def write_nifti(
    path: Path,
    data: np.ndarray,
    affine_ras: np.ndarray,
    sform: bool = True,
    qform: bool = True,
    qform_affine: np.ndarray | None = None,
) -> Path:
    img = nibabel.Nifti1Image(data, None)
    img.set_sform(affine_ras if sform else None, code=1 if sform else 0)
    img.set_qform((affine_ras if qform_affine is None else qform_affine) if qform else None, code=1 if qform else 0)
    img.header.set_xyzt_units("mm")
    img.to_filename(str(path))
    return path


def _affine(linear: np.ndarray, origin: np.ndarray) -> np.ndarray:
    a = np.eye(4)
    a[:3, :3], a[:3, 3] = linear, origin
    return a


def files(tmp: Path) -> dict[str, Path]:
    """The same analytic label map in every format the reader takes."""
    layers = np.zeros((2,) + LABELS.shape, dtype=np.uint8)
    layers[0][LABELS == 1] = 1
    layers[0][LABELS == 3] = 3
    layers[1][LABELS == 2] = 2
    affine_ras = _affine(RAS_FROM_LPS @ D_LPS, RAS_FROM_LPS @ ORIGIN_LPS)
    return {
        "seg.nrrd LPS": write_nrrd(tmp / "lps.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS),
        "seg.nrrd RAS": write_nrrd(
            tmp / "ras.seg.nrrd",
            LABELS,
            RAS_FROM_LPS @ D_LPS,
            RAS_FROM_LPS @ ORIGIN_LPS,
            space="right-anterior-superior",
        ),
        "seg.nrrd layers": write_nrrd(
            tmp / "layers.seg.nrrd", layers, D_LPS, ORIGIN_LPS, segments=((1, 0), (2, 1), (3, 0))
        ),
        "nii.gz sform": write_nifti(tmp / "sform.nii.gz", LABELS, affine_ras, qform=False),
        "nii qform": write_nifti(tmp / "qform.nii", LABELS, affine_ras, sform=False),
    }


@pytest.fixture(scope="module")
def label_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return files(tmp_path_factory.mktemp("seg"))


def _by_label(seg) -> dict[int, np.ndarray]:
    return {info.label: np.asarray(mesh.vertices) for info, mesh in zip(seg.segments, seg.meshes)}


def _on_faces(label: int, n: int, rng: np.random.Generator, margin: float) -> np.ndarray:
    """Points on the shape's surface, for boxes at least ``margin`` from every edge."""
    if label == 3:
        u = rng.normal(size=(n, 3))
        return SPHERE[0] + SPHERE[1] * u / np.linalg.norm(u, axis=1, keepdims=True)
    c, h, r = BOX1 if label == 1 else BOX2
    axis = rng.integers(0, 3, n)
    local = rng.uniform(-1, 1, (n, 3)) * np.maximum(h - margin, 0)
    local[np.arange(n), axis] = h[axis] * rng.choice([-1.0, 1.0], n)
    return c + local @ r.T


@pytest.mark.parametrize("kind", ["seg.nrrd LPS", "seg.nrrd RAS", "seg.nrrd layers", "nii.gz sform", "nii qform"])
def test_surfaces_within_half_a_voxel_diagonal_of_the_analytic_shapes(label_files: dict[str, Path], kind: str) -> None:
    import igl

    seg = read_segmentation(label_files[kind])
    assert sorted(i.label for i in seg.segments) == [1, 2, 3]
    rng = np.random.default_rng(3)
    for info, mesh in zip(seg.segments, seg.meshes):
        v = np.asarray(mesh.vertices)
        # every vertex near the analytic surface: halfway along a grid edge crossing it, or at the centre
        # of a cell with corners on both sides of it, so within half a voxel diagonal
        assert np.abs(sd_shape(info.label, v)).max() <= HALF_DIAGONAL
        # and the analytic surface near the mesh, away from box edges (which marching cubes bevels)
        probe = _on_faces(info.label, 400, rng, margin=3 * HALF_DIAGONAL)
        d2, _, _ = igl.point_mesh_squared_distance(probe, v, np.asarray(mesh.faces, dtype=np.int64))
        assert np.sqrt(d2).max() <= HALF_DIAGONAL
        # provenance: the voxel count of the label, bounds of the surface (patient frame)
        layer_data = LABELS
        assert info.voxels == int((layer_data == info.label).sum())
        if kind.startswith("nii"):
            assert info.name == str(info.label)
        else:
            assert info.name == NAMES[info.label]
        np.testing.assert_allclose(info.lo, v.min(axis=0))
        assert mesh.is_watertight and mesh.volume > 0


def test_every_format_gives_the_same_surfaces(label_files: dict[str, Path]) -> None:
    """LPS and RAS NRRD, layered NRRD, NIfTI sform and qform: the same voxels in the same places."""
    ref = _by_label(read_segmentation(label_files["seg.nrrd LPS"]))
    for kind, path in label_files.items():
        got = _by_label(read_segmentation(path))
        for label in (1, 2, 3):
            # NIfTI stores its affine as float32: about 1e-6 mm here
            np.testing.assert_allclose(got[label], ref[label], atol=1e-5, err_msg=kind)


def _off_edges(p: np.ndarray, margin: float) -> np.ndarray:
    """Points whose nearest analytic point is on the sphere, or on a box face at least ``margin`` from its edges."""
    nearest = np.argmin([sd_shape(k, p) for k in (1, 2, 3)], axis=0) + 1
    keep = nearest == 3
    for label, (c, h, r) in ((1, BOX1), (2, BOX2)):
        q = np.abs((p - c) @ r) - h
        keep |= (nearest == label) & ((q > 0).sum(axis=1) == 1) & (np.sort(q, axis=1)[:, 1] <= -margin)
    return keep


def test_signed_distance_of_the_anatomy_matches_the_analytic_distance(label_files: dict[str, Path]) -> None:
    """The clearance's distance (MODEL.md 14.3): the anatomy's grids at points 0.5-15 mm off the shapes.

    The grids are those of ``Anatomy.distance`` (1 mm fine grid) with smaller margins, so that the test is
    fast (the default 400 mm coarse margin costs most of the build); every point lies in the fine grid."""
    from arcube.evaluation.sdf import AnatomyDistance

    anatomy = load_anatomy([str(label_files["nii.gz sform"])])
    distance = AnatomyDistance.from_meshes(list(anatomy.meshes), fine_margin=16.0, coarse_margin=40.0)
    rng = np.random.default_rng(4)
    centre = np.mean([BOX1[0], BOX2[0], SPHERE[0]], axis=0)
    p = centre + rng.uniform(-40, 40, (20000, 3))
    truth = sd_all(p)
    p, truth = p[(truth > 0.5) & (truth < 15)], truth[(truth > 0.5) & (truth < 15)]
    keep = _off_edges(p, 3 * HALF_DIAGONAL)
    assert keep.sum() > 1000 and distance.fine.contains(p).all()
    error = np.abs(distance(p[keep]) - truth[keep])
    assert error.max() <= HALF_DIAGONAL


def test_lps_and_ras_files_give_the_same_anatomy(label_files: dict[str, Path]) -> None:
    lps = read_segmentation(label_files["seg.nrrd LPS"])
    ras = read_segmentation(label_files["seg.nrrd RAS"])
    assert (lps.space, ras.space) == ("LPS", "RAS")
    np.testing.assert_allclose(ras.index_to_patient, lps.index_to_patient, atol=1e-12)
    for a, b in zip(lps.meshes, ras.meshes):
        np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-9)
        np.testing.assert_array_equal(a.faces, b.faces)


def test_a_left_handed_grid_gives_the_true_geometry(tmp_path: Path) -> None:
    """Axis k reversed (det D < 0), data reversed with it: the same anatomy, surfaces still outward."""
    d = D_LPS @ np.diag([1.0, 1.0, -1.0])
    origin = ORIGIN_LPS + D_LPS[:, 2] * (SHAPE[2] - 1)
    labels = LABELS[:, :, ::-1]
    np.testing.assert_array_equal(labels, label_grid(d, origin))  # the same voxel centres, listed backwards
    seg = read_segmentation(write_nrrd(tmp_path / "left.seg.nrrd", labels, d, origin))
    assert np.linalg.det(seg.index_to_patient[:3, :3]) < 0
    ref = _by_label(read_segmentation(write_nrrd(tmp_path / "right.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS)))
    for info, mesh in zip(seg.segments, seg.meshes):
        assert mesh.volume > 0  # outward faces (the reader's closed-surface checks also passed)
        assert np.abs(sd_shape(info.label, np.asarray(mesh.vertices))).max() <= HALF_DIAGONAL
        assert sorted(map(tuple, np.round(mesh.vertices, 6))) == sorted(map(tuple, np.round(ref[info.label], 6)))


def test_a_mirrored_direction_matrix_gives_the_mirrored_anatomy(tmp_path: Path) -> None:
    """The same voxels with the direction matrix (and origin) mirrored left-right: the mirror image, not the original."""
    mirror = np.diag([-1.0, 1.0, 1.0])  # x -> -x, in LPS as in the patient frame
    seg = read_segmentation(write_nrrd(tmp_path / "mirror.seg.nrrd", LABELS, mirror @ D_LPS, mirror @ ORIGIN_LPS))
    for info, mesh in zip(seg.segments, seg.meshes):
        v = np.asarray(mesh.vertices)
        assert mesh.volume > 0
        assert np.abs(sd_shape(info.label, v * [-1.0, 1.0, 1.0])).max() <= HALF_DIAGONAL  # the mirror image ...
        if info.label != 3:  # (the sphere is on the mid-sagittal plane: its own mirror image)
            assert np.abs(sd_shape(info.label, v)).max() > 5.0  # ... not the original


def test_a_hand_written_nrrd_places_the_voxel_by_the_format(tmp_path: Path) -> None:
    """Bytes written here from the NRRD spec (fastest axis first): one voxel at (i, j, k) = (2, 0, 1)."""
    data = np.zeros((2, 2, 3), dtype=np.uint8)  # [k, j, i]: the file's byte order
    data[1, 0, 2] = 5
    head = (
        "NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\nsizes: 3 2 2\n"
        "space directions: (2,0,0) (0,3,0) (0,0,4)\nkinds: domain domain domain\nendian: little\n"
        "encoding: raw\nspace origin: (10,20,30)\nSegment0_ID:=Segment_1\nSegment0_Name:=V\n"
        "Segment0_LabelValue:=5\nSegment0_Layer:=0\n\n"
    )
    path = tmp_path / "one.seg.nrrd"
    path.write_bytes(head.encode() + data.tobytes())
    seg = read_segmentation(path)
    centre_lps = np.array([10 + 2 * 2, 20 + 0 * 3, 30 + 1 * 4])
    lo = LPS_TO_PATIENT @ (centre_lps - [1, 1.5, 2])
    hi = LPS_TO_PATIENT @ (centre_lps + [1, 1.5, 2])
    np.testing.assert_allclose(seg.segments[0].lo, np.minimum(lo, hi))
    np.testing.assert_allclose(seg.segments[0].hi, np.maximum(lo, hi))
    assert (seg.segments[0].name, seg.segments[0].label, seg.segments[0].voxels) == ("V", 5, 1)


def test_nifti_sform_wins_over_qform(tmp_path: Path) -> None:
    affine = _affine(RAS_FROM_LPS @ D_LPS, RAS_FROM_LPS @ ORIGIN_LPS)
    shifted = affine.copy()
    shifted[:3, 3] += [30.0, 0, 0]
    both = read_segmentation(write_nifti(tmp_path / "both.nii.gz", LABELS, affine, qform_affine=shifted))
    only_q = read_segmentation(write_nifti(tmp_path / "q.nii.gz", LABELS, shifted, sform=False))
    ref = read_segmentation(write_nifti(tmp_path / "s.nii.gz", LABELS, affine, qform=False))
    np.testing.assert_allclose(both.meshes[0].vertices, ref.meshes[0].vertices)
    np.testing.assert_allclose(only_q.meshes[0].vertices, ref.meshes[0].vertices + [30.0, 0, 0], atol=1e-5)


def test_extent_offset_does_not_move_the_voxels(tmp_path: Path) -> None:
    """Slicer shifts 'space origin' by the offset when it saves, so the offset is not applied again."""
    a = read_segmentation(
        write_nrrd(tmp_path / "a.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS, Segmentation_ReferenceImageExtentOffset="0 0 0")
    )
    b = read_segmentation(
        write_nrrd(
            tmp_path / "b.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS, Segmentation_ReferenceImageExtentOffset="12 -3 40"
        )
    )
    np.testing.assert_array_equal(a.meshes[1].vertices, b.meshes[1].vertices)


def test_selection_by_name_and_value(label_files: dict[str, Path]) -> None:
    path = label_files["seg.nrrd LPS"]
    assert [s.name for s in read_segmentation(path, "ball").segments] == ["ball"]
    assert [s.name for s in read_segmentation(path, ["C4 box", 1]).segments] == ["C4 box", "C3 box"]
    assert [s.label for s in read_segmentation(path, "3, 2").segments] == [3, 2]
    nifti = label_files["nii.gz sform"]
    assert [s.label for s in read_segmentation(nifti, "2").segments] == [2]
    # several files: each name in at least one of them
    both = read_segmentations([path, nifti], ["ball", "2"])
    assert [[s.label for s in seg.segments] for seg in both] == [[3, 2], [2]]


def test_anatomy_from_a_segmentation_is_cached_and_carries_its_segments(
    label_files: dict[str, Path], tmp_path: Path
) -> None:
    path = tmp_path / "c.seg.nrrd"
    path.write_bytes(label_files["seg.nrrd LPS"].read_bytes())
    a = resolve_anatomy(str(path), segments="ball")
    assert [s.name for s in a.segments] == ["ball"]
    assert a.segments[0].to_dict()["voxels"] == int((LABELS == 3).sum())
    assert resolve_anatomy(path, segments=["ball"]) is a  # same file, same selection: one anatomy, one grid
    assert resolve_anatomy(str(path)) is not a  # another selection
    os.utime(path, ns=(1, 1))  # the file changed: read again
    assert resolve_anatomy(str(path), segments="ball") is not a


def test_the_report_names_the_segments_used(label_files: dict[str, Path], tmp_path: Path) -> None:
    """An evaluation report of an anatomy read from a segmentation lists the segments kept, with their voxel counts."""
    import html
    import re

    import arcube

    a = resolve_anatomy(str(label_files["seg.nrrd LPS"]), segments="ball")
    ev = arcube.evaluate("paper", "reference", ids="1", points=3, anatomy=a)
    arcube.write_report(ev, tmp_path / "r.html")
    text = " ".join(html.unescape(re.sub(r"<[^>]+>", " ", (tmp_path / "r.html").read_text())).split())
    assert "Anatomy segments" in text and f" ball 3 0 {int((LABELS == 3).sum()):,} " in text
    assert "box" not in text.split("Anatomy segments")[1].split("Why points fail")[0]  # only the segment kept


BAD = {
    "not NRRD": lambda t: _text(t / "x.seg.nrrd", "hello"),
    "not NIfTI": lambda t: _text(t / "x.nii", "hello " * 100),
    "not gzip NIfTI": lambda t: _text(t / "x.nii.gz", "hello"),
    "float labels": lambda t: write_nifti(t / "f.nii.gz", LABELS * np.float32(0.5), np.eye(4)),
    "negative labels": lambda t: write_nifti(t / "n.nii.gz", LABELS.astype(np.int16) - 1, np.eye(4)),
    "no non-zero voxel": lambda t: write_nifti(t / "z.nii.gz", np.zeros((4, 4, 4), np.uint8), np.eye(4)),
    "singular affine": lambda t: write_nifti(t / "s.nii.gz", LABELS, np.diag([1.0, 0.0, 1.0, 1.0]), qform=False),
    "coplanar directions": lambda t: write_nrrd(
        t / "c.seg.nrrd", LABELS, np.array([[1.0, 0, 1], [0, 1, 0], [0, 0, 0]]), ORIGIN_LPS
    ),
    "non-finite origin": lambda t: write_nrrd(t / "nan.seg.nrrd", LABELS, D_LPS, np.array([0.0, np.nan, 0])),
    "4-D NIfTI": lambda t: write_nifti(t / "4d.nii.gz", np.ones((4, 4, 4, 2), np.uint8), np.eye(4)),
    "no orientation": lambda t: write_nifti(t / "o.nii.gz", LABELS, np.eye(4), sform=False, qform=False),
    "other space": lambda t: write_nrrd(t / "las.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS, space="left-anterior-superior"),
    "layer axis last": lambda t: _layer_last(t),
    "truncated NRRD": lambda t: _cut(write_nrrd(t / "cut.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS)),
    "truncated NIfTI": lambda t: _cut(write_nifti(t / "cut.nii", LABELS, np.eye(4))),
    "truncated NIfTI gz": lambda t: _cut(write_nifti(t / "cut.nii.gz", LABELS, np.eye(4))),
    "2 GB volume": lambda t: _huge(t),
    "2 GB NIfTI": lambda t: _huge_nifti(t),
    "a folder": lambda t: _folder(t / "dir.seg.nrrd"),
    "bad extent offset": lambda t: write_nrrd(
        t / "off.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS, Segmentation_ReferenceImageExtentOffset="1 2"
    ),
}
NEEDLES = {
    "not NRRD": "not a NRRD file",
    "not NIfTI": "not a NIfTI file",
    "not gzip NIfTI": "not a NIfTI file",
    "float labels": "non-integer values",
    "negative labels": "negative values",
    "no non-zero voxel": "no non-zero voxel",
    "singular affine": "singular",
    "coplanar directions": "singular",
    "non-finite origin": "non-finite",
    "4-D NIfTI": "4-D image",
    "no orientation": "neither sform nor qform",
    "other space": "not supported",
    "layer axis last": "layer axis first",
    "truncated NRRD": "truncated",
    "truncated NIfTI": "truncated",
    "truncated NIfTI gz": "truncated",
    "2 GB volume": "too large",
    "bad extent offset": "not three integers",
    "2 GB NIfTI": "too large",
    "a folder": "is a folder",
}


def _text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _cut(path: Path) -> Path:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) - max(200, len(data) // 4)])
    return path


def _layer_last(tmp: Path) -> Path:
    path = tmp / "last.seg.nrrd"
    header = {
        "type": "uint8",
        "dimension": 4,
        "space": "left-posterior-superior",
        "sizes": np.array([3, 3, 3, 2]),
        "space directions": np.vstack([np.eye(3), [[np.nan] * 3]]),
        "kinds": ["domain"] * 3 + ["list"],
        "space origin": np.zeros(3),
    }
    nrrd.write(str(path), np.ones((3, 3, 3, 2), np.uint8), header)
    return path


def _huge(tmp: Path) -> Path:
    """A header announcing 2048 x 2048 x 512 bytes (2 GiB) followed by a few bytes: refused from the header."""
    path = tmp / "huge.seg.nrrd"
    head = (
        "NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\nsizes: 2048 2048 512\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\nencoding: raw\n"
        "space origin: (0,0,0)\n\n"
    )
    path.write_bytes(head.encode() + b"\x01" * 64)
    return path


def _huge_nifti(tmp: Path) -> Path:
    """A NIfTI header announcing 2048 x 2048 x 512 voxels of int16 (4 GiB) and 64 bytes of data."""
    header = nibabel.Nifti1Header()
    header.set_data_shape((2048, 2048, 512))
    header.set_data_dtype(np.int16)
    header.set_sform(np.eye(4), code=1)
    path = tmp / "huge.nii"
    path.write_bytes(header.binaryblock + b"\0" * 4 + b"\1" * 64)
    return path


def _folder(path: Path) -> Path:
    path.mkdir()
    return path


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_one_line_naming_the_file(tmp_path: Path, case: str) -> None:
    path = BAD[case](tmp_path)
    with pytest.raises(InputError) as err:
        read_segmentation(path)
    text = str(err.value)
    assert "\n" not in text and str(path) in text and NEEDLES[case] in text, text
    with pytest.raises(InputError):
        load_anatomy([str(path)])


def test_unknown_or_empty_segments_list_the_available_ones(label_files: dict[str, Path], tmp_path: Path) -> None:
    path = label_files["seg.nrrd LPS"]
    with pytest.raises(InputError, match=r"no segment 'C9' \(available: C3 box \(label 1, [0-9]+ voxels\), C4 box"):
        read_segmentation(path, "C9")
    # a segment defined in the header without a voxel: refused when asked for, skipped otherwise
    empty = write_nrrd(tmp_path / "e.seg.nrrd", np.where(LABELS == 2, 0, LABELS).astype(np.uint8), D_LPS, ORIGIN_LPS)
    with pytest.raises(InputError, match="segment 'C4 box' \\(label 2\\) has no voxel"):
        read_segmentation(empty, "C4 box")
    assert [s.label for s in read_segmentation(empty).segments] == [1, 3]
    with pytest.raises(InputError, match="no segment 'nope' in any of them"):
        read_segmentations([path, empty], ["ball", "nope"])
    with pytest.raises(InputError, match="segments applies to segmentation files"):
        load_anatomy(["default"], segments="C3")


def test_a_legacy_four_d_file_without_label_values(tmp_path: Path) -> None:
    """One binary layer per segment, no LabelValue or Layer fields: label 1 in layer N (as Slicer reads it)."""
    layers = np.stack([(LABELS == 1), (LABELS == 3)]).astype(np.uint8)
    path = tmp_path / "legacy.seg.nrrd"
    header = {
        "type": "uint8",
        "dimension": 4,
        "space": "left-posterior-superior",
        "sizes": np.array(layers.shape),
        "space directions": np.vstack([[[np.nan] * 3], D_LPS.T]),
        "kinds": ["list"] + ["domain"] * 3,
        "encoding": "gzip",
        "space origin": ORIGIN_LPS,
        "Segment0_ID": "a",
        "Segment0_Name": "box",
        "Segment1_ID": "b",
        "Segment1_Name": "ball",
    }
    nrrd.write(str(path), layers, header)
    seg = read_segmentation(path)
    assert [(s.name, s.label, s.layer) for s in seg.segments] == [("box", 1, 0), ("ball", 1, 1)]
    ref = _by_label(read_segmentation(label_files_cache(tmp_path)))
    np.testing.assert_array_equal(seg.meshes[0].vertices, ref[1])
    np.testing.assert_array_equal(seg.meshes[1].vertices, ref[3])


def label_files_cache(tmp: Path) -> Path:
    return write_nrrd(tmp / "ref.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS)


@pytest.mark.parametrize("seed", range(40))
def test_random_masks_on_random_grids_close_and_face_outward(seed: int) -> None:
    """Brute force on small cases: any mask, any affine (mirrored or not): closed, outward, vertices between an
    inside and an outside voxel centre."""
    from scipy import ndimage

    from arcube.io.meshes import _signed_volume, _unmatched_edges, split_shells
    from arcube.io.segmentations import label_surface

    rng = np.random.default_rng(seed)
    mask = rng.random((7, 8, 6)) < rng.uniform(0.2, 0.7)
    affine = np.eye(4)
    affine[:3, :3] = _rotation(seed + 100) @ np.diag(rng.uniform(0.3, 2.0, 3) * rng.choice([-1.0, 1.0], 3))
    affine[:3, 3] = rng.uniform(-50, 50, 3)
    mesh = label_surface(mask, affine, start=(3, -2, 5))
    assert _unmatched_edges(np.asarray(mesh.faces)) == 0
    assert all(_signed_volume(np.asarray(s.vertices), np.asarray(s.faces)) > 0 for s in split_shells(mesh))
    assert np.isclose(mesh.volume, abs(np.linalg.det(affine[:3, :3])) * _mc_volume(mask), rtol=1e-9)
    # padded-mask index of each vertex; enclosed holes are part of the solid
    idx = (np.asarray(mesh.vertices) - affine[:3, 3]) @ np.linalg.inv(affine[:3, :3]).T - [3, -2, 5] + 1
    solid = np.pad(ndimage.binary_fill_holes(mask), 1)
    half = np.isclose(np.abs(idx - np.floor(idx)), 0.5, atol=1e-9)
    on_edge = half.sum(axis=1) == 1
    # on a grid edge: halfway between a centre inside and one outside (half a voxel edge from the boundary)
    e = idx[on_edge]
    step = 0.5 * half[on_edge]
    a, b = np.round(e - step).astype(int), np.round(e + step).astype(int)
    assert (solid[tuple(a.T)] != solid[tuple(b.T)]).all()
    # else Lewiner's interior vertex of an ambiguous cell: its centre, the cell having corners on both sides
    assert (half[~on_edge].sum(axis=1) == 3).all()
    for lo in np.round(idx[~on_edge] - 0.5).astype(int):
        corners = solid[lo[0] : lo[0] + 2, lo[1] : lo[1] + 2, lo[2] : lo[2] + 2]
        assert corners.any() and not corners.all()


def _mc_volume(mask: np.ndarray) -> float:
    """Volume (index units) enclosed by the marching-cubes surface of ``mask`` on the identity grid."""
    from arcube.io.segmentations import label_surface

    return float(label_surface(mask, np.eye(4)).volume)


def test_the_cli_exits_2_with_one_line(tmp_path: Path) -> None:
    bad = _cut(write_nrrd(tmp_path / "cut.seg.nrrd", LABELS, D_LPS, ORIGIN_LPS))
    run = subprocess.run(
        [sys.executable, "-m", "arcube", "evaluate", "--anatomy", str(bad)], capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "truncated" in lines[0], run.stderr


def test_a_gzip_compressed_nii_named_nii_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "g.nii"
    path.write_bytes(gzip.compress(b"x" * 400))
    with pytest.raises(InputError, match="g.nii: not a NIfTI file"):
        read_segmentation(path)
