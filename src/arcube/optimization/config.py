"""A run's config (what config.toml holds): validated settings, the plans' coordinates, the start design.

:func:`build_config` takes the plans and a :class:`~arcube.optimization.settings.RunSettings`
(or its fields as keywords), loads the trajectory sets and the start design, checks the anatomy
can be read, and returns the :class:`~arcube.optimization.run_config.RunConfig` that
:mod:`arcube.optimization.run` runs (and writes to ``config.toml`` for a run folder).
"""

from __future__ import annotations

import json
import secrets
from dataclasses import dataclass
from typing import Any

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.standoff import standoff_points
from arcube.io import TrajectorySet, load_trajectories, select
from arcube.model.design import Design
from arcube.optimization.algorithms import make_termination
from arcube.optimization.build import check_engine
from arcube.optimization.folder import versions
from arcube.optimization.run_config import RunConfig
from arcube.optimization.settings import MULTI_OBJECTIVE_ALGORITHMS, RunSettings
from arcube.options import Options, validated

__all__ = ["OWN", "PatientPlan", "build_config", "docking_groups", "own_settings", "patient_settings", "run_settings"]


@dataclass(frozen=True)
class PatientPlan:
    """One patient of a design problem over several (a cohort, model §19): a name, a plan, and what of the
    run's settings is this patient's own (None: the run's). Paths are as the caller resolved them."""

    name: str
    plan: Any
    """What :func:`arcube.io.load_trajectories` reads (CSV, .mrk.json, folder, ``reference``), or a TrajectorySet."""
    anatomy: tuple[str, ...] | None = None
    """``("default",)``, ``()`` (none) or mesh / segmentation files."""
    anatomy_frame: str | None = None
    segments: tuple[str, ...] | None = None
    envelope: tuple[str, ...] | None = None
    table_z: float | None = None


OWN = {
    "anatomy": "anatomy",
    "anatomy_frame": "anatomy_frame",
    "segments": "segments",
    "envelope": "envelope_spec",
    "table_z": "table_z",
}
"""The settings a :class:`PatientPlan` may set for its patient alone -> the key of its config entries that records them
(``envelope`` is the entry's placed envelope, its spec ``envelope_spec``)."""


def own_settings(entry: dict[str, Any]) -> dict[str, Any]:
    """A config entry's own settings (:data:`OWN`), by setting name."""
    return {name: entry[key] for name, key in OWN.items() if key in entry}


def patient_settings(s: RunSettings, own: dict[str, Any]) -> RunSettings:
    """The run's settings with one patient's own (:data:`OWN`, by setting name) on top."""
    changes = {k: own[k] for k in OWN if own.get(k) is not None}
    return (
        s.model_copy(update={k: (tuple(v) if isinstance(v, list) else v) for k, v in changes.items()}) if changes else s
    )


def docking_groups(ts: TrajectorySet, dockings: str | None) -> list[tuple[str, TrajectorySet]]:
    """The dockings of one plan (model §19.1): ``per-side`` one per side present (R before L), ``per-patient``
    one for the whole plan (side ``both``, or its one side), None the plan as it is (side '')."""
    if dockings is None:
        return [("", ts)]
    sides = [sd for sd in ("R", "L") if sd in ts.sides]
    if dockings == "per-side":
        return [(sd, select(ts, side=sd)) for sd in sides]
    return [(sides[0] if len(sides) == 1 else "both", ts)]


