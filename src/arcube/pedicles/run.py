"""``arcube breach``: the probability that each screw of a plan leaves its pedicle (model §22), and its folder.

The robot is a design file (one docking), a design job's ``design.json`` (the robot and its dockings: each side's
screws are drilled from that side's docking, the same built robot in every sample), or the folder of
``arcube calibrate identify`` (its calibrated design; the robot's errors drawn from the identification's covariance).
DIR gets what :func:`arcube.pedicles.output.write_breach` writes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.pedicles.geometry import pedicles
from arcube.pedicles.monte_carlo import BreachResult, monte_carlo
from arcube.pedicles.output import write_breach
from arcube.pedicles.settings import BreachSettings
from arcube.pedicles.sources import RobotModel

__all__ = ["breach", "read_calibration", "robot_dockings"]


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


def robot_dockings(path: str | os.PathLike[str], plan: Any = None) -> dict[str, Any]:
    """Side -> the complete Design of that docking, for a design job's ``design.json`` (a robot with ``dockings``);
    ``{"": design}`` for a design file of one docking. With ``plan`` (a TrajectorySet), each side's docking is the one
    of this plan's trajectories (by their digests, not by the patient's name); a side the robot has not docked on is
    refused (:func:`arcube.breach` docks it first)."""
    from arcube.model.robot import read_robot, trajectory_digests
    from arcube.io.inputs import load_json
    from arcube.model.design import Design

    data = load_json(Path(path))
    if not (isinstance(data, dict) and isinstance(data.get("dockings"), list) and "m_x" not in data):
        return {"": Design.load(path)}
    robot = read_robot(path)
    out: dict[str, Any] = {}
    for side in ("R", "L") if plan is None else tuple(dict.fromkeys(plan.sides)):
        here = [w for w in robot.starts if (w.side or "") == side]
        if plan is not None:
            mine = np.array([sd == side for sd in plan.sides])
            digests = trajectory_digests(plan.entry[mine], plan.target[mine])
            here = [w for w in here if w.docks(digests) is not False]
        if len(here) > 1:  # a robot of a cohort: which patient's docking the plan is for is the user's to say
            raise InputError.of(
                "design",
                f"{path}: the robot docks {len(here)} times on side {side}; give the docking of this plan's patient "
                "(dockings/<patient>_<side>/design.json)",
            )
        if here:
            out[side] = robot.placed(here[0].placement)
        elif plan is not None:
            raise InputError.of(
                "design",
                f"{path}: the robot has no docking of this plan's side-{side} trajectories (its dockings: "
                f"{', '.join(w.label for w in robot.starts)}); dock it first (arcube dock)",
            )
    return out


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
    reached: Any = None,
    notes: dict[str, dict[str, str]] | None = None,
    patient: str | None = None,
    by_sides: bool = False,
    **fields: Any,
) -> BreachResult:
    """The breach probability of every screw of ``plan`` (model §22), the robot given as it is docked: the
    computation of :func:`arcube.breach`, which first finds (or makes) the robot's docking at this patient.

    Args:
        design: a design file (or a design job's ``design.json``: each side from its docking of this plan), a Design,
            a preset, or a mapping side (R, L) -> Design: the robot at this patient's dockings.
        reached: ``(J,)`` the design job's verdict of each selected screw's trajectory at its docking (guards included,
            model §16-17); a screw refused has no P(breach). None: every screw the nominal robot reaches.
        notes: docking (side) -> ``{"docking": its name, "how": how it was found}``, recorded in the settings.
        patient: the patient's name, recorded in the settings and the pictures' titles.
        by_sides: one design over a two-sided plan drills each side as a docking of its own (its registration about
            its own screws): a docking file or calibration of one side, whose other side it does not drill.
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
    elif isinstance(design, Mapping):
        by_side = {str(k): Design.coerce(v) for k, v in design.items()}
    elif design is None:
        raise InputError.of("design", "is required (a design file, a design job's design.json), or give calibration")
    elif isinstance(design, (str, os.PathLike)) and not (isinstance(design, str) and design in ("paper",)):
        from arcube.model.robot import design_at_side

        chosen = design_at_side(
            design, side
        )  # a docking of the other side is refused; a robot's design.json gives this side's
        by_side = None if chosen is design else {"": chosen}
    else:
        by_side = {"": Design.coerce(design)}
    from arcube.io import TrajectorySet

    ts = plan if isinstance(plan, TrajectorySet) and transform is None else load_trajectories(plan, transform)
    ts = select(ts, side=side, levels=levels, ids=ids) if (side or levels or ids) else ts
    if by_side is None:
        by_side = robot_dockings(design, ts)
    verdict = None if reached is None else np.asarray(reached, dtype=bool).reshape(-1)
    if verdict is not None and len(verdict) != len(ts.ids):
        raise InputError.of("reached", f"has {len(verdict)} values for {len(ts.ids)} screws: one per screw")
    p_all = pedicles(ts, s.screw_mm)
    groups = _groups(ts, by_side, by_sides)
    results = []
    pictures: list[tuple[np.ndarray, Any, dict[str, Any]]] = []  # per docking: its screws, Moments, per class
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
        sub = _subset(ts, idx)
        info = {
            "registration_mm": s.registration_mm,
            "registration_deg": s.registration_deg,
            "thrust_N": ld.thrust_N,
            "screw_mm": s.screw_mm,
            "seed": s.seed,
            "robot": "calibrated" if cov is not None else f"ISO 2768-{tol.tolerance_class}",
            **({"dockings": dict(notes)} if notes else {}),
            **({"patient": patient} if patient else {}),
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
                    verdict=None if verdict is None else verdict[idx],
                ),
            )
        )
        pictures.append(
            (idx, *_normal_pictures(model, pedicles(sub, s.screw_mm), name, ld, None if cov is not None else tol))
        )
    result = _with_what_it_takes(_merge(p_all, results, s.samples), pictures, s, calibrated=cov is not None)
    from dataclasses import replace

    result = replace(result, plan=ts)
    if out is not None:
        write_breach(result, out)
    return result


