"""The default anatomy of a patient (model §14.2): boxes of bone and soft tissue.

**Status: [CHOICE] of the tool**, not measured anatomy. It is built from the same parameters as
the patient's trajectories (:func:`arcube.patients.virtual.draw_parameters`: level frames,
body heights H and depths D, pedicle entry points), so it moves with every virtual patient.
All lengths are mm; "vertebra frame" is that of ``MORPHOMETRY.md`` section 4 (origin at the
level's body centre, axes of the patient frame rotated about x by the level's tilt φ).

Per level C3–C7 (the operated levels), two bone blocks, both in the vertebra frame:

* **body**: a box ``BODY_WIDTH_MM`` = 18 mm wide (x; an assumed typical adult subaxial
  value, not in the morphometry table), H tall (y) and D deep (z), centred on the level centre.
* **posterior arch**: one box spanning both lateral masses whose posterior face holds the
  level's two entry points (right and left) exactly. Its thickness axis is the vertebra's z
  axis tilted just enough to be perpendicular to the line joining the two entries (no tilt at
  all when they are mirror images, as in the mean patient), so both entries lie on the face
  for every patient. The entries are those of the patient's trajectories: pedicle entries,
  or for a lateral-mass technique its own entries (which MORPHOMETRY.md section 2 puts at the
  depth of the pedicle entry). Across (x), it reaches ``LATERAL_MASS_MARGIN_MM`` = 2 mm
  beyond each pedicle entry (the pedicle entry lies 2 mm medial to the lateral notch,
  MORPHOMETRY.md section 2); along the vertebra (y), it covers the body's height and every
  entry point (pedicle and trajectory) ± ``ARCH_ENTRY_MARGIN_MM`` = 3 mm; anteriorly it
  reaches the body's posterior wall (z = D/2; for a tilted arch, the most anterior point of
  that wall, so the two blocks always touch), and it is at least ``ARCH_MIN_THICKNESS_MM`` = 2 mm
  thick. Without that floor a patient whose drawn pedicle axis is short and steep has its entries
  at or in front of the body's posterior wall (about one patient in ten of ``arcube patients``),
  and the arch came out flat or inside out: a box no mesh reader accepts and a 0.5 mm label map
  misses. The extra millimetres lie in front of the entries, inside the body or the soft tissue's
  floor layer. The canal is not hollowed out: the arch is solid.

Soft tissue: a slab, axis-aligned in the patient frame, minus a surgical corridor:

* across: x in [−``SLAB_HALF_WIDTH_MM``, +``SLAB_HALF_WIDTH_MM``] = [−80, 80] (a neck is
  ≈ 110–130 mm wide; the extra reaches towards the shoulders and the head holder);
* along: y from ``SLAB_BEYOND_LEVELS_MM`` = 40 mm below the lowest point of the C7 blocks to
  40 mm above the highest point of the C3 blocks;
* posteriorly: up to the skin, a plane z = (most posterior entry point) + t_s (default
  t_s = 40 mm; entry points = the pedicle entries and the trajectories' own entries);
* anteriorly: down to the most anterior point of the vertebral bodies, so slab and blocks
  form one solid neck region (nothing anterior to the spine is modelled: the robot works
  from behind, and a point deep in the neck is inside the slab anyway);
* the corridor, open to the skin and to everything behind it: x in ±(corridor width / 2)
  (default 80 mm wide; widened, if ever needed, so that every entry point is at least
  ``CORRIDOR_BEYOND_ENTRY_MM`` = 5 mm from its walls; at 80 mm no patient needs it: over
  1600 virtual patients (seeds 0–399, four techniques) |x| of an entry stays below 33 mm), y from 10 mm (corridor margin) below the lowest point of the C7
  blocks to 10 mm above the highest point of the C3 blocks, z above the *floor*:
  ``FLOOR_BELOW_ARCH_MM`` = 2 mm below the lowest point of any arch's posterior face. Every
  arch's posterior face, hence every entry point, is exposed, with at least 2 mm to the
  tissue below; below the floor (between levels, lateral to the arches) soft tissue remains.

The slab with its corridor is five overlapping boxes: the floor layer (full footprint, up to
the floor), the tissue below and above the corridor (full width, full height), and the tissue
right and left of it. They overlap rather than touch, so inside the slab no box face is an
internal seam, and no two boxes share a vertex, so the connected shells of the written STL
are exactly the boxes.

The drill paths (entry to target) pass through bone by design (the tool is exempt from the
clearance, model §14.1); the pedicle targets lie inside the body block (all of the mean
patient's; of 4000 random pedicle screws, 11 end up to 0.85 mm beyond the inferior endplate,
where a drawn SIP exceeds a drawn body height). Limits: no head,
shoulders or anterior neck organs, no curved skin, no canal or foramina, flat posterior bone
surface per level.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube import interrupts
from arcube.patients.virtual import LEVELS, build_patient, draw_parameters, level_frames

if TYPE_CHECKING:  # trimesh is imported only when meshes are made (it is slow to import)
    import trimesh

__all__ = [
    "ARCH_ENTRY_MARGIN_MM",
    "ARCH_MIN_THICKNESS_MM",
    "BODY_WIDTH_MM",
    "Box",
    "CORRIDOR_BEYOND_ENTRY_MM",
    "DefaultAnatomy",
    "FLOOR_BELOW_ARCH_MM",
    "LATERAL_MASS_MARGIN_MM",
    "REFERENCE_ANATOMY_FILE",
    "SLAB_BEYOND_LEVELS_MM",
    "SLAB_HALF_WIDTH_MM",
    "default_anatomy",
    "default_anatomy_boxes",
    "default_anatomy_layout",
    "reference_anatomy",
    "reference_anatomy_boxes",
    "reference_anatomy_path",
    "write_anatomy",
]

BODY_WIDTH_MM = 18.0  # vertebral body width (x), assumed
LATERAL_MASS_MARGIN_MM = 2.0  # arch beyond each pedicle entry (entry 2 mm medial to the lateral notch)
ARCH_ENTRY_MARGIN_MM = 3.0  # arch beyond every entry point along the vertebra (y)
ARCH_MIN_THICKNESS_MM = 2.0  # arch at least this thick in front of its posterior face (never flat or inverted)
SLAB_HALF_WIDTH_MM = 80.0  # soft tissue x in [-80, 80]
SLAB_BEYOND_LEVELS_MM = 40.0  # soft tissue 40 mm beyond the C3 and C7 blocks (y)
CORRIDOR_BEYOND_ENTRY_MM = 5.0  # corridor walls at least this far beyond every entry point (x)
FLOOR_BELOW_ARCH_MM = 2.0  # corridor floor below the lowest point of the arches' posterior faces
REFERENCE_ANATOMY_FILE = "reference_patient.anatomy.stl"  # in arcube/data, patient frame


@dataclass(frozen=True)
class Box:
    """A solid box: the points ``centre + rotation @ u`` with |u_i| <= half_extents[i].

    ``rotation`` (3, 3) holds the box's axes (columns) in the patient frame (det +1).
    Unpacks as ``centre, half_extents, rotation = box``.
    """

    centre: np.ndarray
    half_extents: np.ndarray
    rotation: np.ndarray
    name: str = ""
    kind: str = ""  # "bone" or "soft tissue"

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.centre, self.half_extents, self.rotation))

    def corners(self) -> np.ndarray:
        """(8, 3) corners in the patient frame."""
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
        return self.centre + (signs * self.half_extents) @ self.rotation.T

    def mesh(self) -> trimesh.Trimesh:
        """Closed, outward-oriented 12-triangle mesh of the box."""
        import trimesh

        interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost

        transform = np.eye(4)
        transform[:3, :3] = self.rotation
        transform[:3, 3] = self.centre
        return trimesh.creation.box(extents=2.0 * np.asarray(self.half_extents, dtype=float), transform=transform)


@dataclass(frozen=True)
class DefaultAnatomy:
    """One patient's default anatomy and the dimensions that define it (mm, patient frame)."""

    boxes: tuple[Box, ...]
    skin_z: float  # skin plane (top of the slab)
    floor_z: float  # corridor floor
    bottom_z: float  # bottom of the slab (anterior face of the bodies)
    slab_x: tuple[float, float]
    slab_y: tuple[float, float]
    corridor_x: tuple[float, float]
    corridor_y: tuple[float, float]
    skin_mm: float

    def meshes(self) -> list[trimesh.Trimesh]:
        """The boxes as closed meshes, in order."""
        return [b.mesh() for b in self.boxes]

    def summary(self) -> str:
        """One line: what the default anatomy is, with its dimensions."""
        n_bone = sum(b.kind == "bone" for b in self.boxes)
        return (
            f"default anatomy ([CHOICE], boxes): {n_bone} bone blocks (bodies {BODY_WIDTH_MM:g} mm wide, "
            f"posterior arches holding the entry points); soft tissue x {self.slab_x[0]:.1f}..{self.slab_x[1]:.1f}, "
            f"y {self.slab_y[0]:.1f}..{self.slab_y[1]:.1f}, z {self.bottom_z:.1f}..{self.skin_z:.1f} mm "
            f"(skin {self.skin_mm:g} mm above the most posterior entry); corridor x "
            f"{self.corridor_x[0]:.1f}..{self.corridor_x[1]:.1f}, y {self.corridor_y[0]:.1f}..{self.corridor_y[1]:.1f}, "
            f"open above z {self.floor_z:.1f} mm"
        )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _pedicle_entries_local(params: dict[str, Any], lv: str) -> list[np.ndarray]:
    """Right and left pedicle entries in the vertebra frame (MORPHOMETRY.md section 4 step 4)."""
    out = []
    h, d = params["body_height_mm"][lv], params["body_depth_mm"][lv]
    for side, sigma in (("R", 1.0), ("L", -1.0)):
        p = params["pedicle"][lv][side]
        anchor = np.array([sigma * p["XA_mm"], h / 2 - p["SIP_mm"], -d / 2])
        direction = _unit(
            np.array([-sigma * math.tan(math.radians(p["TA_deg"])), math.tan(math.radians(p["SA_deg"])), -1.0])
        )
        out.append(anchor - p["PAL_mm"] * direction)
    return out


