"""Signed distance to the anatomy on grids, for the clearance of model §14.3.

Modules: :mod:`~arcube.evaluation.sdf.grid` (the public :class:`DistanceGrid`, :func:`grid_for_bounds` and
:class:`AnatomyDistance`), ``_boxes`` (exact box distances, compiled grid fill) and ``_mesh`` (triangle BVH,
compiled exact mesh distance, inside/outside by winding number). The names below are re-exported here.

The anatomy is a union of closed solids (meshes of :mod:`arcube.io.meshes`, or the boxes of
:mod:`arcube.patients.anatomy`). Its signed distance at a point p is the minimum over the
solids of each solid's own signed distance:

    sd(p) = min_s sd_s(p),   sd_s(p) = +dist(p, ∂s) outside s, −dist(p, ∂s) inside s.

Outside every solid this is exactly the Euclidean distance to the union. Inside, it is minus
the depth into the *deepest* solid containing p, which is never deeper than the true depth
into the union (where solids overlap, the union can be deeper): it is negative exactly
inside the union, and exact wherever one solid alone is what p is in, e.g. everywhere
outside the overlaps of the default anatomy's boxes.

Grids. :class:`DistanceGrid` stores node values ``values[i, j, k] = sd(origin + spacing ·
(i, j, k))`` (float64, C-contiguous) and reads them by trilinear interpolation inside its box
of nodes; outside that box it returns ``|p − q| + value(q)`` with q the point clamped into the
box. :class:`AnatomyDistance` holds two grids: a fine one (default spacing 1 mm) over the
anatomy's bounding box plus a 30 mm margin, and a coarse one (6 mm) over the bounding box plus
400 mm; a lookup uses the fine grid where p lies in the fine grid's box, else the coarse one.
Node values are exact (up to float64 rounding), whichever way the grid was built; both grids
put their nodes on multiples of their spacing, so fine and coarse nodes coincide where the
coarse spacing is a multiple of the fine one.

Accuracy. sd is 1-Lipschitz, so trilinear interpolation of exact node values is within
(√3/2)·h of the truth anywhere (h = spacing; the weighted mean distance to the cell's corners
is at most half the cell diagonal). That bound is reached only at creases of sd; for the
creases that polyhedral anatomy produces it is much smaller:

* a flat face, or a smooth surface of radius R ≫ h: error ≤ about 3h²/(8R) (0.01 mm for
  h = 1 mm, R = 40 mm); exact (0) next to a flat face, where sd is linear;
* a medial ridge (two surfaces facing each other, e.g. the middle of a gap between two
  solids, or the middle of a box's inside) crossing a cell: ≤ h/2, reached when the ridge
  plane is perpendicular to a grid axis and halfway between two nodes;
* a convex corner (three faces at right angles, e.g. a box vertex) inside a cell: ≤ 0.50·h
  when the box is grid-aligned, and ≤ 0.532·h for boxes rotated arbitrarily (numerical
  maximisation over rotation, vertex position and evaluation point; found at points within
  ~0.1·h of the vertex); the interpolated value is then too large.

So with the default 1 mm fine spacing the error is ≤ 0.5 mm everywhere except within about
0.1 mm of a convex corner of a rotated solid, where it can reach 0.53 mm; a fine spacing of
0.94 mm or less makes 0.5 mm a strict bound. In the coarse region (≥ 30 mm from the anatomy's
bounding box) there are no faces or corners, only ridges and smooth distance, so the error
there is ≤ h/2 = 3 mm for the default coarse spacing (see tests/test_sdf.py for the measured
values). Beyond the coarse box, ``|p − q| + value(q)`` is an upper bound of the distance; the
anatomy sits ≥ 400 mm inside that box, so its excess is a few % of |p − q| at most.

"""

from __future__ import annotations

from arcube.evaluation.sdf._boxes import box_signed_distance
from arcube.evaluation.sdf.grid import AnatomyDistance, DistanceGrid, GridLayout, grid_for_bounds

__all__ = ["AnatomyDistance", "DistanceGrid", "GridLayout", "box_signed_distance", "grid_for_bounds"]
