"""The drilling program (model §17): from a plan of poses to a timed, collision-free joint trajectory.

:func:`program` is the one call: a design, a plan (and its anatomy) in; the rows q(t) of every
approach, drill, retract and transit out, checked everywhere along the way (17.2) and timed under
the joint and tip limits, as a :class:`~arcube.motion.output.Program` (written as ``program.csv``
and ``program.json`` when ``out`` is given). Modules:

* :mod:`~arcube.motion.limits`: the settings (:class:`ProgramLimits`, :class:`Planner`);
* :mod:`~arcube.motion.check`: the continuous check of 17.2 (NumPy reference);
* :mod:`~arcube.motion.segments`: lines and joint paths, as rest-to-rest pieces;
* :mod:`~arcube.motion.transit`: the straight move, else OMPL's RRTConnect;
* :mod:`~arcube.motion.timing`, :mod:`~arcube.motion.sampling`: toppra, then rows on a dt grid;
* :mod:`~arcube.motion.order`: the shortest order (dynamic programming over subsets);
* :mod:`~arcube.motion.assemble`, :mod:`~arcube.motion.output`: the whole, and its files.

```python
from arcube.motion import program
prog = program("design.json", "reference", "out/program", side="R", anatomy="default", feed=1.0)
prog.summary["total_s"], prog.order          # program.csv and program.json are in out/program
```
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.io.trajectories import TrajectorySet
from arcube.options import Options
from arcube.motion.limits import ORDERS, Planner, ProgramLimits
from arcube.motion.output import CSV_COLUMNS, JOINTS, Program

__all__ = ["CSV_COLUMNS", "JOINTS", "ORDERS", "Planner", "Program", "ProgramLimits", "program"]


def _limits(limits: ProgramLimits | None, changes: dict[str, Any]) -> ProgramLimits:
    base = limits if limits is not None else ProgramLimits()
    if not isinstance(base, ProgramLimits):
        raise InputError.of("limits", f"must be a ProgramLimits, got {type(base).__name__}")
    return base.replace(**changes) if changes else base


def program(
    design: Any,
    plan: Any = "reference",
    out: str | os.PathLike[str] | None = None,
    *,
    options: Options | None = None,
    anatomy: Any = None,
    anatomy_frame: str = "LPS",
    mode: Any = None,
    order: str = "shortest",
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    transform: Any = None,
    limits: ProgramLimits | None = None,
    planner: Planner | None = None,
    seed: int | None = None,
    log: Callable[[str], None] | None = None,
    masses: bool | None = None,
    engine: str = "auto",
    segments: Any = None,
    envelope: Any = None,
    table_z: float | None = None,
    figures: Callable[[Program], dict[str, bytes]] | None = None,
    **changes: Any,
) -> Program:
    """The drilling program of ``design`` for a plan (model §17).

    Args:
        design: a :class:`~arcube.Design`, a preset name or a design JSON path; or an :class:`arcube.Request`
            (design, plan, selection, anatomy, envelope, mode and options in one; its keywords here then stay unset).
        plan: a :class:`~arcube.io.TrajectorySet`, or what ``--trajectories`` takes (CSV,
            Slicer markups, ``"reference"``), subset by ``side``, ``levels``, ``ids`` (and ``transform``).
        out: a folder for ``program.csv`` and ``program.json`` (created); None writes nothing.
        options: the :class:`arcube.Options` of the robot: its body (radii), loads (the drilling thrust
            and lateral bound of 15.3) and masses (18.1); None: the defaults.
        anatomy: None, ``"default"``, mesh paths or an :class:`~arcube.evaluation.anatomy.Anatomy`
            (model §14.2): the standoffs, body clearance and tool clearance use it.
        mode: the working mode, ``"+,+,+,+"`` or four signs; None: the design's own, else ``+,+,+,+``.
        order: ``"shortest"`` (least total time) or ``"given"`` (the plan's order).
        limits: a :class:`ProgramLimits`; keyword ``changes`` override its fields by name or short
            name (``feed=1.0``, ``clearance=3``, ``standoff=15``), and then ``options``' (``thrust=25``).
        masses: None: the mass model of ``options`` (none when its links are too thin for the default
            2 mm wall and no masses were given); False: no masses; True: required. With masses the rows
            get the actuator torques of 18.2 (``tau_*_Nm`` columns) and ``program.json`` the motor
            figures of 18.3 (``motors``).
        engine: the continuous check's: ``numba`` (the compiled kernel's condition numbers and body
            clearances), ``numpy`` (the reference) or ``auto`` (numba when it imports).
        envelope, table_z: the envelope of the whole patient and the table (model §19.5: ``"default"``, ``"none"``
            or None, skin mesh files, or an Envelope), placed on the whole plan (before any selection); the body
            then clears it by ``envelope_clearance`` (ProgramLimits, 10 mm) everywhere.
        planner, seed: the transit planner's settings (``seed`` overrides ``planner.seed``).
        log: called with one line per transit planned (progress).
        figures: with ``out``, more files of the folder made from the program (name -> bytes, e.g. the
            timeline ``program.png``), written with program.csv and program.json, all or none.

    Returns:
        The :class:`Program` (its ``path`` is ``out`` when written).

    Raises:
        InputError: bad input (naming the parameter: ``ProgramLimits.feed``, ``order``, ``mode``,
            ``out``, ...), or no program: one line naming the segment and the constraint (``transit 3 -> 5
            blocked: collision/patient at E = (...)``). Nothing is written then.
    """
    from arcube.coerce import engine_name
    from arcube.evaluation.mass_bodies import MassModel
    from arcube.motion.assemble import build_program
    from arcube.motion.output import prepare_folder, remove_folder
    from arcube.motion.rows import check_rows
    from arcube.options import request_options
    from arcube.request import Request, with_design_c_z

    req = Request.of(locals(), program)
    limit_changes = {ProgramLimits.field_of(k): changes.pop(k) for k in list(changes) if ProgramLimits.field_of(k)}
    lim = _limits(limits, limit_changes)
    opts = request_options(req.options, **changes)
    engine = engine_name(engine)
    if order not in ORDERS:
        raise InputError.of("order", f"must be one of {', '.join(ORDERS)}, got {order!r}")
    own: dict[str, Any] = {}

    def before_anatomy(ts: TrajectorySet) -> None:  # before the anatomy, the planning and any folder
        plan_settings = planner if planner is not None else Planner()
        own["planner"] = plan_settings.replace(seed=seed) if seed is not None else plan_settings
        check_rows(lim, ts)

    r = req.resolve(before_anatomy)
    d, signs, ts, anat, env, plan_settings = r.design, r.signs, r.plan, r.anatomy, r.envelope, own["planner"]
    opts = with_design_c_z(opts, d)  # the design's own z dyad (model §19.2): its masses are the two real links
    mass_model = MassModel.of(opts) if opts.mass_model_on(masses) else None
    if out is None:
        return build_program(
            d, ts, anat, signs, order, lim, opts.body, plan_settings, log, mass_model, opts.loads, engine, env
        )
    folder, created, lock = None, False, None
    try:
        folder, created, lock = prepare_folder(out)
        prog = build_program(
            d, ts, anat, signs, order, lim, opts.body, plan_settings, log, mass_model, opts.loads, engine, env
        )
        prog.write(folder, figures(prog) if figures is not None else None)
    except BaseException:
        if folder is not None:
            remove_folder(folder, lock, created)
        raise
    remove_folder(folder, lock, created=False)  # the lock goes; the folder stays, with the program
    return dataclasses.replace(prog, path=Path(folder))