def _arch_box(
    centre: np.ndarray,
    rot: np.ndarray,
    lv: str,
    params: dict[str, Any],
    entries_local: list[np.ndarray],
    cover_local: list[np.ndarray],
) -> Box:
    """The posterior arch of one level: posterior face through the right and left entries.

    ``entries_local``: (right, left) entry, vertebra frame; ``cover_local``: points the arch's
    x and y extents must cover (pedicle and trajectory entries).
    """
    h, d = params["body_height_mm"][lv], params["body_depth_mm"][lv]
    right, left = entries_local
    w = _unit(right - left)
    z_hat, x_hat = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    n = _unit(z_hat - (z_hat @ w) * w)  # thickness axis ⊥ the entry line
    xb = _unit(x_hat - (x_hat @ n) * n)
    yb = np.cross(n, xb)
    axes = np.column_stack([xb, yb, n])  # arch frame in the vertebra frame
    pts = np.array(cover_local) @ axes  # points to cover, in arch coordinates
    wall = np.array([[sx * BODY_WIDTH_MM / 2, sy * h / 2, d / 2] for sx in (-1, 1) for sy in (-1, 1)])
    face = float(right @ n)
    lo = np.array(
        [
            pts[:, 0].min() - LATERAL_MASS_MARGIN_MM,
            min(-h / 2, pts[:, 1].min() - ARCH_ENTRY_MARGIN_MM),
            min(float((wall @ axes)[:, 2].min()), face - ARCH_MIN_THICKNESS_MM),
        ]
    )
    hi = np.array([pts[:, 0].max() + LATERAL_MASS_MARGIN_MM, max(h / 2, pts[:, 1].max() + ARCH_ENTRY_MARGIN_MM), face])
    mid = (lo + hi) / 2
    return Box(centre + rot @ (axes @ mid), (hi - lo) / 2, rot @ axes, f"{lv} posterior arch", "bone")


