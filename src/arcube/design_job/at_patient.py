"""The robot at this patient (model §19.6, 22): which docking drills a plan's screws, and which screws it reaches.

A breach figure belongs to the robot docked at the patient whose plan it is given (:func:`breach`, ``arcube breach``):

* a robot's ``design.json`` (the robot and its dockings, ``arcube design``): each side is drilled from the robot's
  docking of this plan, told by its trajectories' digests (:func:`~arcube.model.robot.trajectory_digests`), not by the
  patient's name; a side the robot has no docking of is docked first, as ``arcube dock`` docks it, and the result says
  so (``settings["dockings"]``);
* a docking file (``dockings/<patient>_<side>/design.json``) or a calibrated ``design.json`` that records whose plan it
  docks (``plan_digest``): refused on another patient's plan; the screws of the other side are not its docking's (not
  reached); a file that records no plan is used as given, and the result says it was not checked;
* a plain design (a preset, a Design, a design file without a patient): used as given.

Then each screw's trajectory is judged as the design job judges it (:func:`~arcube.design_job.outputs.docking_evaluation`:
the NumPy reference at the plan's points, the guards, the z dyad with the robot's c_z, the clearances to the anatomy and
the envelope, as ``arcube dock`` sets them up): a screw whose trajectory is not 100 % reachable there is not reached and
gets no P(breach) (model §22: one truth per screw, the same "reached" as the docking's report).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.design_job.dock import DOCK_EVALUATIONS, DockingJob, docking_inputs, solve_docking
from arcube.design_job.outputs import docking_evaluation, trajectory_failures, trajectory_verdict
from arcube.errors import InputError
from arcube.model.design import Design
from arcube.model.robot import PLAN_DIGEST, BuiltRobot, read_robot, trajectory_digests
from arcube.optimization.config import PatientPlan

__all__ = ["AtPatient", "breach", "has_default_anatomy", "robot_at_patient"]

PATIENT_KEYS = ("anatomy", "anatomy_frame", "segments", "envelope", "table_z")
"""The keywords of :func:`breach` that say what surrounds the plan (as ``arcube dock`` takes them)."""


@dataclass(frozen=True)
class AtPatient:
    """One docking that drills some of a plan's screws: the docking's name (its side, R or L, or ``""`` for one design
    over the whole plan), the design at that docking, the screws' indices ``(k,)`` into the plan, the verdict ``(k,)``
    of each screw's trajectory, and how the docking was found (a sentence)."""

    group: str
    label: str
    design: Design
    screws: np.ndarray
    verdict: np.ndarray
    why: dict[str, str]  # screw id -> why the design job refuses its trajectory (the report's first failure)
    how: str


def _json_object(source: Any) -> dict[str, Any] | None:
    """The JSON object of a ``.json`` design file, None for anything else."""
    from arcube.io.inputs import load_json

    if not isinstance(source, (str, os.PathLike)) or Path(source).suffix.lower() != ".json":
        return None
    data = load_json(Path(source))
    return data if isinstance(data, dict) else None


def has_default_anatomy(plan: Any) -> bool:
    """Whether ``plan`` has a default anatomy: the reference patient's, or the file ``arcube patients`` wrote beside it."""
    from arcube.evaluation.anatomy import _default_file

    if plan is None or (isinstance(plan, str) and plan == "reference"):
        return True
    if not isinstance(plan, (str, os.PathLike)):
        return False
    try:
        _default_file(os.fspath(plan))
    except InputError:
        return False
    return True


