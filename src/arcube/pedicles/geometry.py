"""The pedicle of each screw (model §22.1) and the breach test at its isthmus (22.3).

Screw j of a plan: entry A, target B, u = (B - A)/|B - A| (into the bone). Its isthmus is the plane
perpendicular to u through I = A + s u (s the isthmus depth); there the bone is an ellipse centred on
the planned axis, half-width a = W/2 along w = P_perp x / |P_perp x| (x the patient's right,
P_perp = I - u u^T) and half-height b = H/2 along h = u x w. Medial is the one of +-w that points to the
patient's other side (-x for a right screw, +x for a left one); cranial the one of +-h with +y.

A screw of diameter d leaves the room a' = a - d/2, b' = b - d/2. A screw wider than its pedicle
(a' <= 0 or b' <= 0) breaches whatever the errors (``too_wide``). Otherwise an offset
delta = (w^T D, h^T D) of the hole at the isthmus breaches when (delta_w/a')^2 + (delta_h/b')^2 > 1;
its direction is medial or lateral when |delta_w|/a' >= |delta_h|/b', else cranial or caudal; its depth
g = max(|delta_w| - a', |delta_h| - b', 0), graded as Gertzbein-Robbins (A none, B < 2 mm, C < 4, D < 6,
E >= 6 mm), a major breach C or worse.

Arrays: a plan's J screws, offsets ``(..., J, 2)`` for any leading axes (samples).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.io.trajectories import PEDICLE_COLUMNS
from arcube.patients.isthmus import DEFAULT_SCREW_MM, isthmus_mean

__all__ = [
    "DEFAULT_ISTHMUS_DEPTH_MM",
    "DEFAULT_SCREW_MM",
    "DIRECTIONS",
    "GRADES",
    "Pedicles",
    "breach_depth",
    "classify",
    "pedicles",
]

DEFAULT_ISTHMUS_DEPTH_MM = 12.0
"""s where the plan does not give ``isthmus_depth_mm`` (model §22.1), mm."""
DIRECTIONS = ("medial", "lateral", "cranial", "caudal")
"""The direction codes 0-3 of :func:`classify` (-1: no breach)."""
GRADES = ((0.0, "A"), (0.0, "B"), (2.0, "C"), (4.0, "D"), (6.0, "E"))
"""Gertzbein-Robbins by breach depth g (mm): A none, B 0 < g < 2, C 2 <= g < 4, D 4 <= g < 6, E g >= 6."""
MAJOR_MM = 2.0
"""A major breach is grade C or worse: g >= 2 mm."""


@dataclass(frozen=True)
class Pedicles:
    """The J screws of a plan at their isthmus, each field ``(J,)`` or ``(J, 3)``; mm."""

    ids: tuple[str, ...]
    levels: tuple[str, ...]
    sides: tuple[str, ...]
    isthmus: NDArray[np.float64]  # (J, 3) I = A + s u
    u: NDArray[np.float64]  # (J, 3) into the bone
    w: NDArray[np.float64]  # (J, 3) medio-lateral axis of the ellipse (+x component)
    h: NDArray[np.float64]  # (J, 3) cranio-caudal axis, u x w
    medial: NDArray[np.float64]  # (J,) +1 where +w is medial, -1 where -w is
    cranial: NDArray[np.float64]  # (J,) +1 where +h is cranial, -1 where -h is
    width: NDArray[np.float64]  # (J,) W
    height: NDArray[np.float64]  # (J,) H
    depth: NDArray[np.float64]  # (J,) s
    screw: NDArray[np.float64]  # (J,) d

    @property
    def room(self) -> NDArray[np.float64]:
        """(J, 2) the room a' = W/2 - d/2 and b' = H/2 - d/2 on each side, mm."""
        return np.stack([0.5 * (self.width - self.screw), 0.5 * (self.height - self.screw)], axis=-1)

    @property
    def too_wide(self) -> NDArray[np.bool_]:
        """(J,) the screw is wider (or taller) than its pedicle: it breaches whatever the errors."""
        return np.any(self.room <= 0.0, axis=-1)

    def offsets(self, D: ArrayLike) -> NDArray[np.float64]:
        """The hole's offsets ``(..., J, 2)`` (w^T D, h^T D) in the isthmus planes, from displacements D ``(..., J, 3)`` mm."""
        d = np.asarray(D, dtype=float)
        return np.stack([np.sum(d * self.w, axis=-1), np.sum(d * self.h, axis=-1)], axis=-1)


