"""Clearance of the robot's body to the envelope of the whole patient (model §19.5), NumPy reference.

``envelope_clearance`` = the smallest signed distance from the body (14.1, every part but the tool:
the primitives of :func:`arcube.model.body.body_parts`) to the envelope
(:class:`arcube.evaluation.envelope.Envelope`): per primitive, the signed distance from its axis
(segment, point or great-circle arc) to a region, minus the primitive's radius; the minimum over the
primitives and regions, the part that attains it (index into ``PART_NAMES``) and the region (index into
``Envelope.names``). Ties go to the first region, then to the first primitive, a tie being a value within
:data:`TIE_MM` of the least: parts that meet at a joint (an output link, the platform and a spherical link
at Q_u) reach the same point by different arithmetic, and rounding must not decide which one is named.
How each pair is computed:

* **segment or point to a rounded box**: exact. Along a segment p(t) = a + t (b - a), t in [0, 1], the
  box's signed distance f(t) is piecewise: between the breakpoints where a coordinate of p - c crosses
  -a_i, 0 or a_i, either p is outside (f = the square root of a quadratic in t) or inside (f = the
  largest of three linear functions). The minimum of f is at 0, 1, a breakpoint, the stationary point of
  a quadratic piece, or a crossing of two linear pieces; :func:`segment_box_min` evaluates f at every
  such candidate of every possible piece (49 values of t) and takes the least. Minus rho;
* **segment or point to the table** (z <= z_t): exact, min(z_a, z_b) - z_t;
* **arc to the table**: exact, the lowest point of the arc (its ends, or where its z is stationary);
* **arc to a rounded box**: the arc as a polyline of :data:`ENVELOPE_ARC_CHORDS` chords through points
  on it (its ends exactly), each chord exact as above. Every arc point lies within the sag
  r (1 - cos(theta / 2N)) of its chord and every chord point within it of the arc, and a signed
  distance is 1-Lipschitz, so the value is within that sag of the arc's: for N = 24, at most
  0.043 mm for r <= 80 mm and theta <= 90 deg (model §12.1's default bounds), 0.5 mm for r up to
  233 mm at any theta <= 180 deg;
* **anything to a skin mesh**: the anatomy's method (:func:`arcube.evaluation.clearance.anatomy_clearance`:
  the axes sampled every 0.25 mm against the mesh's distance grids, within 0.125 mm plus the grids'
  interpolation error of :mod:`arcube.evaluation.sdf`).

Leading axes broadcast (designs, points, states); NaN, -1 and -1 where the body is undefined (no IK).
The compiled kernel (``kernel._envelope``) computes the same with its own exact minimisation.
"""

from __future__ import annotations

import itertools
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.evaluation.envelope import Envelope
from arcube.model.body import N_ARCS, PRIMITIVE_PART, BodyParts, body_parts, mechanism_points
from arcube.model.mechanism import DEFAULT_MODE

__all__ = [
    "ENVELOPE_ARC_CHORDS",
    "TIE_MM",
    "EnvelopeClearance",
    "arc_chord_points",
    "arc_lowest_z",
    "arc_sag_bound",
    "envelope_clearance",
    "pose_envelope_clearance",
    "segment_box_min",
]

ENVELOPE_ARC_CHORDS = 24
"""Chords per spherical arc against a rounded box (the error bound in the module doc)."""
TIE_MM = 1e-9
"""Values within this of the least are ties (module doc): the first region, then the first primitive, is named."""


class EnvelopeClearance(NamedTuple):
    """The body's clearance to the envelope, each ``(...)``."""

    clearance: NDArray[np.float64]  # mm, NaN where the body is undefined
    part: NDArray[np.intp]  # index into arcube.model.body.PART_NAMES of the closest part, -1 where undefined
    region: NDArray[np.intp]  # index into Envelope.names of the region it is closest to, -1 where undefined


def _box_sd(p: NDArray[np.float64], c: NDArray[np.float64], h: NDArray[np.float64]) -> NDArray[np.float64]:
    """Signed distance to the (not rounded) box |X - c| <= h, component by component (as the kernel)."""
    q0 = np.abs(p[..., 0] - c[..., 0]) - h[..., 0]
    q1 = np.abs(p[..., 1] - c[..., 1]) - h[..., 1]
    q2 = np.abs(p[..., 2] - c[..., 2]) - h[..., 2]
    o0, o1, o2 = np.maximum(q0, 0.0), np.maximum(q1, 0.0), np.maximum(q2, 0.0)
    return np.sqrt(o0 * o0 + o1 * o1 + o2 * o2) + np.minimum(np.maximum(q0, np.maximum(q1, q2)), 0.0)


