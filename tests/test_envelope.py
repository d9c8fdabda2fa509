"""The envelope of the whole patient as data (MODEL.md 19.5), against oracles written from the spec.

* the default envelope is 19.5's table, on landmarks computed here by hand (and, for the skin z_s, by
  marching along each axis with an inside test of the anatomy's meshes);
* its signed distance equals brute-force distances to densely sampled surface points of its rounded
  boxes (faces, edge cylinders, corner spheres, parametrized here) and of its plane, signed by an
  inside test (distance to the sharp box <= rho, z <= table), at random points;
* the mesh writer's shells are closed, lie on their regions' surfaces, and read back;
* bad input: one line naming the field or the file.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from arcube.options import Outputs
from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope_drawing import ROUND_CELLS, envelope_meshes, write_envelope_mesh
from arcube.evaluation.envelope import (
    BOX_TABLE,
    Envelope,
    Landmarks,
    default_envelope,
    envelope_from_boxes,
    landmarks,
    resolve_envelope,
    rounded_box_distance,
)
from arcube.io import load_trajectories, select
from arcube.io.meshes import read_meshes, split_shells, write_stl

PLAN = load_trajectories("reference")


# ----------------------------------------------------------------------------- the table of 19.5


def test_default_envelope_is_the_table_of_19_5() -> None:
    marks = Landmarks(x0=1.0, y_top=30.0, y_bot=-20.0, z_s=50.0, skin_from="test")
    env = default_envelope(marks)
    # centre (x0, (y_top + y_bot)/2, z_s - 60), half extents (20, (y_top - y_bot)/2 + 15, 20), rho 40; ...
    want = {
        "neck": ([1.0, 5.0, -10.0], [20.0, 40.0, 20.0], 40.0),
        "head": ([1.0, 140.0, -20.0], [35.0, 55.0, 50.0], 40.0),
        "torso": ([1.0, -335.0, -50.0], [180.0, 280.0, 100.0], 20.0),
    }
    assert env.names == ("neck", "head", "torso", "table") and env.table_region == 3 and env.skin_region == -1
    for name, box in zip(env.names, env.boxes):
        c, a, rho = want[name]
        np.testing.assert_array_equal(box, [*c, *a, rho], err_msg=name)
    assert env.table_z == 50.0 - 240.0
    assert default_envelope(marks, table_z=-120.0).table_z == -120.0
    # the neck's top is the skin, the head's and torso's 20 mm above it; the table 20 mm below the torso
    top = env.boxes[:, 2] + env.boxes[:, 5] + env.boxes[:, 6]
    np.testing.assert_array_equal(top, [50.0, 70.0, 70.0])
    assert env.boxes[2, 2] - env.boxes[2, 5] - env.boxes[2, 6] - env.table_z == 20.0
    assert [b[0] for b in BOX_TABLE] == ["neck", "head", "torso"]


def _exit_z_by_marching(entry: np.ndarray, target: np.ndarray, boxes: list, step: float = 0.01) -> float:
    """The largest z at which an axis A + t e (t >= 0) is inside one of the (rotated) boxes of the default anatomy,
    by an inside test |R^T (p - c)| <= h every ``step`` mm."""
    best = -np.inf
    t = np.arange(0.0, 250.0, step)
    for A, B in zip(entry, target):
        e = (A - B) / np.linalg.norm(A - B)
        pts = A + t[:, None] * e
        inside = np.zeros(len(t), dtype=bool)
        for box in boxes:
            inside |= np.all(np.abs((pts - box.centre) @ box.rotation) <= box.half_extents, axis=-1)
        last = t[np.flatnonzero(inside)].max() if inside.any() else 0.0
        best = max(best, (A + last * e)[2])
    return float(best)


def test_landmarks_come_from_the_whole_plan() -> None:
    ent = PLAN.entry
    marks = landmarks(PLAN.entry, PLAN.target)
    assert marks.x0 == pytest.approx(np.mean(ent[:, 0]), abs=1e-12) and abs(marks.x0) < 1e-9  # both sides: the midline
    assert (marks.y_top, marks.y_bot) == (35.351, -31.438)
    assert marks.z_s == pytest.approx(19.691 + 50.0, abs=1e-12)  # no anatomy: largest entry z + 50
    anatomy = resolve_anatomy("default", "LPS", "reference")
    with_anatomy = landmarks(PLAN.entry, PLAN.target, anatomy)
    march = _exit_z_by_marching(PLAN.entry, PLAN.target, list(anatomy.boxes))
    assert with_anatomy.z_s == pytest.approx(march, abs=0.02)
    # the envelope of a plan is placed on all of it: one side alone would move the patient
    env = resolve_envelope("default", PLAN, anatomy)
    assert env.landmarks == with_anatomy
    right = select(PLAN, side="R")
    assert landmarks(right.entry, right.target).x0 > 20.0  # what selecting first would have done


# ----------------------------------------------------------------------------- signed distance vs brute force


def _rounded_box_surface(c: np.ndarray, a: np.ndarray, rho: float, s: float) -> np.ndarray:
    """Points on the boundary of the rounded box, at most ``s`` mm apart: the six faces pushed out by rho, the
    twelve quarter cylinders along the edges and the eight octant spheres at the corners."""
    out = []
    for i in range(3):
        j, k = [x for x in range(3) if x != i]
        uj, uk = (np.linspace(-a[m], a[m], max(int(np.ceil(2 * a[m] / s)) + 1, 2)) for m in (j, k))
        J, K = np.meshgrid(uj, uk, indexing="ij")
        for sgn in (-1.0, 1.0):
            p = np.zeros(J.shape + (3,))
            p[..., i], p[..., j], p[..., k] = sgn * (a[i] + rho), J, K
            out.append(p.reshape(-1, 3))
    phis = np.linspace(0.0, np.pi / 2, max(int(np.ceil(rho * np.pi / 2 / s)) + 1, 2))
    for k in range(3):  # edges along axis k
        i, j = [x for x in range(3) if x != k]
        w = np.linspace(-a[k], a[k], max(int(np.ceil(2 * a[k] / s)) + 1, 2))
        W, P = np.meshgrid(w, phis, indexing="ij")
        for si, sj in itertools.product((-1.0, 1.0), repeat=2):
            p = np.zeros(W.shape + (3,))
            p[..., i] = si * (a[i] + rho * np.cos(P))
            p[..., j] = sj * (a[j] + rho * np.sin(P))
            p[..., k] = W
            out.append(p.reshape(-1, 3))
    T, P = np.meshgrid(phis, phis, indexing="ij")  # octant: polar and azimuth in [0, pi/2]
    n = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    for sg in itertools.product((-1.0, 1.0), repeat=3):
        sg = np.array(sg)
        out.append(sg * (a + rho * n))
    return c + np.concatenate(out)


def _inside_rounded_box(x: np.ndarray, c: np.ndarray, a: np.ndarray, rho: float) -> np.ndarray:
    """Within rho of the sharp box (its nearest point by clamping): the definition of 19.5."""
    return np.linalg.norm(x - np.clip(x, c - a, c + a), axis=-1) <= rho


def test_rounded_box_distance_equals_brute_force() -> None:
    rng = np.random.default_rng(0)
    s = 0.2
    cover = s * np.sqrt(2.0) / 2 + 1e-9  # the samples' covering radius on the faces (the arcs' is smaller)
    for _ in range(12):
        c = rng.uniform(-50.0, 50.0, 3)
        a = rng.uniform(1.0, 15.0, 3)
        rho = float(rng.uniform(0.5, 10.0))
        tree = cKDTree(_rounded_box_surface(c, a, rho, s))
        x = c + rng.uniform(-1.3, 1.3, (200, 3)) * (a + rho + 2.0)
        brute, _ = tree.query(x)
        sd = rounded_box_distance(x, c, a, rho)
        inside = _inside_rounded_box(x, c, a, rho)
        assert np.array_equal(sd <= 0.0, inside) or np.all(np.abs(sd[(sd <= 0.0) != inside]) < 1e-9)
        assert 0.1 < inside.mean() < 0.9
        err = brute - np.abs(sd)
        assert err.min() >= -1e-9 and err.max() <= cover, (err.min(), err.max())


def test_envelope_distance_is_the_least_over_its_regions_by_brute_force() -> None:
    """The default envelope of the reference patient (coarser samples: its boxes are large) and its table."""
    env = resolve_envelope("default", PLAN, None)
    s = 2.0
    samples = [_rounded_box_surface(b[:3], b[3:6], b[6], s) for b in env.boxes]
    rng = np.random.default_rng(1)
    lo = (env.boxes[:, :3] - env.boxes[:, 3:6] - env.boxes[:, 6:7]).min(axis=0) - 40.0
    hi = (env.boxes[:, :3] + env.boxes[:, 3:6] + env.boxes[:, 6:7]).max(axis=0) + 40.0
    lo[2] = env.table_z - 30.0
    x = rng.uniform(lo, hi, (3000, 3))
    per = env.region_distances(x)
    for k, (pts, b) in enumerate(zip(samples, env.boxes)):
        brute, _ = cKDTree(pts).query(x)
        inside = _inside_rounded_box(x, b[:3], b[3:6], b[6])
        assert np.array_equal(per[:, k] <= 0.0, inside)
        err = brute - np.abs(per[:, k])
        assert err.min() >= -1e-9 and err.max() <= s * np.sqrt(2.0) / 2, env.names[k]
    # the table: distance to dense points of its plane about each point's foot, negative below it
    g = np.linspace(-3.0, 3.0, 61)
    G = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    for p, d in zip(x[:50], per[:50, 3]):
        plane = np.column_stack([p[0] + G[:, 0], p[1] + G[:, 1], np.full(len(G), env.table_z)])
        assert abs(np.min(np.linalg.norm(plane - p, axis=-1)) - abs(d)) < 1e-9 and (d < 0) == (p[2] < env.table_z)
    np.testing.assert_array_equal(env(x), per.min(axis=-1))
    outside = np.all(per > 0.0, axis=-1)  # there the envelope's distance is the distance to the union
    assert outside.any() and (~outside).any()


# ----------------------------------------------------------------------------- the mesh writer


def test_envelope_mesh_is_closed_and_on_the_surfaces(tmp_path) -> None:
    env = resolve_envelope("default", PLAN, None)
    drawn = envelope_meshes(env)
    assert [name for name, _ in drawn] == list(env.names)
    for k, (name, mesh) in enumerate(drawn):
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0.0, name
        v = np.asarray(mesh.vertices)
        d = env.region_distances(v)[:, k]
        if name == "table":
            assert v[:, 2].max() == pytest.approx(env.table_z, abs=1e-9) and v[:, 2].min() < env.table_z - 10.0
            assert np.all(env(v[v[:, 2] == v[:, 2].max()]) <= 1e-9)  # the slab's top lies on the table, under the body
        else:  # a mapped cube: every vertex on the rounded box's surface, a closed shell of few triangles
            assert np.abs(d).max() < 1e-9 and len(mesh.faces) == 12 * ROUND_CELLS**2, name
            # and the mesh is the rounded box: its volume, (2a)^3-like terms of the Minkowski sum, to 1 %
            a, rho = env.boxes[k, 3:6], env.boxes[k, 6]
            vol = (
                8 * np.prod(a)
                + 8 * rho * (a[0] * a[1] + a[1] * a[2] + a[0] * a[2])
                + 2 * np.pi * rho**2 * a.sum()
                + 4 / 3 * np.pi * rho**3
            )
            assert mesh.volume == pytest.approx(vol, rel=0.01), name
    path = write_envelope_mesh(env, tmp_path / "patient.envelope.stl")
    read = read_meshes([path], "patient")[0]  # closed, outward shells, else InputError
    assert len(read.faces) == sum(len(m.faces) for _, m in drawn)


def test_a_skin_mesh_envelope_is_read_in_its_frame(tmp_path) -> None:
    skin = trimesh.creation.box(
        extents=(120.0, 200.0, 90.0), transform=trimesh.transformations.translation_matrix((30.0, -40.0, 10.0))
    )
    path = write_stl(skin, tmp_path / "skin.stl", frame="LPS")
    env = resolve_envelope([path], None, None, table_z=-100.0, anatomy_frame="LPS")
    assert env.names == ("skin", "table") and env.skin_region == 0 and env.table_region == 1 and env.n_boxes == 0
    # the file holds LPS coordinates of the patient-frame box: read in LPS, the same box comes back
    np.testing.assert_allclose(
        np.sort(np.asarray(env.skin[0].vertices), axis=0), np.sort(np.asarray(skin.vertices), axis=0), atol=1e-4
    )
    # no table_z: the table of 19.5 from the plan's landmarks
    env2 = resolve_envelope([path], PLAN, None, anatomy_frame="LPS")
    assert env2.table_z == pytest.approx(19.691 + 50.0 - 240.0)
    out = write_envelope_mesh(env, tmp_path / "drawn.stl")
    assert len(split_shells(read_meshes([out], "patient")[0])) == 2


# ----------------------------------------------------------------------------- bad input


def _one_line(exc: pytest.ExceptionInfo[InputError], *words: str) -> None:
    text = str(exc.value)
    assert "\n" not in text and all(w in text for w in words), text


def test_bad_input_is_one_line_naming_it(tmp_path) -> None:
    for bad in (float("nan"), float("inf"), "abc"):
        with pytest.raises(InputError) as exc:
            resolve_envelope("default", PLAN, None, table_z=bad)
        _one_line(exc, "table_z", "finite")
        assert exc.value.param == "table_z"
    with pytest.raises(InputError) as exc:
        resolve_envelope([tmp_path / "missing.stl"], PLAN, None)
    _one_line(exc, "missing.stl")
    open_box = trimesh.creation.box(extents=(50.0, 50.0, 50.0))
    open_box = trimesh.Trimesh(open_box.vertices, open_box.faces[:-2], process=False)  # one face missing: not closed
    path = tmp_path / "open.stl"
    path.write_bytes(open_box.export(file_type="stl"))
    with pytest.raises(InputError) as exc:
        resolve_envelope([path], PLAN, None, anatomy_frame="patient")
    _one_line(exc, "open.stl", "not closed")
    with pytest.raises(InputError) as exc:
        resolve_envelope("default", None, None)
    _one_line(exc, "envelope", "landmarks")
    with pytest.raises(InputError) as exc:
        resolve_envelope("none", PLAN, None, table_z=-100.0)
    _one_line(exc, "table_z", "none")
    with pytest.raises(InputError) as exc:
        resolve_envelope(["default", str(path)], PLAN, None)
    _one_line(exc, "envelope", "stand alone")
    good = write_stl(trimesh.creation.box(extents=(50.0, 50.0, 50.0)), tmp_path / "skin.stl")
    with pytest.raises(InputError) as exc:
        resolve_envelope([good], None, None, anatomy_frame="patient")  # no table_z and no plan to place one
    _one_line(exc, "table_z")
    with pytest.raises(InputError) as exc:
        resolve_envelope([good], PLAN, None, anatomy_frame="XYZ")
    _one_line(exc, "anatomy_frame")
    assert resolve_envelope("none", PLAN, None) is None and resolve_envelope(None) is None
    env = resolve_envelope("default", PLAN, None)
    assert resolve_envelope(env) is env
    assert isinstance(envelope_from_boxes([[0, 0, 0, 1, 1, 1, 1]], ["b"], 0.0), Envelope)


@pytest.mark.parametrize(
    "argv, culprit",
    [
        (["--table-z", "nan"], "--table-z"),
        (["--envelope", "{tmp}/missing.stl"], "missing.stl"),
        (["--envelope", "{tmp}/open.stl", "--anatomy-frame", "patient"], "open.stl"),
        (["--envelope", "none", "--table-z", "-100"], "--table-z"),
        (["--envelope", "default", "{tmp}/open.stl"], "--envelope"),
    ],
    ids=["table-z nan", "missing file", "open surface", "table without envelope", "default beside a file"],
)
def test_the_cli_refuses_a_bad_envelope_in_one_line(tmp_path, capsys, argv, culprit) -> None:
    """The command line names its own flag or the file, exits 2 and writes no report."""
    from arcube.cli import main

    box = trimesh.creation.box(extents=(50.0, 50.0, 50.0))
    (tmp_path / "open.stl").write_bytes(
        trimesh.Trimesh(box.vertices, box.faces[:-2], process=False).export(file_type="stl")
    )
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(
            [
                "evaluate",
                "--design",
                "paper",
                "--trajectories",
                "reference",
                "--points",
                "3",
                "--report",
                str(tmp_path / "r.html"),
                *args,
            ]
        )
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and err.startswith("error: ") and culprit in err, err
    assert not (tmp_path / "r.html").exists()


def test_the_evaluation_path_keeps_the_whole_plan_for_the_envelope() -> None:
    import arcube
    from arcube.evaluation.reference import Options, evaluate_task
    from arcube.evaluation.task import build_task
    from arcube.io import load_trajectories
    from arcube.model.design import Design

    full = load_trajectories("reference")
    right = select(full, side="R")
    assert len(full) == 10 and len(right) == 5
    design = Design.preset("paper").replace(m_x=88.23, m_y=79.40, m_z=56.89)
    ev = arcube.evaluate(design, "reference", side="R", points=6, envelope="default", engine="numpy")
    env = ev.envelope
    assert abs(env.landmarks.x0) < 1e-9  # the midline of the whole plan, not the right side's mean
    assert env.landmarks == resolve_envelope("default", full, None).landmarks
    task = build_task(right.entry, right.target, 6)
    want = evaluate_task(
        design.to_vector(), task.E, task.e, np.ones(4), Options(outputs=Outputs(envelope_clearance=True)), envelope=env
    )
    np.testing.assert_array_equal(ev.points.envelope_clearance_mm, want.points.envelope_clearance_mm)
    assert np.all(np.isfinite(ev.points.envelope_clearance_mm))


def test_the_settings_name_their_fields() -> None:
    from arcube.evaluation.envelope import EnvelopeSettings

    with pytest.raises(InputError) as exc:
        EnvelopeSettings(table_z=float("nan"))
    _one_line(exc, "EnvelopeSettings.table_z", "finite")
    s = EnvelopeSettings(envelope="default", table_z=-150.0)
    assert s.envelope == ("default",) and s.resolve(PLAN).table_z == -150.0
    assert EnvelopeSettings(envelope="none").resolve(PLAN) is None
    assert EnvelopeSettings(envelope="a.stl,b.stl").envelope == ("a.stl", "b.stl")
