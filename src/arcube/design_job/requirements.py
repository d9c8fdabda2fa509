"""The requirements of a buildable robot (``arcube design``) and their check by the NumPy reference.

A requirement is a limit on one figure over the points where it applies:

* ``clearance`` >= 5 mm and ``self_clearance`` >= 2 mm (model §14.3), and ``envelope_clearance`` >= 10 mm
  (the envelope of the whole patient and the table, model §19.5) over each trajectory's whole line, from
  its standoff to its target (model §17.1): the robot must pull the drill out;
* ``lateral_error`` <= 0.5 mm, ``axis_error`` <= 0.25 deg (15.2), ``torque`` <= 20 N m (15.3) and
  ``holding_torque`` <= 20 N m (18.2: the robot's weight with the drilling loads, the masses of
  :class:`arcube.options.Masses`) where the drill works, from entry to target;
* optional, the accuracy of the robot as built (model §20.3, under ``--class`` and ``--tol``; not by default):
  ``lateral_error_wc`` (first-order worst case) and ``lateral_error_rms`` (mm) where the drill works; the
  ``part`` of their row is the error source with the largest share at the tightest point;
* optional, on the drilling program of the chosen design (model §18.3; a program cannot be built
  inside the optimizer, so these are checked, not searched for): ``torque_peak`` (N m) and
  ``power_peak`` (W), the largest over the actuators of ``program.json``'s motor figures;
* and always: every point of every line reachable with the guards of model §8.2 (rho_max 75 deg,
  transmission 20 deg, kappa_max 100, a single assembly mode) in one working mode.

:func:`assess` re-evaluates a design with the NumPy reference (not the kernel the optimizer ran)
and returns one row per requirement: its limit, the value, the margin, pass or fail, where it
is tightest (patient, trajectory, segment, point, part or actuator), and its ``violation``: the
requirement's term of model §16's graded violation, a pure number on one scale for every row (see :func:`assess`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.performance import ACTUATOR_NAMES
from arcube.evaluation.reference import FAILURES, GRADE_SCALES, IK_FAILURES, _guard_checks
from arcube.evaluation.standoff import approach_lines
from arcube.evaluation.task import build_task
from arcube.metrics import METRICS, metric
from arcube.model.body import PART_NAMES
from arcube.model.design import unpack
from arcube.model.mechanism import inverse_kinematics
from arcube.optimization.settings import RunSettings
from arcube.options import GUARDED_OPTIONS, Options

__all__ = [
    "CHECKED_AFTER",
    "DEFAULTS",
    "DOCKING_KEYS",
    "PROGRAM_FIGURES",
    "REQUIREMENTS",
    "Requirement",
    "assess",
    "design_settings",
    "guard_terms",
    "judge",
    "normalized_shortfall",
    "program_rows",
    "requirement_figure",
    "requirements_from",
    "write_requirements_csv",
]

REQUIREMENTS: dict[str, tuple[str, str, str]] = {
    m.name: (m.requirement, m.unit, m.where) for m in METRICS if m.requirement
}  # type: ignore[misc]
"""Each requirement's kind (``min``: value >= limit, ``max``: value <= limit), unit and where it holds (:mod:`arcube.metrics`)."""
PROGRAM_FIGURES: dict[str, str] = {m.name: m.program_key for m in METRICS if m.requirement and m.program_key}  # type: ignore[misc]
"""The requirements on the drilling program: their figure in each actuator's ``motors`` entry of program.json."""
CHECKED_AFTER: tuple[str, ...] = tuple(m.name for m in METRICS if m.requirement and m.checked_after)
"""The requirements checked on the chosen robot only, not searched for: the program's figures, and the breach probability
(model §22.4: a Monte Carlo is too slow for every candidate; the search can bound it through lateral_error_rms)."""
DOCKING_KEYS: dict[str, str] = {m.name: m.docking_key for m in METRICS if m.requirement and m.docking_key}  # type: ignore[misc]
"""The requirements each docking's entry of a design job's summary.json carries, and their fields there."""
DEFAULTS: dict[str, float] = {m.name: m.default_limit for m in METRICS if m.requirement and m.default_limit is not None}
"""The limits of ``arcube design`` unless changed (``--min clearance=8``) or dropped (``--no-clearance``)."""
_GUARDS = ("guard/rho_max", "guard/transmission", "guard/kappa_max", "guard/single_assembly_mode")
_CLEARANCE_SCALES = {"clearance_mm": "clearance", "self_clearance_mm": "clearance", "envelope_clearance_mm": "envelope"}
"""The key of :data:`~arcube.evaluation.reference.GRADE_SCALES` (model §16's scale S) of each clearance guard, by the
:attr:`~arcube.metrics.Metric.guard_option` of its requirement."""


