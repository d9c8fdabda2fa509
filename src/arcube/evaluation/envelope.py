"""The envelope of the whole patient (model §19.5): where the robot must not be besides the spine.

The anatomy of 14.2 is the spine and the muscle over it. The **envelope** is the rest of the prone
patient and the operating table, as forbidden solids in the patient frame (mm; x right, y superior,
z posterior): a union of *regions*, each with a signed distance (negative inside), and the envelope's
signed distance is the minimum over its regions.

* The **default envelope** (:func:`default_envelope`) is a coarse adult body of rounded boxes and a
  plane placed on landmarks of the plan (:class:`Landmarks`), the table of 19.5 exactly:

  ======  =========================================  ==============================  ===
  region  centre                                     half extents a                  rho
  ======  =========================================  ==============================  ===
  neck    (x0, (y_top + y_bot) / 2, z_s - 60)        (20, (y_top - y_bot)/2 + 15, 20)  40
  head    (x0, y_top + 110, z_s - 70)                (35, 55, 50)                     40
  torso   (x0, y_bot - 315, z_s - 100)               (180, 280, 100)                  20
  table   the half-space z <= z_s - 240 (or ``table_z``)
  ======  =========================================  ==============================  ===

  A rounded box is the set of points within rho of the axis-aligned box of centre c and half extents
  a; its signed distance is d = |max(q, 0)| + min(max_i q_i, 0) - rho with q = |X - c| - a. The table's
  is z - z_table (positive above it, where the patient lies).
* A **user's envelope** (:func:`resolve_envelope` with mesh files) is a skin surface: closed meshes
  with the patient inside (region ``skin``, the signed distance of :mod:`arcube.evaluation.sdf` on the
  same grids as the anatomy), and the table at ``table_z`` (patient frame).
* ``none``: no envelope (None).

The landmarks come from the **whole plan as loaded** (both sides, every level), before any side or
level selection: the patient does not move when one side is evaluated. So a caller that evaluates a
subset passes the plan as read (``arcube.io.load_trajectories(spec, transform=...)``), not the
output of :func:`arcube.io.select`.

Regions are numbered in :attr:`Envelope.names` order: the rounded boxes, then ``skin``, then ``table``
(``envelope_region`` in the results indexes this tuple).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import BeforeValidator, Field

from arcube.errors import InputError
from arcube.io.inputs import COORDINATE_LIMIT_MM
from arcube.options import Settings

if TYPE_CHECKING:  # trimesh and the grids load only when a mesh is used
    import trimesh

    from arcube.evaluation.sdf import AnatomyDistance

__all__ = [
    "BOX_TABLE",
    "ENVELOPE_SPECS",
    "Envelope",
    "EnvelopeSettings",
    "Landmarks",
    "TABLE_BELOW_SKIN_MM",
    "TableZ",
    "default_envelope",
    "envelope_from_boxes",
    "landmarks",
    "resolve_envelope",
    "rounded_box_distance",
]

SKIN_WITHOUT_ANATOMY_MM = 50.0
"""z_s without anatomy: the largest entry z plus this (model §19.5)."""
TABLE_BELOW_SKIN_MM = 240.0
"""The table's top lies this far below the posterior skin z_s (model §19.5)."""
TableZ = Annotated[float, Field(ge=-COORDINATE_LIMIT_MM, le=COORDINATE_LIMIT_MM, allow_inf_nan=False)]
"""The table's top, mm, patient frame: a coordinate, within the ±100 m of every coordinate read
(:data:`arcube.io.inputs.COORDINATE_LIMIT_MM`, where the plan's points lie); 1e9 is a unit mistake."""
BOX_TABLE: tuple[tuple[str, tuple[float, float, float], tuple[float, float, float], float], ...] = (
    ("neck", (0.0, 0.0, -60.0), (20.0, 15.0, 20.0), 40.0),
    ("head", (0.0, 110.0, -70.0), (35.0, 55.0, 50.0), 40.0),
    ("torso", (0.0, -315.0, -100.0), (180.0, 280.0, 100.0), 20.0),
)
"""The rounded boxes of model §19.5 as (name, centre offsets, half extents, rho), mm: the centre is
(x0, y_ref, z_s) + offsets with y_ref the middle of the entries (neck), y_top (head) or y_bot (torso);
the neck's half extent along y is (y_top - y_bot) / 2 + its 15 mm (:func:`default_envelope`)."""
ENVELOPE_SPECS = ("default", "none")
"""The words ``resolve_envelope`` takes besides mesh files."""


