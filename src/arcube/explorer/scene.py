"""The explorer's scene at one pose: the robot's body as solids, their colours, and the closest pairs.

Pure NumPy (no viser, no plotly), so the live app (:mod:`arcube.explorer.app`) and the static export
(:mod:`arcube.explorer.static`) draw the same thing:

* :func:`body_solids`: the parts of model §14.1 (:func:`arcube.model.body.body_parts`) as solids
  with their radii: each segment a cylinder with a sphere at both ends (a capsule), each actuator a
  sphere, each great-circle arc of the spherical stage the chords the self clearance uses
  (:func:`arcube.evaluation.clearance.arc_chords`), each a capsule;
* :func:`anatomy_closest`: the clearance of every primitive to the anatomy (the axis sampled every
  ``step`` mm on the anatomy's distance grid, minus the radius, as the NumPy reference does) and the
  closest pair, robot surface -> anatomy surface (along the distance field's gradient);
* :func:`self_closest`: the self clearance of model §14.3 over :data:`arcube.model.body.SELF_PAIRS`
  (exact closest points of segments; arcs as chords) and the closest pair of surface points;
* :func:`clearance_classes` / :func:`part_colours`: a colour per part from its clearances against the
  requirement limits (:data:`CLASSES`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.evaluation.clearance import ARC_CHORDS, arc_chords
from arcube.model.body import (
    N_ARCS,
    N_SEGMENTS,
    N_SPHERES,
    PART_NAMES,
    PRIMITIVE_PART,
    SELF_PAIRS,
    BodyParts,
    BodyRadii,
    MechanismPoints,
    body_parts,
    great_circle,
    mechanism_points,
)

__all__ = [
    "CLASSES",
    "CLOSE_MM",
    "COLOURS",
    "Closest",
    "Solids",
    "anatomy_closest",
    "body_solids",
    "clearance_classes",
    "cylinder_frames",
    "part_colours",
    "part_minimum",
    "pose",
    "self_closest",
]

N_PRIMITIVES = N_SEGMENTS + N_SPHERES + N_ARCS
CLASSES: tuple[str, ...] = ("unknown", "clear", "close", "below", "collision")
"""Clearance classes of a part, in rising severity: no value (no anatomy, no IK), >= limit + CLOSE_MM,
>= limit, >= 0 but below the requirement's limit, < 0 (inside the anatomy / parts overlapping)."""
COLOURS: dict[str, tuple[int, int, int]] = {
    "unknown": (150, 160, 175),
    "clear": (80, 170, 105),
    "close": (235, 195, 50),
    "below": (245, 135, 35),
    "collision": (215, 35, 45),
}
"""RGB of each class."""
CLOSE_MM = 10.0
"""A part within this much of a requirement's limit is ``close``."""


def pose(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike,
    radii: BodyRadii = BodyRadii(),
    c_z: float | None = None,
) -> tuple[MechanismPoints, BodyParts]:
    """Joint positions and body parts of ``params`` ``(27,)`` at one pose (E, e ``(3,)``)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        mp = mechanism_points(params, E, e, mode, c_z=c_z, motor_length=radii.motor_length)
        return mp, body_parts(mp, radii)


@dataclass(frozen=True)
class Solids:
    """The body as capsules and spheres (mm, patient frame); NaN where the IK has no solution."""

    cylinders: NDArray[np.float64]
    """``(N, 2, 3)`` the capsules' axis end points: the segments, then the chords of the arcs."""
    cylinder_radius: NDArray[np.float64]
    """``(N,)`` their radii."""
    cylinder_primitive: NDArray[np.intp]
    """``(N,)`` the primitive each belongs to: an index into :data:`arcube.model.body.PRIMITIVES`."""
    spheres: NDArray[np.float64]
    """``(M, 3)`` the spheres' centres: the caps (both ends of every segment, the chord ends along every arc), then
    the five actuators."""
    sphere_radius: NDArray[np.float64]
    """``(M,)`` their radii."""
    sphere_primitive: NDArray[np.intp]
    """``(M,)`` the primitive each belongs to, as ``cylinder_primitive``."""

    @property
    def cylinder_part(self) -> NDArray[np.intp]:
        """Index into PART_NAMES of each cylinder."""
        return PRIMITIVE_PART[self.cylinder_primitive]

    @property
    def sphere_part(self) -> NDArray[np.intp]:
        """Index into PART_NAMES of each sphere."""
        return PRIMITIVE_PART[self.sphere_primitive]


