"""Anatomy meshes (MODEL.md 14.2): reading/writing (``arcube.io.meshes``) and the default anatomy.

Oracles are independent of the code under test: frame conversions written out by hand from the
axis definitions (RAS: r, a, s; LPS: l, p, s; patient: x right, y superior, z posterior), box
distances by closest-point projection, and the reference patient's numbers read from the bundled
CSV and MORPHOMETRY.md (lordosis 18.6°, H = 12.5 mm, D = 16.5 mm).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from arcube.errors import InputError
from arcube.io.meshes import read_mesh, read_meshes, split_shells, write_stl
from arcube.patients.anatomy import (
    default_anatomy,
    default_anatomy_boxes,
    default_anatomy_layout,
    reference_anatomy,
    reference_anatomy_boxes,
    reference_anatomy_path,
)
from arcube.patients.virtual import build_patient, draw_parameters

from designs import REFERENCE_CSV


# ------------------------------------------------------------ independent helpers


def lps_from_patient(v: np.ndarray) -> np.ndarray:
    """x = -l, y = s, z = p  =>  (l, p, s) = (-x, z, y)."""
    return np.column_stack([-v[:, 0], v[:, 2], v[:, 1]])


def ras_from_patient(v: np.ndarray) -> np.ndarray:
    """x = r, y = s, z = -a  =>  (r, a, s) = (x, -z, y)."""
    return np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])


def box_sd(points, centre, half, rot) -> np.ndarray:
    """Signed distance to a box by projection: outside |p - closest point|, inside -(distance to the nearest face)."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    local = (p - centre) @ rot  # coordinates along the box axes (rot columns)
    closest = np.clip(local, -half, half)
    outside = np.linalg.norm(local - closest, axis=1)
    inside = np.all(np.abs(local) <= half, axis=1)
    depth = np.min(half - np.abs(local), axis=1)
    return np.where(inside, -depth, outside)


def same_vertex_set(a: np.ndarray, b: np.ndarray, tol: float = 1e-4) -> bool:
    a = np.unique(np.round(np.asarray(a, dtype=float), 3), axis=0)
    b = np.unique(np.round(np.asarray(b, dtype=float), 3), axis=0)
    return a.shape == b.shape and np.abs(a - b).max() <= tol + 1e-3


def asym_box() -> trimesh.Trimesh:
    """A box that is not symmetric in any axis, so axis mix-ups show (patient frame)."""
    rot = trimesh.transformations.rotation_matrix(0.3, [1, 2, 3])
    rot[:3, 3] = [10.0, -20.0, 35.0]
    return trimesh.creation.box(extents=(4.0, 7.0, 11.0), transform=rot)


def reference_rows() -> list[dict[str, str]]:
    with REFERENCE_CSV.open() as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------ read_mesh / write_stl


@pytest.mark.parametrize(
    "frame, to_file", [("LPS", lps_from_patient), ("RAS", ras_from_patient), ("patient", lambda v: v)]
)
@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply"])
def test_read_mesh_converts_to_patient_frame(tmp_path: Path, frame, to_file, suffix) -> None:
    box = asym_box()
    in_file = trimesh.Trimesh(vertices=to_file(box.vertices), faces=box.faces, process=False)
    path = tmp_path / f"box{suffix}"
    in_file.export(path)
    got = read_mesh(path, frame)
    assert isinstance(got, trimesh.Trimesh)
    assert len(got.faces) == 12
    assert same_vertex_set(got.vertices, box.vertices)
    assert got.is_watertight and got.volume == pytest.approx(4 * 7 * 11, rel=1e-5)  # still outward


@pytest.mark.parametrize("frame, to_file", [("LPS", lps_from_patient), ("RAS", ras_from_patient)])
def test_write_stl_declares_frame_and_round_trips(tmp_path: Path, frame, to_file) -> None:
    box = asym_box()
    path = write_stl([box, box.copy().apply_translation([50, 0, 0])], tmp_path / "two.stl", frame=frame)
    raw = path.read_bytes()
    assert f"SPACE={frame}".encode() in raw[:80]
    # the file holds file-frame coordinates: compare with trimesh's own reading, unconverted
    plain = trimesh.load(path, force="mesh")
    both = np.vstack([box.vertices, box.vertices + [50, 0, 0]])
    assert same_vertex_set(plain.vertices, to_file(both))
    back = read_mesh(path, frame)
    assert same_vertex_set(back.vertices, both)
    assert len(split_shells(back)) == 2
    other = "RAS" if frame == "LPS" else "LPS"
    with pytest.raises(InputError, match="declares"):
        read_mesh(path, other)


