"""Clearance of the robot's body (model §14.3): to the patient's anatomy and between its own parts.

NumPy reference (the compiled kernel computes the same with a branch-and-bound search):

* :func:`anatomy_clearance`: for each primitive of the body (:func:`arcube.model.body.body_parts`:
  segments, points, great-circle arcs), the smallest signed distance from its axis to the
  anatomy (negative inside), minus its radius; the minimum over primitives and the part that
  attains it. The axis is sampled every ``step`` mm (default 0.25), so the sampled minimum of the
  distance field is within ``step/2`` of the axis's true minimum (a distance is 1-Lipschitz);
  the distance field itself is the anatomy's grid (:mod:`arcube.evaluation.sdf`).
* :func:`self_clearance`: the smallest distance between the primitives of
  :data:`arcube.model.body.SELF_PAIRS` (different legs or stages, no shared joint, no two arcs),
  minus both radii. Segments and points by the exact closest-point formula; an arc by the
  polyline of :data:`ARC_CHORDS` chords through its end points (sag r (1 - cos(theta/24)), at most
  0.15 mm for a 90-degree arc of r = 80 mm), the same polyline in the kernel.

Leading axes broadcast (designs, points); NaN where the IK has no solution.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from arcube.model.body import N_ARCS, N_SEGMENTS, N_SPHERES, PRIMITIVE_PART, SELF_PAIRS, BodyParts, great_circle

ARC_CHORDS = 12
"""Chords per spherical arc in the self clearance."""
SAMPLE_STEP_MM = 0.25
"""Spacing of the reference's samples along every axis (mm)."""

Distance = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def _fractions(length: NDArray[np.float64], n: int, step: float) -> NDArray[np.float64]:
    """``(..., max(n, 2))`` fractions of an axis at arc lengths 0, step, 2 step, ..., clamped to its end."""
    s = np.arange(max(n, 2)) * step
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.minimum(s, length[..., None]) / length[..., None]
    return np.where(length[..., None] > 0.0, f, 0.0)


