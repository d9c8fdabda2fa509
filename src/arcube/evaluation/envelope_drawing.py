"""Drawing the envelope of the whole patient and the table (model §19.5): its regions as closed
triangle meshes (rounded boxes as mapped cubes, the table as a slab), for
reports, the explorer, ``arcube patients`` and a user who wants to see where the robot stands."""

from __future__ import annotations

import os
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from arcube import interrupts
from arcube.evaluation.envelope import Envelope, resolve_envelope

if TYPE_CHECKING:  # trimesh loads only when an envelope is drawn
    import trimesh

__all__ = ["ROUND_CELLS", "envelope_meshes", "write_envelope_mesh", "write_plan_envelope"]


ROUND_CELLS = 13
"""Squares per cube face in a drawn rounded box (odd; 2028 triangles a box): vertices on the surface, the
faces' chords within rho (1 - cos 4°) of it."""


_TABLE_THICKNESS_MM = 20.0
"""Thickness of the slab that draws the table (its top is the plane), mm."""


_TABLE_BEYOND_MM = 150.0
"""How far the drawn table reaches beyond the other regions, mm."""


def _rounded_box_mesh(box: NDArray[np.float64], cells: int = ROUND_CELLS) -> trimesh.Trimesh:
    """A closed, outward-oriented mesh of a rounded box ``(c, a, rho)`` (model §19.5): a cube's surface cut into
    ``cells`` x ``cells`` squares per face, each node v sent to ``c + sign(v) a + rho v/|v|`` (a point of the surface,
    whose outward normal is v/|v|). ``cells`` is odd, so no node lies on a symmetry plane: the squares that straddle
    one become the flat faces and the rounded edges, and every vertex lies on the surface."""
    import trimesh

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost
    c, a, rho = box[:3], box[3:6], box[6]
    t = np.linspace(-1.0, 1.0, cells + 1)
    U, V = (g.ravel() for g in np.meshgrid(t, t, indexing="ij"))
    k = np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]
    quads = np.stack([k, k + cells + 1, k + cells + 2, k + 1], axis=-1).reshape(-1, 4)  # counter-clockwise in (u, v)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    nodes, faces = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            p = np.empty((len(U), 3))
            p[:, axis], p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = sign, U, V  # (u, v, normal) right-handed for +1
            faces.append((tris if sign > 0 else tris[:, ::-1]) + sum(len(n) for n in nodes))
            nodes.append(p)
    cube = np.concatenate(nodes)
    verts = c + np.sign(cube) * a + rho * cube / np.linalg.norm(cube, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(vertices=verts, faces=np.concatenate(faces), process=False)
    mesh.merge_vertices(digits_vertex=9)  # the faces' shared borders become one vertex each: a closed shell
    if mesh.volume < 0.0:
        mesh.invert()
    return mesh


def _table_mesh(envelope: Envelope) -> trimesh.Trimesh:
    """The table as a thin box under everything else: its top at ``table_z``, 150 mm beyond the other regions."""
    import trimesh

    interrupts.check()  # as in _rounded_box_mesh
    if envelope.n_boxes:
        b = envelope.boxes
        lo, hi = (b[:, :3] - b[:, 3:6] - b[:, 6:7]).min(axis=0), (b[:, :3] + b[:, 3:6] + b[:, 6:7]).max(axis=0)
    else:
        v = np.concatenate([np.asarray(m.vertices) for m in envelope.skin])
        lo, hi = v.min(axis=0), v.max(axis=0)
    lo, hi = lo - _TABLE_BEYOND_MM, hi + _TABLE_BEYOND_MM
    z = float(envelope.table_z)  # type: ignore[arg-type]
    extents = (hi[0] - lo[0], hi[1] - lo[1], _TABLE_THICKNESS_MM)
    centre = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), z - 0.5 * _TABLE_THICKNESS_MM)
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(centre))


def envelope_meshes(envelope: Envelope, cells: int = ROUND_CELLS) -> list[tuple[str, trimesh.Trimesh]]:
    """(region name, closed mesh) per region, patient frame: each rounded box as a mapped cube of ``cells`` x
    ``cells`` squares a face (every vertex on the surface), the skin as given, the table as a slab 20 mm thick
    whose top is the table, 150 mm beyond the other regions."""
    out = [(name, _rounded_box_mesh(b, cells)) for name, b in zip(envelope.names, envelope.boxes)]
    out += [("skin", m) for m in envelope.skin]
    if envelope.table_z is not None:
        out.append(("table", _table_mesh(envelope)))
    return out


def write_envelope_mesh(envelope: Envelope, path: str | os.PathLike[str], frame: str = "patient") -> Path:
    """Every region of ``envelope`` (:func:`envelope_meshes`) as closed shells of one binary STL, written
    atomically (``frame``: the file's coordinate system, as :func:`arcube.io.meshes.write_stl`)."""
    from arcube.io.meshes import write_stl

    return write_stl([m for _, m in envelope_meshes(envelope)], path, frame)


def plan_envelope_path(plan_csv: str | os.PathLike[str]) -> Path:
    """Where :func:`write_plan_envelope` writes a plan's envelope: ``<stem>.envelope.stl`` beside it."""
    path = Path(plan_csv)
    return path.with_name(path.stem + ".envelope.stl")


def write_plan_envelope(plan_csv: str | os.PathLike[str]) -> str:
    """Write the default envelope (model §19.5) of a plan CSV, placed on its landmarks with its default
    anatomy, beside it as ``<stem>.envelope.stl`` (patient frame); returns a note naming the file."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.io.load import load_trajectories

    path = Path(plan_csv)
    plan = load_trajectories(path)
    envelope = resolve_envelope("default", plan, resolve_anatomy("default", "patient", path))
    out = plan_envelope_path(path)
    write_envelope_mesh(envelope, out)  # type: ignore[arg-type]
    return f"; envelope: {out}"
