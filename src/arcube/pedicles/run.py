"""``arcube breach``: the probability that each screw of a plan leaves its pedicle (model §22), and its folder.

The robot is a design file (one docking), a design job's ``design.json`` (the robot and its dockings: each side's
screws are drilled from that side's docking, the same built robot in every sample), or the folder of
``arcube calibrate identify`` (its calibrated design; the robot's errors drawn from the identification's covariance).
DIR gets ``breach.csv`` (one row per screw, :data:`~arcube.pedicles.monte_carlo.BREACH_COLUMNS`), ``summary.json``
and two pictures: ``breach_by_screw.png`` (P(breach) per screw, and with each source alone) and ``worst_screw.png``
(the worst screw's isthmus: the bone's ellipse, the screw, the room it leaves, the sampled offsets).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.pedicles.geometry import pedicles
from arcube.pedicles.monte_carlo import BREACH_COLUMNS, BreachResult, monte_carlo
from arcube.pedicles.settings import BreachSettings
from arcube.pedicles.sources import RobotModel

__all__ = ["breach", "breach_csv", "read_calibration", "robot_dockings", "write_breach"]


def read_calibration(folder: str | os.PathLike[str]) -> tuple[Any, np.ndarray, dict[str, Any]]:
    """(calibrated Design, covariance ``(31, 31)`` mm/deg, calibration settings) of an ``arcube calibrate identify`` folder;
    InputError naming the file that is missing or wrong."""
    from arcube.calibrate.output import COVARIANCE_FILE, read_covariance
    from arcube.io.inputs import load_json
    from arcube.model.design import Design

    d = Path(folder)
    if not d.is_dir():
        raise InputError.of("calibration", f"{d}: not a folder (give the folder of arcube calibrate identify)")
    for name in ("design.json", "calibration.json", COVARIANCE_FILE):
        if not (d / name).is_file():
            raise InputError.of(
                "calibration",
                f"{d}: has no {name} (the folder of arcube calibrate identify holds design.json, "
                f"calibration.json and {COVARIANCE_FILE})",
            )
    info = load_json(d / "calibration.json")
    if not isinstance(info, dict) or not isinstance(info.get("settings"), dict):
        raise InputError(f"{d / 'calibration.json'}: not a calibration (no settings)")
    identified, own = info.get("design"), load_json(d / "design.json")
    if not isinstance(own, dict):
        raise InputError(f"{d / 'design.json'}: a design file must hold one JSON object keyed by parameter names")
    if isinstance(identified, dict):  # the covariance belongs to this design: a design.json put there since is not it
        differ = sorted(k for k in set(identified) | set(own) if own.get(k) != identified.get(k))
        if differ:
            raise InputError(
                f"{d / 'design.json'}: is not the design that calibration.json identified ({', '.join(differ[:4])}"
                f"{' ...' if len(differ) > 4 else ''} differ): give the folder as arcube calibrate identify wrote it"
            )
    return Design.from_dict(own, source=str(d / "design.json")), read_covariance(d / COVARIANCE_FILE), info["settings"]


def robot_dockings(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Side -> the complete Design of that docking, for a design job's ``design.json`` (a robot with ``dockings``);
    ``{"": design}`` for a design file of one docking."""
    from arcube.model.robot import read_robot
    from arcube.io.inputs import load_json
    from arcube.model.design import Design

    data = load_json(Path(path))
    if isinstance(data, dict) and isinstance(data.get("dockings"), list) and "m_x" not in data:
        robot = read_robot(path)
        out: dict[str, Any] = {}
        for w in robot.starts:
            side = w.side or ""
            if side in out:  # a robot of a cohort: which patient's docking the plan is for is the user's to say
                raise InputError.of(
                    "design",
                    f"{path}: the robot docks {sum(s.label.endswith('_' + side) for s in robot.starts)} times on side "
                    f"{side}; give the docking of this plan's patient (dockings/<patient>_<side>/design.json)",
                )
            out[side] = robot.placed(w.placement)
        return out
    return {"": Design.load(path)}