def body_solids(parts: BodyParts) -> Solids:
    """The solids of one pose's :class:`~arcube.model.body.BodyParts` (leading shape ``()``)."""
    chords = arc_chords(parts).reshape(N_ARCS * ARC_CHORDS, 2, 3)
    cyl = np.concatenate([parts.segments, chords])
    cyl_prim = np.concatenate(
        [np.arange(N_SEGMENTS), N_SEGMENTS + N_SPHERES + np.repeat(np.arange(N_ARCS), ARC_CHORDS)]
    )
    # caps: both ends of every segment; along an arc, each chord's start and the last chord's end
    arc_pts = np.concatenate(
        [chords.reshape(N_ARCS, ARC_CHORDS, 2, 3)[:, :, 0], chords.reshape(N_ARCS, ARC_CHORDS, 2, 3)[:, -1:, 1]], axis=1
    )
    sph = np.concatenate([parts.segments.reshape(-1, 3), arc_pts.reshape(-1, 3), parts.spheres])
    arc_prim = N_SEGMENTS + N_SPHERES + np.repeat(np.arange(N_ARCS), ARC_CHORDS + 1)
    sph_prim = np.concatenate([np.repeat(np.arange(N_SEGMENTS), 2), arc_prim, N_SEGMENTS + np.arange(N_SPHERES)])
    return Solids(cyl, parts.radius[cyl_prim], cyl_prim, sph, parts.radius[sph_prim], sph_prim)


