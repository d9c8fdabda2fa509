"""Segmentations in (issue 33): cost of reading a label map and of its distance grids, and the clearances it gives.

The mean patient's default anatomy (the bundled reference patient's, MODEL.md 14.2) written as a
``.seg.nrrd`` and a ``.nii.gz`` at ``--spacing`` mm (:mod:`arcube.patients.anatomy_segments`), then:

* write, read (marching cubes of every segment) and distance-grid times, and the triangle count;
* the process cache: loading the same file again returns the same anatomy (no second read, no second grid);
* the clearance (MODEL.md 14.3) of Table 2's links placed for the right side (the README's example
  design) on the reference plan's right side, per point, to the vertebrae C3-C7 read from the
  segmentation against the same vertebrae as boxes (the STL's), in the NumPy reference and the
  compiled kernel. Vertebrae only: this design's body goes through the soft tissue, and inside a
  solid the two differ by construction (the STL's boxes overlap, the label map's soft tissue has
  the bone carved out), so the comparison is made where the body clears the bone.

Rerun: ``.venv/bin/python benchmarks/bench_segmentation.py [--spacing 1.0] [--points 10]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import arcube
from arcube.evaluation.anatomy import Anatomy, load_anatomy
from arcube.io.segmentations import read_segmentation
from arcube.patients import draw_parameters
from arcube.patients.anatomy import reference_anatomy_boxes
from arcube.patients.anatomy_segments import write_anatomy_as


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spacing", type=float, default=1.0, help="voxel size, mm")
    ap.add_argument("--points", type=int, default=10, help="points per trajectory")
    args = ap.parse_args()
    params = draw_parameters(None)
    with tempfile.TemporaryDirectory() as tmp:
        paths = {}
        for fmt in ("seg.nrrd", "nii.gz"):
            path = Path(tmp) / f"mean.anatomy.{fmt}"
            t = time.perf_counter()
            write_anatomy_as(params, path, fmt, args.spacing)
            t_write = time.perf_counter() - t
            t = time.perf_counter()
            seg = read_segmentation(path)
            t_read = time.perf_counter() - t
            tri = sum(len(m.faces) for m in seg.meshes)
            print(f"{fmt:8s} at {args.spacing:g} mm: grid {seg.shape}, {path.stat().st_size / 1e3:.0f} kB, "
                  f"write {t_write:.2f} s, read {t_read:.2f} s, {len(seg.meshes)} segments, {tri} triangles")
            paths[fmt] = path
        seg_path = str(paths["seg.nrrd"])
        t = time.perf_counter()
        anatomy = load_anatomy([seg_path])
        t_load = time.perf_counter() - t
        t = time.perf_counter()
        grid = anatomy.distance
        t_grid = time.perf_counter() - t
        t = time.perf_counter()
        again = load_anatomy([seg_path])
        t_again = time.perf_counter() - t
        print(f"load_anatomy {t_load:.2f} s, distance grids {t_grid:.1f} s ({grid.nbytes / 2**20:.0f} MiB; fine "
              f"{grid.fine.values.shape}, coarse {grid.coarse.values.shape}); loaded again: same anatomy "
              f"{again is anatomy}, same grids {again.distance is grid}, {t_again * 1e3:.1f} ms")
        design = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
        t = time.perf_counter()
        bones_seg = load_anatomy([seg_path], segments="C3,C4,C5,C6,C7")
        bones_seg.distance
        t_bones = time.perf_counter() - t
        boxes = [b for b in reference_anatomy_boxes() if b.kind == "bone"]
        bones_stl = Anatomy(tuple(b.mesh() for b in boxes), "C3-C7 boxes", boxes=tuple(boxes))
        print(f"vertebrae C3-C7 only: {sum(len(m.faces) for m in bones_seg.meshes)} triangles, read + grids {t_bones:.1f} s")
        rows = {}
        for engine in ("numpy", "numba"):
            for name, anat in (("stl", bones_stl), ("seg.nrrd", bones_seg)):
                ev = arcube.evaluate(design, "reference", side="R", points=args.points, engine=engine, anatomy=anat,
                                     clearance=5.0)
                rows[engine, name] = np.array([p["clearance_mm"] if p["clearance_mm"] is not None else np.nan
                                               for p in ev.to_json()["points"]])
        ok = np.isfinite(rows["numpy", "stl"])
        out = ok & (rows["numpy", "stl"] > 0)  # inside a vertebra, body and arch overlap as boxes, not in the label map
        for engine in ("numpy", "numba"):
            diff = rows[engine, "seg.nrrd"] - rows[engine, "stl"]
            print(f"{engine}: clearance seg.nrrd - STL at the {out.sum()} of {ok.sum()} points where the body clears the "
                  f"STL anatomy: max |diff| {np.abs(diff[out]).max():.3f} mm, mean {diff[out].mean():+.3f} mm (half voxel "
                  f"diagonal {args.spacing * np.sqrt(3) / 2:.3f} mm); all points: max |diff| {np.abs(diff[ok]).max():.3f} mm; "
                  f"smallest clearance {np.nanmin(rows[engine, 'seg.nrrd']):.2f} mm (STL {np.nanmin(rows[engine, 'stl']):.2f})")
        for name in ("stl", "seg.nrrd"):
            same = np.abs(rows["numpy", name][ok] - rows["numba", name][ok]).max()
            print(f"numpy vs numba on the {name} anatomy: max |diff| {same:.2e} mm")

if __name__ == "__main__":
    main()
