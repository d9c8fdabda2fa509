"""The patient's anatomy as the evaluation sees it (MODEL.md 14.2): meshes, their distance grids, a source.

``--anatomy`` takes ``none``, ``default`` or mesh files:

* ``default`` is the default anatomy of the plan's patient (:mod:`arcube.patients.anatomy`): the
  bundled reference patient's for ``--trajectories reference``; for a virtual patient's CSV,
  the ``<name>.anatomy.stl`` that ``arcube patients`` wrote beside it (patient frame);
* files are STL, OBJ or PLY meshes in the frame ``--anatomy-frame`` (LPS, RAS or patient).

Anything else is a one-line :class:`~arcube.errors.InputError`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from typing import TYPE_CHECKING

from arcube.errors import InputError

if TYPE_CHECKING:  # trimesh, libigl and the grids load only when an anatomy is used
    import trimesh

    from arcube.evaluation.sdf import AnatomyDistance

__all__ = ["Anatomy", "load_anatomy", "resolve_anatomy"]

FRAMES = ("LPS", "RAS", "patient")


@dataclass(frozen=True, eq=False)
class Anatomy:
    """Closed meshes in the patient frame (mm), where they came from, and (built when first asked for)
    their signed distance grids; ``boxes``, when known, give exact grids faster than the meshes."""

    meshes: tuple[trimesh.Trimesh, ...]
    source: str
    boxes: tuple[Any, ...] | None = None
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def from_meshes(cls, meshes: Sequence[trimesh.Trimesh], source: str) -> Anatomy:
        """The anatomy of ``meshes`` (patient frame)."""
        return cls(tuple(meshes), source)

    def vertices_faces(self) -> tuple[Any, Any]:
        """Every mesh as one: vertices ``(V, 3)`` mm and triangles ``(F, 3)`` (indices into them)."""
        import numpy as np

        vertices, faces, offset = [], [], 0
        for mesh in self.meshes:
            vertices.append(np.asarray(mesh.vertices, dtype=np.float64))
            faces.append(np.asarray(mesh.faces, dtype=np.int64) + offset)
            offset += len(mesh.vertices)
        return np.concatenate(vertices), np.concatenate(faces)

    @property
    def distance(self) -> AnatomyDistance:
        """The signed distance grids (MODEL.md 14.3), built once."""
        from arcube.evaluation.sdf import AnatomyDistance

        if "d" not in self._cache:
            if self.boxes is not None:
                self._cache["d"] = AnatomyDistance.from_boxes(list(self.boxes))
            else:
                self._cache["d"] = AnatomyDistance.from_meshes(list(self.meshes))
        return self._cache["d"]

    def write_stl(self, path: str | os.PathLike[str]) -> Path:
        """All meshes as one STL (patient frame), written atomically; returns the path."""
        from arcube.io.meshes import write_stl

        write_stl(list(self.meshes), path)
        return Path(path)


def _default_for(plan: str | None) -> Anatomy:
    from arcube.io.meshes import read_meshes
    from arcube.patients.anatomy import reference_anatomy_boxes

    if plan is None or plan == "reference":
        boxes = reference_anatomy_boxes()
        return Anatomy(tuple(b.mesh() for b in boxes), "default (reference patient)", boxes=tuple(boxes))
    stl = Path(plan)
    stl = stl.with_name(stl.name.removesuffix(".csv") + ".anatomy.stl") if stl.suffix.lower() == ".csv" else stl / "anatomy.stl"
    if not stl.exists():
        raise InputError.of("anatomy", f"'default': no default anatomy for {plan} (expected {stl}, written by 'arcube patients')")
    return Anatomy.from_meshes(read_meshes([stl], "patient"), f"default ({stl})")


def load_anatomy(spec: Sequence[str] | str | None, frame: str = "LPS", plan: str | None = None) -> Anatomy | None:
    """The anatomy named by ``--anatomy`` (None for ``none``); ``plan`` is the ``--trajectories`` value."""
    items = [spec] if isinstance(spec, str) else list(spec or [])
    if frame not in FRAMES:
        raise InputError.of("anatomy_frame", f"{frame!r}: expected one of {', '.join(FRAMES)}")
    if not items or items == ["none"]:
        return None
    if "none" in items or "default" in items:
        if items != ["default"]:
            raise InputError.of("anatomy", "'none' and 'default' stand alone (not with mesh files)")
        return _default_for(plan)
    from arcube.io.meshes import read_meshes

    meshes = read_meshes(items, frame)
    return Anatomy.from_meshes(meshes, ", ".join(os.fspath(i) for i in items) + f" ({frame})")


def resolve_anatomy(anatomy: Any, frame: str = "LPS", plan: Any = None) -> Anatomy | None:
    """An :class:`Anatomy` from what ``--anatomy`` accepts (None, 'none', 'default', mesh paths)."""
    if anatomy is None or isinstance(anatomy, Anatomy):
        return anatomy
    items = [os.fspath(anatomy)] if isinstance(anatomy, (str, os.PathLike)) else [os.fspath(a) for a in anatomy]
    plan_spec = plan.source if hasattr(plan, "source") and not isinstance(plan, (str, os.PathLike)) else (None if plan is None else os.fspath(plan))
    return load_anatomy(items, frame, plan_spec)
