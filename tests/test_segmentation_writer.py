"""Label maps out (issue 33): a virtual patient's default anatomy as .seg.nrrd / .nii.gz, read back.

Oracle: the boxes of the default anatomy (:mod:`arcube.patients.anatomy`) and the rule the writer
documents (a voxel carries the label of the first segment, bone before soft tissue, one of whose boxes
holds its centre), evaluated here point by point with the exact box distance. Marching cubes puts each
vertex halfway between two neighbouring voxel centres of which exactly one carries the segment's label
(or, in Lewiner's ambiguous cells, at the centre of a cell whose corners differ), so that is checked at
every vertex, and with it that every vertex lies within half a voxel diagonal of the STL boxes.
"""

from __future__ import annotations

import os
from pathlib import Path

import nibabel
import nrrd
import numpy as np
import pytest

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.sdf import box_signed_distance
from arcube.io.segmentation_writer import write_segmentation
from arcube.io.segmentations import read_segmentation
from arcube.patients import draw_parameters
from arcube.patients.anatomy import default_anatomy_layout
from arcube.patients.cohort import write_patients
from arcube.patients.anatomy_segments import anatomy_segments, write_anatomy_as

SPACING = 1.0
LEVELS = ("C3", "C4", "C5", "C6", "C7")


@pytest.fixture(scope="module")
def layout():
    return default_anatomy_layout(draw_parameters(None))


def _label_at(layout, p: np.ndarray) -> np.ndarray:
    """The documented rule, from the boxes: first of C3..C7 (body or arch), then soft tissue (100), else 0."""
    out = np.zeros(len(p), dtype=int)
    groups = [
        (int(lv[1]), [b for b in layout.boxes if b.kind == "bone" and b.name.startswith(lv + " ")]) for lv in LEVELS
    ]
    groups.append((100, [b for b in layout.boxes if b.kind == "soft tissue"]))
    for label, boxes in reversed(groups):
        inside = np.min([box_signed_distance(p, *b) for b in boxes], axis=0) <= 0
        out[inside] = label
    return out


@pytest.mark.parametrize("suffix", [".seg.nrrd", ".nii.gz"])
def test_round_trip_of_the_default_anatomy(tmp_path: Path, layout, suffix: str) -> None:
    path = tmp_path / f"p.anatomy{suffix}"
    write_anatomy_as(draw_parameters(None), path, suffix[1:], SPACING)
    seg = read_segmentation(path)
    names = [s.name for s in seg.segments]
    assert names == (list(LEVELS) + ["soft tissue"] if suffix == ".seg.nrrd" else ["3", "4", "5", "6", "7", "100"])
    assert [s.label for s in seg.segments] == [3, 4, 5, 6, 7, 100]
    patient_to_index = np.linalg.inv(seg.index_to_patient)
    half_diagonal = SPACING * np.sqrt(3) / 2
    for info, mesh in zip(seg.segments, seg.meshes):
        v = np.asarray(mesh.vertices)
        idx = v @ patient_to_index[:3, :3].T + patient_to_index[:3, 3]
        half = np.isclose(np.abs(idx - np.floor(idx)), 0.5, atol=1e-6)
        assert (half | np.isclose(idx, np.round(idx), atol=1e-6)).all()  # every coordinate on a centre or halfway
        unit = seg.index_to_patient[:3, :3]
        n_half = half.sum(axis=1)
        assert np.isin(n_half, (1, 3)).all()
        # on a grid edge: the two centres it joins; at a cell centre (Lewiner): the cell's 8 corners
        edge = n_half == 1
        ends = [v[edge] + s * 0.5 * half[edge] @ unit.T for s in (-1.0, 1.0)]
        corners = [v[~edge] + (np.array(c) - 0.5) @ unit.T for c in np.ndindex(2, 2, 2)]
        for points in (ends, corners):
            inside = np.array([_label_at(layout, p) == info.label for p in points])
            assert (inside.any(axis=0) & ~inside.all(axis=0)).all()
        # hence within half a voxel diagonal of the STL boxes' surfaces
        to_boxes = np.min([np.abs(box_signed_distance(v, *box)) for box in layout.boxes], axis=0)
        assert to_boxes.max() <= half_diagonal
        assert info.voxels > 0 and mesh.volume > 0


def test_the_seg_nrrd_holds_the_fields_slicer_reads(tmp_path: Path, layout) -> None:
    path = write_segmentation(anatomy_segments(layout), tmp_path / "a.seg.nrrd", 2.0)
    data, header = nrrd.read(str(path))
    assert header["space"] == "left-posterior-superior" and header["dimension"] == 3
    np.testing.assert_allclose(header["space directions"], 2.0 * np.eye(3))
    assert header["Segmentation_ReferenceImageExtentOffset"] == "0 0 0"
    assert header["Segmentation_MasterRepresentation"] == "Binary labelmap"
    for n, (name, label) in enumerate(zip(list(LEVELS) + ["soft tissue"], [3, 4, 5, 6, 7, 100])):
        assert header[f"Segment{n}_Name"] == name and header[f"Segment{n}_LabelValue"] == str(label)
        assert header[f"Segment{n}_Layer"] == "0" and header[f"Segment{n}_ID"]
        assert len(header[f"Segment{n}_Color"].split()) == 3
        idx = np.nonzero(data == label)
        assert header[f"Segment{n}_Extent"] == " ".join(f"{i.min()} {i.max()}" for i in idx)


