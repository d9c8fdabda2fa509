"""A built robot read from a file (model §19.1, 19.6): its 22 parameters, working mode and z-dyad elbow, and its
own dockings as warm starts for docking it on a new patient.

A robot file is ``design.json`` of ``arcube design`` (the robot's parameters, ``mode``, ``c_z`` and a ``dockings``
list: each docking's patient, side, placement m and mounting angles, and, from this version on, the entry and target
points of that docking's trajectories), or any docking file (a complete design: its own placement is its one docking).
The robot is used as it is; its dockings only say where to start looking.

A docking file says whose docking it is and which side (``patient``, ``side``): :func:`write_docking` writes them and
:func:`design_at_side` holds a command's side to them (a robot's ``design.json`` and a side give that side's docking).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import load_json, short_repr
from arcube.model.design import PLACEMENT, ROBOT_NAMES, Design

__all__ = [
    "BuiltRobot",
    "PLAN_DIGEST",
    "WarmStart",
    "design_at_side",
    "docking_labels",
    "read_robot",
    "trajectory_digests",
    "write_docking",
]

PLAN_DIGEST = "plan_digest"
"""The key of a docking file that lists its trajectories' digests (:func:`trajectory_digests`): whose plan it docks."""
DIGEST_DECIMALS = 4
"""Entry and target points are compared to 1e-4 mm: a plan written to a file and read back is the same plan."""


def trajectory_digests(entry: np.ndarray, target: np.ndarray) -> tuple[str, ...]:
    """One digest per trajectory: 16 hex digits of the SHA-256 of its entry and target ``(T, 3)`` mm, rounded to
    :data:`DIGEST_DECIMALS`. Two plans share a trajectory when they share its digest, whatever their names."""
    import hashlib

    pts = np.round(np.concatenate([np.asarray(entry, float), np.asarray(target, float)], axis=-1), DIGEST_DECIMALS)
    return tuple(
        hashlib.sha256(",".join(f"{v + 0.0:.{DIGEST_DECIMALS}f}" for v in row).encode()).hexdigest()[:16]
        for row in pts.reshape(-1, 6)
    )


@dataclass(frozen=True)
class WarmStart:
    """One of the robot's own dockings: its placement (m_x, m_y, m_z mm, mount_rx, mount_ry, mount_rz deg) ``(6,)``
    and, when the file records them, the entry and target points ``(T, 3)`` mm of that docking's trajectories."""

    label: str
    placement: np.ndarray
    entry: np.ndarray | None = None
    target: np.ndarray | None = None
    side: str | None = None  # R or L, when the file says
    digests: tuple[str, ...] | None = None  # its trajectories' (trajectory_digests), when the file records them

    def docks(self, digests: tuple[str, ...]) -> bool | None:
        """Whether this docking is of the trajectories ``digests`` (each of them among its own); None when the file
        records no trajectories to tell."""
        own = self.digests
        if own is None and self.entry is not None and self.target is not None:
            own = trajectory_digests(self.entry, self.target)
        return None if own is None else set(digests) <= set(own)


@dataclass(frozen=True)
class BuiltRobot:
    """The robot of a file: ``design`` is complete (its first docking's placement, or zeros without one), with
    ``c_z``, ``mode`` and ``zdyad_elbow``; ``c_z_assumed`` when the file had no c_z (then d_z, model §6)."""

    source: str
    design: Design
    starts: tuple[WarmStart, ...]
    c_z_assumed: bool = False

    def placed(self, placement: np.ndarray) -> Design:
        """The robot at one docking: its parameters unchanged, the placement ``(6,)`` given."""
        return self.design.replace(**dict(zip(PLACEMENT, (float(v) for v in placement))))

    @property
    def values(self) -> dict[str, float]:
        """The robot's 22 parameters (model §19.1) by name, c_z last."""
        d = self.design.to_dict()
        return {**{n: d[n] for n in ROBOT_NAMES if n != "c_z"}, "c_z": float(self.design.c_z_mm)}


def _points(value: Any, key: str, where: str) -> np.ndarray | None:
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {key} must be a list of [x, y, z] points in mm") from None
    if arr.ndim != 2 or arr.shape[1] != 3 or not len(arr) or not np.isfinite(arr).all():
        raise InputError(f"{where}: {key} must be a non-empty list of finite [x, y, z] points in mm")
    return arr


def _placement(entry: Any, where: str) -> np.ndarray:
    if not isinstance(entry, dict):
        raise InputError(f"{where}: expected a table with {', '.join(PLACEMENT)}, got {short_repr(entry)}")
    missing = [n for n in PLACEMENT if n not in entry]
    if missing:
        raise InputError(f"{where}: missing {', '.join(missing)}")
    out = []
    for n in PLACEMENT:
        v = entry[n]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise InputError(f"{where}: {n} must be a finite number, got {short_repr(v)}")
        out.append(float(v))
    return np.array(out)