def _aligned(lo: Sequence[float], hi: Sequence[float], name: str) -> Box:
    lo_a, hi_a = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    return Box((lo_a + hi_a) / 2, (hi_a - lo_a) / 2, np.eye(3), name, "soft tissue")


def default_anatomy_layout(
    params: dict[str, Any], skin_mm: float = 40.0, corridor_width_mm: float = 80.0, corridor_margin_mm: float = 10.0
) -> DefaultAnatomy:
    """The default anatomy of the patient ``params`` (from :func:`draw_parameters`), with its dimensions.

    Args:
        params: the patient's parameters (any technique; the arch is built on the pedicle entries).
        skin_mm: t_s, skin plane above the most posterior entry point (> 0).
        corridor_width_mm: width of the surgical corridor across x (> 0).
        corridor_margin_mm: corridor beyond the C3 and C7 blocks along y (>= 0).
    """
    if not skin_mm > 0 or not corridor_width_mm > 0 or not corridor_margin_mm >= 0:
        raise ValueError("skin_mm and corridor_width_mm must be > 0, corridor_margin_mm >= 0")
    frames = level_frames(params)
    ts = build_patient(params)
    bone: list[Box] = []
    entries: list[np.ndarray] = []
    for lv in LEVELS:
        centre, rot, _ = frames[lv]
        ped = _pedicle_entries_local(params, lv)
        own = {side: rot.T @ (e - centre) for e, level, side in zip(ts.entry, ts.levels, ts.sides) if level == lv}
        h, d = params["body_height_mm"][lv], params["body_depth_mm"][lv]
        bone.append(Box(centre.copy(), np.array([BODY_WIDTH_MM / 2, h / 2, d / 2]), rot.copy(), f"{lv} body", "bone"))
        bone.append(_arch_box(centre, rot, lv, params, [own["R"], own["L"]], ped + list(own.values())))
        entries += [centre + rot @ e for e in ped + list(own.values())]
    corners = np.concatenate([b.corners() for b in bone])
    arches = [b for b in bone if b.name.endswith("arch")]
    # lowest point of any arch's posterior face (local +z face of the arch box)
    floor_z = min(float((b.corners()[[1, 3, 5, 7]])[:, 2].min()) for b in arches) - FLOOR_BELOW_ARCH_MM
    bottom_z = float(min(b.corners()[:, 2].min() for b in bone if b.name.endswith("body")))
    entry = np.array(entries)
    skin_z = float(entry[:, 2].max()) + float(skin_mm)
    cx = max(corridor_width_mm / 2, float(np.abs(entry[:, 0]).max()) + CORRIDOR_BEYOND_ENTRY_MM)
    y_lo, y_hi = float(corners[:, 1].min()), float(corners[:, 1].max())
    cy = (y_lo - corridor_margin_mm, y_hi + corridor_margin_mm)
    sx = max(SLAB_HALF_WIDTH_MM, cx + 10.0)
    sy = (min(y_lo - SLAB_BEYOND_LEVELS_MM, cy[0] - 10.0), max(y_hi + SLAB_BEYOND_LEVELS_MM, cy[1] + 10.0))
    z_mid = (bottom_z + floor_z) / 2  # walls start here: overlap the floor layer
    overlap = min(5.0, (cy[0] - sy[0]) / 2)  # side walls reach into the end walls
    soft = [
        _aligned((-sx, sy[0], bottom_z), (sx, sy[1], floor_z), "soft tissue: floor layer"),
        _aligned((-sx, sy[0], z_mid), (sx, cy[0], skin_z), "soft tissue: below the corridor"),
        _aligned((-sx, cy[1], z_mid), (sx, sy[1], skin_z), "soft tissue: above the corridor"),
        _aligned((cx, cy[0] - overlap, z_mid), (sx, cy[1] + overlap, skin_z), "soft tissue: right of the corridor"),
        _aligned((-sx, cy[0] - overlap, z_mid), (-cx, cy[1] + overlap, skin_z), "soft tissue: left of the corridor"),
    ]
    return DefaultAnatomy(tuple(bone + soft), skin_z, floor_z, bottom_z, (-sx, sx), sy, (-cx, cx), cy, float(skin_mm))