def breach(
    design: Any = None,
    plan: Any = "reference",
    out: str | os.PathLike[str] | None = None,
    *,
    calibration: Any = None,
    side: str | None = None,
    levels: Any = None,
    ids: Any = None,
    mode: Any = None,
    transform: Any = None,
    tolerances: Any = None,
    settings: BreachSettings | None = None,
    loads: Any = None,
    **fields: Any,
) -> BreachResult:
    """The breach probability of every screw of ``plan`` (model §22; ``arcube breach``).

    Args:
        design: a design file (or a design job's ``design.json``: each side from its docking), a Design, or a preset.
        plan: the plan and which of its screws (as :func:`arcube.evaluate` takes them).
        side: see ``plan``.
        levels: see ``plan``.
        ids: see ``plan``.
        transform: see ``plan``.
        out: a folder to create (new or empty): breach.csv, summary.json and the pictures; None writes nothing.
        calibration: the folder of ``arcube calibrate identify`` instead of (or with the same) ``design``.
        mode: the working mode (None: the design's own; a design without one needs it).
        tolerances: an :class:`arcube.ToleranceSettings` (class m by default) for a robot that is not calibrated;
            refused with ``calibration``.
        settings: a :class:`BreachSettings` and changes to it (``registration_mm=1.0``, ``samples=2000``).
        fields: see ``settings``.
        loads: an :class:`arcube.Loads` (the thrust and the actuators' stiffness); default 30 N, 1e4 N m/rad.

    Returns:
        A :class:`~arcube.pedicles.monte_carlo.BreachResult` (``rows()``, ``summary()``).
    """
    from arcube.accuracy import ToleranceSettings
    from arcube.coerce import mode_signs
    from arcube.io import load_trajectories, select
    from arcube.model.design import Design
    from arcube.options import Loads, validated

    s = (
        validated(BreachSettings, {**(settings.model_dump() if settings is not None else {}), **fields})
        if fields or settings is None
        else settings
    )
    tol = ToleranceSettings() if tolerances is None else tolerances
    ld = Loads() if loads is None else loads
    cov, cal = None, None
    if calibration is not None:
        if tolerances is not None:  # the covariance draws the robot's errors: tolerances would be ignored
            raise InputError.of(
                "tolerances", f"and a calibration ({calibration}): its covariance gives the robot's errors, give one"
            )
        cal_design, cov, cal = read_calibration(calibration)
        if design is not None and not (
            isinstance(design, (str, os.PathLike))
            and Path(design).resolve() == (Path(calibration) / "design.json").resolve()
        ):
            raise InputError.of(
                "calibration",
                f"{calibration}: and design {design} are two robots: give the calibration folder alone "
                "(its design.json is the calibrated design)",
            )
        by_side: dict[str, Any] = {"": cal_design}
    elif design is None:
        raise InputError.of("design", "is required (a design file, a design job's design.json), or give calibration")
    elif isinstance(design, (str, os.PathLike)) and not (isinstance(design, str) and design in ("paper",)):
        from arcube.model.robot import design_at_side

        chosen = design_at_side(
            design, side
        )  # a docking of the other side is refused; a robot's design.json gives this side's
        by_side = robot_dockings(design) if chosen is design else {"": chosen}
    else:
        by_side = {"": Design.coerce(design)}
    from arcube.io import TrajectorySet

    ts = plan if isinstance(plan, TrajectorySet) and transform is None else load_trajectories(plan, transform)
    ts = select(ts, side=side, levels=levels, ids=ids) if (side or levels or ids) else ts
    p_all = pedicles(ts, s.screw_mm)
    groups = _groups(ts, by_side)
    results = []
    for name, idx, d in groups:
        text = mode if mode is not None else d.mode
        if text is None:
            raise InputError.of("mode", "is not in the design file: give the robot's working mode (e.g. +,+,+,-)")
        signs = mode_signs(text)
        x = d.to_vector()
        if cov is not None:
            model = RobotModel(x, signs, _calibrated_T(cal), "normal", cov)
        else:
            model = RobotModel(x, signs, tol.tolerances(x), tol.distribution)
        sub = select(ts, ids=",".join(ts.ids[i] for i in idx))
        info = {
            "registration_mm": s.registration_mm,
            "registration_deg": s.registration_deg,
            "thrust_N": ld.thrust_N,
            "screw_mm": s.screw_mm,
            "seed": s.seed,
            "robot": "calibrated" if cov is not None else f"ISO 2768-{tol.tolerance_class}",
        }
        results.append(
            (
                idx,
                monte_carlo(
                    model,
                    pedicles(sub, s.screw_mm),
                    (name,) * len(idx),
                    samples=s.samples,
                    seed=s.seed,
                    registration_mm=s.registration_mm,
                    registration_deg=s.registration_deg,
                    thrust_N=ld.thrust_N,
                    stiffness_Nm_per_rad=ld.actuator_stiffness,
                    settings=info,
                ),
            )
        )
    result = _merge(p_all, results, s.samples)
    if out is not None:
        write_breach(result, out)
    return result