DOCKING_KEYS = ("patient", "side", *PLACEMENT, "entry", "target")
"""The keys of one entry of a robot's ``dockings`` list (what ``arcube design`` writes)."""


def _check_docking(entry: dict[str, Any], label: str, place: np.ndarray, where: str, before: list[WarmStart]) -> None:
    """InputError for an unknown key, a side other than R, L or both, or an earlier docking's patient, side and
    placement (``label``: ``<patient>_<side>``; ``place`` ``(6,)``)."""
    unknown = [k for k in entry if k not in DOCKING_KEYS]
    if unknown:
        raise InputError(f"{where}: unknown key {short_repr(unknown[0])} (known: {', '.join(DOCKING_KEYS)})")
    side = entry.get("side")
    if side is not None and side not in ("R", "L", "both"):
        raise InputError(f"{where}: side {short_repr(side)}: expected R, L or both")
    twin = next((k for k, w in enumerate(before) if w.label == label and np.array_equal(w.placement, place)), None)
    if twin is not None:
        raise InputError(
            f"{where}: the same patient, side and placement as docking {twin + 1}: one docking given twice"
        )


def read_robot(path: str | os.PathLike[str]) -> BuiltRobot:
    """The robot of ``path`` (a design job's ``design.json`` or a docking file); one-line InputError naming the file
    and what is missing or wrong (a robot parameter, the working mode, a docking's placement)."""
    p = Path(path)
    data = load_json(p)
    if not isinstance(data, dict):
        raise InputError(
            f"{p}: a robot file must hold one JSON object (a design.json of arcube design, or a docking's design file)"
        )
    missing = [n for n in ROBOT_NAMES if n != "c_z" and n not in data]
    if missing:
        raise InputError(
            f"{p}: not a robot: missing robot parameter(s) {', '.join(missing)} (give a design.json of arcube design "
            "or a docking's design file)"
        )
    if data.get("mode") is None:
        raise InputError(
            f'{p}: the robot\'s working mode is missing ("mode": "+,+,+,-"): a built robot has one; add it to the file'
        )
    raw = data.get("dockings")
    if raw is not None and (not isinstance(raw, list) or not raw):
        raise InputError(f"{p}: dockings must be a non-empty list of the robot's dockings")
    starts: list[WarmStart] = []
    for k, entry in enumerate(raw or []):
        where = f"{p}: docking {k + 1}"
        label = (
            f"{entry.get('patient', k + 1)}_{entry.get('side', '')}".rstrip("_")
            if isinstance(entry, dict)
            else str(k + 1)
        )
        placement = _placement(entry, where)
        _check_docking(entry, label, placement, where, starts)
        entry_pts, target_pts = (
            _points(entry.get("entry"), "entry", where),
            _points(entry.get("target"), "target", where),
        )
        if (entry_pts is None) != (target_pts is None) or (
            entry_pts is not None and entry_pts.shape != target_pts.shape
        ):
            raise InputError(f"{where}: entry and target must be given together, one point each per trajectory")
        starts.append(WarmStart(label, placement, entry_pts, target_pts, entry.get("side")))
    values = {n: data[n] for n in ROBOT_NAMES if n != "c_z"}
    if all(n in data for n in PLACEMENT):
        own = _placement(data, str(p))
        if not starts:  # a docking file: its own placement is its one docking
            starts.append(
                WarmStart(
                    str(data.get("patient", "own")) + (f"_{data['side']}" if data.get("side") else ""),
                    own,
                    side=data.get("side"),
                    digests=_digests(data.get(PLAN_DIGEST), str(p)),
                )
            )
    else:
        own = starts[0].placement if starts else np.zeros(len(PLACEMENT))
    values.update(zip(PLACEMENT, (float(v) for v in own)))
    extras = {k: data[k] for k in ("c_z", "mode", "zdyad_elbow") if k in data}
    design = Design.from_dict({**values, **extras}, source=str(p))
    assumed = design.c_z is None
    if assumed:
        design = design.with_extras(c_z=float(design["d_z"]))
    return BuiltRobot(str(p), design, tuple(starts), assumed)


def _digests(value: Any, where: str) -> tuple[str, ...] | None:
    """A docking file's ``plan_digest`` (None when absent); InputError unless a list of 16-hex-digit texts."""
    if value is None:
        return None
    if (
        not isinstance(value, list)
        or not value
        or not all(isinstance(v, str) and len(v) == 16 and all(c in "0123456789abcdef" for c in v) for v in value)
    ):
        raise InputError(
            f"{where}: {PLAN_DIGEST} must be the list of its trajectories' digests (16 hex digits each), "
            f"got {short_repr(value)}"
        )
    return tuple(value)