def _settings(patient: Mapping[str, Any], ts_fields: Mapping[str, Any], plan: Any) -> tuple[Any, list[Any]]:
    """The design job's settings and requirements (:func:`~arcube.design_job.requirements.design_settings`) with the
    patient around the plan as ``arcube dock`` takes it (its default anatomy, where it has one, unless told); a
    requirement that needs what is not given (the clearance without an anatomy, the envelope clearance without an
    envelope) is left out. A plan without an anatomy given or of its own is judged without the envelope too (unless
    told): the envelope is placed on the skin the anatomy gives, and a guess would refuse what the patient allows."""
    from arcube.design_job.requirements import design_settings, requirements_from
    from arcube.optimization.config import run_settings

    fields = {k: v for k, v in patient.items() if v is not None}
    if "anatomy" not in fields and not has_default_anatomy(plan):
        fields["anatomy"] = "none"
        fields.setdefault("envelope", "none")
    fields.setdefault("anatomy", "default")
    s = run_settings(None, **fields, **{k: v for k, v in ts_fields.items() if v is not None})
    drop = [] if s.anatomy else ["clearance"]
    if "envelope" in s.model_fields_set and s.envelope == ("none",):
        drop.append("envelope_clearance")
    reqs = requirements_from(drop=drop)
    return design_settings(reqs, s), reqs


def _job(
    robot: BuiltRobot, name: str, spec: Any, side: str | None, s: Any, reqs: Sequence[Any], **kw: Any
) -> DockingJob:
    return DockingJob(
        robot,
        PatientPlan(name, spec),
        side,
        s,
        tuple(reqs),
        int(kw.get("seed", 1)),
        int(kw.get("starts", 8)),
        int(kw.get("evaluations", DOCK_EVALUATIONS)),
        str(kw.get("folder", "")),
    )


def _judged(dock: Any, s: Any, idx: np.ndarray, ids: Sequence[str]) -> tuple[np.ndarray, dict[str, str]]:
    """The design job's verdict ``(len(idx),)`` of the screws ``idx`` of the plan (ids ``ids``) at the docking ``dock``
    (its design, plan, anatomy and envelope), and why it refuses those it refuses."""
    ev = docking_evaluation(dock, s)
    by_id = dict(zip(dock.plan.ids, trajectory_verdict(ev)))
    verdict = np.array([bool(by_id.get(ids[i], False)) for i in idx], dtype=bool)
    failures = trajectory_failures(ev)
    why = {ids[i]: failures.get(ids[i], "not in the docking's plan") for i, ok in zip(idx, verdict) if not ok}
    return verdict, why


def _verdict(job: DockingJob, design: Design, idx: np.ndarray, ids: Sequence[str]) -> tuple[np.ndarray, dict[str, str]]:
    """:func:`_judged` at ``design``, docked as ``job`` says (its plan, anatomy and envelope as arcube dock sets them)."""
    _, dock, s, _ = docking_inputs(job)
    dock.design = design
    if design.c_z is None:  # a plain design without c_z: judged without its z dyad, as arcube evaluate judges it
        s = s.replace(options=s.options.replace(z_dyad=False))
    return _judged(dock, s, idx, ids)


def robot_at_patient(
    design: Any,
    plan: Any,
    ts: Any,
    *,
    name: str,
    mode: Any = None,
    side: str | None = None,
    patient: Mapping[str, Any] | None = None,
    ts_fields: Mapping[str, Any] | None = None,
    seed: int = 1,
    evaluations: int = DOCK_EVALUATIONS,
    say: Callable[[str], None] | None = None,
) -> list[AtPatient]:
    """The dockings that drill the screws of ``ts`` (the selected plan; ``plan`` what it was read from), one per group
    of screws (module docstring): the robot file's docking of this plan, the robot docked first where it has none, or
    the design as given; each with the design job's verdict of its screws. ``name``: the patient's name; ``patient``:
    anatomy, envelope ... (:data:`PATIENT_KEYS`); ``ts_fields``: transform, levels, ids, as the plan was selected."""
    data = _json_object(design)
    s, reqs = _settings(patient or {}, ts_fields or {}, plan)
    if data is not None and isinstance(data.get("dockings"), list) and "m_x" not in data:
        return [
            _robot_side(design, read_robot(design), plan, ts, sd, name, s, reqs, seed, evaluations, say)
            for sd in dict.fromkeys(ts.sides)
        ]
    if isinstance(design, Mapping):  # the caller's dockings, as they are
        out = []
        for sd, d in design.items():
            idx = np.flatnonzero(np.array(ts.sides) == sd) if sd else np.arange(len(ts.ids))
            robot = _as_robot(Design.coerce(d), mode, "given")
            job = _job(robot, name, plan, sd or side, s, reqs)
            out.append(
                AtPatient(sd, sd or "given", robot.design, idx, *_verdict(job, robot.design, idx, ts.ids), "as given")
            )
        return out
    return [_one_design(design, data, plan, ts, name, mode, side, s, reqs)]


