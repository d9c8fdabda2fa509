"""3D Slicer markups JSON (``.mrk.json``) input and output for trajectory sets.

Reading: every markup of type ``"Line"`` is one trajectory; its first control point is the
entry, its second the target. Markups of other types (Fiducial, Curve, Plane, ...) are skipped,
because a planning scene often keeps landmarks next to the planned lines; a file without any
Line is an error. The trajectory id is the markup's ``name``; without a name it is the file
name stem (``plan.mrk.json`` → ``plan``) when the file holds one Line, else ``stem-k`` with k
the 1-based position of the Line among the file's Lines.

Level and side are not part of the Slicer format. They are carried in the first control
point's ``description`` as ``level=C3;side=R`` (Slicer keeps point descriptions when it
re-saves a file); when absent they are unknown (``""``).

Writing follows Slicer's own writer (schema v1.0.3, LPS, mm). A path ending in ``.json``
receives one file holding all lines (Slicer loads each markup of a file as its own node);
any other path is a folder receiving one ``NNN_<id>.mrk.json`` per trajectory, as Slicer
saves a scene.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import load_json, short_repr
from arcube.io.trajectories import TrajectorySet, atomic_write, validate_points

__all__ = ["MARKUPS_SCHEMA", "PATIENT_FROM_LPS", "PATIENT_FROM_RAS", "read_markups", "write_markups"]

# The identifier Slicer writes (it keeps "master" for compatibility with Slicer < 5.1).
MARKUPS_SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/"
    "Markups/Resources/Schema/markups-schema-v1.0.3.json#"
)
# Slicer accepts any v1.x.y markups schema; the same pattern tells a markups file from other JSON.
_SCHEMA_RE = re.compile(r".*markups-schema-v1\.[0-9]+\.[0-9]+\.json#*$", re.IGNORECASE)

# Patient frame: +x toward the patient's right, +y superior, +z posterior.
# RAS: +r toward the Right, +a Anterior, +s Superior. So x = r, y = s, z = −a:
#   (x, y, z)ᵀ = PATIENT_FROM_RAS · (r, a, s)ᵀ
PATIENT_FROM_RAS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
# LPS: +l toward the Left, +p Posterior, +s Superior. So x = −l, y = s, z = p:
#   (x, y, z)ᵀ = PATIENT_FROM_LPS · (l, p, s)ᵀ
PATIENT_FROM_LPS = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
# Both are rotations (det +1), so the inverse used for writing is the transpose.
_TO_PATIENT = {"RAS": PATIENT_FROM_RAS, "LPS": PATIENT_FROM_LPS}
_UNIT_TO_MM = {"mm": 1.0, "um": 1e-3}
_META_RE = re.compile(r"^\s*level=([^;]*);\s*side=([^;]*)\s*$")


def _number_list(value: Any) -> bool:
    return (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    )


def _units_scale(markup: dict[str, Any], where: str) -> float:
    units = markup.get("coordinateUnits", "mm")
    if isinstance(units, list) and units:  # DICOM coded form ["mm", "UCUM", "millimeter"]
        units = units[0]
    if not isinstance(units, str) or units not in _UNIT_TO_MM:
        raise InputError(f"{where}: unknown coordinateUnits {short_repr(units)} (expected mm or um)")
    return _UNIT_TO_MM[units]


def _read_file(path: Path) -> list[tuple[str, str, str, str, np.ndarray, np.ndarray]]:
    """Lines of one markups file as (label, id, level, side, entry, target), patient frame."""
    data = load_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("markups"), list):
        raise InputError(f"{path}: not a Slicer markups file (no 'markups' list)")
    schema = data.get("@schema")
    if schema is not None and not (isinstance(schema, str) and _SCHEMA_RE.match(schema)):
        raise InputError(f"{path}: not a Slicer markups file (@schema {short_repr(schema)})")
    lines = [(k, m) for k, m in enumerate(data["markups"], start=1) if isinstance(m, dict) and m.get("type") == "Line"]
    if not lines:
        raise InputError(f"{path}: no markup of type 'Line' (one Line per trajectory)")
    stem = path.name[: -len(".mrk.json")] if path.name.lower().endswith(".mrk.json") else path.stem
    out = []
    for pos, (k, markup) in enumerate(lines, start=1):
        name = markup.get("name")
        has_name = isinstance(name, str) and name.strip() != ""
        where = f"{path} markup {k}" + (f" ({short_repr(name)})" if has_name else "")
        tid = name.strip() if has_name else (stem if len(lines) == 1 else f"{stem}-{pos}")
        system = markup.get("coordinateSystem", "LPS")  # absent means LPS, as Slicer writes
        if not isinstance(system, str) or system not in _TO_PATIENT:
            raise InputError(f"{where}: unknown coordinate system {short_repr(system)} (expected RAS or LPS)")
        scale = _units_scale(markup, where)
        cps = markup.get("controlPoints")
        if not isinstance(cps, list) or len(cps) != 2:
            n = len(cps) if isinstance(cps, list) else 0
            raise InputError(f"{where}: Line has {n} control points, expected 2 (entry, target)")
        pts = []
        for j, cp in enumerate(cps, start=1):
            pos_value = cp.get("position") if isinstance(cp, dict) else None
            if not _number_list(pos_value):
                raise InputError(f"{where}: control point {j} has no position of 3 numbers")
            raw = np.array(pos_value, dtype=float)  # an int past the float range was read as inf
            if not np.all(np.isfinite(raw)):
                raise InputError(f"{where}: control point {j} position is not finite ({short_repr(pos_value)})")
            pts.append(_TO_PATIENT[system] @ (raw * scale))
        level, side = "", ""
        desc = cps[0].get("description", "")
        meta = _META_RE.match(desc) if isinstance(desc, str) else None
        if meta:
            level, side = meta.group(1).strip().upper(), meta.group(2).strip().upper()
            if side not in ("R", "L", ""):
                raise InputError(f"{where}: side must be R, L or empty ({short_repr(side)})")
        out.append((where, tid, level, side, pts[0], pts[1]))
    return out


def read_markups(path: str | os.PathLike[str]) -> TrajectorySet:
    """Read trajectories from a ``.mrk.json`` file or a folder of them (sorted by file name).

    Returns:
        TrajectorySet with points converted from the markup's coordinate system (RAS or LPS,
        mm or um) to the patient frame, mm. ``source`` is the given path.
    """
    p = Path(path)
    try:
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.is_file() and f.name.lower().endswith(".mrk.json"))
            if not files:
                raise InputError(f"{p}: folder holds no .mrk.json file")
        elif p.exists():
            files = [p]
        else:
            raise InputError(f"{p}: no such file or folder")
    except OSError as exc:  # e.g. a name too long, an unreadable folder
        raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    rows = [row for f in files for row in _read_file(f)]
    labels, ids, levels, sides, entry, target = (list(c) for c in zip(*rows))
    entry_arr, target_arr = np.array(entry), np.array(target)
    validate_points(labels, ids, entry_arr, target_arr)
    return TrajectorySet(tuple(ids), tuple(levels), tuple(sides), entry_arr, target_arr, str(p))


def _plain(values: np.ndarray) -> list[float]:
    return [float(v) + 0.0 for v in values]  # + 0.0 drops the -0.0 a sign flip creates


def _markup(ts: TrajectorySet, i: int) -> dict[str, Any]:
    """One Slicer Line markup (LPS, mm) for trajectory i."""
    tid = ts.ids[i]
    to_lps = PATIENT_FROM_LPS.T
    points = []
    for j, (role, p) in enumerate((("entry", ts.entry[i]), ("target", ts.target[i])), start=1):
        points.append(
            {
                "id": str(j),
                "label": f"{tid}-{role}",
                "description": f"level={ts.levels[i]};side={ts.sides[i]}" if j == 1 else "",
                "associatedNodeID": "",
                "position": _plain(to_lps @ p),
                "orientation": [-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0],
                "selected": True,
                "locked": False,
                "visibility": True,
                "positionStatus": "defined",
            }
        )
    return {
        "type": "Line",
        "coordinateSystem": "LPS",
        "coordinateUnits": "mm",
        "locked": False,
        "fixedNumberOfControlPoints": False,
        "labelFormat": "%N-%d",
        "lastUsedControlPointNumber": 2,
        "name": tid,
        "controlPoints": points,
        "measurements": [],
    }


def _document(markups: list[dict[str, Any]]) -> str:
    return json.dumps({"@schema": MARKUPS_SCHEMA, "markups": markups}, indent=4) + "\n"


def write_markups(ts: TrajectorySet, path: str | os.PathLike[str]) -> None:
    """Write ``ts`` as Slicer Line markups (LPS, mm), atomically per file.

    Args:
        path: ``*.json`` (normally ``*.mrk.json``) → one file with all lines; anything else
            → a folder (created if needed) with one ``NNN_<id>.mrk.json`` per trajectory, NNN
            being the 0-based position so that reading the folder back keeps the order.
    """
    p = Path(path)
    if p.name.lower().endswith(".json"):
        atomic_write(p, _document([_markup(ts, i) for i in range(len(ts))]))
        return
    if p.exists() and not p.is_dir():
        raise InputError(f"{p}: exists and is not a folder (name a .mrk.json file for one file)")
    # ids are free text; file names are not.
    names = [f"{i:03d}_{re.sub(r'[^A-Za-z0-9._-]+', '_', tid)}.mrk.json" for i, tid in enumerate(ts.ids)]
    if p.is_dir():
        # A later read takes every .mrk.json of the folder: leftovers would join the set.
        stale = sorted(f.name for f in p.iterdir() if f.name.lower().endswith(".mrk.json") and f.name not in names)
        if stale:
            raise InputError(f"{p}: folder already holds other markups files ({stale[0]}, ...)")
    for i, name in enumerate(names):
        atomic_write(p / name, _document([_markup(ts, i)]))
