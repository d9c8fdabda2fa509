"""The grids of signed distance (:class:`DistanceGrid`, :func:`grid_for_bounds`) and the two-level
lookup the clearance reads (:class:`AnatomyDistance`); node values are filled by ``_boxes`` or ``_mesh``.
Conventions and accuracy: see :mod:`arcube.evaluation.sdf`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.progress import GRIDS, tell

from arcube.evaluation.sdf._boxes import _box_arrays, _boxes_bounds, _boxes_on_grid
from arcube.evaluation.sdf._mesh import _Shells

__all__ = ["AnatomyDistance", "DistanceGrid", "GridLayout", "MAX_GRID_BYTES", "grid_for_bounds"]

MAX_GRID_BYTES = 4 * 2**30
"""Largest memory the two distance grids of an anatomy may take (a few metres of mesh read in the
wrong unit would ask for hundreds of GiB)."""


@dataclass(frozen=True)
class DistanceGrid:
    """Signed distance sampled on a regular grid (patient frame, mm).

    Attributes:
        origin: (3,) float64, position of node (0, 0, 0).
        spacing: node spacing, mm.
        values: (nx, ny, nz) float64, C-contiguous, values[i, j, k] = signed distance at
            ``origin + spacing * (i, j, k)``; every n >= 2.
    """

    origin: np.ndarray
    spacing: float
    values: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", np.ascontiguousarray(self.origin, dtype=np.float64).reshape(3))
        object.__setattr__(self, "spacing", float(self.spacing))
        object.__setattr__(self, "values", np.ascontiguousarray(self.values, dtype=np.float64))
        if self.values.ndim != 3 or min(self.values.shape) < 2 or not self.spacing > 0:
            raise ValueError("DistanceGrid needs values of shape (nx, ny, nz), every n >= 2, and spacing > 0")

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.values.shape  # type: ignore[return-value]

    @property
    def lo(self) -> np.ndarray:
        """Lower corner of the box of nodes."""
        return self.origin.copy()

    @property
    def hi(self) -> np.ndarray:
        """Upper corner of the box of nodes (the last node)."""
        return self.origin + self.spacing * (np.array(self.values.shape, dtype=np.float64) - 1.0)

    def contains(self, points: Any) -> np.ndarray:
        """(...,) bool: points inside the (closed) box of nodes."""
        p = np.asarray(points, dtype=np.float64)
        return np.all((p >= self.lo) & (p <= self.hi), axis=-1)

    def __call__(self, points: Any) -> np.ndarray:
        """Signed distance at ``points`` (..., 3) -> (...): trilinear inside, |p - q| + value(q) outside."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError("points must have shape (..., 3)")
        flat = p.reshape(-1, 3)
        q = np.clip(flat, self.lo, self.hi)
        t = (q - self.origin) / self.spacing
        n = np.array(self.values.shape)
        i0 = np.clip(np.floor(t).astype(np.int64), 0, n - 2)
        f = t - i0
        v = self.values
        out = np.zeros(len(flat))
        for dx in (0, 1):
            wx = f[:, 0] if dx else 1.0 - f[:, 0]
            for dy in (0, 1):
                wy = f[:, 1] if dy else 1.0 - f[:, 1]
                for dz in (0, 1):
                    wz = f[:, 2] if dz else 1.0 - f[:, 2]
                    out += wx * wy * wz * v[i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz]
        out += np.linalg.norm(flat - q, axis=1)
        return out.reshape(p.shape[:-1])

    def nodes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The node coordinates along x, y and z (1-D arrays)."""
        return tuple(self.origin[a] + self.spacing * np.arange(self.values.shape[a]) for a in range(3))  # type: ignore[return-value]


def grid_for_bounds(
    lo: Sequence[float], hi: Sequence[float], spacing: float, margin: float
) -> tuple[np.ndarray, tuple[int, int, int]]:
    """Origin and shape of the grid of the given spacing that covers [lo − margin, hi + margin].

    Nodes sit on multiples of ``spacing``: origin = floor((lo − margin) / spacing) · spacing.
    """
    if not spacing > 0 or not margin >= 0:
        raise ValueError("spacing must be > 0 and margin >= 0")
    lo_a = np.asarray(lo, dtype=np.float64) - margin
    hi_a = np.asarray(hi, dtype=np.float64) + margin
    origin = np.floor(lo_a / spacing + 1e-9) * spacing
    n = np.ceil((hi_a - origin) / spacing - 1e-9).astype(np.int64) + 1
    n = np.maximum(n, 2)
    return origin, (int(n[0]), int(n[1]), int(n[2]))


@dataclass(frozen=True)
class GridLayout:
    """Where the two distance grids of :class:`AnatomyDistance` lie, mm: a fine grid close around the anatomy (the
    clearances that decide a design) and a coarse one far around it (a link well away from it)."""

    fine_spacing: float = 1.0
    """Node spacing of the fine grid, mm."""
    fine_margin: float = 30.0
    """How far the fine grid reaches beyond the anatomy's bounding box, mm."""
    coarse_spacing: float = 6.0
    """Node spacing of the coarse grid, mm."""
    coarse_margin: float = 400.0
    """How far the coarse grid reaches beyond the anatomy's bounding box, mm."""


