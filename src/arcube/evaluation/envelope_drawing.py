"""Drawing the envelope of the whole patient and the table (MODEL.md 19.5): its regions as closed
triangle meshes (rounded boxes by marching cubes of their signed distance, the table as a slab), for
reports, the explorer, ``arcube patients`` and a user who wants to see where the robot stands."""

from __future__ import annotations

import os
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from arcube import interrupts
from arcube.evaluation.envelope import Envelope, resolve_envelope, rounded_box_distance

if TYPE_CHECKING:  # trimesh loads only when an envelope is drawn
    import trimesh

__all__ = ["MESH_STEP_MM", "envelope_meshes", "write_envelope_mesh", "write_plan_envelope"]


MESH_STEP_MM = 4.0
"""Grid step of the marching cubes that draw a rounded box (:func:`write_envelope_mesh`)."""


_TABLE_THICKNESS_MM = 20.0
"""Thickness of the slab that draws the table (its top is the plane), mm."""


_TABLE_BEYOND_MM = 150.0
"""How far the drawn table reaches beyond the other regions, mm."""


def _rounded_box_mesh(box: NDArray[np.float64], step: float = MESH_STEP_MM) -> trimesh.Trimesh:
    """A closed, outward-oriented mesh of a rounded box (marching cubes of its signed distance, ``step`` mm)."""
    import trimesh
    from skimage.measure import marching_cubes

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost

    c, a, rho = box[:3], box[3:6], box[6]
    # nodes off the surface (a node on it gives degenerate triangles): an offset no lattice of round sizes has
    lo = c - a - rho - (2.0 + 0.3819660113) * step
    n = np.ceil(2.0 * (a + rho + 2.5 * step) / step).astype(int) + 1
    axes = [lo[i] + step * np.arange(n[i]) for i in range(3)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    values = rounded_box_distance(X, c, a, rho)
    verts, faces, _, _ = marching_cubes(values, level=0.0, spacing=(step, step, step))
    mesh = trimesh.Trimesh(vertices=verts + lo, faces=faces, process=False)
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


def envelope_meshes(envelope: Envelope, step: float = MESH_STEP_MM) -> list[tuple[str, trimesh.Trimesh]]:
    """(region name, closed mesh) per region, patient frame: each rounded box drawn by marching cubes of its
    signed distance every ``step`` mm (vertices within about step^2 / (8 rho) of the surface), the skin as
    given, the table as a slab 20 mm thick whose top is the table, 150 mm beyond the other regions."""
    out = [(name, _rounded_box_mesh(b, step)) for name, b in zip(envelope.names, envelope.boxes)]
    out += [("skin", m) for m in envelope.skin]
    if envelope.table_z is not None:
        out.append(("table", _table_mesh(envelope)))
    return out


def write_envelope_mesh(envelope: Envelope, path: str | os.PathLike[str], frame: str = "patient") -> Path:
    """Every region of ``envelope`` (:func:`envelope_meshes`) as closed shells of one binary STL, written
    atomically (``frame``: the file's coordinate system, as :func:`arcube.io.meshes.write_stl`)."""
    from arcube.io.meshes import write_stl

    return write_stl([m for _, m in envelope_meshes(envelope)], path, frame)


def write_plan_envelope(plan_csv: str | os.PathLike[str]) -> str:
    """Write the default envelope (MODEL.md 19.5) of a plan CSV, placed on its landmarks with its default
    anatomy, beside it as ``<stem>.envelope.stl`` (patient frame); returns a note naming the file."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.io.load import load_trajectories

    path = Path(plan_csv)
    plan = load_trajectories(path)
    envelope = resolve_envelope("default", plan, resolve_anatomy("default", "patient", path))
    out = path.with_name(path.stem + ".envelope.stl")
    write_envelope_mesh(envelope, out)  # type: ignore[arg-type]
    return f"; envelope: {out}"
