"""The picture of docs/img/segmentation.png: a segmented anatomy read from a .seg.nrrd, beside the robot.

The mean patient's default anatomy (the bundled reference patient's) is written as a 3D Slicer
segmentation at 1 mm (:func:`arcube.patients.segmentation.write_anatomy_as`), read back through
the anatomy path (:func:`arcube.evaluation.anatomy.load_anatomy`: marching cubes of every segment,
patient frame), and drawn with matplotlib: vertebrae C3-C7 in their segment colours, soft tissue
translucent. The robot is Table 2's links placed for the right side (the README's example design),
drawn from :func:`arcube.model.body.mechanism_points` at the first reachable point of the right
side's middle trajectory, with the report's trace layout (:mod:`arcube.report.mechanism3d`).

Run: ``.venv/bin/python examples/segmentation_picture.py [OUT.png]`` (default docs/img/segmentation.png).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import nrrd  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import arcube  # noqa: E402
from arcube.evaluation.anatomy import load_anatomy  # noqa: E402
from arcube.coerce import mode_signs  # noqa: E402
from arcube.model.body import mechanism_points  # noqa: E402
from arcube.patients import draw_parameters  # noqa: E402
from arcube.patients.segmentation import write_anatomy_as  # noqa: E402
from arcube.report.mechanism3d import SCENE_TRACES, STYLE, mechanism_extent, mechanism_traces  # noqa: E402


def main(out: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mean.anatomy.seg.nrrd"
        write_anatomy_as(draw_parameters(None), path, "seg.nrrd", 1.0)
        anatomy = load_anatomy([str(path)])
        header = nrrd.read_header(str(path))
    colours = {header[f"Segment{n}_Name"]: [float(c) for c in header[f"Segment{n}_Color"].split()]
               for n in range(len(anatomy.segments))}
    design = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
    ev = arcube.evaluate(design, "reference", side="R", points=10)
    reach = ev.results.points.reachable
    per = ev.task.n_points
    middle = len(ev.task.ids) // 2
    row = middle * per + int(np.flatnonzero(reach[middle * per:(middle + 1) * per])[0])
    mp = mechanism_points(design.to_vector(), ev.task.E[row:row + 1], ev.task.e[row:row + 1], mode_signs(ev.mode))

    fig = plt.figure(figsize=(9, 7), dpi=120)
    ax = fig.add_subplot(projection="3d")
    for info, mesh in zip(anatomy.segments, anatomy.meshes):
        soft = info.name == "soft tissue"
        tri = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
        ax.add_collection3d(Poly3DCollection(tri, facecolors=[[0.95, 0.6, 0.5, 0.09] if soft else colours[info.name] + [0.95]],
                                             edgecolor="none", shade=not soft, label=f"{info.name} ({info.voxels} voxels)"))
    for name, data in zip(SCENE_TRACES, mechanism_traces(mp, 0)):
        style = STYLE[name]
        xyz = [np.array([np.nan if v is None else v for v in data[c]]) for c in "xyz"]
        colour = style.get("line", style.get("marker", {})).get("color", "black")
        width = style.get("line", {}).get("width", 3) / 2.5
        ax.plot(*xyz, color=colour, lw=width, marker="o" if "markers" in style["mode"] else None, ms=2)
    entry, target = np.asarray(ev.trajectories.entry), np.asarray(ev.trajectories.target)
    for a, b in zip(entry, target):
        ax.plot(*np.stack([a, b]).T, color="#17becf", lw=1.5)
    robot = mechanism_extent(mp, np.array([0]))
    lo = np.min([np.asarray(m.vertices).min(axis=0) for m in anatomy.meshes] + [np.nanmin(robot, axis=0)], axis=0)
    hi = np.max([np.asarray(m.vertices).max(axis=0) for m in anatomy.meshes] + [np.nanmax(robot, axis=0)], axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x right (mm)")
    ax.set_ylabel("y superior (mm)")
    ax.set_zlabel("z posterior (mm)")
    ax.view_init(elev=22, azim=-58)
    ax.set_title("Mean patient's anatomy read from a .seg.nrrd (C3-C7, soft tissue) beside the robot", fontsize=10)
    ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    print(f"wrote {out}: segments {', '.join(s.name for s in anatomy.segments)}; robot at point {row} of the right side")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "docs" / "img" / "segmentation.png")