@dataclass(frozen=True)
class Landmarks:
    """The landmarks of model §19.5 (patient frame, mm).

    ``x0``: mean x of the entry points (the midline); ``y_top``, ``y_bot``: largest and smallest entry
    y; ``z_s``: the posterior skin, the largest z at which a trajectory's axis leaves the anatomy (the
    point A_j + t_j e_j of 17.1), or without anatomy the largest entry z + 50; ``skin_from`` says which.
    """

    x0: float
    y_top: float
    y_bot: float
    z_s: float
    skin_from: str

    def as_dict(self) -> dict[str, Any]:
        """The landmarks by name (for JSON)."""
        return {"x0": self.x0, "y_top": self.y_top, "y_bot": self.y_bot, "z_s": self.z_s, "skin_from": self.skin_from}


def landmarks(entry: ArrayLike, target: ArrayLike, anatomy: Any = None) -> Landmarks:
    """The :class:`Landmarks` of a plan: ``entry``, ``target`` ``(T, 3)`` mm of **every** trajectory of the
    plan as loaded (both sides: the patient does not move when one side is evaluated); ``anatomy``: an
    :class:`~arcube.evaluation.anatomy.Anatomy` (its meshes) or None. InputError when the plan is empty
    or not finite."""
    from arcube.evaluation.standoff import exit_depths

    A = np.atleast_2d(np.asarray(entry, dtype=float))
    B = np.atleast_2d(np.asarray(target, dtype=float))
    if A.size == 0 or A.shape[-1] != 3 or A.shape != B.shape or not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise InputError.of("envelope", "cannot place its landmarks: the plan has no finite entry and target points")
    if anatomy is None:
        z_s, skin_from = (
            float(np.max(A[:, 2])) + SKIN_WITHOUT_ANATOMY_MM,
            f"largest entry z + {SKIN_WITHOUT_ANATOMY_MM:g} mm",
        )
    else:
        d = A - B
        e = d / np.linalg.norm(d, axis=-1, keepdims=True)
        t = exit_depths(anatomy.meshes, A, e)
        z_s, skin_from = float(np.max(A[:, 2] + t * e[:, 2])), "where the plan's axes leave the anatomy"
    return Landmarks(float(np.mean(A[:, 0])), float(np.max(A[:, 1])), float(np.min(A[:, 1])), z_s, skin_from)


def rounded_box_distance(points: ArrayLike, centre: ArrayLike, half: ArrayLike, rho: ArrayLike) -> NDArray[np.float64]:
    """Signed distance ``(...)`` mm of ``points`` ``(..., 3)`` to the rounded box of ``centre`` and ``half``
    extents ``(..., 3)`` (broadcasting) and radius ``rho``: |max(q, 0)| + min(max_i q_i, 0) - rho,
    q = |X - c| - a (model §19.5). Written component by component, as the compiled kernel does."""
    p, c, a = (np.asarray(v, dtype=float) for v in (points, centre, half))
    q0 = np.abs(p[..., 0] - c[..., 0]) - a[..., 0]
    q1 = np.abs(p[..., 1] - c[..., 1]) - a[..., 1]
    q2 = np.abs(p[..., 2] - c[..., 2]) - a[..., 2]
    o0, o1, o2 = np.maximum(q0, 0.0), np.maximum(q1, 0.0), np.maximum(q2, 0.0)
    return (
        np.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
        + np.minimum(np.maximum(q0, np.maximum(q1, q2)), 0.0)
        - np.asarray(rho, dtype=float)
    )