def _load_patients(specs: list[Any], s: RunSettings) -> list[dict[str, Any]]:
    patients = []
    names: list[str] = []
    for index, item in enumerate(specs):
        pat = item if isinstance(item, PatientPlan) else None
        spec = pat.plan if pat is not None else item
        own = {k: getattr(pat, k) for k in OWN if getattr(pat, k) is not None} if pat is not None else {}
        ps = patient_settings(s, own)
        full = ts = spec if isinstance(spec, TrajectorySet) else load_trajectories(spec, s.transform)
        if s.side is not None or s.levels is not None or s.ids is not None:
            ts = select(ts, side=s.side, levels=s.levels, ids=s.ids)
        if not len(ts.ids):
            raise InputError(f"{ts.source}: no trajectories to optimize over")
        if s.setups == 2:
            for sd in ("R", "L"):
                if sd not in ts.sides:
                    raise InputError.of(
                        "RunSettings.setups",
                        f"2 needs R and L trajectories; {spec} has no side {sd} (after the selection)",
                    )
        anatomy = (
            resolve_anatomy(list(ps.anatomy), ps.anatomy_frame, spec, segments=ps.segments) if ps.anatomy else None
        )
        envelope = None
        if ps.envelope != ("none",):  # model §19.5: placed once on the whole plan (both sides), kept in config.toml
            try:
                envelope = json.dumps(
                    resolve_envelope(list(ps.envelope), full, anatomy, ps.table_z, ps.anatomy_frame).to_record()
                )
            except InputError as exc:  # a cohort patient's own table_z is its file's, not the command line's
                if exc.param == "table_z" and "table_z" in own:
                    raise InputError(f"patient {pat.name}: {exc}") from None  # type: ignore[union-attr]
                raise
        name = pat.name if pat is not None else (f"patient_{index + 1}" if len(specs) > 1 else "patient")
        names.append(name)
        for side, group in docking_groups(ts, s.dockings):
            patient = {
                "source": ts.source if isinstance(spec, TrajectorySet) else str(spec),
                "ids": list(group.ids),
                "levels": list(group.levels),
                "sides": list(group.sides),
                "entry": [[float(v) for v in row] for row in group.entry],
                "target": [[float(v) for v in row] for row in group.target],
            }
            if s.dockings is not None or pat is not None:  # model §19: whose docking this is (written only then)
                patient.update(name=name, side=side or "both", plan_index=index)
            patient.update({OWN[k]: (list(v) if isinstance(v, tuple) else v) for k, v in own.items()})
            if s.standoff is not None:  # model §17.1: computed once, with the anatomy as given, and kept in config.toml
                S, _ = standoff_points(group.entry, group.target, anatomy, s.standoff)
                patient["standoff"] = [[float(v) for v in row] for row in S]
            if envelope is not None:
                patient["envelope"] = envelope
            patients.append(patient)
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError.of("plan", f"two patients are named {dup!r}: each needs its own name")
    return patients


def run_settings(settings: RunSettings | None = None, **fields: Any) -> RunSettings:
    """``settings`` with ``fields`` changed (flat names accepted: ``thrust=25``), validated once."""
    base = settings.model_dump() if settings is not None else {}
    fields = RunSettings.renamed(fields)  # an old keyword beside a settings object (which holds its new name)
    return validated(RunSettings, {**base, **fields}) if fields or settings is None else settings


def build_config(
    trajectories: list[Any],
    settings: RunSettings | None = None,
    *,
    workers: int = 1,
    dask: str | None = None,
    **fields: Any,
) -> RunConfig:
    """The run's config for these plans (each a TrajectorySet or what ``load_trajectories`` reads).

    ``workers`` and ``dask`` say where the evaluations run (recorded, not part of the settings).
    """
    s = run_settings(settings, **fields)
    if s.options.guards.c_z is not None:  # only a folder of before holds one (RunConfig.from_toml)
        raise InputError.of(
            "RunSettings.options.guards.c_z",
            "is the design's in a run (model §19.1): give RunSettings.c_z, which sets the start design's c_z",
        )
    if not trajectories:
        raise InputError.of("plan", "give at least one trajectory set (CSV, .mrk.json, folder or 'reference')")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError.of("workers", f"must be an integer >= 1, got {workers!r}")
    if dask:
        from arcube.optimization.executors import check_dask_address

        check_dask_address(dask)
    if dask and workers > 1:
        raise InputError.of("workers", "and dask exclude each other (the Dask cluster has its own workers)")
    make_termination(s.algorithm, s.generations, s.ftol)
    if s.seed is None:
        s = s.replace(seed=secrets.randbelow(2**31))
    engine_resolved = check_engine(s.engine)
    design = Design.load(s.design_from)
    if s.c_z is not None:  # the one home of c_z is the design (model §19.1): --c-z sets the start design's
        design = design.with_extras(c_z=s.c_z)
    patients = _load_patients(trajectories, s)  # reads every anatomy: a bad file stops the run before its folder exists
    plans = [t.plan if isinstance(t, PatientPlan) else t for t in trajectories]
    sources = tuple(t.source if isinstance(t, TrajectorySet) else str(t) for t in plans)
    start = design.to_dict()
    if design.c_z is not None:  # the start design's own z dyad (model §19.1): fixed parameters keep it
        start["c_z"] = design.c_z
    return RunConfig(
        settings=s,
        patients=tuple(patients),
        design=start,
        bounds=s.all_bounds,
        trajectories=sources,
        engine_resolved=engine_resolved,
        executor={"workers": workers, "dask": dask or ""},
        versions=versions(),
        rerun=_rerun_command(s, list(sources)),
    )