def _as_robot(design: Design, mode: Any, source: str) -> BuiltRobot:
    """A design as a robot to judge (its working mode given or its own); InputError naming ``mode`` without one."""
    from arcube.coerce import mode_text

    text = mode if mode is not None else design.mode
    if text is None:
        raise InputError.of("mode", "is not in the design file: give the robot's working mode (e.g. +,+,+,-)")
    return BuiltRobot(source, design.with_extras(mode=mode_text(text)), ())


def _robot_side(
    design: Any,
    robot: BuiltRobot,
    plan: Any,
    ts: Any,
    sd: str,
    name: str,
    s: Any,
    reqs: Sequence[Any],
    seed: int,
    evaluations: int,
    say: Callable[[str], None] | None,
) -> AtPatient:
    """One side of a robot file: its docking of this plan's side-``sd`` trajectories, else the robot docked first."""
    idx = np.flatnonzero(np.array(ts.sides) == sd)
    digests = trajectory_digests(ts.entry[idx], ts.target[idx])
    here = [w for w in robot.starts if w.side == sd and w.docks(digests)]
    unchecked = [w for w in robot.starts if w.side == sd and w.docks(digests) is None and w.label == f"{name}_{sd}"]
    if len(here) > 1:  # two dockings of the same trajectories: which one drills is the user's to say
        raise InputError.of(
            "design",
            f"{design}: the robot docks {len(here)} times on side {sd} with this plan's trajectories "
            f"({', '.join(w.label for w in here)}); give the docking of this plan's patient "
            "(dockings/<patient>_<side>/design.json)",
        )
    if here or unchecked:
        w = (here or unchecked)[0]
        placed = robot.placed(w.placement)
        how = f"the robot file's docking {w.label}" + (
            " (this plan's trajectories)" if here else " (not checked: the file records no trajectories)"
        )
        job = _job(robot, name, plan, sd, s, reqs)
        return AtPatient(sd, w.label, placed, idx, *_verdict(job, placed, idx, ts.ids), how)
    if say is not None:
        say(f"side {sd}: {design} has no docking of this plan: docking the robot first, as arcube dock does")
    with tempfile.TemporaryDirectory(prefix="arcube-breach-dock-") as tmp:
        outcome, dock, s_job = solve_docking(
            _job(robot, name, plan, sd, s, reqs, seed=seed, evaluations=evaluations, folder=tmp)
        )
        verdict, why = _judged(dock, s_job, idx, ts.ids)
    how = f"docked anew as arcube dock docks it (seed {seed}): {'met' if outcome.met else 'not met'}"
    return AtPatient(sd, f"{name}_{sd}", outcome.design, idx, verdict, why, how)


