"""Polish: a short optimization from the explorer's current design, in memory (nothing written but a
temporary start design), with the explorer's plan, mode, guards, radii and anatomy.

The search box is the current design ± ``span`` of each free parameter's default range
(:data:`arcube.optimization.settings.DEFAULT_BOUNDS`), so the run stays near what the person is
looking at; the GA (the default here) seeds its first population with the current design and keeps
its best, so the result is never worse by the optimizer's own ranking (reach first, then eta_G).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from arcube.explorer.live import LiveModel
from arcube.model.design import Design
from arcube.model.mechanism import format_mode
from arcube.optimization.settings import DEFAULT_BOUNDS, parse_free

__all__ = ["polish"]


def polish(
    model: LiveModel,
    *,
    population: int = 16,
    generations: int = 15,
    free: str = "all",
    span: float = 0.05,
    algorithm: str = "ga",
    seed: int = 0,
    anatomy_spec: list[str] | None = None,
    anatomy_frame: str = "LPS",
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> tuple[Design, dict[str, Any]]:
    """(best design, the run's summary) of a short run from ``model``'s current design.

    ``anatomy_spec``: what ``--anatomy`` said (``["default"]`` or mesh files, in ``anatomy_frame``);
    None with an anatomy writes the anatomy to a temporary STL (patient frame) for the run.
    ``progress`` is called with each generation's history row (``generation``, ``total``, ...).
    Bad settings raise :class:`~arcube.errors.InputError` naming the RunSettings field.
    """
    from arcube.api import optimize  # the top of the library: the in-memory run of arcube.optimize

    x = model.current_design().to_dict()
    names = parse_free(free)
    bounds = {}
    for n in names:
        lo, hi = DEFAULT_BOUNDS[n]
        w = span * (hi - lo)
        bounds[n] = (x[n] - w, x[n] + w)
    with tempfile.TemporaryDirectory(prefix="arcube-polish-") as tmp:
        start = Path(tmp) / "start.json"
        model.current_design().to_json(start)
        anatomy: tuple[str, ...] = ()
        frame = anatomy_frame
        if model.anatomy is not None:
            if anatomy_spec:
                anatomy = tuple(anatomy_spec)
            else:
                anatomy, frame = (str(model.anatomy.write_stl(Path(tmp) / "anatomy.stl")),), "patient"
        opts = model.options()
        result = optimize(
            model.plan,
            None,
            progress=progress,
            algorithm=algorithm,
            population=population,
            generations=generations,
            ftol=0.0,
            points=model.points,
            mode=format_mode(model.mode),
            guarded=model.guarded,
            seed=seed,
            design_from=str(start),
            free=list(names),
            bounds=bounds,
            anatomy=anatomy,
            anatomy_frame=frame,
            standoff=model.standoff_mm if (model.guarded and model.anatomy is not None) else None,
            options=opts.replace(outputs=type(opts.outputs)(), c_z=None),  # c_z: the start design's (model §19.1)
        )
    return result.best_design, dict(result.summary)
