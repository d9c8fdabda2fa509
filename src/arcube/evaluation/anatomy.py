"""The patient's anatomy as the evaluation sees it (model §14.2): meshes, their distance grids, a source.

``--anatomy`` takes ``none``, ``default`` or files:

* ``default`` is the default anatomy of the plan's patient (:mod:`arcube.patients.anatomy`): the
  bundled reference patient's for ``--trajectories reference``; for a virtual patient's CSV,
  the ``<name>.anatomy.stl`` (patient frame), ``.anatomy.seg.nrrd`` or ``.anatomy.nii.gz`` that
  ``arcube patients`` wrote beside it (the newest when there are several);
* files are STL, OBJ or PLY meshes in the frame ``--anatomy-frame`` (LPS, RAS or patient), and
  segmentations (``.seg.nrrd``, ``.nrrd``, ``.nii``, ``.nii.gz``; :mod:`arcube.io.segmentations`),
  which carry their own frame; ``segments`` (``--segments``) keeps some of their segments, and the
  anatomy's ``segments`` says which were used.

An anatomy read from files is kept for the process: loading the same files (same path, size and
modification time), frame and segments again returns the same :class:`Anatomy`, so its distance
grids are built once. Anything else is a one-line :class:`~arcube.errors.InputError`.
"""

from __future__ import annotations

import os
import weakref
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from arcube.errors import InputError

if TYPE_CHECKING:  # trimesh, libigl and the grids load only when an anatomy is used
    import trimesh

    from arcube.evaluation.sdf import AnatomyDistance
    from arcube.io.segmentations import SegmentInfo

__all__ = ["Anatomy", "load_anatomy", "resolve_anatomy"]

FRAMES = ("LPS", "RAS", "patient")


@dataclass(frozen=True, eq=False)
class Anatomy:
    """Closed meshes in the patient frame (mm), where they came from, and (built when first asked for)
    their signed distance grids; ``boxes``, when known, give exact grids faster than the meshes;
    ``segments``, for an anatomy read from segmentations, the kept segments (name, label, voxels, bounds)."""

    meshes: tuple[trimesh.Trimesh, ...]
    source: str
    boxes: tuple[Any, ...] | None = None
    segments: tuple[SegmentInfo, ...] | None = None
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
        """The signed distance grids (model §14.3), built once."""
        from arcube.evaluation.sdf import AnatomyDistance

        if "d" not in self._cache:
            try:
                if self.boxes is not None:
                    self._cache["d"] = AnatomyDistance.from_boxes(list(self.boxes))
                else:
                    self._cache["d"] = AnatomyDistance.from_meshes(list(self.meshes))
            except InputError as exc:  # name the files: "anatomy spans ..." alone does not say which
                if exc.param != "anatomy" or not str(exc).startswith("anatomy "):
                    raise
                raise InputError(f"anatomy {self.source}: {str(exc)[len('anatomy ') :]}", param="anatomy") from None
        return self._cache["d"]

    def write_stl(self, path: str | os.PathLike[str]) -> Path:
        """All meshes as one STL (patient frame), written atomically; returns the path."""
        from arcube.io.meshes import write_stl

        write_stl(list(self.meshes), path)
        return Path(path)


_KEEP = 4  # anatomies held for the process beyond those still in use (their grids can be 100 MB each)
_recent: OrderedDict[tuple[Any, ...], Anatomy] = OrderedDict()
_alive: weakref.WeakValueDictionary[tuple[Any, ...], Anatomy] = weakref.WeakValueDictionary()
_DEFAULT_SUFFIXES = (".anatomy.stl", ".anatomy.seg.nrrd", ".anatomy.nii.gz")