def _calibrated_T(cal: dict[str, Any]) -> np.ndarray:
    """T ``(41,)`` of a calibrated robot's encoders and lost motion (its calibration's), 0 elsewhere (the covariance)."""
    from arcube.calibrate.budget import source_covariance

    return source_covariance(
        np.zeros((31, 31)), float(cal.get("encoder_deg", 0.01)), float(cal.get("backlash_arcmin", 1.0))
    )[1]


def _groups(ts: Any, by_side: dict[str, Any]) -> list[tuple[str, np.ndarray, Any]]:
    """(docking name, screw indices, design) per docking: one for a design of one docking (named by its screws' side, or
    ``both``), one per side for a robot with dockings."""
    if "" in by_side:
        sides = set(ts.sides)
        return [(next(iter(sides)) if len(sides) == 1 else "both", np.arange(len(ts.ids)), by_side[""])]
    out = []
    for side in dict.fromkeys(ts.sides):
        if side not in by_side:
            raise InputError.of(
                "design",
                f"has no docking for side {side!r} (its dockings: {', '.join(by_side)}); keep to the side it has: "
                f"RunSettings.side {next(iter(by_side))}",
            )
        out.append((side, np.array([i for i, sd in enumerate(ts.sides) if sd == side]), by_side[side]))
    return out


def _merge(p_all: Any, results: list[tuple[np.ndarray, BreachResult]], samples: int) -> BreachResult:
    """One result in the plan's order from the results of each docking (their screws ``idx``)."""
    if len(results) == 1:
        return results[0][1]
    J = len(p_all.ids)

    def put(name: str, shape: tuple[int, ...], dtype: Any = float) -> np.ndarray:
        a = np.empty((J, *shape), dtype=dtype)
        for idx, r in results:
            a[idx] = getattr(r, name)
        return a

    offsets = np.empty((samples, J, 2))
    docking = [""] * J
    for idx, r in results:
        offsets[:, idx] = r.offsets
        for k, i in enumerate(idx):
            docking[i] = r.docking[k]
    first = results[0][1]
    return BreachResult(
        p_all,
        tuple(docking),
        samples,
        put("reached", (), bool),
        put("p_breach", ()),
        put("p_direction", (4,)),
        put("p_major", ()),
        put("offset_p95_mm", ()),
        put("p_alone", (3,)),
        offsets,
        first.settings,
    )


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def breach_csv(result: BreachResult) -> str:
    """breach.csv's text: :data:`BREACH_COLUMNS`, then ``room_height_mm``, ``docking``, ``reached``; one row per screw."""
    columns = (*BREACH_COLUMNS, "room_height_mm", "docking", "reached")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in result.rows():
        w.writerow([_cell(row[c]) for c in columns])
    return buf.getvalue()


def write_breach(result: BreachResult, out: str | os.PathLike[str]) -> Path:
    """The folder (module docstring), all or nothing; ``out`` must be new or empty."""
    from arcube.io.files import write_folder
    from arcube.io.json_values import finite
    from arcube.report.breach import breach_bars_png, worst_screw_png

    summary = result.summary()
    files = {
        "breach.csv": breach_csv(result).encode(),
        "summary.json": (json.dumps(finite(summary), indent=2, allow_nan=False) + "\n").encode(),
        "breach_by_screw.png": breach_bars_png(result.rows()),
    }
    worst = summary["worst_screw"]
    if worst is not None:
        j = result.pedicles.ids.index(worst)
        p = result.pedicles
        files["worst_screw.png"] = worst_screw_png(
            result.offsets[:, j],
            p.room[j],
            (p.width[j] / 2, p.height[j] / 2),
            p.screw[j] / 2,
            float(p.medial[j]),
            float(p.cranial[j]),
            f"trajectory {worst} ({p.levels[j]} {p.sides[j]})",
            float(result.p_breach[j]),
        )
    return write_folder(files, out)