@dataclass(frozen=True, eq=False)
class Envelope:
    """The envelope of model §19.5: rounded boxes, a skin mesh, a table, each a region (forbidden solid).

    ``boxes`` ``(B, 7)``: per rounded box its centre (3), half extents (3) and radius rho, mm, named by
    the first B ``names``; ``skin``: closed meshes with the patient inside (patient frame), or ();
    ``table_z``: the table's top, the half-space z <= table_z is forbidden (None: no table).
    ``names``: the regions in order (boxes, ``skin`` when there is one, ``table`` when there is one).
    """

    boxes: NDArray[np.float64]
    names: tuple[str, ...]
    table_z: float | None = None
    skin: tuple[trimesh.Trimesh, ...] = ()
    source: str = ""
    landmarks: Landmarks | None = None
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        boxes = np.ascontiguousarray(np.asarray(self.boxes, dtype=float).reshape(-1, 7))
        boxes.setflags(write=False)
        object.__setattr__(self, "boxes", boxes)
        want = len(boxes) + bool(self.skin) + (self.table_z is not None)
        if len(self.names) != want or not want:
            raise ValueError(f"Envelope: {len(self.names)} names for {want} regions")
        if self.table_z is not None and not math.isfinite(self.table_z):
            raise InputError.of("table_z", f"must be a finite number of mm (patient frame), got {self.table_z!r}")

    @property
    def n_boxes(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def skin_region(self) -> int:
        """Index of the ``skin`` region in :attr:`names`, -1 without a skin mesh."""
        return self.n_boxes if self.skin else -1

    @property
    def table_region(self) -> int:
        """Index of the ``table`` region in :attr:`names`, -1 without a table."""
        return len(self.names) - 1 if self.table_z is not None else -1

    @property
    def skin_distance(self) -> AnatomyDistance | None:
        """The skin meshes' signed distance grids (those of the anatomy, :mod:`arcube.evaluation.sdf`), built once."""
        if not self.skin:
            return None
        if "skin" not in self._cache:
            from arcube.evaluation.sdf import AnatomyDistance

            self._cache["skin"] = AnatomyDistance.from_meshes(list(self.skin))
        return self._cache["skin"]

    def region_distances(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance to each region, ``(..., len(names))`` mm, of points ``(..., 3)``."""
        p = np.asarray(points, dtype=float)
        out = [rounded_box_distance(p, b[:3], b[3:6], b[6]) for b in self.boxes]
        if self.skin:
            out.append(self.skin_distance(p))  # type: ignore[misc]
        if self.table_z is not None:
            out.append(p[..., 2] - self.table_z)
        return np.stack(out, axis=-1)

    def __call__(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance ``(...)`` mm to the envelope (the least over its regions; negative inside)."""
        return np.min(self.region_distances(points), axis=-1)

    def to_record(self) -> dict[str, Any]:
        """The envelope as a run's config records it (boxes, region names, table, source; a skin mesh is
        copied beside the config, :meth:`from_record` reads it back)."""
        return {
            "boxes": self.boxes.tolist(),
            "names": list(self.names),
            "table_z": self.table_z,
            "source": self.source,
            "skin": bool(self.skin),
        }

    @classmethod
    def from_record(cls, record: dict[str, Any], skin: Sequence[Any] = ()) -> Envelope:
        """The envelope of :meth:`to_record` (``skin``: its skin meshes, patient frame)."""
        return cls(
            np.asarray(record["boxes"], dtype=float).reshape(-1, 7),
            tuple(record["names"]),
            record.get("table_z"),
            tuple(skin),
            str(record.get("source", "")),
        )

    def describe(self) -> dict[str, Any]:
        """What the envelope is, for a report or a JSON: source, regions, boxes, table and landmarks."""
        return {
            "source": self.source,
            "regions": list(self.names),
            "table_z": self.table_z,
            "boxes": {
                name: {"centre": b[:3].tolist(), "half_extents": b[3:6].tolist(), "rho": float(b[6])}
                for name, b in zip(self.names, self.boxes)
            },
            "landmarks": None if self.landmarks is None else self.landmarks.as_dict(),
        }


def default_envelope(marks: Landmarks, table_z: float | None = None) -> Envelope:
    """The envelope of model §19.5 on ``marks``: neck, head, torso and the table at z_s - 240 (or ``table_z``)."""
    x0, top, bot, z_s = marks.x0, marks.y_top, marks.y_bot, marks.z_s
    y_ref = {"neck": 0.5 * (top + bot), "head": top, "torso": bot}
    rows = []
    for name, (dx, dy, dz), (ax, ay, az), rho in BOX_TABLE:
        ay = ay + 0.5 * (top - bot) if name == "neck" else ay
        rows.append([x0 + dx, y_ref[name] + dy, z_s + dz, ax, ay, az, rho])
    table = z_s - TABLE_BELOW_SKIN_MM if table_z is None else float(table_z)
    source = f"default (model §19.5; skin z_s = {z_s:.1f} mm, {marks.skin_from}; table z = {table:.1f} mm)"
    return Envelope(np.array(rows), (*(b[0] for b in BOX_TABLE), "table"), table, (), source, marks)


def _items(spec: Any) -> list[str]:
    if spec is None:
        return ["none"]
    if isinstance(spec, (str, os.PathLike)):
        return [os.fspath(spec)]
    return [os.fspath(s) for s in spec] or ["none"]


def _table(table_z: Any) -> float | None:
    if table_z is None:
        return None
    try:
        value = float(table_z)
    except (TypeError, ValueError):
        raise InputError.of("table_z", f"must be a finite number of mm (patient frame), got {table_z!r}") from None
    if not math.isfinite(value):
        raise InputError.of("table_z", f"must be a finite number of mm (patient frame), got {value!r}")
    if abs(value) > COORDINATE_LIMIT_MM:  # as TableZ, for every caller
        raise InputError.of(
            "table_z", f"must lie within ±{COORDINATE_LIMIT_MM:g} mm (a coordinate of the patient frame), got {value:g}"
        )
    return value


def resolve_envelope(
    spec: Any, plan: Any = None, anatomy: Any = None, table_z: float | None = None, anatomy_frame: str = "LPS"
) -> Envelope | None:
    """The envelope named by ``spec``: ``"default"``, ``"none"`` (or None), mesh file(s), or an :class:`Envelope`.

    ``plan``: the trajectories **as loaded, before any side, level or id selection** (a
    :class:`~arcube.io.TrajectorySet`, or anything with ``entry`` and ``target`` ``(T, 3)``): the landmarks
    of the default envelope (and of its table) come from all of them. ``anatomy``: the plan's
    :class:`~arcube.evaluation.anatomy.Anatomy` (where its axes leave it is the skin z_s), or None.
    ``table_z``: the table's top (mm, patient frame); None: the table of 19.5, z_s - 240. Mesh files are
    read in ``anatomy_frame`` (LPS, RAS or patient), each a closed surface with the patient inside.

    One-line :class:`~arcube.errors.InputError` for a ``table_z`` not finite or beyond ±1e5 mm, a file that does not exist or
    is not a closed surface, ``default`` (or a skin mesh without ``table_z``) with no plan to place the
    landmarks, ``table_z`` with ``none``, or ``none``/``default`` mixed with files.
    """
    if isinstance(spec, Envelope):
        return spec
    table = _table(table_z)
    items = _items(spec)
    if items == ["none"]:
        if table is not None:
            raise InputError.of("table_z", "is set but the envelope is 'none' (no envelope to hold a table)")
        return None
    from arcube.evaluation.anatomy import FRAMES, names_default

    if names_default(items, "envelope"):
        if plan is None:
            raise InputError.of(
                "envelope",
                "'default' needs the plan's entry points to place its landmarks (model §19.5); give the trajectories, or 'none', or a skin mesh with table_z",
            )
        return default_envelope(landmarks(plan.entry, plan.target, anatomy), table)
    from arcube.io.meshes import read_meshes

    if anatomy_frame not in FRAMES:
        raise InputError.of("anatomy_frame", f"{anatomy_frame!r}: expected one of {', '.join(FRAMES)}")
    meshes = tuple(read_meshes(items, anatomy_frame))
    marks = None
    if table is None:
        if plan is None:
            raise InputError.of(
                "table_z", "is needed with a skin mesh envelope when no plan places the table of model §19.5"
            )
        marks = landmarks(plan.entry, plan.target, anatomy)
        table = marks.z_s - TABLE_BELOW_SKIN_MM
    source = ", ".join(items) + f" ({anatomy_frame}); table z = {table:.1f} mm"
    return Envelope(np.zeros((0, 7)), ("skin", "table"), table, meshes, source, marks)


def envelope_spec(value: Any) -> tuple[str, ...]:
    """``"default"``, ``"none"``, a path or several (a list, or comma-separated text) -> a tuple of words and paths."""
    if value is None:
        return ("none",)
    if isinstance(value, (str, os.PathLike)):
        items = [t.strip() for t in os.fspath(value).split(",")]
    else:
        items = [os.fspath(v).strip() for v in value]
    if not items or any(not t for t in items):
        raise ValueError("must be default, none, or mesh files")
    return tuple(items)


class EnvelopeSettings(Settings):
    """The envelope of the whole patient and the table (model §19.5), as the flags will set them."""

    envelope: Annotated[tuple[str, ...], BeforeValidator(envelope_spec)] = ("default",)
    """``default`` (a coarse body placed on the plan's landmarks), ``none``, or skin mesh files (closed surfaces with
    the patient inside, read in the anatomy's frame)."""
    table_z: TableZ | None = None
    """The operating table's top, mm, patient frame (z <= table_z is forbidden); None: 240 mm below the skin z_s."""

    def resolve(self, plan: Any = None, anatomy: Any = None, anatomy_frame: str = "LPS") -> Envelope | None:
        """:func:`resolve_envelope` of these settings (``plan``: the trajectories as loaded, before any selection)."""
        return resolve_envelope(list(self.envelope), plan, anatomy, self.table_z, anatomy_frame)


# ----------------------------------------------------------------------------- drawing


def envelope_from_boxes(
    boxes: Sequence[Sequence[float]], names: Sequence[str], table_z: float | None = None, source: str = "boxes"
) -> Envelope:
    """An envelope of rounded boxes ``(B, 7)`` (centre, half extents, rho) named ``names``, and an optional table."""
    return Envelope(
        np.asarray(boxes, dtype=float),
        (*names, *(("table",) if table_z is not None else ())),
        _table(table_z),
        (),
        source,
    )