def _file_key(path: str) -> tuple[Any, ...]:
    """What identifies a file's content for the cache: resolved path, size, modification time."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return (path,)  # the reader reports the problem
    return (os.path.realpath(path), st.st_size, st.st_mtime_ns, st.st_ino)


def _cached(key: tuple[Any, ...], build: Any) -> Anatomy:
    """The anatomy of ``key``, built by ``build()`` only when no live or recent one has it."""
    anatomy = _alive.get(key)
    if anatomy is None:
        anatomy = build()
        _alive[key] = anatomy
    _recent[key] = anatomy
    _recent.move_to_end(key)
    while len(_recent) > _KEEP:
        _recent.popitem(last=False)
    return anatomy


def _from_files(
    items: Sequence[str], frame: str, segments: tuple[str, ...] | None, source: str | None = None
) -> Anatomy:
    """The anatomy of mesh and segmentation files; ``source`` None: the files named, each with its frame."""
    from arcube.io.meshes import read_mesh
    from arcube.io.segmentations import is_segmentation, read_segmentations

    seg_files = [i for i in items if is_segmentation(i)]
    if segments is not None and not seg_files:
        raise InputError.of(
            "segments", "applies to segmentation files (.seg.nrrd, .nrrd, .nii, .nii.gz); none was given"
        )
    read = iter(read_segmentations(seg_files, segments) if seg_files else [])
    meshes: list[trimesh.Trimesh] = []
    infos: list[SegmentInfo] = []
    labels: list[str] = []  # each file with its frame: a mesh's is --anatomy-frame, a segmentation's its own space
    for item in items:
        if is_segmentation(item):
            seg = next(read)
            meshes += seg.meshes
            infos += seg.segments
            labels.append(f"{item} ({seg.space}, the file's own)")
        else:
            meshes.append(read_mesh(item, frame))
            labels.append(f"{item} ({frame})")
    if source is None:
        source = ", ".join(labels) + (f" segments {','.join(segments)}" if segments is not None else "")
    return Anatomy(tuple(meshes), source, segments=tuple(infos) if seg_files else None)


def _default_file(plan: str) -> Path:
    """The anatomy file ``arcube patients`` wrote beside ``plan`` (the newest of the formats present)."""
    base = Path(plan)
    stem = base.with_name(base.name.removesuffix(".csv")) if base.suffix.lower() == ".csv" else base / "anatomy"
    candidates = [stem.with_name(stem.name + s) for s in _DEFAULT_SUFFIXES]
    found = [c for c in candidates if c.exists()]
    if not found:
        raise InputError.of(
            "anatomy",
            f"'default': no default anatomy for {plan} (expected {candidates[0]}, "
            f"or its .seg.nrrd or .nii.gz, written by 'arcube patients')",
        )
    return max(found, key=lambda c: c.stat().st_mtime_ns)  # max keeps the first of equals: STL first


def _default_for(plan: str | None, segments: tuple[str, ...] | None = None) -> Anatomy:
    from arcube.io.segmentations import is_segmentation
    from arcube.patients.anatomy import reference_anatomy_boxes

    if plan is None or plan == "reference":
        if segments is not None:
            raise InputError.of(
                "segments", "applies to segmentation files; the reference patient's default anatomy is boxes"
            )

        def build() -> Anatomy:
            boxes = reference_anatomy_boxes()
            return Anatomy(tuple(b.mesh() for b in boxes), "default (reference patient)", boxes=tuple(boxes))

        return _cached(("default", "reference"), build)
    path = _default_file(plan)
    if segments is not None and not is_segmentation(path):
        raise InputError.of("segments", f"applies to segmentation files; the default anatomy {path} is a mesh")
    key = ("default", _file_key(str(path)), segments)
    return _cached(key, lambda: _from_files([str(path)], "patient", segments, f"default ({path})"))


def names_default(items: Sequence[str], param: str) -> bool:
    """Whether the words and paths ``items`` of ``--anatomy`` or ``--envelope`` (``param``) are ``default``; False
    for files. An :class:`InputError` when ``none`` or ``default`` stands with anything else."""
    if "none" not in items and "default" not in items:
        return False
    if list(items) != ["default"]:
        raise InputError.of(param, "'none' and 'default' stand alone (not with mesh files)")
    return True


def check_frame(frame: Any) -> str:
    """``frame`` if it is one of :data:`FRAMES`, else InputError naming ``anatomy_frame``."""
    if frame not in FRAMES:
        raise InputError.of("anatomy_frame", f"{frame!r}: expected one of {', '.join(FRAMES)}")
    return frame


def load_anatomy(
    spec: Sequence[str] | str | None,
    frame: str = "LPS",
    plan: str | None = None,
    *,
    segments: str | Iterable[str | int] | None = None,
) -> Anatomy | None:
    """The anatomy named by ``--anatomy`` (None for ``none``); ``plan`` is the ``--trajectories`` value;
    ``segments`` (``--segments``: names or label values, ``"C3,C4"``) keeps some segments of segmentation files."""
    from arcube.io.segmentations import parse_segments

    items = [spec] if isinstance(spec, str) else list(spec or [])
    check_frame(frame)
    selection = parse_segments(segments)
    if not items or items == ["none"]:
        if selection is not None:
            raise InputError.of("segments", "needs an anatomy (a segmentation file, or 'default')")
        return None
    if names_default(items, "anatomy"):
        return _default_for(plan, selection)
    key = ("files", tuple(_file_key(os.fspath(i)) for i in items), frame, selection)
    return _cached(key, lambda: _from_files([os.fspath(i) for i in items], frame, selection))


def resolve_anatomy(
    anatomy: Any, frame: str = "LPS", plan: Any = None, *, segments: str | Iterable[str | int] | None = None
) -> Anatomy | None:
    """An :class:`Anatomy` from what ``--anatomy`` accepts (None, 'none', 'default', mesh or segmentation paths)."""
    if anatomy is None or isinstance(anatomy, Anatomy):
        if segments is not None:
            raise InputError.of(
                "segments",
                "needs an anatomy (a segmentation file, or 'default')"
                if anatomy is None
                else "applies to anatomy files, not to an Anatomy already loaded",
            )
        return anatomy
    items = [os.fspath(anatomy)] if isinstance(anatomy, (str, os.PathLike)) else [os.fspath(a) for a in anatomy]
    plan_spec = (
        plan.source
        if hasattr(plan, "source") and not isinstance(plan, (str, os.PathLike))
        else (None if plan is None else os.fspath(plan))
    )
    return load_anatomy(items, frame, plan_spec, segments=segments)
