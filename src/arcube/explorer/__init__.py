"""An interactive design explorer in the browser (issue 22): :func:`explore`.

A top layer like :mod:`arcube.report`: it may use the evaluation, the optimization and the report,
and nothing below imports it. viser (the live app) and plotly (the static export) load only when used.

* :mod:`~arcube.explorer.scene`: the body as solids, their colours, the closest pairs (NumPy);
* :mod:`~arcube.explorer.live`: the design on the plan, figures from the compiled kernel;
* :mod:`~arcube.explorer.app`: the viser server, its controls and the refresh worker;
* :mod:`~arcube.explorer.static`: the standalone HTML scene (``--html``);
* :mod:`~arcube.explorer.polish`: a short optimization from the current design.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from arcube.explorer.app import ExplorerApp
    from arcube.explorer.live import LiveModel
    from arcube.options import Options

__all__ = ["explore", "live_model"]


def live_model(
    design: Any = "paper",
    plan: Any = "reference",
    *,
    options: Options | None = None,
    anatomy: Any = None,
    anatomy_frame: str = "LPS",
    mode: str | Sequence[float] | None = None,
    points: int = 30,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    guarded: bool = True,
    segments: Any = None,
    envelope: Any = "default",
    table_z: float | None = None,
    **changes: Any,
) -> LiveModel:
    """The explorer's :class:`~arcube.explorer.live.LiveModel` (InputError on bad input).

    Args:
        design: a :class:`~arcube.Design`, a preset name or a design JSON path; or an :class:`arcube.Request`
            (its keywords here then stay unset).
        plan: a :class:`~arcube.TrajectorySet` or what :func:`arcube.load_trajectories` reads; ``side``,
            ``levels``, ``ids`` keep some of its trajectories.
        options: the :class:`arcube.Options` whose body radii the robot starts with (``**changes``: its
            settings by name, e.g. ``link_radius=6``).
        anatomy: ``"default"``, mesh files (in ``anatomy_frame``), an Anatomy, or None.
        anatomy_frame: see ``anatomy``.
        mode: the starting working mode, points per trajectory and whether the guards
            of ``arcube design`` apply.
        points: see ``mode``.
        side: see ``plan``.
        levels: see ``plan``.
        ids: see ``plan``.
        guarded: see ``mode`` (``guards`` before 0.3, taken for one release).
        segments: the segments of a segmentation anatomy to keep.
        envelope: the envelope of the whole patient and the table (model §19.5), ``"default"`` or skin meshes.
        table_z: the table's top (mm, patient frame) of the default envelope.
        **changes: see ``options``.
    """
    from arcube.coerce import points as checked_points
    from arcube.explorer.live import LiveModel
    from arcube.options import request_options
    from arcube.request import Request
    from arcube.validation import renamed_keyword

    guarded = renamed_keyword(changes, "guards", "guarded", guarded, True)
    req = Request.of(locals(), live_model)
    n = checked_points(req.points)
    own: dict[str, Any] = {}
    # the options checked before the slow anatomy; the envelope of model §19.5 placed as design places it
    r = req.resolve(lambda _: own.update(opts=request_options(req.options, **changes)))
    radii = own["opts"].body.radii
    return LiveModel(
        r.design, r.plan, r.anatomy, mode=r.signs, points=n, radii=radii, guarded=bool(guarded), envelope=r.envelope
    )


def explore(
    design: Any = "paper",
    plan: Any = "reference",
    *,
    port: int = 8080,
    host: str = "127.0.0.1",
    html: str | os.PathLike[str] | None = None,
    point: int | None = None,
    save_path: str | os.PathLike[str] = "design_explored.json",
    block: bool = True,
    **request: Any,
) -> ExplorerApp | Path:
    """Explore a design on a drilling plan in the browser: sliders, the robot's solids coloured by
    clearance, live figures against the requirements of ``arcube design``, save and polish.

    Args:
        design: as :func:`live_model`.
        plan: as :func:`live_model`.
        port: where the app listens (InputError naming ``port`` when it is taken).
        host: see ``port``.
        html: write the standalone static scene (at ``point`` of the lines) there instead of serving;
            returns its path.
        save_path: the panel's default file for "Save design JSON".
        block: serve until Ctrl-C (then stop); False returns the running :class:`~arcube.explorer.app.ExplorerApp`
            (call ``.stop()``).
        **request: the keywords of :func:`live_model` (the request, the options, ``guarded``: whether the guards of
            ``arcube design`` apply, the anatomy and the envelope).
    """
    from arcube.explorer.app import check_port

    if html is None:
        check_port(host, port)  # before the slow part: a taken port fails at once
    model = live_model(design, plan, **request)
    if point is not None and (isinstance(point, bool) or not isinstance(point, int) or not 0 <= point < len(model)):
        from arcube.errors import InputError

        raise InputError.of(
            "point",
            f"must be an integer in [0, {len(model) - 1}] (the points of the lines: per trajectory "
            f"{model.points} approach points, then {model.points} drill points), got {point!r}",
        )
    anat = "none" if model.anatomy is None else model.anatomy.source
    title = f"{model.plan.source}: {len(model.plan.ids)} trajectories × {model.points} points · anatomy: {anat}"
    if html is not None:
        from arcube.explorer.static import write_static

        return write_static(model, html, point, title)
    from arcube.explorer.app import ExplorerApp

    anatomy, anatomy_frame = request.get("anatomy"), request.get("anatomy_frame", "LPS")
    spec = (
        [anatomy]
        if isinstance(anatomy, (str, os.PathLike))
        else list(anatomy)
        if isinstance(anatomy, (list, tuple))
        else None
    )
    spec = None if spec is None else [os.fspath(s) for s in spec]
    app = ExplorerApp(
        model, host=host, port=port, save_path=save_path, anatomy_spec=spec, anatomy_frame=anatomy_frame, title=title
    )
    if point is not None:
        app.point.value = int(point)
    if not block:
        return app
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        app.stop()
    return app