def _normal_pictures(model: RobotModel, p: Any, name: str, ld: Any, tol: Any) -> tuple[Any, dict[str, Any]]:
    """The first-order picture (:class:`~arcube.pedicles.first_order.Moments`) of one docking's screws, and of the
    same robot built to each ISO 2768 class (``tol`` with its class changed; none for a calibrated robot)."""
    from arcube.pedicles.first_order import CLASSES_COARSE_FIRST, moments

    names = (name,) * len(p.ids)
    mom = moments(model, p, names, ld.thrust_N, ld.actuator_stiffness)
    classes = {}
    if tol is not None:
        for c in CLASSES_COARSE_FIRST:
            built = tol.replace(tolerance_class=c, tol={})
            other = RobotModel(model.design, model.mode, built.tolerances(model.design), built.distribution)
            classes[c] = moments(other, p, names, ld.thrust_N, ld.actuator_stiffness)
    return mom, classes


def _with_what_it_takes(
    result: BreachResult, pictures: list[tuple[np.ndarray, Any, dict[str, Any]]], s: BreachSettings, calibrated: bool
) -> BreachResult:
    """``result`` with each screw's first-order P and what it takes to reach ``s.target`` (model §22, first order)."""
    from dataclasses import replace

    from arcube.pedicles.first_order import Moments, breach_first_order, what_it_takes

    J = len(result.pedicles.ids)

    def merged(get: Any) -> Moments:
        fields = {"mean": np.full((J, 2), np.nan), "robot": np.full((J, 2, 2), np.nan)}
        fields.update(reg_t=np.full((J, 2, 2), np.nan), reg_r=np.full((J, 2, 2), np.nan))
        for idx, mom, classes in pictures:
            m = get(mom, classes)
            for key, a in fields.items():
                a[idx] = getattr(m, key)
        return Moments(**fields)

    mom = merged(lambda m, c: m)
    names = pictures[0][2].keys() if pictures else ()
    classes = {c: merged(lambda m, per, c=c: per[c]) for c in names}
    with np.errstate(invalid="ignore"):
        p_fo = breach_first_order(mom, result.pedicles, s.registration_mm, s.registration_deg)
        takes = what_it_takes(
            mom,
            result.pedicles,
            result.p_breach,
            result.status,
            s.registration_mm,
            s.registration_deg,
            s.target,
            classes,
            calibrated,
        )
    return replace(result, p_first_order=np.where(result.reached, p_fo, np.nan), takes=tuple(takes))


def _calibrated_T(cal: dict[str, Any]) -> np.ndarray:
    """T ``(41,)`` of a calibrated robot's encoders and lost motion (its calibration's), 0 elsewhere (the covariance)."""
    from arcube.calibrate.budget import source_covariance

    return source_covariance(
        np.zeros((31, 31)), float(cal.get("encoder_deg", 0.01)), float(cal.get("backlash_arcmin", 1.0))
    )[1]


def _subset(ts: Any, idx: np.ndarray) -> Any:
    """The screws ``idx`` of a plan, in that order (by index: an id may hold any text, a comma too)."""
    from arcube.io import TrajectorySet

    idx = np.asarray(idx, dtype=np.intp)
    return TrajectorySet(
        tuple(ts.ids[i] for i in idx),
        tuple(ts.levels[i] for i in idx),
        tuple(ts.sides[i] for i in idx),
        np.asarray(ts.entry)[idx],
        np.asarray(ts.target)[idx],
        ts.source,
        None if ts.pedicle is None else np.asarray(ts.pedicle)[idx],
    )


def _groups(ts: Any, by_side: dict[str, Any], by_sides: bool = False) -> list[tuple[str, np.ndarray, Any]]:
    """(docking name, screw indices, design) per docking: one for a design of one docking (named by its screws' side, or
    ``both``; one per side with ``by_sides``: a docking of one side, whose registration is about its own screws), one
    per side for a robot with dockings."""
    if "" in by_side:
        sides = list(dict.fromkeys(ts.sides))
        if by_sides and len(sides) > 1:
            return [(sd, np.array([i for i, s in enumerate(ts.sides) if s == sd]), by_side[""]) for sd in sides]
        return [(sides[0] if len(sides) == 1 else "both", np.arange(len(ts.ids)), by_side[""])]
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
    docking, deciding = [""] * J, [""] * J
    for idx, r in results:
        offsets[:, idx] = r.offsets
        for k, i in enumerate(idx):
            docking[i] = r.docking[k]
            deciding[i] = r.deciding[k]
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
        tuple(deciding),
    )
