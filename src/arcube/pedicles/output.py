"""``arcube breach``'s folder and files (model §22): breach.csv, what_it_takes.csv, summary.json, the two pictures, and
the screws as 3D Slicer markups.

DIR gets ``breach.csv`` (one row per screw, :data:`~arcube.pedicles.monte_carlo.BREACH_COLUMNS` then
:data:`~arcube.pedicles.monte_carlo.MORE_COLUMNS`), ``what_it_takes.csv``, ``summary.json`` and two pictures:
``breach_by_screw.png`` (P(breach) per screw, and with each source alone) and ``worst_screw.png`` (the worst screw's
isthmus: the bone's ellipse, the screw, the room it leaves, the sampled offsets), all or nothing.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.pedicles.monte_carlo import BREACH_COLUMNS, MORE_COLUMNS, BreachResult

__all__ = ["breach_csv", "breach_markups", "what_it_takes_csv", "whose", "write_breach"]


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def breach_csv(result: BreachResult) -> str:
    """breach.csv's text: :data:`BREACH_COLUMNS`, then :data:`MORE_COLUMNS` (``room_height_mm``, ``docking``,
    ``reached``, ``status``, ``deciding_source``); one row per screw, empty cells where a figure is not defined."""
    columns = (*BREACH_COLUMNS, *MORE_COLUMNS)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in result.rows():
        w.writerow([_cell(row[c]) for c in columns])
    return buf.getvalue()


def whose(result: BreachResult, docking: str | None = None) -> str:
    """The patient and the docking(s) a result's screws were drilled from, for a picture's title: ``patient reference,
    docking reference_R`` (every docking, or the one of side or name ``docking``)."""
    info = result.settings
    notes = info.get("dockings") or {}
    names = [docking] if docking is not None else list(dict.fromkeys(result.docking))
    shown = [str(notes.get(n, {}).get("docking", n)) if isinstance(notes.get(n), dict) else n for n in names]
    patient = info.get("patient")
    return (f"patient {patient}, " if patient else "") + f"docking {', '.join(shown)}"


def what_it_takes_csv(result: BreachResult) -> str:
    """what_it_takes.csv's text: :data:`~arcube.pedicles.first_order.WHAT_IT_TAKES_COLUMNS`, then ``p_breach``, ``p_first_order`` and
    ``target``; one row per level and a last one ``all`` (the worst screw); empty where nothing reaches the target."""
    from arcube.pedicles.first_order import WHAT_IT_TAKES_COLUMNS

    columns = (*WHAT_IT_TAKES_COLUMNS, "p_breach", "p_first_order", "target")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in result.takes:
        w.writerow(["" if row[c] is None else _cell(row[c]) for c in columns])
    return buf.getvalue()


def breach_markups(result: BreachResult) -> str:
    """The screws as a 3D Slicer line markups document (LPS, mm, :mod:`arcube.io.slicer`'s), each line's entry point
    carrying its level and side and its target point the screw's verdict in the description
    (``P(breach)=12.3%;status=assessed;deciding=robot;docking=reference_R``), for looking at the risk where surgeons
    look. InputError when the result does not carry its plan."""
    from arcube.io.slicer import _document, _markup

    if result.plan is None:
        raise InputError.of("markups", "needs the plan of the result (arcube.breach keeps it)")
    notes = result.settings.get("dockings") or {}
    out = []
    for j, row in enumerate(result.rows()):
        m = _markup(result.plan, j)
        note = notes.get(row["docking"]) if isinstance(notes.get(row["docking"]), dict) else {}
        p = "" if math.isnan(row["p_breach"]) else f"P(breach)={100 * row['p_breach']:.1f}%;"
        m["controlPoints"][1]["description"] = (
            f"{p}status={row['status']};deciding={row['deciding_source'] or '-'};"
            f"docking={note.get('docking', row['docking'])}"
        )
        out.append(m)
    return _document(out)


def write_breach(result: BreachResult, out: str | os.PathLike[str]) -> Path:
    """The folder (module docstring), all or nothing; ``out`` must be new or empty."""
    from arcube.io.files import write_folder
    from arcube.io.json_values import finite
    from arcube.report.breach import breach_bars_png, worst_screw_png

    summary = result.summary()
    files = {
        "breach.csv": breach_csv(result).encode(),
        "what_it_takes.csv": what_it_takes_csv(result).encode(),
        "summary.json": (json.dumps(finite(summary), indent=2, allow_nan=False) + "\n").encode(),
        "breach_by_screw.png": breach_bars_png(result.rows(), whose(result)),
    }
    worst = summary["worst_screw"]
    if worst is not None and worst not in summary["too_wide"]:
        j = result.pedicles.ids.index(worst)
        p = result.pedicles
        files["worst_screw.png"] = worst_screw_png(
            result.offsets[:, j],
            p.room[j],
            (p.width[j] / 2, p.height[j] / 2),
            p.screw[j] / 2,
            float(p.medial[j]),
            float(p.cranial[j]),
            f"trajectory {worst} ({p.levels[j]} {p.sides[j]}), {whose(result, result.docking[j])}",
            float(result.p_breach[j]),
        )
    return write_folder(files, out)
