"""One robot, several dockings (model §19): each docking's design, its check, and the requirements over all of them.

A design job's run holds one patient entry per docking (:func:`arcube.optimization.config.docking_groups`):
a name (the patient's), a side (``R``, ``L`` or ``both``), its trajectories, and its own placement m and
mounting angles in the run's ``best_design_p<K>.json``. :func:`run_dockings` reads them back with their
plans, anatomies and envelopes as the user gave them (not the run folder's copies: the check is
independent of the optimizer's inputs); :func:`assess_dockings` re-checks each with the NumPy reference
(:func:`arcube.design_job.requirements.assess`); :func:`merge_rows` keeps, per requirement, the docking
where it is tightest (model §19.4).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from arcube.coerce import design_mode
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.io import load_trajectories, select
from arcube.model.design import PLACEMENT, ROBOT_NAMES, Design
from arcube.optimization.config import own_settings, patient_settings
from arcube.optimization.run_config import RunConfig
from arcube.optimization.settings import RunSettings

__all__ = [
    "Docking",
    "PLACEMENT",
    "ROBOT_NAMES",
    "assess_dockings",
    "docking_entry",
    "merge_rows",
    "run_dockings",
    "warm_starts",
]


@dataclass
class Docking:
    """One docking of the robot: whose, which side, its trajectories, anatomy and envelope, and its full design."""

    name: str
    side: str
    plan: Any  # TrajectorySet: this docking's trajectories
    anatomy: Any  # Anatomy or None
    envelope: Any  # Envelope or None
    design: Design
    rows: list[dict[str, Any]] = field(default_factory=list)
    """Its requirement rows (:func:`arcube.design_job.requirements.assess`, then its program's)."""
    redocked: bool = False
    """Docked anew with the robot fixed (:mod:`arcube.design_job.redock`): its placement is not the search's."""
    breach: dict[str, Any] = field(default_factory=dict)
    """Its breach figures (model §22, :func:`arcube.design_job.outputs.breach_check`), once checked."""
    eta_G: float | None = None
    """Its eta_G at its placement: the search's (the run's task figure), or the re-docking's once docked anew."""
    search_feasible: bool | None = None
    """Whether the search called this docking feasible (its own violation V_k = 0, model §19.3)."""
    met_at_search: bool | None = None
    """Whether the re-check met it at the search's placement (plan's points, approach lines, program built)."""

    @property
    def label(self) -> str:
        """``<patient>_<side>``: its folder under ``dockings/`` and its name in tables."""
        return f"{self.name}_{self.side}"

    @property
    def met(self) -> bool:
        return bool(self.rows) and all(r["passed"] for r in self.rows)


def run_dockings(cfg: RunConfig, run: Any, mode: str) -> list[Docking]:
    """The dockings of a finished run (``run``: its :class:`~arcube.optimization.run_results.OptimizeResult`), each with
    the run's design for it (with c_z and ``mode``), its plan as the run selected it, and its anatomy and envelope."""
    from arcube.optimization.build import run_envelopes

    s = cfg.settings
    designs = run.designs
    envelopes = run_envelopes(cfg, run.path)
    plans: dict[int, Any] = {}
    anatomies: dict[int, Any] = {}
    out = []
    for k, entry in enumerate(cfg.patients):
        plan = entry.get("plan_index", k)
        spec = cfg.trajectories[plan]
        if plan not in plans:
            plans[plan] = load_trajectories(spec, s.transform)
            ps = patient_settings(s, own_settings(entry))
            anatomies[plan] = (
                resolve_anatomy(list(ps.anatomy), ps.anatomy_frame, spec, segments=ps.segments) if ps.anatomy else None
            )
        ts = select(plans[plan], ids=",".join(entry["ids"]))
        d = designs[k] if k < len(designs) else designs[0]
        out.append(
            Docking(
                str(entry.get("name", f"patient_{k + 1}")),
                str(entry.get("side", "both")),
                ts,
                anatomies[plan],
                envelopes[k] if envelopes else None,
                d.with_extras(mode=mode),
            )
        )
    return out


def assess_dockings(dockings: Sequence[Docking], reqs: Sequence[Any], s: RunSettings) -> None:
    """Fill each docking's rows: every requirement re-checked by the NumPy reference on its own lines (the plan's,
    and the approach lines from the standoffs), the z dyad closed with the design's c_z (model §19.2)."""
    from arcube.design_job.requirements import assess

    base = s.evaluation_options()
    for d in dockings:
        options = base if d.design.c_z is None else base.replace(z_dyad=True, c_z=d.design.c_z)
        rows = assess(
            [d.design.to_vector()],
            design_mode(d.design),
            [d.plan],
            [d.anatomy],
            reqs,
            options=options,
            envelopes=[d.envelope] if d.envelope is not None else (),
            points=s.points,
            standoff_mm=float(s.standoff or 0.0),
            accuracy=s.accuracy_settings(),
        )
        if d.design.c_z is not None:
            rows.insert(1, _z_dyad_row(rows, d, options, s))
        for r in rows:
            if r.get("where"):
                r["where"] = {**r["where"], "patient": d.name}
        d.rows = rows


def _z_dyad_row(rows: list[dict[str, Any]], d: Docking, options: Any, s: RunSettings) -> dict[str, Any]:
    """The z dyad's row (model §19.2): the points where it cannot close with the design's c_z, on the plan's lines and the
    approach lines (failing points, as the guards of 8.2 are counted)."""
    import numpy as np

    from arcube.evaluation.engine import evaluate_task
    from arcube.evaluation.reference import FAILURES
    from arcube.evaluation.standoff import approach_lines
    from arcube.evaluation.task import build_task

    drill = build_task(d.plan.entry, d.plan.target, s.points)
    E_a, e_a = approach_lines(d.plan.entry, d.plan.target, d.anatomy, s.points, float(s.standoff or 0.0))
    code = FAILURES.index("guard/z_dyad") + 1
    bad = 0
    only = options.replace(
        rho_max_deg=None,
        min_transmission_deg=None,
        kappa_max=None,
        single_assembly_mode=False,
        clearance_mm=None,
        self_clearance_mm=None,
        envelope_clearance_mm=None,
        outputs=options.outputs.replace(tip_metrics=False),
    )
    for E, e in ((drill.E, drill.e), (E_a, e_a)):
        res = evaluate_task(d.design.to_vector(), E, e, design_mode(d.design), only, engine="numpy")
        bad += int(np.sum(np.asarray(res.points.failure) == code))
    row = {
        "requirement": "z_dyad",
        "kind": "max",
        "limit": 0.0,
        "value": float(bad),
        "unit": "failing points",
        "where": {},
        "part": f"c_z {d.design.c_z:.1f} mm, d_z {d.design['d_z']:.1f} mm",
    }
    row["margin"] = 0.0 - row["value"]
    row["passed"] = bad == 0
    return row


def merge_rows(dockings: Sequence[Docking]) -> list[dict[str, Any]]:
    """Per requirement, the row of the docking where it is tightest (least margin; a failing or unmeasured one first),
    with ``docking`` naming it (model §19.4); the requirements in the first docking's order."""
    out: dict[str, dict[str, Any]] = {}
    for d in dockings:
        for r in d.rows:
            key = r["requirement"]
            old = out.get(key)
            if old is None or _tighter(r, old):
                out[key] = {**r, "docking": d.label}
    return list(out.values())


def _tighter(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether row ``a`` binds more than row ``b``: failing before passing, then the smaller margin (NaN: unmeasured, least)."""
    if a["passed"] != b["passed"]:
        return not a["passed"]
    ma, mb = a["margin"], b["margin"]
    ma = -math.inf if not math.isfinite(ma) else ma
    mb = -math.inf if not math.isfinite(mb) else mb
    return ma < mb


def docking_entry(d: Docking, points: bool = False) -> dict[str, Any]:
    """``{"patient", "side", "m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz"}``: one entry of a robot's ``design.json``
    ``dockings`` list (model §19.1; its full design is ``dockings/<patient>_<side>/design.json``); with ``points``
    also ``entry`` and ``target``, the docking's trajectories (mm, patient frame), which ``arcube dock`` carries onto
    a new patient's plan to start its search there (model §19.6)."""
    values = d.design.to_dict()
    out: dict[str, Any] = {"patient": d.name, "side": d.side, **{n: values[n] for n in PLACEMENT}}
    if points:
        out["entry"] = [[round(float(v), 4) for v in row] for row in d.plan.entry]
        out["target"] = [[round(float(v), 4) for v in row] for row in d.plan.target]
    return out


def warm_starts(dockings: Sequence[Docking]) -> tuple[Any, ...]:
    """Each docking as a :class:`~arcube.model.robot.WarmStart` (its placement, its trajectories' entry and target
    points, its side): where docking the robot anew starts looking."""
    from arcube.model.robot import WarmStart

    return tuple(
        WarmStart(d.label, np.array([d.design[n] for n in PLACEMENT]), d.plan.entry, d.plan.target, d.side)
        for d in dockings
    )