def test_read_meshes_keeps_order(tmp_path: Path) -> None:
    a = trimesh.creation.box(extents=(1, 2, 3))
    b = trimesh.creation.icosphere(subdivisions=2, radius=5.0).apply_translation([0, 0, 40])
    write_stl(a, tmp_path / "a.stl")
    write_stl(b, tmp_path / "b.stl")
    got = read_meshes([tmp_path / "a.stl", tmp_path / "b.stl"], "patient")
    assert [len(m.faces) for m in got] == [12, len(b.faces)]
    assert got[1].vertices[:, 2].mean() == pytest.approx(40.0, abs=1e-3)


def _write_text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _open_box(path: Path) -> Path:
    box = trimesh.creation.box(extents=(1, 2, 3))
    trimesh.Trimesh(vertices=box.vertices, faces=box.faces[:-1], process=False).export(path)
    return path


def _nan_box(path: Path) -> Path:
    box = trimesh.creation.box(extents=(1, 2, 3))
    v = box.vertices.copy()
    v[0] = np.nan
    trimesh.Trimesh(vertices=v, faces=box.faces, process=False).export(path)
    return path


def _inverted_box(path: Path) -> Path:
    box = trimesh.creation.box(extents=(1, 2, 3))
    trimesh.Trimesh(vertices=box.vertices, faces=box.faces[:, ::-1], process=False).export(path)
    return path


def _empty_stl(path: Path) -> Path:
    path.write_bytes(b"empty".ljust(80, b" ") + (0).to_bytes(4, "little"))
    return path


def _point_cloud(path: Path) -> Path:
    return _write_text(
        path,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
    )


@pytest.mark.parametrize(
    "make, frame, needle",
    [
        (lambda d: d / "missing.stl", "LPS", "no such file"),
        (lambda d: _write_text(d / "notes.stl", "these are my notes\nnot a mesh\n"), "LPS", "not an STL file"),
        (lambda d: _write_text(d / "notes.obj", "these are my notes\n"), "LPS", "no triangles"),
        (lambda d: _write_text(d / "notes.ply", "these are my notes\n"), "LPS", "cannot read"),
        (_empty_stl_name := (lambda d: _empty_stl(d / "empty.stl")), "LPS", "no triangles"),
        (lambda d: _point_cloud(d / "cloud.ply"), "LPS", "point cloud"),
        (lambda d: _open_box(d / "open.stl"), "LPS", "not closed"),
        (lambda d: _nan_box(d / "nan.stl"), "LPS", "NaN"),
        (lambda d: _inverted_box(d / "inverted.obj"), "RAS", "oriented inward"),
        (lambda d: _open_box(d / "ok_but.stl"), "XYZ", "unknown frame"),
        (lambda d: _write_text(d / "mesh.vtk", "x"), "LPS", "or a segmentation .seg.nrrd, .nrrd, .nii or .nii.gz"),
    ],
)
def test_bad_mesh_inputs_raise_one_line_input_error(tmp_path: Path, make, frame, needle) -> None:
    path = make(tmp_path)
    with pytest.raises(InputError) as info:
        read_mesh(path, frame)
    message = str(info.value)
    assert needle in message
    assert str(path) in message
    assert "\n" not in message


def test_touching_shells_are_closed(tmp_path: Path) -> None:
    """Two boxes sharing an edge: every directed edge still has its opposite, so the file is accepted."""
    a = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    b = trimesh.creation.box(bounds=[[1, 1, 0], [2, 2, 1]])
    write_stl([a, b], tmp_path / "touch.stl")
    got = read_mesh(tmp_path / "touch.stl", "patient")
    assert len(got.faces) == 24


# ------------------------------------------------------------ default anatomy


@pytest.fixture(scope="module")
def mean_params() -> dict:
    return draw_parameters(None)