def _point_at(a: NDArray[np.float64], b: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
    """a + t (b - a), from the nearer end (so that t = 0 and t = 1 give a and b exactly)."""
    d = b - a
    t = t[..., None]
    return np.where(t <= 0.5, a + t * d, b - (1.0 - t) * d)


_SUBSETS = [s for s in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(s)]
"""Sign patterns of the outside pieces: sigma_i = +-1 for the axes outside the box, 0 for the others (26)."""
_CROSSINGS = [(i, j, si, sj) for i, j in ((0, 1), (0, 2), (1, 2)) for si in (-1.0, 1.0) for sj in (-1.0, 1.0)]
"""Pairs of the inside pieces' linear functions s_i (u_i + t d_i) - h_i (12)."""


def _candidates(u: NDArray[np.float64], d: NDArray[np.float64], h: NDArray[np.float64]) -> list[Any]:
    """Every t at which the minimum of the signed distance along a + t d can lie (module doc), unclipped."""
    ts: list[Any] = [np.zeros(u.shape[:-1]), np.ones(u.shape[:-1])]
    for i in range(3):  # breakpoints: u_i + t d_i = -h_i, 0, h_i
        ts += [(s * h[..., i] - u[..., i]) / d[..., i] for s in (-1.0, 0.0, 1.0)]
    for sig in _SUBSETS:  # stationary points of sum over the axes outside of (s_i (u_i + t d_i) - h_i)^2
        num = sum(
            ((s * u[..., i] - h[..., i]) * (s * d[..., i]) for i, s in enumerate(sig) if s),
            start=np.zeros(u.shape[:-1]),
        )
        den = sum((d[..., i] * d[..., i] for i, s in enumerate(sig) if s), start=np.zeros(u.shape[:-1]))
        ts.append(-num / den)
    for i, j, si, sj in _CROSSINGS:  # the inside pieces: s_i (u_i + t d_i) - h_i = s_j (u_j + t d_j) - h_j
        ts.append(((sj * u[..., j] - h[..., j]) - (si * u[..., i] - h[..., i])) / (si * d[..., i] - sj * d[..., j]))
    return ts


def segment_box_min(a: ArrayLike, b: ArrayLike, centre: ArrayLike, half: ArrayLike) -> NDArray[np.float64]:
    """Exact min over t in [0, 1] of the signed distance of a + t (b - a) to the box |X - centre| <= half.

    ``a``, ``b`` ``(..., 3)`` mm (a point: a = b); ``centre``, ``half`` broadcast to ``(..., 3)``. Returns
    ``(...)`` mm, NaN where a or b is not finite.
    """
    a_, b_ = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    shape = np.broadcast_shapes(a_.shape, b_.shape, np.shape(centre), np.shape(half))
    a_, b_ = np.broadcast_to(a_, shape), np.broadcast_to(b_, shape)
    c, h = (
        np.broadcast_to(np.asarray(centre, dtype=float), shape),
        np.broadcast_to(np.asarray(half, dtype=float), shape),
    )
    u, d = a_ - c, b_ - a_
    best = np.full(shape[:-1], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for t in _candidates(u, d, h):
            t = np.clip(np.where(np.isfinite(t), t, 0.0), 0.0, 1.0)
            best = np.minimum(best, _box_sd(_point_at(a_, b_, t), c, h))  # NaN (no body) propagates
    return best


def _arc_frames(parts: BodyParts) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(start directions ``(..., 4, 3)``, unit in-plane normals ``(..., 4, 3)`` (0 for a zero arc), angles ``(..., 4)`` rad)."""
    a, b = parts.arc_ends[..., 0, :], parts.arc_ends[..., 1, :]
    dot = np.sum(a * b, axis=-1)
    nrm = b - dot[..., None] * a
    nn = np.sqrt(np.sum(nrm * nrm, axis=-1))
    ok = nn > 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.where(ok[..., None], nrm / nn[..., None], 0.0)
    return a, n, np.where(ok, np.arctan2(nn, dot), 0.0)


def arc_chord_points(parts: BodyParts, n: int = ENVELOPE_ARC_CHORDS) -> NDArray[np.float64]:
    """``(..., 4, n + 1, 3)`` points on the spherical arcs, C + r (a cos(k theta / n) + n sin(k theta / n)),
    k = 0 .. n, the ends exactly C + r a and C + r b: the vertices of their chord polylines."""
    a, nrm, theta = _arc_frames(parts)
    phi = theta[..., None] * (np.arange(n + 1) / n)  # (..., 4, n + 1)
    dirs = a[..., None, :] * np.cos(phi)[..., None] + nrm[..., None, :] * np.sin(phi)[..., None]
    dirs[..., 0, :] = a
    dirs[..., -1, :] = parts.arc_ends[..., 1, :]
    return parts.arc_centre[..., None, None, :] + parts.arc_radius[..., None, None, None] * dirs


def arc_sag_bound(radius: ArrayLike, angle: ArrayLike, n: int = ENVELOPE_ARC_CHORDS) -> NDArray[np.float64]:
    """The chord polyline's error bound r (1 - cos(theta / 2n)) mm, for arcs of ``radius`` mm and ``angle`` rad."""
    return np.asarray(radius, dtype=float) * (1.0 - np.cos(np.asarray(angle, dtype=float) / (2.0 * n)))


def arc_lowest_z(parts: BodyParts) -> NDArray[np.float64]:
    """``(..., 4)`` the least z over each spherical arc, exactly: z(phi) = C_z + r (a_z cos phi + n_z sin phi) is
    least at its ends or at phi* = atan2(-n_z, -a_z) (mod 2 pi) when phi* lies on the arc."""
    a, nrm, theta = _arc_frames(parts)
    cz, r = parts.arc_centre[..., None, 2], parts.arc_radius[..., None]
    ends = np.minimum(cz + r * a[..., 2], cz + r * parts.arc_ends[..., 1, 2])
    phi = np.mod(np.arctan2(-nrm[..., 2], -a[..., 2]), 2.0 * np.pi)
    inner = cz - r * np.sqrt(a[..., 2] * a[..., 2] + nrm[..., 2] * nrm[..., 2])
    return np.where(phi <= theta, np.minimum(inner, ends), ends)


def _lines(parts: BodyParts) -> NDArray[np.float64]:
    """The segments then the points (as zero-length segments): ``(..., 23, 2, 3)``, PRIMITIVES order."""
    return np.concatenate([parts.segments, np.stack([parts.spheres, parts.spheres], axis=-2)], axis=-3)


def envelope_clearance(parts: BodyParts, envelope: Envelope) -> EnvelopeClearance:
    """The body's clearance to ``envelope`` (module doc): ``(...)`` mm, part and region, for body parts ``(...)``."""
    from arcube.evaluation.clearance import anatomy_clearance

    lines = _lines(parts)
    per_region: list[Any] = []  # per region: (..., 27) values per primitive, or (value, part) for a skin mesh
    if envelope.n_boxes:
        chords = arc_chord_points(parts)  # (..., 4, n + 1, 3)
        for box in envelope.boxes:
            c, h, rho = box[:3], box[3:6], box[6]
            on_lines = segment_box_min(lines[..., 0, :], lines[..., 1, :], c, h)
            on_arcs = np.min(segment_box_min(chords[..., :-1, :], chords[..., 1:, :], c, h), axis=-1)
            per_region.append(np.concatenate([on_lines, on_arcs], axis=-1) - rho - parts.radius)
    if envelope.skin:
        per_region.append(anatomy_clearance(parts, envelope.skin_distance))  # type: ignore[arg-type]
    if envelope.table_z is not None:
        low = np.concatenate([np.minimum(lines[..., 0, 2], lines[..., 1, 2]), arc_lowest_z(parts)], axis=-1)
        per_region.append(low - envelope.table_z - parts.radius)
    mins = np.stack(
        [r[0] if isinstance(r, tuple) else np.min(r, axis=-1) for r in per_region], axis=-1
    )  # NaN propagates
    least = np.min(mins, axis=-1)
    defined = np.isfinite(least) & np.all(np.isfinite(mins), axis=-1)
    tie = np.where(defined, least + TIE_MM, -np.inf)
    region = np.argmax(mins <= tie[..., None], axis=-1)  # the first region within TIE_MM of the least
    owners = [
        r[1] if isinstance(r, tuple) else PRIMITIVE_PART[np.argmax(r <= tie[..., None], axis=-1)] for r in per_region
    ]
    part = np.take_along_axis(np.stack(owners, axis=-1), region[..., None], axis=-1)[..., 0]
    return EnvelopeClearance(
        np.where(defined, least, np.nan), np.where(defined, part, -1), np.where(defined, region, -1)
    )


def pose_envelope_clearance(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    envelope: Envelope,
    mode: ArrayLike = DEFAULT_MODE,
    *,
    radii: Any = None,
    c_z: ArrayLike | None = None,
) -> EnvelopeClearance:
    """The envelope clearance of a design ``(..., 27)`` at poses (``E``, ``e`` ``(..., 3)``), e.g. the states of a
    program (model §17.2): the body of 14.1 from the IK in working ``mode``, then :func:`envelope_clearance`.

    ``radii``: :class:`arcube.model.body.BodyRadii` (or anything with ``.radii``, e.g. ``Options().body``);
    ``c_z``: the z dyad's second link (None: d_z). NaN, -1, -1 at the poses the IK does not solve.
    """
    from arcube.model.body import BodyRadii

    r = BodyRadii() if radii is None else getattr(radii, "radii", radii)
    with np.errstate(invalid="ignore", divide="ignore"):
        mp = mechanism_points(params, E, e, mode, c_z=c_z, motor_length=r.motor_length)
        return envelope_clearance(body_parts(mp, r), envelope)


assert N_ARCS == 4