def default_anatomy_boxes(
    params: dict[str, Any], skin_mm: float = 40.0, corridor_width_mm: float = 80.0, corridor_margin_mm: float = 10.0
) -> list[Box]:
    """The default anatomy as boxes: 10 bone blocks (C3 body, C3 arch, ..., C7 arch), then 5 soft-tissue boxes."""
    return list(default_anatomy_layout(params, skin_mm, corridor_width_mm, corridor_margin_mm).boxes)


def default_anatomy(
    params: dict[str, Any], skin_mm: float = 40.0, corridor_width_mm: float = 80.0, corridor_margin_mm: float = 10.0
) -> list[trimesh.Trimesh]:
    """The default anatomy as closed box meshes (patient frame, mm), in the order of :func:`default_anatomy_boxes`."""
    return [b.mesh() for b in default_anatomy_boxes(params, skin_mm, corridor_width_mm, corridor_margin_mm)]


def reference_anatomy_boxes() -> list[Box]:
    """Boxes of the bundled mean patient (``draw_parameters(None)``), default dimensions."""
    return default_anatomy_boxes(draw_parameters(None))


def reference_anatomy() -> list[trimesh.Trimesh]:
    """Meshes of the bundled mean patient's default anatomy (the content of ``data/reference_patient.anatomy.stl``)."""
    return default_anatomy(draw_parameters(None))


def reference_anatomy_path() -> Path:
    """Path of the bundled ``reference_patient.anatomy.stl`` (patient frame: read it with ``frame="patient"``)."""
    return Path(str(resources.files("arcube").joinpath("data", REFERENCE_ANATOMY_FILE)))


def write_anatomy(
    params: dict[str, Any],
    path: str | os.PathLike[str],
    skin_mm: float = 40.0,
    corridor_width_mm: float = 80.0,
    corridor_margin_mm: float = 10.0,
) -> DefaultAnatomy:
    """Write the default anatomy of ``params`` as one binary STL (patient frame, one shell per box).

    Returns:
        The layout written (its :meth:`DefaultAnatomy.summary` documents the dimensions).
    """
    from arcube.io.meshes import write_stl

    layout = default_anatomy_layout(params, skin_mm, corridor_width_mm, corridor_margin_mm)
    write_stl(layout.meshes(), path, frame="patient")
    return layout