@pytest.fixture(scope="module")
def mean_boxes(mean_params) -> list:
    return default_anatomy_boxes(mean_params)


def bone(boxes) -> list:
    return [b for b in boxes if b.kind == "bone"]


def soft(boxes) -> list:
    return [b for b in boxes if b.kind == "soft tissue"]


def test_default_anatomy_meshes_are_closed_boxes(mean_params, mean_boxes) -> None:
    meshes = default_anatomy(mean_params)
    assert len(meshes) == len(mean_boxes) == 15
    assert len(bone(mean_boxes)) == 10 and len(soft(mean_boxes)) == 5
    for mesh, box in zip(meshes, mean_boxes):
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume
        assert mesh.volume == pytest.approx(8 * np.prod(box.half_extents), rel=1e-9)
        assert same_vertex_set(mesh.vertices, box.corners())
        rot = box.rotation
        assert np.allclose(rot.T @ rot, np.eye(3), atol=1e-12) and np.linalg.det(rot) > 0
    # the STL of all boxes: one closed shell per box, no shared vertices between boxes
    merged = trimesh.util.concatenate(meshes)
    merged.merge_vertices()
    assert len(split_shells(merged)) == 15


def test_bodies_follow_the_level_frames(mean_boxes) -> None:
    """Body = 18 x H x D box on the level centre, tilted by the level tilt (MORPHOMETRY.md 4, mean patient)."""
    theta = 18.6 / 5
    for k, lv in enumerate(("C3", "C4", "C5", "C6", "C7")):
        body = next(b for b in mean_boxes if b.name == f"{lv} body")
        assert np.allclose(body.half_extents, [9.0, 6.25, 8.25])
        tilt = math.degrees(math.atan2(body.rotation[2, 1], body.rotation[1, 1]))
        assert tilt == pytest.approx((2 - k) * theta, abs=1e-9)
        assert np.allclose(body.rotation[:, 0], [1, 0, 0])
    c5 = next(b for b in mean_boxes if b.name == "C5 body")
    assert np.allclose(c5.centre, 0.0)
    c3 = next(b for b in mean_boxes if b.name == "C3 body")
    assert c3.centre[1] == pytest.approx(35.5, abs=0.05) and c3.centre[2] == pytest.approx(2.3, abs=0.05)


def test_reference_entries_lie_on_the_arch_and_in_the_corridor(mean_boxes) -> None:
    rows = reference_rows()
    assert len(rows) == 10
    arches = {b.name.split()[0]: b for b in mean_boxes if b.name.endswith("arch")}
    for row in rows:
        entry = np.array([float(row[f"entry_{a}"]) for a in "xyz"])
        arch = arches[row["level"]]
        sd = box_sd(entry, *arch)[0]
        assert -1.0 <= sd <= 0.5, (row["level"], row["side"], sd)
        assert abs(sd) <= 1e-3  # 3-decimal CSV: on the face
        # on the posterior face: the closest face's outward normal points posteriorly
        local = (entry - arch.centre) @ arch.rotation
        assert local[2] == pytest.approx(arch.half_extents[2], abs=1e-3)
        assert arch.rotation[2, 2] > 0.99
        for tissue in soft(mean_boxes):
            assert box_sd(entry, *tissue)[0] >= 2.0, (row["level"], tissue.name)  # floor 2 mm below the arches


def test_entries_on_arch_for_random_and_lateral_mass_patients() -> None:
    """Asymmetric patients: both entries of each level on the (slightly tilted) arch face, for every technique."""
    for seed in range(6):
        for technique in ("pedicle", "magerl", "roy-camille"):
            params = draw_parameters(seed, technique)
            boxes = default_anatomy_boxes(params)
            arches = {b.name.split()[0]: b for b in boxes if b.name.endswith("arch")}
            ts = build_patient(params)
            for lv, entry in zip(ts.levels, ts.entry):
                sd = box_sd(entry, *arches[lv])[0]
                assert abs(sd) <= 1e-9, (seed, technique, lv, sd)
                assert min(box_sd(entry, *t)[0] for t in soft(boxes)) >= 2.0 - 1e-9


