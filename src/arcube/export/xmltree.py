"""The MJCF element builders of :mod:`arcube.export.mjcf`: a body built in the assembled pose (frame
parallel to the patient frame R_w, positions in mm) with its hinges, geoms, sites and inertial, and
number formatting."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.export.inertia import Inertial, principal_axes

__all__ = ["COLORS", "XmlBody", "mesh_items", "num", "vec"]

COLORS = {
    "base": "0.35 0.35 0.40 1",
    "actuator": "0.15 0.15 0.18 1",
    "tls": "0.30 0.45 0.75 1",
    "tms": "0.90 0.55 0.15 1",
    "zdyad": "0.60 0.40 0.80 1",
    "platform": "0.80 0.80 0.30 1",
    "rts": "0.25 0.70 0.40 1",
    "tool": "0.85 0.85 0.90 1",
    "motor": "0.20 0.20 0.25 1",
    "anatomy": "0.95 0.85 0.75 0.35",
    "envelope": "0.56 0.66 0.78 0.12",
}
"""Colours (rgba) of the geoms by part."""


def num(x: float) -> str:
    """A finite number as MJCF text (the shortest repr; InputError for a non-finite one)."""
    v = float(x) + 0.0
    if not math.isfinite(v):
        raise InputError("MJCF export: a computed position is not finite (degenerate pose)")
    return repr(v)


def vec(v: ArrayLike) -> str:
    """Numbers as space-separated MJCF text."""
    return " ".join(num(x) for x in np.asarray(v, dtype=float).reshape(-1))


class XmlBody:
    """A body built in the assembled pose: frame parallel to the patient frame, origin at ``origin`` (R_w)."""

    def __init__(
        self, parent_el: ET.Element, name: str, origin: NDArray[np.float64], parent_origin: NDArray[np.float64] | None
    ):
        self.origin = np.asarray(origin, dtype=float)
        attrs = {"name": name}
        if parent_origin is not None:
            attrs["pos"] = vec(self.origin - parent_origin)
        self.el = ET.SubElement(parent_el, "body", attrs)
        self.name = name
        self.registry: dict[str, XmlBody] = {name: self}

    def child(self, name: str, origin: NDArray[np.float64]) -> XmlBody:
        body = XmlBody(self.el, name, origin, self.origin)
        body.registry = self.registry  # one name -> body map for the whole tree
        self.registry[name] = body
        return body

    def local(self, p: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(p, dtype=float) - self.origin

    def hinge(self, name: str, point: ArrayLike, axis: ArrayLike, ref: float, cls: str) -> None:
        ax = np.asarray(axis, dtype=float)
        ax = ax / np.linalg.norm(ax)
        ET.SubElement(
            self.el,
            "joint",
            {
                "name": name,
                "class": cls,
                "type": "hinge",
                "pos": vec(self.local(point)),
                "axis": vec(ax),
                "ref": num(ref),
            },
        )

    def capsule(self, name: str, a: ArrayLike, b: ArrayLike, radius: float, color: str) -> None:
        pa, pb = self.local(a), self.local(b)
        if np.linalg.norm(pb - pa) < 1e-6:
            self.sphere(name, a, radius, color)
            return
        ET.SubElement(
            self.el,
            "geom",
            {
                "name": name,
                "type": "capsule",
                "fromto": vec(np.concatenate([pa, pb])),
                "size": num(radius),
                "rgba": COLORS[color],
            },
        )

    def sphere(self, name: str, p: ArrayLike, radius: float, color: str) -> None:
        ET.SubElement(
            self.el,
            "geom",
            {"name": name, "type": "sphere", "pos": vec(self.local(p)), "size": num(radius), "rgba": COLORS[color]},
        )

    def polyline(self, name: str, pts: NDArray[np.float64], radius: float, color: str) -> None:
        for j in range(len(pts) - 1):
            self.capsule(f"{name}_{j}", pts[j], pts[j + 1], radius, color)

    def inertial(self, part: Inertial) -> None:
        """The body's mass, centre of mass and principal inertia (first child element)."""
        moments, axes = principal_axes(part.inertia)
        attrs = {
            "pos": vec(self.local(part.com)),
            "mass": num(part.mass),
            "diaginertia": vec(moments),
            "xyaxes": vec(np.concatenate([axes[:, 0], axes[:, 1]])),
        }
        self.el.insert(0, ET.Element("inertial", attrs))

    def site(
        self, name: str, p: ArrayLike, zaxis: ArrayLike | None = None, size: float = 2.0, group: int | None = None
    ) -> None:
        attrs = {"name": name, "pos": vec(self.local(p)), "size": num(size)}
        if group is not None:
            attrs["group"] = str(group)
        if zaxis is not None:
            attrs["zaxis"] = vec(zaxis)
        ET.SubElement(self.el, "site", attrs)


def mesh_items(anatomy: Any) -> list[Any]:
    """The triangle meshes of an anatomy (an Anatomy, meshes, one mesh or None); InputError otherwise."""
    if anatomy is None:
        return []
    meshes = getattr(anatomy, "meshes", anatomy)  # an arcube Anatomy, or a sequence of trimesh meshes
    if hasattr(meshes, "vertices") and hasattr(meshes, "faces"):
        meshes = [meshes]
    items = list(meshes)
    for i, m in enumerate(items):
        if not (hasattr(m, "vertices") and hasattr(m, "faces")):
            raise InputError(f"anatomy item {i}: not a triangle mesh (needs vertices and faces)")
    return items