def pedicles(plan: object, screw_mm: float | None = None) -> Pedicles:
    """The pedicles of a plan's screws (:class:`~arcube.io.TrajectorySet`): W, H, s and d from its pedicle columns, else
    the level's mean W and H (MORPHOMETRY.md section 6), s = 12 mm and d = ``screw_mm`` (default 3.5 mm).

    Raises:
        InputError: a screw without a side, or without a width or height and a level in C3-C7 to take its mean from.
    """
    ids, levels, sides = tuple(plan.ids), tuple(plan.levels), tuple(plan.sides)  # type: ignore[attr-defined]
    A, B = np.asarray(plan.entry, dtype=float), np.asarray(plan.target, dtype=float)  # type: ignore[attr-defined]
    J = len(ids)
    given = (
        np.full((J, len(PEDICLE_COLUMNS)), np.nan) if plan.pedicle is None else np.asarray(plan.pedicle, dtype=float)
    )  # type: ignore[attr-defined]
    mean = np.array([isthmus_mean(lv) for lv in levels]).reshape(J, 2)
    width = np.where(np.isnan(given[:, 0]), mean[:, 0], given[:, 0])
    height = np.where(np.isnan(given[:, 1]), mean[:, 1], given[:, 1])
    for j in range(J):
        if sides[j] not in ("R", "L"):
            raise InputError(
                f"{plan.source} trajectory {ids[j]}: a screw needs its side (R or L) to tell medial from lateral"
            )  # type: ignore[attr-defined]
        if np.isnan(width[j]) or np.isnan(height[j]):
            raise InputError(
                f"{plan.source} trajectory {ids[j]}: no pedicle width or height, and level {levels[j]!r} is not C3-C7 "  # type: ignore[attr-defined]
                "(give pedicle_width_mm and pedicle_height_mm)"
            )
    depth = np.where(np.isnan(given[:, 2]), DEFAULT_ISTHMUS_DEPTH_MM, given[:, 2])
    default_screw = DEFAULT_SCREW_MM if screw_mm is None else float(screw_mm)
    screw = np.where(np.isnan(given[:, 3]), default_screw, given[:, 3])
    u = (B - A) / np.linalg.norm(B - A, axis=-1, keepdims=True)
    x_hat = np.array([1.0, 0.0, 0.0])
    px = x_hat - u[:, :1] * u
    norm = np.linalg.norm(px, axis=-1)
    if np.any(norm < 1e-9):
        j = int(np.argmin(norm))
        raise InputError(
            f"{plan.source} trajectory {ids[j]}: runs along the patient's x axis: no medio-lateral direction across it"
        )  # type: ignore[attr-defined]
    w = px / norm[:, None]
    h = np.cross(u, w)
    medial = np.where(np.array(sides) == "R", -1.0, 1.0)  # w has +x: medial is -w on the right, +w on the left
    cranial = np.where(h[:, 1] >= 0.0, 1.0, -1.0)
    return Pedicles(ids, levels, sides, A + depth[:, None] * u, u, w, h, medial, cranial, width, height, depth, screw)


def breach_depth(delta: ArrayLike, room: ArrayLike) -> NDArray[np.float64]:
    """g = max(|delta_w| - a', |delta_h| - b', 0) ``(...)`` mm, for offsets ``(..., 2)`` and the room ``(..., 2)``."""
    return np.maximum(np.max(np.abs(np.asarray(delta, dtype=float)) - np.asarray(room, dtype=float), axis=-1), 0.0)


def classify(delta: ArrayLike, p: Pedicles) -> tuple[NDArray[np.bool_], NDArray[np.int8], NDArray[np.bool_]]:
    """(breach, direction, major), each ``(..., J)``, for offsets ``(..., J, 2)`` at the J isthmuses (model §22.3).

    ``direction`` indexes :data:`DIRECTIONS` (-1 where there is no breach). A too-wide screw breaches in every
    sample; its direction is -1 and its grade not defined (``major`` False): it is reported apart. A non-finite
    offset (a robot that cannot be assembled at the screw) is a breach of undefined direction and grade."""
    d = np.asarray(delta, dtype=float)
    room = p.room
    wide = p.too_wide
    safe = np.where(wide[:, None], 1.0, room)
    finite = np.all(np.isfinite(d), axis=-1)
    rel = np.where(finite[..., None], np.abs(np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0)) / safe, 0.0)
    q = np.sum((np.where(finite[..., None], d, 0.0) / safe) ** 2, axis=-1)
    breach = wide | ~finite | (q > 1.0)
    across = rel[..., 0] >= rel[..., 1]  # medio-lateral (as far out, relative to its room, as cranio-caudal)
    med = d[..., 0] * p.medial > 0.0
    cra = d[..., 1] * p.cranial > 0.0
    direction = np.where(across, np.where(med, 0, 1), np.where(cra, 2, 3)).astype(np.int8)
    direction = np.where(breach & finite & ~wide, direction, np.int8(-1)).astype(np.int8)
    major = breach & finite & ~wide & (breach_depth(np.where(finite[..., None], d, 0.0), room) >= MAJOR_MM)
    return breach, direction, major