def write_docking(design: Design, path: str | os.PathLike[str], patient: str, side: str, plan: Any = None) -> None:
    """Write one docking's complete design (atomically): the design file's keys, then ``patient`` and ``side``, and
    with ``plan`` (its TrajectorySet) the digests of its trajectories (``plan_digest``: whose plan it docks)."""
    import json

    from arcube.io.files import atomic_write_text

    data = {**design.to_file_dict(), "patient": patient, "side": side}
    if plan is not None:
        data[PLAN_DIGEST] = list(trajectory_digests(plan.entry, plan.target))
    atomic_write_text(path, json.dumps(data, indent=2) + "\n")


def _design_data(design: Any) -> dict[str, Any] | None:
    """The JSON object of a design file, None for anything else (a Design, a preset, another file)."""
    if not isinstance(design, (str, os.PathLike)):
        return None
    p = Path(design)
    if p.suffix.lower() != ".json" or not p.is_file():
        return None
    data = load_json(p)
    return data if isinstance(data, dict) else None


def _check_placed(design: Any) -> None:
    """InputError naming ``side`` when ``design`` is a robot's ``design.json`` without a placement of its own."""
    data = _design_data(design)
    if data is None or "m_x" in data or not isinstance(data.get("dockings"), list):
        return
    sides = list(
        dict.fromkeys(e["side"] for e in data["dockings"] if isinstance(e, dict) and e.get("side") in ("R", "L"))
    )
    raise InputError.of(
        "side",
        f"is needed: {design} is one robot at {len(data['dockings'])} dockings (sides {', '.join(sides) or '?'}), with "
        "no placement of its own; give the side whose docking to use, or one docking's design "
        "(dockings/<patient>_<side>/design.json beside it)",
    )


def docking_labels(design: Any, side: str | None) -> dict[str, Any]:
    """Whose docking ``design`` is on ``side``: ``patient``, ``side`` and ``plan_digest`` (what a docking file records),
    for a robot's ``design.json`` with one docking on that side; {} for anything else (a docking file carries its own)."""
    data = _design_data(design)
    if data is None or side is None or not isinstance(data.get("dockings"), list) or "m_x" in data:
        return {}
    here = [w for w in read_robot(design).starts if w.side == side.strip().upper()]
    if len(here) != 1:
        return {}
    w = here[0]
    labels: dict[str, Any] = {"patient": w.label.rsplit("_", 1)[0], "side": w.side}
    if w.entry is not None and w.target is not None:
        labels[PLAN_DIGEST] = list(trajectory_digests(w.entry, w.target))
    return labels


def design_at_side(design: Any, side: str | None, *, alone: bool = False, placed: bool = False) -> Any:
    """The design a command uses on ``side`` (R or L): a docking file whose ``side`` contradicts it is refused; a
    robot's ``design.json`` (robot and dockings) gives its docking on that side, when it has exactly one there.
    Anything else (a Design, a preset, a plain design file, no side) is returned as given, unless ``alone``: the
    command has no plan that ``side`` would filter, so a design without a side would ignore it and is refused.
    A side other than R or L is refused. ``placed``: the caller needs one placed design, so a robot's ``design.json``
    (a robot at its dockings, no placement of its own) without a side is refused naming ``side``."""
    if side is None:
        if placed:
            _check_placed(design)
        return design
    s = side.strip().upper() if isinstance(side, str) else None
    if s not in ("R", "L"):
        raise InputError.of("side", f"{side!r}: expected R or L")
    data = _design_data(design)
    if data is None or (data.get("side") is None and not isinstance(data.get("dockings"), list)):
        if alone:
            raise InputError.of(
                "side",
                f"{s}: {design if isinstance(design, (str, os.PathLike)) else 'the design'} has no side (a plain "
                "design, no docking) and there is no plan to keep to one side: "
                "the side would be ignored",
            )
        return design
    p = Path(design)
    own = data.get("side")
    if own in ("R", "L") and own != s:
        other = p.parent.parent / f"{data.get('patient', '<patient>')}_{s}" / "design.json"
        hint = f"; its side-{s} docking is {other}" if other.is_file() else ""
        raise InputError.of("side", f"{s}: {p} is the docking of side {own} (patient {data.get('patient', '?')}){hint}")
    dockings = data.get("dockings")
    if own is not None or not isinstance(dockings, list):
        return design
    sides = {e.get("side") for e in dockings if isinstance(e, dict)}
    if "m_x" in data:  # a design job of one docking: its design.json is that docking's complete design
        if sides and s not in sides:
            raise InputError.of(
                "side", f"{s}: {p} is the robot's one docking, on side {'/'.join(sorted(map(str, sides)))}"
            )
        return design
    robot = read_robot(p)
    here = [w for w in robot.starts if w.side == s]
    if len(here) == 1:
        return robot.placed(here[0].placement)
    names = ", ".join(str(p.parent / "dockings" / w.label / "design.json") for w in here)
    problem = (
        f"docks it {len(here)} times on side {s}; give one docking's file: {names}"
        if here
        else f"has no docking on side {s}"
    )
    raise InputError.of("side", f"{s}: the robot of {p} {problem}")