def cylinder_frames(ends: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(centres ``(N, 3)``, quaternions wxyz ``(N, 4)``, lengths ``(N,)``) that place a unit cylinder
    along z, centred at the origin, on each axis ``ends`` ``(N, 2, 3)``; degenerate or NaN axes get
    length 0 (NaN ends are moved to the origin)."""
    a, b = ends[:, 0], ends[:, 1]
    ok = np.all(np.isfinite(ends), axis=(1, 2))
    d = np.where(ok[:, None], b - a, 0.0)
    length = np.linalg.norm(d, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length[:, None] > 1e-12, d / length[:, None], np.array([0.0, 0.0, 1.0]))
    # rotation z -> u: axis z x u = (-u_y, u_x, 0), w = 1 + u_z (normalised); u = -z: half turn about x
    q = np.stack([1.0 + u[:, 2], -u[:, 1], u[:, 0], np.zeros(len(u))], axis=1)
    flip = q[:, 0] < 1e-9
    q[flip] = (0.0, 1.0, 0.0, 0.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    centre = np.where(ok[:, None], 0.5 * (a + b), 0.0)
    return centre, q, np.where(ok, length, 0.0)


class Closest(NamedTuple):
    """The closest pair of a clearance: ``robot`` on the surface of ``part``, ``other`` on the anatomy
    or on the surface of ``other_part``; ``clearance`` = their signed distance (mm, < 0: overlap).
    NaN points and clearance, empty names, where there is none."""

    clearance: float
    robot: NDArray[np.float64]
    other: NDArray[np.float64]
    part: str
    other_part: str


_NONE = Closest(float("nan"), np.full(3, np.nan), np.full(3, np.nan), "", "")


def _axis_samples(parts: BodyParts, step: float) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Points along every primitive's axis (``step`` mm apart, both ends) and the primitive of each."""
    pts, owner = [], []
    for s in range(N_SEGMENTS):
        a, b = parts.segments[s]
        n = int(np.ceil(np.linalg.norm(b - a) / step)) + 1
        pts.append(a + np.linspace(0.0, 1.0, max(n, 2))[:, None] * (b - a))
        owner.append(np.full(len(pts[-1]), s))
    pts.append(parts.spheres)
    owner.append(N_SEGMENTS + np.arange(N_SPHERES))
    for k in range(N_ARCS):
        u, v = parts.arc_ends[k]
        angle = float(np.arccos(np.clip(np.dot(u, v), -1.0, 1.0)))
        n = int(np.ceil(float(parts.arc_radius) * angle / step)) + 1
        pts.append(parts.arc_centre + float(parts.arc_radius) * great_circle(u, v, max(n, 2)))
        owner.append(np.full(len(pts[-1]), N_SEGMENTS + N_SPHERES + k))
    return np.concatenate(pts), np.concatenate(owner)


def anatomy_closest(parts: BodyParts, distance: Any, step: float = 1.0) -> tuple[NDArray[np.float64], Closest]:
    """(clearance of each primitive to the anatomy ``(27,)`` mm, the closest pair) at one pose.

    ``distance``: the anatomy's signed distance (``Anatomy.distance``). The sampled minimum along an
    axis is within ``step / 2`` of the exact one (a distance is 1-Lipschitz). NaN without an IK solution.
    """
    if not np.all(np.isfinite(parts.segments)) or distance is None:
        return np.full(N_PRIMITIVES, np.nan), _NONE
    pts, owner = _axis_samples(parts, step)
    d = np.asarray(distance(pts), dtype=float) - parts.radius[owner]
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    per = np.full(N_PRIMITIVES, np.nan)
    per[owner[starts]] = np.minimum.reduceat(d, starts)
    i = int(np.argmin(d))
    p, k = pts[i], int(owner[i])
    h = 0.25
    offsets = np.concatenate([np.eye(3) * h, -np.eye(3) * h])
    g6 = np.asarray(distance(p + offsets), dtype=float)
    grad = (g6[:3] - g6[3:]) / (2.0 * h)
    norm = float(np.linalg.norm(grad))
    grad = grad / norm if norm > 1e-9 else np.array([0.0, 0.0, 1.0])
    sd = float(d[i] + parts.radius[k])
    closest = Closest(float(d[i]), p - parts.radius[k] * grad, p - sd * grad, PART_NAMES[PRIMITIVE_PART[k]], "anatomy")
    return per, closest


def closest_points(
    p1: NDArray[np.float64], q1: NDArray[np.float64], p2: NDArray[np.float64], q2: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The closest points of segments p1-q1 and p2-q2 ``(..., 3)`` (Ericson 5.1.9; points are
    zero-length segments): the same parameters as :func:`arcube.evaluation.clearance.segment_distance`."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = np.sum(d1 * d1, axis=-1), np.sum(d2 * d2, axis=-1)
    f, c, b = np.sum(d2 * r, axis=-1), np.sum(d1 * r, axis=-1), np.sum(d1 * d2, axis=-1)
    tiny = 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = a * e - b * b
        s_gen = np.where(denom > 0.0, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t_gen = (b * s_gen + f) / e
        s_low, s_high = np.clip(-c / a, 0.0, 1.0), np.clip((b - c) / a, 0.0, 1.0)
        s = np.where(t_gen < 0.0, s_low, np.where(t_gen > 1.0, s_high, s_gen))
        t = np.clip(t_gen, 0.0, 1.0)
        s, t = np.where(e <= tiny, s_low, s), np.where(e <= tiny, 0.0, t)
        s = np.where(a <= tiny, 0.0, s)
        t = np.where(a <= tiny, np.where(e <= tiny, 0.0, np.clip(f / e, 0.0, 1.0)), t)
    return p1 + d1 * s[..., None], p2 + d2 * t[..., None]


def self_closest(parts: BodyParts) -> tuple[NDArray[np.float64], Closest]:
    """(each primitive's smallest self clearance over its pairs ``(27,)`` mm, the closest pair) at one
    pose: model §14.3 over SELF_PAIRS, arcs as chords, as :func:`arcube.evaluation.clearance.self_clearance`."""
    if not np.all(np.isfinite(parts.segments)):
        return np.full(N_PRIMITIVES, np.nan), _NONE
    n_lines = N_SEGMENTS + N_SPHERES
    lines = np.concatenate([parts.segments, np.stack([parts.spheres, parts.spheres], axis=-2)])  # (23, 2, 3)
    chords = arc_chords(parts)  # (4, n, 2, 3)
    i, j = SELF_PAIRS[:, 0], SELF_PAIRS[:, 1]
    A = lines[i]  # (pairs, 2, 3): the first primitive is never an arc
    B = np.where(
        (j < n_lines)[:, None, None, None],
        lines[np.minimum(j, n_lines - 1)][:, None],
        chords[np.clip(j - n_lines, 0, N_ARCS - 1)],
    )  # (pairs, n, 2, 3)
    ca, cb = closest_points(A[:, None, 0], A[:, None, 1], B[:, :, 0], B[:, :, 1])
    dist = np.linalg.norm(ca - cb, axis=-1)  # (pairs, n)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(i))
    d = dist[rows, best] - parts.radius[i] - parts.radius[j]
    per = np.full(N_PRIMITIVES, np.inf)
    np.minimum.at(per, i, d)
    np.minimum.at(per, j, d)
    per[~np.isfinite(per)] = np.nan
    k = int(np.argmin(d))
    pa, pb = ca[k, best[k]], cb[k, best[k]]
    gap = pb - pa
    n = float(np.linalg.norm(gap))
    u = gap / n if n > 1e-12 else np.zeros(3)
    closest = Closest(
        float(d[k]),
        pa + parts.radius[i[k]] * u,
        pb - parts.radius[j[k]] * u,
        PART_NAMES[PRIMITIVE_PART[i[k]]],
        PART_NAMES[PRIMITIVE_PART[j[k]]],
    )
    return per, closest


def part_minimum(per_primitive: ArrayLike) -> NDArray[np.float64]:
    """The smallest value over each part's primitives ``(len(PART_NAMES),)`` (NaN where none is finite)."""
    v = np.asarray(per_primitive, dtype=float)
    out = np.full(len(PART_NAMES), np.inf)
    np.minimum.at(out, PRIMITIVE_PART, np.where(np.isfinite(v), v, np.inf))
    out[~np.isfinite(out)] = np.nan
    return out


def clearance_classes(values: ArrayLike, limit: float | None) -> NDArray[np.intp]:
    """Index into :data:`CLASSES` of each clearance value against a requirement's ``limit`` (mm;
    None: 0, no requirement): NaN -> unknown, < 0 -> collision, < limit -> below, < limit +
    :data:`CLOSE_MM` -> close, else clear."""
    v = np.asarray(values, dtype=float)
    lim = 0.0 if limit is None else float(limit)
    out = np.where(v < 0.0, 4, np.where(v < lim, 3, np.where(v < lim + CLOSE_MM, 2, 1)))
    return np.where(np.isfinite(v), out, 0).astype(np.intp)


def part_colours(
    anatomy: ArrayLike, self_: ArrayLike, clearance_limit: float | None, self_limit: float | None
) -> tuple[NDArray[np.intp], NDArray[np.uint8]]:
    """(class ``(parts,)``, RGB ``(parts, 3)``) of every part: the worse of its clearance to the
    anatomy and its self clearance, each against its own limit."""
    cls = np.maximum(clearance_classes(anatomy, clearance_limit), clearance_classes(self_, self_limit))
    table = np.array([COLOURS[c] for c in CLASSES], dtype=np.uint8)
    return cls, table[cls]