def _min_along(distance: Distance, pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """min over the sample axis (-2) of distance(pts), NaN where a sample is NaN."""
    bad = ~np.all(np.isfinite(pts), axis=-1)
    d = distance(np.where(bad[..., None], 0.0, pts))
    d = np.where(bad, np.nan, d)
    return np.min(d, axis=-1)


def anatomy_clearance(
    parts: BodyParts, distance: Distance, step: float = SAMPLE_STEP_MM
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """(clearance ``(...)`` mm, index into PART_NAMES ``(...)``, -1 where undefined) of the body to the anatomy.

    ``distance`` maps points ``(..., 3)`` in R_w to signed distances ``(...)`` (negative inside).
    """
    per_primitive = []
    seg = parts.segments
    length = np.linalg.norm(seg[..., 1, :] - seg[..., 0, :], axis=-1)  # (..., 18)
    for s in range(N_SEGMENTS):
        # samples at arc lengths 0, step, 2 step, ... and the end: where each lies does not depend on the batch
        n = int(np.ceil(np.nanmax(length[..., s], initial=0.0) / step)) + 1
        t = _fractions(length[..., s], n, step)
        a, b = seg[..., s, None, 0, :], seg[..., s, None, 1, :]
        per_primitive.append(_min_along(distance, a + t[..., None] * (b - a)))
    for k in range(N_SPHERES):
        per_primitive.append(_min_along(distance, parts.spheres[..., k, None, :]))
    ends = parts.arc_ends
    angle = np.arccos(np.clip(np.sum(ends[..., 0, :] * ends[..., 1, :], axis=-1), -1.0, 1.0))  # (..., 4)
    for k in range(N_ARCS):
        arc_length = parts.arc_radius * angle[..., k]
        n = int(np.ceil(np.nanmax(arc_length, initial=0.0) / step)) + 1
        phi = _fractions(arc_length, n, step) * angle[..., k, None]  # (..., n) angles from the start
        a, b = ends[..., k, 0, :], ends[..., k, 1, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            nrm = b - np.sum(a * b, axis=-1, keepdims=True) * a
            nrm = nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)
        nrm = np.where(np.isfinite(nrm), nrm, 0.0)  # a zero-length arc: its start point only
        dirs = a[..., None, :] * np.cos(phi)[..., None] + nrm[..., None, :] * np.sin(phi)[..., None]
        per_primitive.append(
            _min_along(distance, parts.arc_centre[..., None, :] + parts.arc_radius[..., None, None] * dirs)
        )
    values = np.stack(per_primitive, axis=-1) - parts.radius  # (..., 27)
    defined = np.all(np.isfinite(values), axis=-1)
    best = np.argmin(np.where(np.isfinite(values), values, np.inf), axis=-1)
    clearance = np.where(defined, np.take_along_axis(values, best[..., None], axis=-1)[..., 0], np.nan)
    return clearance, np.where(defined, PRIMITIVE_PART[best], -1)


def segment_distance(
    p1: NDArray[np.float64], q1: NDArray[np.float64], p2: NDArray[np.float64], q2: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance between segments p1-q1 and p2-q2 ``(..., 3)`` -> ``(...)`` (points are zero-length segments).

    The closest-point computation of Ericson, *Real-Time Collision Detection*, 5.1.9, vectorized.
    """
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.sum(d1 * d1, axis=-1)
    e = np.sum(d2 * d2, axis=-1)
    f = np.sum(d2 * r, axis=-1)
    c = np.sum(d1 * r, axis=-1)
    b = np.sum(d1 * d2, axis=-1)
    tiny = 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = a * e - b * b
        s_gen = np.where(denom > 0.0, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t_gen = (b * s_gen + f) / e
        s_low = np.clip(-c / a, 0.0, 1.0)
        s_high = np.clip((b - c) / a, 0.0, 1.0)
        s = np.where(t_gen < 0.0, s_low, np.where(t_gen > 1.0, s_high, s_gen))
        t = np.clip(t_gen, 0.0, 1.0)
        # degenerate segments
        s = np.where(e <= tiny, s_low, s)
        t = np.where(e <= tiny, 0.0, t)
        s = np.where(a <= tiny, 0.0, s)
        t = np.where(a <= tiny, np.where(e <= tiny, 0.0, np.clip(f / e, 0.0, 1.0)), t)
    return np.linalg.norm(p1 + d1 * s[..., None] - (p2 + d2 * t[..., None]), axis=-1)


def arc_chords(parts: BodyParts) -> NDArray[np.float64]:
    """The spherical arcs as polylines of ARC_CHORDS chords through their end points ``(..., 4, ARC_CHORDS, 2, 3)``."""
    with np.errstate(invalid="ignore"):
        dirs = great_circle(parts.arc_ends[..., 0, :], parts.arc_ends[..., 1, :], ARC_CHORDS + 1)  # (..., 4, n+1, 3)
    pts = parts.arc_centre[..., None, None, :] + parts.arc_radius[..., None, None, None] * dirs
    return np.stack([pts[..., :-1, :], pts[..., 1:, :]], axis=-2)


def self_clearance(parts: BodyParts) -> NDArray[np.float64]:
    """Smallest distance between the primitive pairs of :data:`SELF_PAIRS`, minus both radii, ``(...)`` mm."""
    n_lines = N_SEGMENTS + N_SPHERES
    lines = np.concatenate(
        [parts.segments, np.stack([parts.spheres, parts.spheres], axis=-2)], axis=-3
    )  # (..., 23, 2, 3)
    i, j = SELF_PAIRS[:, 0], SELF_PAIRS[:, 1]  # i < j; two arcs are never paired, so only j can be an arc
    straight = j < n_lines
    i_s, j_s = i[straight], j[straight]
    d_s = segment_distance(lines[..., i_s, 0, :], lines[..., i_s, 1, :], lines[..., j_s, 0, :], lines[..., j_s, 1, :])
    i_a, j_a = i[~straight], j[~straight] - n_lines
    chords = arc_chords(parts)[..., j_a, :, :, :]  # (..., n_arc_pairs, n, 2, 3)
    A = lines[..., i_a, None, :, :]
    d_a = np.min(segment_distance(A[..., 0, :], A[..., 1, :], chords[..., 0, :], chords[..., 1, :]), axis=-1)
    d = (
        np.concatenate([d_s, d_a], axis=-1)
        - parts.radius[np.concatenate([i_s, i[~straight]])]
        - parts.radius[np.concatenate([j_s, j[~straight]])]
    )
    return np.min(d, axis=-1)