def test_reference_targets_inside_bone(mean_boxes) -> None:
    rows = reference_rows()
    bodies = {b.name.split()[0]: b for b in mean_boxes if b.name.endswith("body")}
    for row in rows:
        target = np.array([float(row[f"target_{a}"]) for a in "xyz"])
        assert box_sd(target, *bodies[row["level"]])[0] < -0.5
        assert min(box_sd(target, *b)[0] for b in bone(mean_boxes)) < 0


def test_skin_corridor_and_slab_dimensions(mean_boxes) -> None:
    rows = reference_rows()
    max_entry_z = max(float(r["entry_z"]) for r in rows)
    corners = np.vstack([b.corners() for b in soft(mean_boxes)])
    assert corners[:, 2].max() == pytest.approx(max_entry_z + 40.0, abs=1e-3)
    assert corners[:, 0].min() == pytest.approx(-80.0) and corners[:, 0].max() == pytest.approx(80.0)
    # bottom: the C5 body's anterior face, -D/2
    assert corners[:, 2].min() == pytest.approx(-8.25, abs=1e-9)
    # highest bone point: C3 body's superior-anterior edge, c_y + (H/2) cos φ + (D/2) sin φ
    phi = math.radians(2 * 18.6 / 5)
    top = next(b for b in mean_boxes if b.name == "C3 body").centre[1] + 6.25 * math.cos(phi) + 8.25 * math.sin(phi)

    # probes (hand-placed): in the corridor above each arch it is open; beside and beyond it, tissue
    def inside_any(p) -> bool:
        return min(box_sd(p, *b)[0] for b in mean_boxes) < 0

    for y in (-40.0, -20.0, 0.0, 20.0, 40.0):
        assert not inside_any([0.0, y, 25.0]) and not inside_any([39.0, y, max_entry_z + 39.0])
        assert inside_any([41.0, y, 25.0]) and inside_any([-41.0, y, 25.0])
        assert inside_any([60.0, y, 5.0]) and inside_any([0.0, y, -5.0])  # one solid neck below the floor
    assert not inside_any([0.0, top + 9.5, 30.0]) and inside_any([0.0, top + 10.5, 30.0])
    assert not inside_any([0.0, -top - 9.5, 30.0]) and inside_any([0.0, -top - 10.5, 30.0])
    assert not inside_any([0.0, 0.0, max_entry_z + 40.5]) and inside_any([70.0, 0.0, max_entry_z + 39.5])
    assert inside_any([0.0, top + 39.5, 0.0]) and not inside_any([0.0, top + 40.5, 0.0])


def test_anatomy_options_change_the_dimensions(mean_params) -> None:
    layout = default_anatomy_layout(mean_params, skin_mm=25.0, corridor_width_mm=60.0, corridor_margin_mm=5.0)
    base = default_anatomy_layout(mean_params)
    assert layout.skin_z == pytest.approx(base.skin_z - 15.0)
    assert layout.corridor_x == pytest.approx((-30.0, 30.0))  # entries |x| <= 24.5: no widening needed
    assert layout.corridor_y[1] == pytest.approx(base.corridor_y[1] - 5.0)
    assert "corridor" in layout.summary()


def test_reference_anatomy_file_matches_the_mean_patient() -> None:
    path = reference_anatomy_path()
    mesh = read_mesh(path, "patient")
    boxes = reference_anatomy_boxes()
    assert same_vertex_set(mesh.vertices, np.vstack([b.corners() for b in boxes]))
    assert len(split_shells(mesh)) == len(boxes) == len(reference_anatomy())
    with pytest.raises(InputError, match="declares"):
        read_mesh(path, "LPS")


def test_cli_patients_writes_the_anatomy_beside_the_csv(tmp_path: Path) -> None:
    from arcube.cli import app

    out = tmp_path / "X.csv"
    result = CliRunner().invoke(app, ["patients", "--mean", "--out", str(out)])
    assert result.exit_code == 0, result.output
    stl = tmp_path / "X.anatomy.stl"
    assert stl.is_file()
    assert str(stl) in result.output and "corridor" in result.output
    assert stl.read_bytes() == reference_anatomy_path().read_bytes()
    mesh = read_mesh(stl, "patient")
    assert len(split_shells(mesh)) == 15