@dataclass(frozen=True)
class AnatomyDistance:
    """Signed distance to the anatomy: a fine grid near it, a coarse one around it.

    Attributes:
        fine: grid over the anatomy's bounding box + ``fine_margin`` (default 1 mm spacing, 30 mm).
        coarse: grid over the bounding box + ``coarse_margin`` (default 6 mm spacing, 400 mm).
        bounds: (lo, hi), each (3,), the anatomy's axis-aligned bounding box (patient frame, mm).
    """

    fine: DistanceGrid
    coarse: DistanceGrid
    bounds: tuple[np.ndarray, np.ndarray]

    def __call__(self, points: Any) -> np.ndarray:
        """Signed distance (..., 3) -> (...): the fine grid where p is in its box, else the coarse one."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError("points must have shape (..., 3)")
        flat = p.reshape(-1, 3)
        in_fine = self.fine.contains(flat)
        out = np.empty(len(flat))
        if in_fine.any():
            out[in_fine] = self.fine(flat[in_fine])
        if (~in_fine).any():
            out[~in_fine] = self.coarse(flat[~in_fine])
        return out.reshape(p.shape[:-1])

    @property
    def nbytes(self) -> int:
        """Memory held by the two grids' values, bytes."""
        return int(self.fine.values.nbytes + self.coarse.values.nbytes)

    @classmethod
    def from_meshes(cls, meshes: Sequence[Any], **layout: float) -> AnatomyDistance:
        """Grids of the union of closed meshes (each connected shell is one solid), laid out by ``layout``: the fields
        of :class:`GridLayout` (mm), e.g. ``coarse_margin=60.0``, its defaults for the others.

        Node values are exact: the distance to each shell at the nodes of its bounding box and
        the distance of every node outside all shells to the nearest triangle, both by an
        exact search in a bounding-volume hierarchy (compiled); inside/outside of each shell by
        libigl's fast winding number near its surface and once per connected region away from
        it (see ``_Shells.on_grid``).
        """
        grids_at = GridLayout(**layout)  # a wrong keyword before the slow work
        if not isinstance(meshes, (list, tuple)):
            meshes = [meshes]
        shells = _Shells(meshes)
        total, done = 2 * (len(shells.shells) + 1), [0]

        def tick() -> None:
            done[0] += 1
            tell(GRIDS, done[0], total)

        tell(GRIDS, 0, total)
        return cls._build(
            shells.lo,
            shells.hi,
            lambda o, sh, h: shells.on_grid(o, sh, h, tick),
            grids_at,
        )

    @classmethod
    def from_boxes(cls, boxes: Iterable[Any], **layout: float) -> AnatomyDistance:
        """Grids of a union of boxes, each ``(centre, half_extents, rotation)``, by the exact box formula; ``layout``
        as in :meth:`from_meshes`."""
        grids_at = GridLayout(**layout)
        arrays = _box_arrays(boxes)
        lo, hi = _boxes_bounds(*arrays)
        return cls._build(lo, hi, lambda o, s, h: _boxes_on_grid(o, s, h, arrays), grids_at)

    @classmethod
    def _build(cls, lo: np.ndarray, hi: np.ndarray, fill: Any, grids_at: GridLayout) -> AnatomyDistance:
        layout = [
            (spacing, *grid_for_bounds(lo, hi, spacing, margin))
            for spacing, margin in (
                (grids_at.fine_spacing, grids_at.fine_margin),
                (grids_at.coarse_spacing, grids_at.coarse_margin),
            )
        ]
        need = sum(8 * int(np.prod(shape, dtype=np.float64)) for _, _, shape in layout)
        if need > MAX_GRID_BYTES:  # checked before anything is allocated
            extent = np.asarray(hi, float) - np.asarray(lo, float)
            raise InputError.of(
                "anatomy",
                f"spans {extent[0]:.4g} x {extent[1]:.4g} x {extent[2]:.4g} mm: its distance grids would need "
                f"{need / 2**30:.1f} GiB (at most {MAX_GRID_BYTES / 2**30:.0f}); is it in mm "
                "(not um or m) and only the operated region?",
            )
        grids = [
            DistanceGrid(origin, spacing, fill(origin, shape, float(spacing))) for spacing, origin, shape in layout
        ]
        return cls(
            grids[0], grids[1], (np.asarray(lo, dtype=np.float64).copy(), np.asarray(hi, dtype=np.float64).copy())
        )