def _one_design(
    design: Any, data: dict[str, Any] | None, plan: Any, ts: Any, name: str, mode: Any, side: Any, s: Any, reqs: Any
) -> AtPatient:
    """One design over the whole plan: a docking file (its side's screws, of its patient's plan: refused on another
    patient's), or a plain design as given."""
    d = Design.coerce(design)
    robot = _as_robot(d, mode, str(design))
    sides = np.array(ts.sides)
    idx = np.arange(len(ts.ids))
    own = data.get("side") if data is not None else None
    how = "the design as given, at its own placement"
    if data is not None and own in ("R", "L"):  # a docking file: its side's screws, of its patient's plan
        who = f"the docking file of patient {data.get('patient', '?')} side {own}"
        mine = np.flatnonzero(sides == own)
        recorded = data.get(PLAN_DIGEST)
        if recorded is not None and len(mine):
            digests = trajectory_digests(ts.entry[mine], ts.target[mine])
            if not set(digests) <= set(recorded):
                raise InputError.of(
                    "design",
                    f"{design}: is the docking of patient {data.get('patient', '?')} side {own}, not of this plan's "
                    f"side-{own} trajectories ({sum(g not in recorded for g in digests)} of {len(digests)} differ): "
                    "give this patient's docking, or the robot's design.json (breach docks it first)",
                )
            how = f"{who} (this plan's trajectories)"
        else:
            other = data.get("patient") not in (None, name)
            how = f"{who} (not checked: it records no plan{f'; this plan is patient {name}' if other else ''})"
    job = _job(robot, name, plan, own if own in ("R", "L") else side, s, reqs)
    verdict, why = _verdict(job, robot.design, idx, ts.ids)
    if own in ("R", "L"):
        for j in np.flatnonzero(sides != own):
            verdict[j] = False
            why[ts.ids[j]] = f"side {ts.sides[j]}: not this docking's side ({own})"
    label = f"{data.get('patient', name)}_{own}" if data is not None and own in ("R", "L") else "given"
    if d.c_z is None:
        how += "; its z dyad not judged (the file has no c_z)"
    return AtPatient("", label, d, idx, verdict, why, how)


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
    settings: Any = None,
    loads: Any = None,
    anatomy: Any = None,
    anatomy_frame: Any = None,
    segments: Any = None,
    envelope: Any = None,
    table_z: Any = None,
    dock_seed: int = 1,
    dock_evaluations: int = DOCK_EVALUATIONS,
    say: Callable[[str], None] | None = None,
    **fields: Any,
) -> Any:
    """The breach probability of every screw of ``plan``, drilled by the robot docked at this patient (model §22,
    ``arcube breach``; module docstring for which docking).

    Args:
        design: a robot's ``design.json`` (its docking of this plan, or docked first), a docking file, a design file, a
            Design or a preset.
        plan: the plan and which of its screws (as :func:`arcube.evaluate` takes them).
        side: see ``plan``.
        levels: see ``plan``.
        ids: see ``plan``.
        transform: see ``plan``.
        out: a folder to create (new or empty): breach.csv, summary.json and the pictures; None writes nothing.
        calibration: the folder of ``arcube calibrate identify`` instead of ``design``.
        mode: the working mode (None: the design's own).
        tolerances: an :class:`arcube.ToleranceSettings` (class m by default); refused with ``calibration``.
        settings: a :class:`~arcube.pedicles.settings.BreachSettings` and changes to it (``registration_mm=1.0``).
        fields: see ``settings``.
        loads: an :class:`arcube.Loads` (the thrust and the actuators' stiffness).
        anatomy: what surrounds the plan, as ``arcube dock`` takes it (default: the plan's default anatomy, the
            default envelope), for the verdict of each screw and for a docking made first.
        anatomy_frame: see ``anatomy``.
        segments: see ``anatomy``.
        envelope: see ``anatomy``.
        table_z: see ``anatomy``.
        dock_seed: the seed of a docking made first (as ``arcube dock --seed``).
        dock_evaluations: its search's budget (as ``arcube dock --evaluations``).
        say: told what is done that takes a while (docking first).

    Returns:
        A :class:`~arcube.pedicles.monte_carlo.BreachResult`: ``status`` per screw, ``settings["dockings"]`` (how each
        docking was found) and ``settings["patient"]``.
    """
    from arcube.design_job.cohort import plans_as_cohort
    from arcube.io import TrajectorySet, load_trajectories, select
    from arcube.pedicles.geometry import pedicles
    from arcube.pedicles.run import breach as run_breach
    from arcube.pedicles.run import read_calibration

    if (
        isinstance(dock_evaluations, bool)
        or not isinstance(dock_evaluations, int)
        or not 100 <= dock_evaluations <= 10**6
    ):
        raise InputError.of("dock_evaluations", f"must be an integer in [100, 1000000], got {dock_evaluations!r}")
    ts = plan if isinstance(plan, TrajectorySet) and transform is None else load_trajectories(plan, transform)
    ts = select(ts, side=side, levels=levels, ids=ids) if (side or levels or ids) else ts
    pedicles(ts)  # a screw without a side, or without a pedicle, is refused before any docking is looked for
    name = (plans_as_cohort([plan]) or [PatientPlan("patient", plan)])[0].name
    patient = dict(zip(PATIENT_KEYS, (anatomy, anatomy_frame, segments, envelope, table_z)))
    ts_fields = {"transform": transform, "levels": levels, "ids": ids}
    common = {"mode": mode, "settings": settings, "loads": loads, "patient": name, **fields}
    if calibration is not None:
        if design is not None and not (
            isinstance(design, (str, os.PathLike))
            and Path(design).resolve() == (Path(calibration) / "design.json").resolve()
        ):
            raise InputError.of(
                "calibration",
                f"{calibration}: and design {design} are two robots: give the calibration folder alone "
                "(its design.json is the calibrated design)",
            )
        read_calibration(calibration)  # a folder that is not one is refused before anything is judged
        design = Path(calibration) / "design.json"
    elif design is None:
        raise InputError.of("design", "is required (a design file, a design job's design.json), or give calibration")
    own = _json_object(design)
    if side is not None and own is not None and own.get("side") is not None:
        from arcube.model.robot import design_at_side

        design_at_side(design, side)  # a docking (or calibration) of the other side is refused
    found = robot_at_patient(
        design,
        plan,
        ts,
        name=name,
        mode=mode,
        side=side,
        patient=patient,
        ts_fields=ts_fields,
        seed=dock_seed,
        evaluations=dock_evaluations,
        say=say,
    )
    verdict = np.zeros(len(ts.ids), dtype=bool)
    for g in found:
        verdict[g.screws] = g.verdict
    judged = _judged_with(_settings(patient, ts_fields, plan)[0])
    own_side = (_json_object(design) or {}).get("side")
    # a docking (or calibration) of one side drills each side of the plan as a docking of its own: the registration
    # of its side is about its own screws' entries, and the other side's screws are not its (model §22.2)
    by_sides = len(found) == 1 and not found[0].group and own_side in ("R", "L")
    notes = {
        key: {"docking": g.label, "how": g.how, "not_reached": g.why, "judged_with": judged}
        for g in found
        for key in (dict.fromkeys(ts.sides) if by_sides else [g.group or _group_name(ts)])
    }
    common["by_sides"] = by_sides
    if calibration is not None:
        return run_breach(
            None, ts, out, calibration=calibration, tolerances=tolerances, reached=verdict, notes=notes, **common
        )
    chosen: Any = {g.group: g.design for g in found} if found[0].group else found[0].design
    return run_breach(chosen, ts, out, tolerances=tolerances, reached=verdict, notes=notes, **common)


def _judged_with(s: Any) -> str:
    """What a screw's verdict was judged with: the anatomy and the envelope of the settings ``s``."""
    anatomy = " ".join(s.anatomy) if s.anatomy else "none"
    envelope = " ".join(s.envelope)
    return f"the design job's guards and requirements, anatomy {anatomy}, envelope {envelope}"


def _group_name(ts: Any) -> str:
    """The name :mod:`arcube.pedicles.run` gives one docking over a whole plan: its one side, or ``both``."""
    sides = set(ts.sides)
    return next(iter(sides)) if len(sides) == 1 else "both"
