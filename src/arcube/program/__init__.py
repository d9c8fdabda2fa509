"""The drilling program (MODEL.md 17): from a plan of poses to a timed, collision-free joint trajectory.

:func:`program` is the one call: a design, a plan (and its anatomy) in; the rows q(t) of every
approach, drill, retract and transit out, checked everywhere along the way (17.2) and timed under
the joint and tip limits, as a :class:`~arcube.program.output.Program` (written as ``program.csv``
and ``program.json`` when ``out`` is given). Modules:

* :mod:`~arcube.program.limits`: the settings (:class:`ProgramLimits`, :class:`Planner`);
* :mod:`~arcube.program.check`: the continuous check of 17.2 (NumPy reference);
* :mod:`~arcube.program.segments`: lines and joint paths, as rest-to-rest pieces;
* :mod:`~arcube.program.transit`: the straight move, else OMPL's RRTConnect;
* :mod:`~arcube.program.timing`, :mod:`~arcube.program.sampling`: toppra, then rows on a dt grid;
* :mod:`~arcube.program.order`: the shortest order (dynamic programming over subsets);
* :mod:`~arcube.program.assemble`, :mod:`~arcube.program.output`: the whole, and its files.

```python
from arcube.program import program
prog = program("design.json", "reference", "out/program", side="R", anatomy="default", feed=1.0)
prog.summary["total_s"], prog.order          # program.csv and program.json are in out/program
```
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from arcube.errors import InputError
from arcube.options import Body, Loads, Masses, Options, validated
from arcube.program.limits import ORDERS, Planner, ProgramLimits
from arcube.program.output import CSV_COLUMNS, JOINTS, Program

__all__ = ["CSV_COLUMNS", "JOINTS", "ORDERS", "Planner", "Program", "ProgramLimits", "program"]


def _limits(limits: ProgramLimits | None, changes: dict[str, Any]) -> ProgramLimits:
    base = limits if limits is not None else ProgramLimits()
    if not isinstance(base, ProgramLimits):
        raise InputError.of("limits", f"must be a ProgramLimits, got {type(base).__name__}")
    return base.replace(**changes) if changes else base


def program(
    design: Any, trajectories: Any, out: str | os.PathLike[str] | None = None, *, anatomy: Any = None,
    anatomy_frame: str = "LPS", mode: Any = "+,+,+,+", order: str = "shortest", side: str | None = None,
    levels: str | None = None, ids: str | None = None, transform: Any = None, limits: ProgramLimits | None = None,
    body: Body | None = None, planner: Planner | None = None, seed: int | None = None, log: Callable[[str], None] | None = None,
    masses: Masses | bool | None = None, loads: Loads | None = None, engine: str = "auto", **changes: Any,
) -> Program:  # fmt: skip
    """The drilling program of ``design`` for a plan (MODEL.md 17).

    Args:
        design: a :class:`~arcube.Design`, a preset name or a design JSON path.
        trajectories: a :class:`~arcube.io.TrajectorySet`, or what ``--trajectories`` takes (CSV,
            Slicer markups, ``"reference"``), subset by ``side``, ``levels``, ``ids`` (and ``transform``).
        out: a folder for ``program.csv`` and ``program.json`` (created); None writes nothing.
        anatomy: None, ``"default"``, mesh paths or an :class:`~arcube.evaluation.anatomy.Anatomy`
            (MODEL.md 14.2): the standoffs, body clearance and tool clearance use it.
        mode: the working mode, ``"+,+,+,+"`` or four signs.
        order: ``"shortest"`` (least total time) or ``"given"`` (the plan's order).
        limits: a :class:`ProgramLimits`; keyword ``changes`` override its fields
            (``feed=1.0``, ``clearance=3``, ...).
        body: the body's radii (:class:`arcube.options.Body`).
        masses: the mass model (:class:`arcube.options.Masses`, MODEL.md 18.1; None: its defaults, or
            none when the links are too thin for the default 2 mm wall; False: no masses): the rows get the actuator torques of 18.2 (``tau_*_Nm`` columns) and
            ``program.json`` the motor figures of 18.3 (``motors``).
        loads: the drilling thrust and lateral bound (:class:`arcube.options.Loads`, 15.3).
        engine: the continuous check's: ``numba`` (the compiled kernel's condition numbers and body
            clearances), ``numpy`` (the reference) or ``auto`` (numba when it imports).
        planner, seed: the transit planner's settings (``seed`` overrides ``planner.seed``).
        log: called with one line per transit planned (progress).

    Returns:
        The :class:`Program` (its ``path`` is ``out`` when written).

    Raises:
        InputError: bad input (naming the parameter: ``ProgramLimits.feed``, ``order``, ``mode``,
            ``out``, ...), or no program: one line naming the segment and the constraint (``transit 3 -> 5
            blocked: collision/patient at E = (...)``). Nothing is written then.
    """
    import numpy as np

    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.evaluation.result import parse_mode_option
    from arcube.io import TrajectorySet, load_trajectories, select
    from arcube.model.design import Design
    from arcube.program.assemble import build_program
    from arcube.program.output import prepare_folder, remove_folder

    from arcube.evaluation.engine import resolve

    lim = _limits(limits, changes)
    try:
        engine = resolve(engine)
    except ValueError as exc:
        raise InputError.of("engine", str(exc)) from None
    if order not in ORDERS:
        raise InputError.of("order", f"must be one of {', '.join(ORDERS)}, got {order!r}")
    signs = parse_mode_option(mode) if isinstance(mode, str) else np.sign(np.asarray(mode, dtype=float)).reshape(4)
    if not np.all(np.abs(signs) == 1.0):
        raise InputError.of("mode", f"must be four signs +1/-1, got {mode!r}")
    plan = planner if planner is not None else Planner()
    if seed is not None:
        plan = plan.replace(seed=seed)
    body = validated(Body, body.model_dump()) if body is not None else Body()
    mass_model = None
    # the default mass model, unless the links are too thin for its wall and no mass model was asked for
    # (as arcube evaluate does): then the program has no torques rather than an error about a wall never given
    if masses is not False and not (masses is None and body.link_radius <= Masses().wall_mm):
        from arcube.evaluation.bodies import MassModel

        m = Masses() if masses is None or masses is True else validated(Masses, masses.model_dump())
        mass_model = MassModel.of(Options(body=body, masses=m).check_masses())
    loads = validated(Loads, loads.model_dump()) if loads is not None else Loads()
    d = Design.coerce(design)
    ts = trajectories if isinstance(trajectories, TrajectorySet) else load_trajectories(trajectories, transform=transform)
    if side or levels or ids:
        ts = select(ts, side=side, levels=levels, ids=ids)
    anat = resolve_anatomy(anatomy, anatomy_frame, None if isinstance(trajectories, TrajectorySet) else trajectories)
    folder, created = prepare_folder(out) if out is not None else (None, False)
    try:
        prog = build_program(d, ts, anat, signs, order, lim, body, plan, log, mass_model, loads, engine)
        if folder is None:
            return prog
        prog.write(folder)
        from arcube.report.program import timeline_png

        timeline_png(prog, Path(folder) / "program.png")
    except BaseException:
        if created and folder is not None:
            remove_folder(folder)
        raise
    return dataclasses.replace(prog, path=Path(folder))