@dataclass(frozen=True)
class Requirement:
    """One limit: ``name`` (a key of :data:`REQUIREMENTS`), its kind and value."""

    name: str
    kind: str
    limit: float


def requirements_from(
    minima: Mapping[str, float] | Sequence[str] | str | None = None,
    maxima: Mapping[str, float] | Sequence[str] | str | None = None,
    drop: Sequence[str] = (),
) -> list[Requirement]:
    """The defaults, changed by ``minima`` / ``maxima`` and without the names in ``drop`` (checked).

    ``minima`` / ``maxima``: name -> limit, or ``"NAME=VALUE"`` texts as the command line gives them
    (:func:`arcube.coerce.limit_pairs`: a name given twice, or a value such as ``1_5``, is refused);
    a requirement both changed and dropped is a contradiction, refused too."""
    from arcube.coerce import limit_pairs

    limits = dict(DEFAULTS)
    for name in drop:
        if name not in REQUIREMENTS:
            raise InputError.of(
                "requirements.drop", f"{name!r}: unknown requirement (known: {', '.join(REQUIREMENTS)})"
            )
    for kind, given in (("min", minima), ("max", maxima)):
        param = f"requirements.{kind}"
        for name, v, shown in limit_pairs(given, param=param, example="clearance=5" if kind == "min" else "torque=20"):
            if name not in REQUIREMENTS:
                raise InputError.of(param, f"{name!r}: unknown requirement (known: {', '.join(REQUIREMENTS)})")
            if REQUIREMENTS[name][0] != kind:
                raise InputError.of(
                    param,
                    f"{name!r}: a {REQUIREMENTS[name][0]}imum requirement, give it as {REQUIREMENTS[name][0]} {name}=VALUE",
                )
            if metric(name).unit == "probability" and not 0.0 < v <= 1.0:
                raise InputError.of(param, f"{shown}: a probability, in (0, 1]")
            if not v >= 0.0 or (kind == "max" and v == 0.0):
                raise InputError.of(
                    param, f"{shown}: the limit must be a finite number {'> 0' if kind == 'max' else '>= 0'}"
                )
            if name in drop:
                raise InputError.of(
                    param, f"{shown}: the {name} requirement is also dropped; limit it or drop it, not both"
                )
            limits[name] = v
    for name in drop:
        limits.pop(name, None)
    return [Requirement(n, REQUIREMENTS[n][0], v) for n, v in limits.items()]


def design_options(reqs: Sequence[Requirement], base: Options = GUARDED_OPTIONS) -> Options:
    """The evaluation options of a design problem: the guards of 8.2 and, for each ``min`` requirement the search meets
    as a guard (:attr:`arcube.metrics.Metric.guard_option`: the clearances), its limit (None where dropped)."""
    limit = {r.name: r.limit for r in reqs}
    return base.replace(**{m.guard_option: limit.get(m.name) for m in METRICS if m.guard_option})