def test_the_nifti_has_sform_qform_and_mm(tmp_path: Path, layout) -> None:
    path = write_segmentation(anatomy_segments(layout), tmp_path / "a.nii.gz", 2.0)
    img = nibabel.load(str(path))
    assert img.get_sform(coded=True)[1] == 1 and img.get_qform(coded=True)[1] == 1
    np.testing.assert_allclose(img.get_qform(), img.get_sform(), atol=1e-5)
    assert img.header.get_xyzt_units()[0] == "mm"
    ras_x = img.affine[:3, 0]
    np.testing.assert_allclose(ras_x, [-2.0, 0, 0])  # first axis along L, as in the .seg.nrrd


def test_write_patients_in_each_format_and_default_finds_the_newest(tmp_path: Path) -> None:
    csv = tmp_path / "p.csv"
    write_patients(True, None, "pedicle", 1, csv, anatomy_format="nii.gz", anatomy_spacing_mm=2.0)
    assert (tmp_path / "p.anatomy.nii.gz").exists() and not (tmp_path / "p.anatomy.stl").exists()
    a = resolve_anatomy("default", plan=str(csv))
    assert a.source == f"default ({tmp_path / 'p.anatomy.nii.gz'})" and [s.label for s in a.segments] == [
        3,
        4,
        5,
        6,
        7,
        100,
    ]
    write_patients(True, None, "pedicle", 1, csv, anatomy_format="stl")
    os.utime(tmp_path / "p.anatomy.nii.gz", ns=(1, 1))  # the older one
    b = resolve_anatomy("default", plan=str(csv))
    assert b.source.endswith("p.anatomy.stl)") and b.segments is None
    write_patients(True, None, "pedicle", 1, csv, anatomy_format="seg.nrrd", anatomy_spacing_mm=2.0)
    c = resolve_anatomy("default", plan=str(csv), segments="C3,C4")
    assert c.source.endswith("p.anatomy.seg.nrrd)") and [s.name for s in c.segments] == ["C3", "C4"]
    # given by name, each file says its own frame: the NIfTI's RAS and the .seg.nrrd's LPS, whatever --anatomy-frame (the meshes') says
    d = resolve_anatomy([str(tmp_path / "p.anatomy.nii.gz"), str(tmp_path / "p.anatomy.stl")], "patient", plan=str(csv))
    assert d.source == f"{tmp_path / 'p.anatomy.nii.gz'} (RAS, the file's own), {tmp_path / 'p.anatomy.stl'} (patient)"
    e = resolve_anatomy(str(tmp_path / "p.anatomy.seg.nrrd"), "RAS", plan=str(csv))
    assert e.source == f"{tmp_path / 'p.anatomy.seg.nrrd'} (LPS, the file's own)"
    with pytest.raises(InputError, match="^anatomy_format 'stl.gz'"):
        write_patients(True, None, "pedicle", 1, csv, anatomy_format="stl.gz")


@pytest.mark.parametrize("spacing", [-1.0, 40.0, 0.001])
def test_a_bad_spacing_writes_nothing(tmp_path: Path, spacing: float) -> None:
    """Negative; so coarse that a vertebra has no voxel centre; so fine that the grid is too large."""
    with pytest.raises(InputError) as err:
        write_patients(
            True, None, "pedicle", 1, tmp_path / "p.csv", anatomy_format="seg.nrrd", anatomy_spacing_mm=spacing
        )
    assert "\n" not in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_bad_segments_write_nothing(tmp_path: Path, layout) -> None:
    segs = anatomy_segments(layout)
    cases = {
        "a.seg.nrrd": [segs[0], (segs[1][0], segs[0][1], segs[1][2])],  # a label used twice
        "b.nii.gz": [("x", 0, segs[0][2])],  # the background label
        "c.stl": segs,  # not a label-map format
        "d.nii.gz": [],  # nothing to write
    }
    for name, segments in cases.items():
        with pytest.raises(InputError) as err:
            write_segmentation(segments, tmp_path / name, 2.0)
        assert str(tmp_path / name) in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_settings_name_their_field() -> None:
    from arcube.patients.settings import PatientAnatomyFormat, SegmentSelection

    assert SegmentSelection(segments="C3, 4").segments == ("C3", "4") and SegmentSelection().segments is None
    assert SegmentSelection(segments=["skin", 7]).segments == ("skin", "7")
    with pytest.raises(InputError, match=r"^SegmentSelection\.segments must be names or label values"):
        SegmentSelection(segments="C3,,C4")
    with pytest.raises(
        InputError, match=r"^PatientAnatomyFormat\.anatomy_format must be one of stl, seg\.nrrd, nii\.gz"
    ):
        PatientAnatomyFormat(anatomy_format="obj")
    with pytest.raises(InputError, match=r"^PatientAnatomyFormat\.anatomy_spacing_mm must be > 0"):
        PatientAnatomyFormat(anatomy_spacing_mm=0)