def _text(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(_text(v) for v in value)
    return repr(value) if isinstance(value, float) else str(value)


def _ignored(s: RunSettings, n_sets: int) -> set[str]:
    """The settings a run of ``s`` over ``n_sets`` trajectory sets does not use, whose flags the command line refuses
    (:mod:`arcube.cli.optimize`): the rerun line leaves them out."""
    from arcube.accuracy.sources import class_unused
    from arcube.optimization.objectives import needs

    out = set()
    if s.objectives or s.algorithm not in MULTI_OBJECTIVE_ALGORITHMS:
        out.add("compactness")
    if not needs("robust", s.run_objectives, s.limits):
        out |= {"tolerance_class", "tol"}
    elif class_unused(s.tol):
        out.add("tolerance_class")
    if n_sets <= 1 and s.dockings is None:
        out |= {"aggregate", "placement"}
    from arcube.io.label_files import LABEL_SUFFIXES

    if all(v in ("default", "none") or v.lower().endswith(LABEL_SUFFIXES) for v in (*s.anatomy, *s.envelope)):
        out.add("anatomy_frame")  # the frame of mesh files, and there are none (a segmentation states its own)
    return out


def _rerun_command(s: RunSettings, trajectories: list[str]) -> str:
    """The command line that reruns this run: every setting of ``s`` written out with its flag
    (:meth:`arcube.options.Settings.flag`, the rule the CLI's options are generated with), so that the
    line holds even when a default changes."""
    parts = [
        "arcube optimize",
        RunSettings.flag("trajectories"),
        *trajectories,
        RunSettings.flag("out"),
        "DIR",
        RunSettings.flag("seed"),
        str(s.seed),
    ]
    ignored = _ignored(s, len(trajectories))
    for name in RunSettings.model_fields:
        value = getattr(s, name)
        if name in ("seed", "period", "options") or value is None or value == () or value == {} or value is False:
            continue
        if name in ignored:
            continue  # not used: the command line refuses the flag where it would be ignored
        flag = RunSettings.flag(name)
        if value is True:
            parts.append(flag)
        elif name in ("maxima", "minima"):
            parts += [f"{flag} {n}={v!r}" for n, v in value.items()]
        elif name == "tol":
            parts.append(f"{flag} " + ",".join(f"{n}={v!r}" for n, v in value.items()))
        elif name == "bounds":
            parts.append(f"{flag} " + ",".join(f"{k}={lo!r}:{hi!r}" for k, (lo, hi) in value.items()))
        elif name == "anatomy":
            parts.append(f"{flag} {' '.join(value)}")
        else:
            parts.append(f"{flag}={_text(value)}" if name == "mode" else f"{flag} {_text(value)}")
    default = Options()
    for group in ("guards", "body", "loads", "masses"):
        model, mine, base = type(getattr(default, group)), getattr(s.options, group), getattr(default, group)
        for name in model.model_fields:
            value = getattr(mine, name)
            if value != getattr(base, name):
                parts.append(model.flag(name) if value is True else f"{model.flag(name)} {_text(value)}")
    return " ".join(parts)