def _where(patient: int, ids: Sequence[str], segment: str, n_points: int, index: int) -> dict[str, Any]:
    return {"patient": patient + 1, "trajectory": ids[index // n_points], "segment": segment, "point": index % n_points}


def assess(
    designs: Sequence[Any],
    mode: Any,
    plans: Sequence[Any],
    anatomies: Sequence[Any],
    reqs: Sequence[Requirement],
    *,
    options: Options,
    points: int,
    standoff_mm: float,
    engine: str = "numpy",
    envelopes: Sequence[Any] = (),
    accuracy: Any = None,
) -> list[dict[str, Any]]:
    """One row per requirement (and per guard of 8.2, and reach): the worst over every patient.

    ``designs``: per patient, a ``(27,)`` vector; ``plans``: per patient a TrajectorySet; ``anatomies``:
    per patient an :class:`~arcube.evaluation.anatomy.Anatomy` or None; ``mode``: four signs; ``envelopes``:
    per patient the envelope of model §19.5 (an :class:`~arcube.evaluation.envelope.Envelope`), or ();
    ``accuracy``: the :class:`~arcube.accuracy.settings.ToleranceSettings` of ``lateral_error_wc`` and
    ``lateral_error_rms`` (default class m), computed by the NumPy first order of model §20.3.

    Each row's ``violation`` is its term of model §16's graded violation, the worst over the patients, a pure number
    comparable across rows whatever their units (:func:`arcube.design_job.coverage.binding_row` ranks by it; ``value``,
    ``margin`` and ``unit`` stay the requirement's own):

    * ``reach``: V_reach over the patient's points (the plan's and the approach lines'): the fraction where the inverse
      kinematics has no solution or eta_L = inf, and, with the z-dyad guard on, where the z dyad cannot close (§16's
      amendment: the dyad is closed with the design's own c_z, 19.2), plus their domain excess; 0 when only guards fail;
    * each guard of model §8.2 (``value``: its failing points) and each clearance requirement (a guard of 14.3 and 19.5):
      the mean over the points of min(s / S, 1), s its shortfall at the point and S its scale (clearances 10 mm, rho_max
      10 deg, each transmission sine sin 20 deg, kappa_max kappa_max, 1 outside the majority assembly mode), counted
      where the inverse kinematics solves the point, also where another guard fails first (so a guard row met can carry
      a violation); a point adds one such term per transmission sine;
    * every other requirement, a limit: its normalized shortfall (:func:`normalized_shortfall`);
    * NaN where the value is not measured (no point where it holds is reached).
    """
    holding = any(r.name == "holding_torque" for r in reqs)  # model §18.2 (needs a valid mass model)
    opts = options.replace(
        outputs=options.outputs.replace(
            clearances=True, tip_metrics=True, clearance_min_exact=True, holding_torque=holding
        )
    )
    worst: dict[str, dict[str, Any]] = {}
    reach = {
        "requirement": "reach",
        "kind": "min",
        "limit": 1.0,
        "value": 1.0,
        "unit": "fraction",
        "where": {},
        "part": "",
    }
    guard_fail = {g: 0 for g in _GUARDS}
    # model §16: V_reach, and each guard's (and clearance requirement's) term of G, the worst over the patients
    ik_last = IK_FAILURES + int(opts.guards.z_dyad)  # the z dyad's code is an IK failure (§16's amendment, 19.2)
    reach_violation, fit = 0.0, dict[str, float]()
    for p, (x, plan, anat) in enumerate(zip(designs, plans, anatomies)):
        dist = None if anat is None else anat.distance
        env = envelopes[p] if envelopes else None
        drill = build_task(plan.entry, plan.target, points)
        E_a, e_a = approach_lines(plan.entry, plan.target, anat, points, standoff_mm)
        xv = np.asarray(x, float)
        own = _own_c_z(xv, opts)
        v_reach, n_points, sums = 0.0, 0, dict.fromkeys(fit, 0.0)
        for segment, E, e in (("drill", drill.E, drill.e), ("approach", E_a, e_a)):
            res = evaluate_task(xv, E, e, mode, opts, engine=engine, anatomy=dist, envelope=env, c_z=own)
            pts = res.points
            ok = np.asarray(pts.reachable)
            failure = np.asarray(pts.failure)
            frac = float(ok.mean())
            if frac < reach["value"]:
                bad = int(np.argmin(ok))
                reach.update(
                    value=frac, where=_where(p, plan.ids, segment, points, bad), part=FAILURES[failure[bad] - 1]
                )
            for g in _GUARDS:
                guard_fail[g] += int(np.sum(failure == FAILURES.index(g) + 1))
            v_reach += float(res.violation_reach)
            n_points += failure.size
            solved = (failure == 0) | (failure > ik_last)  # the points the inverse kinematics solves (model §16)
            for name, term in guard_terms(xv, E, e, mode, opts, pts, solved).items():
                sums[name] = sums.get(name, 0.0) + float(np.sum(term))
            robust = None
            if segment == "drill" and any(r.name in ROBUST_FIGURES for r in reqs):
                robust = robust_figures(xv, E, e, mode, accuracy)
            for r in reqs:
                if (segment == "approach" and REQUIREMENTS[r.name][2] == "drill") or r.name in CHECKED_AFTER:
                    continue
                if r.name in ROBUST_FIGURES:
                    values, part = robust[r.name]  # type: ignore[index]
                else:
                    values, part = requirement_figure(pts, r.name, () if env is None else tuple(env.names))
                values = np.where(np.isfinite(values), values, np.nan)
                scale = _clearance_scale(r.name)
                if scale is not None:  # a guard of model §16: min(s / S, 1) at each point the IK solves
                    term = np.minimum(np.maximum(r.limit - values, 0.0) / scale, 1.0)
                    sums[r.name] = sums.get(r.name, 0.0) + float(np.sum(np.where(solved, np.nan_to_num(term), 0.0)))
                if np.all(np.isnan(values)):
                    continue
                i = int(np.nanargmin(values) if r.kind == "min" else np.nanargmax(values))
                v = float(values[i])
                old = worst.get(r.name)
                if old is None or (v < old["value"] if r.kind == "min" else v > old["value"]):
                    worst[r.name] = {"value": v, "where": _where(p, plan.ids, segment, points, i), "part": part(i)}
        reach_violation = max(reach_violation, v_reach)
        for name, total in sums.items():
            fit[name] = max(fit.get(name, 0.0), total / n_points)
    reach["violation"] = reach_violation
    rows = [reach]
    for g in _GUARDS:
        rows.append(
            {
                "requirement": g.split("/")[1],
                "kind": "max",
                "limit": 0.0,
                "value": float(guard_fail[g]),
                "unit": "failing points",
                "where": {},
                "part": "",
                "violation": fit.get(g.split("/")[1], 0.0),
            }
        )
    for r in (r for r in reqs if r.name not in CHECKED_AFTER):  # the program's and the breach's rows come after
        w = worst.get(r.name, {"value": math.nan, "where": {}, "part": ""})
        row = {"requirement": r.name, "kind": r.kind, "limit": r.limit, "unit": REQUIREMENTS[r.name][1], **w}
        if _clearance_scale(r.name) is not None:
            row["violation"] = fit.get(r.name, 0.0) if math.isfinite(w["value"]) else math.nan
        rows.append(row)
    return judge(rows)


def _clearance_scale(name: str) -> float | None:
    """Model §16's scale S (mm) of a requirement the search meets as a guard (the clearances), None for a limit."""
    option = metric(name).guard_option
    return None if option is None else GRADE_SCALES[_CLEARANCE_SCALES[option]]


def _own_c_z(x: np.ndarray, options: Options) -> float | None:
    """The design's own z-dyad link (mm) when the z-dyad guard is on, so that an open dyad is a point not reached
    (model §16's amendment): the options' c_z (the design job sets the design's, 19.2), else d_z (19.1); None when off."""
    if not options.guards.z_dyad:
        return None
    return float(options.guards.c_z) if options.guards.c_z is not None else float(unpack(x).d[2])


def guard_terms(
    x: np.ndarray, E: np.ndarray, e: np.ndarray, mode: Any, options: Options, pts: Any, solved: np.ndarray
) -> dict[str, np.ndarray]:
    """Per point ``(P,)``, each active guard of model §8.2's term of model §16's G, by the guard's row name: min(s / S, 1)
    with the reference's scales (:data:`~arcube.evaluation.reference.GRADE_SCALES`; the transmission's summed over its
    seven sines; ``kappa_max``'s scale kappa_max), and for ``single_assembly_mode`` 1 outside the task's majority
    assembly mode (taken, as the reference does, over the points that pass every other guard); 0 where the inverse
    kinematics does not solve the point (``solved`` ``(P,)``). The z dyad is not among them (an IK failure, §16's
    amendment). ``pts``: the task's :class:`~arcube.evaluation.reference.PointResults` of design ``x`` ``(27,)`` at
    (E, e) ``(P, 3)`` with ``options``."""
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(x, E, e, np.asarray(mode, float))
        kappa = np.asarray(pts.kappa, float)
        eta = np.max(
            np.where(np.isnan(kappa), np.inf, kappa), axis=-1
        )  # eta_L before the guards, inf without a solution
        out = {
            reason.split("/")[1]: np.where(solved, grade, 0.0)
            for reason, _, grade in _guard_checks(sol, x, eta, options)
            if reason != "guard/z_dyad"
        }
        if options.guards.single_assembly_mode:
            asm = sol.assembly
            code = ((asm[..., 0] > 0) * 4 + (asm[..., 1] > 0) * 2 + (asm[..., 2] > 0)).astype(np.int64)
            failure = np.asarray(pts.failure)
            before = (failure == 0) | (failure == FAILURES.index("guard/single_assembly_mode") + 1)
            majority = int(np.argmax(np.bincount(code[before], minlength=8)))  # ties: the lowest code
            out["single_assembly_mode"] = np.where(solved & (code != majority), 1.0, 0.0)
    return out


def judge(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each row's margin (value - limit for ``min``, limit - value for ``max``) and pass/fail (NaN fails); and its
    ``violation``, unless the row carries one (:func:`assess`'s reach, guards and clearances): the normalized shortfall
    of a limit (:func:`normalized_shortfall`)."""
    for row in rows:
        v, lim = row["value"], row["limit"]
        row["margin"] = (v - lim) if row["kind"] == "min" else (lim - v)
        row["passed"] = bool(math.isfinite(v) and row["margin"] >= 0.0)
        row.setdefault("violation", normalized_shortfall(row["kind"], lim, row["margin"]))
    return rows


def normalized_shortfall(kind: str, limit: float, margin: float) -> float:
    """A limit's term of model §16's G from its margin, as the optimizer grades a --max / --min
    (:func:`arcube.optimization.objectives.limit_shortfall`): (value - limit) / limit above a ``max``, (limit - value) /
    max(|limit|, 1) below a ``min``, 0 when met; NaN for a margin not measured or a ``max`` of 0 (no scale)."""
    if not isinstance(margin, (int, float)) or not math.isfinite(margin) or (kind == "max" and not limit):
        return math.nan
    return max(-float(margin), 0.0) / (abs(float(limit)) if kind == "max" else max(abs(float(limit)), 1.0))


def program_rows(reqs: Sequence[Requirement], motors: Mapping[str, Mapping[str, float]] | None) -> list[dict[str, Any]]:
    """The rows of the program requirements in ``reqs`` from a program's motor figures (None: no program,
    every such requirement fails); ``part`` names the actuator that attains the value."""
    rows = []
    for r in reqs:
        if r.name not in PROGRAM_FIGURES:
            continue
        key = PROGRAM_FIGURES[r.name]
        value, part = math.nan, ""
        for name, fig in (motors or {}).items():
            v = fig.get(key)
            if isinstance(v, (int, float)) and math.isfinite(v) and not v <= value:
                value, part = float(v), name
        rows.append(
            {
                "requirement": r.name,
                "kind": r.kind,
                "limit": r.limit,
                "unit": REQUIREMENTS[r.name][1],
                "value": value,
                "where": {},
                "part": part,
            }
        )
    return judge(rows)


ROBUST_FIGURES = tuple(m.name for m in METRICS if m.requirement and m.source == "robust")
"""The requirements on the robot as built (model §20.3), from the first order rather than a point result."""


def robust_figures(
    x: np.ndarray, E: np.ndarray, e: np.ndarray, mode: Any, accuracy: Any = None
) -> dict[str, tuple[np.ndarray, Any]]:
    """Per point, the first-order worst-case and RMS lateral errors (mm) of design ``x`` ``(27,)`` at (E, e) ``(P, 3)``
    (NaN where the point is not reached), each with index -> the source with the largest share there."""
    from arcube.accuracy.first_order import first_order
    from arcube.accuracy.settings import ToleranceSettings
    from arcube.accuracy.sources import SOURCE_NAMES, sigmas

    s = ToleranceSettings() if accuracy is None else accuracy
    T = s.tolerances(x)
    fo = first_order(x, E, e, np.asarray(mode, float), T, sigmas(T, s.distribution))
    share = np.asarray(fo.share)

    def top(i: int) -> str:
        return (
            SOURCE_NAMES[int(np.nanargmax(share[i]))] if np.isfinite(share[i]).any() and np.nanmax(share[i]) > 0 else ""
        )

    return {
        "lateral_error_wc": (np.asarray(fo.lateral_wc_mm, float), top),
        "lateral_error_rms": (np.asarray(fo.lateral_rms_mm, float), top),
    }


def requirement_figure(pts: Any, name: str, regions: Sequence[str] = ()) -> tuple[np.ndarray, Any]:
    """(values per point, index -> part or actuator name) of a requirement's figure, from a result's
    ``points`` (:class:`arcube.evaluation.reference.PointResults`): the metric's ``point_field``, named by its
    ``part_field`` (:mod:`arcube.metrics`); ``regions``: the envelope's region names, for ``envelope_clearance``'s
    part (``drill_motor vs head``)."""
    m = metric(name)
    values = np.asarray(getattr(pts, m.point_field), float)  # type: ignore[arg-type]
    if m.part_names == "envelope":
        part, region = np.asarray(getattr(pts, m.part_field)), np.asarray(pts.envelope_region)  # type: ignore[arg-type]

        def where(i: int) -> str:
            body = PART_NAMES[part[i]] if part[i] >= 0 else ""
            return f"{body} vs {regions[region[i]]}" if body and regions and region[i] >= 0 else body

        return values, where
    if m.part_field is None:
        return values, lambda i: ""
    names = {"parts": PART_NAMES, "actuators": ACTUATOR_NAMES}[m.part_names]
    index = np.asarray(getattr(pts, m.part_field))
    return values, lambda i: names[index[i]] if index[i] >= 0 else ""


CSV_COLUMNS = (
    "requirement",
    "kind",
    "limit",
    "value",
    "unit",
    "margin",
    "passed",
    "docking",
    "patient",
    "trajectory",
    "segment",
    "point",
    "part",
)
"""The columns of ``requirements.csv`` (``docking``: where the requirement is tightest, ``<patient>_<side>``, model §19.4)."""


def requirements_csv(rows: Sequence[Mapping[str, Any]]) -> str:
    """``requirements.csv``'s text: one row per requirement, numbers in full precision."""
    import csv
    import io

    buf = io.StringIO()
    writer = csv.writer(
        buf, lineterminator="\n"
    )  # a field with a comma (a part: "c_z 277.4 mm, d_z 85.3 mm") is quoted
    writer.writerow(CSV_COLUMNS)
    for row in rows:
        w = row.get("where") or {}
        writer.writerow(
            [
                row["requirement"],
                row["kind"],
                repr(float(row["limit"])),
                "" if not math.isfinite(row["value"]) else repr(float(row["value"])),
                row["unit"],
                "" if not math.isfinite(row["margin"]) else repr(float(row["margin"])),
                "pass" if row["passed"] else "fail",
                str(row.get("docking", "")),
                str(w.get("patient", "")),
                str(w.get("trajectory", "")),
                str(w.get("segment", "")),
                str(w.get("point", "")),
                row.get("part", ""),
            ]
        )
    return buf.getvalue()


def write_requirements_csv(path: Any, rows: Sequence[Mapping[str, Any]]) -> None:
    """Write ``requirements.csv`` atomically."""
    from arcube.io.files import atomic_write_text

    atomic_write_text(path, requirements_csv(rows))


def design_settings(reqs: Sequence[Requirement], settings: RunSettings | None = None, **fields: Any) -> RunSettings:
    """The optimization a design job runs: ``settings`` (budget, engine, anatomy, objective ...) with
    the robot's 22 parameters (c_z among them, model §19.1), each docking's placement and the working mode
    free, the guards of 8.2 and the z dyad (19.2), the clearance guards and the limits of ``reqs``, the standoff
    lines of model §17.1 (20 mm unless set), the envelope of the whole patient (19.5: ``default`` unless
    set), one docking per side unless ``dockings`` is set, and the worst docking's eta_G unless ``aggregate`` is."""
    from arcube.optimization.config import run_settings

    s = run_settings(settings, **fields)
    if not s.anatomy and any(r.name == "clearance" for r in reqs):  # before the guard below would blame its own field
        raise InputError.of(
            "RunSettings.anatomy",
            "is needed by the clearance requirement (anatomy default, mesh files or a "
            "segmentation); or drop the clearance requirement",
        )
    maxima = {
        r.name: r.limit for r in reqs if r.kind == "max" and r.name not in CHECKED_AFTER
    }  # checked on the chosen robot
    options = design_options(reqs, s.options).replace(z_dyad=True)
    envelope = s.envelope if "envelope" in s.model_fields_set else ("default",)
    if envelope == ("none",) and any(r.name == "envelope_clearance" for r in reqs):
        raise InputError.of(
            "RunSettings.envelope",
            "is none, but the envelope_clearance requirement needs one (envelope default or a skin "
            "mesh); or drop the requirement",
        )
    dockings = s.dockings if s.dockings is not None or s.setups != 1 else "per-side"
    aggregate = s.aggregate if "aggregate" in s.model_fields_set else "max"
    algorithm = (
        s.algorithm if "algorithm" in s.model_fields_set or dockings is None else "docked"
    )  # mscmaes with one docking
    return s.replace(
        free=["all", "mount", "L", "c_z"],
        mode="free",
        guarded=True,
        maxima={**s.maxima, **maxima},
        options=options,
        standoff=20.0 if s.standoff is None else s.standoff,
        envelope=envelope,
        dockings=dockings,
        aggregate=aggregate,
        placement="per-patient",
        algorithm=algorithm,
    )
