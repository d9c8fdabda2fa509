"""The flags every command shares, each declared once: the plan and its selection, the design, the
anatomy, the body, loads and masses of :class:`arcube.Options`, where results go; and the progress bars.

A command takes the flags it needs from here (``dataclasses.replace`` changes a help text where one
command means something narrower), adds its own, and :func:`arcube.cli.projection.command` builds it.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any
from collections.abc import Callable

from arcube.cli.projection import Flag, Given, model_flags, option
from arcube.errors import InputError
from arcube.options import GUARDED_OPTIONS, Body, Guards, Loads, Masses, Options
from arcube.evaluation.envelope import EnvelopeSettings
from arcube.patients.settings import SegmentSelection
from arcube.validation import renamed_keyword

__all__ = [
    "ANATOMY",
    "C_Z",
    "ANATOMY_FRAME",
    "DASK",
    "DESIGN",
    "ENGINE",
    "ENVELOPE",
    "GUARDS",
    "OLD_GUARDS",
    "IDS",
    "LEVELS",
    "MODE",
    "OPTION_FLAGS",
    "OUT",
    "PLAN",
    "FORCE",
    "GridBar",
    "LIVE_BARS",
    "POINTS",
    "QUIET",
    "RichBar",
    "check_class_counts",
    "check_replace",
    "file_out",
    "file_path",
    "with_given_c_z",
    "SEED",
    "SIDE",
    "TRAJECTORIES",
    "TRANSFORM",
    "WORKERS",
    "options_of",
    "request_flags",
]

DESIGN = option(
    "--design", "Design: a preset name (paper) or a design JSON file. [default: paper]", params=("design",), path=True
)


TRAJECTORIES = option(
    "--trajectories",
    "Trajectories: a CSV, a Slicer .mrk.json (file or folder), or 'reference'. [default: reference]",
    key="plan",
    params=("plan",),
    spread=True,
    path=True,
)
POINTS = option(
    "--points",
    "Points per trajectory (N >= 2), both ends included. [default: 30]",
    int,
    params=("points", "RunSettings.points"),
)
MODE = option(
    "--mode",
    "Working mode: signs of TMS x, TMS y, RTS x, RTS y, e.g. --mode=-,+,+,- [default: the design file's mode, else +,+,+,+]",
    params=("mode", "RunSettings.mode"),
)
GUARDS = option(
    "--guarded",
    "Turn on the guards of model §8.2 (all but z_dyad).",
    bool,
    key="guarded",
    params=("guarded", "RunSettings.guarded"),
)
OLD_GUARDS = option("--guards", "Renamed --guarded.", bool, key="guards", params=("guards",), hidden=True)
"""``--guarded``'s name before 0.3, taken for one release with a warning (:func:`options_of`)."""
SIDE = option("--side", "Keep trajectories of one side: R or L.", params=("side", "RunSettings.side"))
LEVELS = option("--levels", "Keep levels, e.g. C3-C5 or C3,C6.", params=("levels", "RunSettings.levels"))
IDS = option("--ids", "Keep trajectory ids, e.g. 1,3,5.", params=("ids", "RunSettings.ids"))
TRANSFORM = option(
    "--transform",
    "4x4 rigid transform (JSON) from the file's frame to the patient frame.",
    Path,
    params=("transform", "RunSettings.transform"),
)
ENGINE = option(
    "--engine",
    "Evaluation engine: auto (numba if available), numba or numpy. [default: auto]",
    params=("engine", "RunSettings.engine"),
)
ANATOMY = option(
    "--anatomy",
    "Patient anatomy (model §14.2): none, default (the plan's default anatomy), or files FILE [FILE ...]: "
    "meshes (STL, OBJ, PLY) or segmentations (.seg.nrrd, .nii, .nii.gz).",
    params=("anatomy", "RunSettings.anatomy"),
    spread=True,
)


def _frame(value: Any, flag: str) -> Any:
    """An anatomy frame as given, checked even where no anatomy file is (a mistyped flag is not ignored); the error
    names ``anatomy_frame``, which the command shows as its flag."""
    from arcube.evaluation.anatomy import check_frame

    return check_frame(value)


ANATOMY_FRAME = option(
    "--anatomy-frame",
    "Frame of the anatomy files: LPS (3D Slicer's default), RAS or patient. [default: LPS]",
    params=("anatomy_frame", "RunSettings.anatomy_frame"),
    parse=_frame,
)
SEGMENTS = replace(
    model_flags(SegmentSelection, only=("segments",))[0],
    params=("segments", "SegmentSelection.segments", "RunSettings.segments"),
)
"""``--segments``: which segments of segmentation anatomy files to keep (names or label values)."""
ENVELOPE = [
    replace(
        f, spread=f.multiple, params=(*f.params, f.key), help=f.help.replace("[default: default]", "[default: none]")
    )
    for f in model_flags(EnvelopeSettings)
]
"""``--envelope default|none|FILE...`` and ``--table-z MM``: the envelope of the whole patient and the table (model §19.5)."""
OUT = option("--out", "Output folder (created; must be new or empty).", Path, params=("out",))


def file_path(example: str) -> Callable[[Any, str], Path]:
    """The parser of an output file's path: the path as typed, refused (InputError naming the flag) when it ends with
    a separator (``jdir/``): that names a folder, and the file would be written as ``jdir`` beside it. ``example``:
    a file name to suggest in that folder (``joints.csv``)."""

    def parse(value: Any, flag: str) -> Path:
        text = str(value)
        if text.endswith(("/", os.sep)):
            raise InputError(
                f"{flag} {text}: ends with '{text[-1]}', so it names a folder; give a file's path, e.g. {flag} "
                f"{text}{example}"
            )
        return Path(text)

    return parse


def file_out(flag: Flag, text: str, example: str, **changes: Any) -> Flag:
    """``flag`` (a path) as a single output file's, with help ``text``: its value is refused when it names a folder
    (:func:`file_path`, suggesting ``example`` in it)."""
    return replace(flag, help=text, parse=file_path(example), **changes)


SEED = option("--seed", "Random seed.", int, params=("seed", "RunSettings.seed"))


def _workers(value: Any, flag: str) -> Any:
    """A worker count as given, refused above :func:`arcube.optimization.executors.max_workers` (4 x the CPUs);
    the least (1) is each command's own check."""
    from arcube.optimization.executors import check_workers

    return check_workers(value, flag)


WORKERS = option(
    "--workers",
    "Local worker processes for each population batch. [default: 1]",
    int,
    params=("workers",),
    parse=_workers,
)
DASK = option("--dask", "Address of a dask.distributed scheduler to send batches to.", params=("dask",))
QUIET = option("--quiet", "No progress bar.", bool)
FORCE = option("--force", "Replace the output file if it exists (a file is never replaced without it).", bool)


def check_new_file(given: Given, key: str) -> None:
    """InputError naming the flag of ``key`` when the file it names exists as a regular file and ``--force`` was not
    given (a single-file output beside the command's main one: ``evaluate --report``, ``explore --html``)."""
    path = given.get(key)
    if path is None and given.get("force"):
        raise InputError(f"{FORCE.name} replaces the {given.flag(key)} file: give {given.flag(key)}, or leave it out")
    if path is not None and not given.get("force") and Path(path).is_file():
        raise InputError(f"{given.flag(key)} {path}: exists; give {FORCE.name} to replace it")


def check_class_counts(given: Given, class_key: str, tol_key: str, tol: Any) -> None:
    """InputError naming ``--class`` when it is given but the tolerances ``tol`` (of ``--tol``) set every length and
    angle by hand: the ISO 2768 class sets only those (model §20.1), so it would be recorded and change nothing."""
    from arcube.accuracy.sources import class_unused

    if class_key in given and class_unused(tol or {}):
        raise InputError(
            f"{given.flag(class_key)} {given.get(class_key)}: the ISO 2768 class sets the lengths' and angles' "
            f"tolerances, and {given.flag(tol_key)} sets them all, so it would change nothing: leave it out"
        )


def check_replace(given: Given, *beside: Any) -> None:
    """InputError when the command's ``--out`` file (or a file it writes ``beside``) exists as a regular file and
    ``--force`` was not given: measurements a user took by hand are never overwritten silently. A FIFO or a device
    (/dev/stdout) is written into, not replaced."""
    if given.get("force"):
        return
    for path in (given.get("out"), *beside):
        if path is not None and Path(path).is_file():
            raise InputError(f"{OUT.name} {given.get('out')}: {path} exists; give {FORCE.name} to replace it")


PLAN: list[Flag] = [
    DESIGN,
    TRAJECTORIES,
    POINTS,
    MODE,
    GUARDS,
    OLD_GUARDS,
    SIDE,
    LEVELS,
    IDS,
    TRANSFORM,
    ENGINE,
    ANATOMY,
    ANATOMY_FRAME,
    SEGMENTS,
]
"""The plan, its selection and what evaluates it: the request of ``evaluate``, ``joints``, ``export`` and ``explore``."""

SELECTION: list[Flag] = [SIDE, LEVELS, IDS]
"""The trajectories of a plan a command keeps (:func:`arcube.select`)."""
PATIENT: list[Flag] = [ANATOMY, ANATOMY_FRAME, SEGMENTS, *ENVELOPE]
"""The patient around a plan: the anatomy (model §14.2) and the envelope of the whole patient and the table (19.5)."""

OPTION_FLAGS: dict[str, list[Flag]] = {
    "clearances": model_flags(
        Guards, "options.guards", only=("clearance_mm", "self_clearance_mm", "envelope_clearance_mm")
    ),
    "guards": model_flags(Guards, "options.guards", skip=("c_z",)),
    "body": model_flags(Body, "options.body"),
    "loads": model_flags(Loads, "options.loads"),
    "masses": model_flags(Masses, "options.masses"),
}
"""The flags of :class:`arcube.Options`' groups, by group (``clearances``: the clearance guards of 14.3
alone; ``guards``: every guard, 8.2's too, but c_z: it is the design's, :data:`C_Z`)."""

C_Z = option(
    "--c-z",
    "Second link of the z-leg dyad, mm: sets the design's c_z (default the design file's, else d_z; model §6, 19.1).",
    float,
    key="c_z",
    params=("c_z",),
)
"""The design's z-dyad link (model §19.1): the one flag of c_z, which sets the design's value (:func:`with_given_c_z`)."""


def with_given_c_z(given: Given, design: Any) -> Any:
    """``design`` (a Design, preset, file or vector) with ``--c-z``'s value when given, else as it is
    (:func:`arcube.export.mjcf.design_with_c_z`: InputError naming ``--c-z`` unless a finite length > 0 mm)."""
    from arcube.export.mjcf import design_with_c_z

    c_z = given.get("c_z")
    return design if c_z is None else design_with_c_z(design, c_z)


def request_flags(*groups: str) -> list[Flag]:
    """The :data:`OPTION_FLAGS` of these groups, in order."""
    return [f for g in groups for f in OPTION_FLAGS[g]]


def options_of(given: Given, guarded: bool | None = None, base: Options | None = None) -> Options:
    """The :class:`arcube.Options` of the flags given (``base``, else the paper's with the guards of
    model §8.2 when ``--guarded``), checked; the mass model applies as :meth:`Options.mass_model_on` says."""
    old = {OLD_GUARDS.name: True} if given.get("guards") else {}
    on = renamed_keyword(old, OLD_GUARDS.name, GUARDS.name, bool(given.get("guarded")), False)
    start = base if base is not None else (GUARDED_OPTIONS if (on if guarded is None else guarded) else Options())
    tree = given.tree("options")
    return start.merged(tree) if tree else start


def masses_given(given: Given) -> bool:
    """Whether any flag of the mass model (model §18.1) was given."""
    return bool(given.tree("options.masses"))


def plan_request(given: Given) -> dict[str, Any]:
    """The plan keywords of the API calls (``side``, ``levels``, ``ids``, ``transform``, ``anatomy``,
    ``anatomy_frame``), from the flags given (absent ones keep the API's defaults)."""
    keys = ("side", "levels", "ids", "transform", "anatomy", "anatomy_frame", "segments", "envelope", "table_z")
    return {k: given.get(k) for k in keys if k in given}


def one_plan(given: Given, default: str | None = "reference") -> Any:
    """The one trajectory set of a command that takes one (``--trajectories``); InputError for several."""

    plans = given.get("plan") or ([default] if default is not None else [])
    if not plans:
        raise InputError(f"{TRAJECTORIES.name} is required")
    if len(plans) > 1:
        raise InputError(f"{TRAJECTORIES.name}: one trajectory set here, got {len(plans)} ({' '.join(plans)})")
    return plans[0]


def with_help(flag: Flag, text: str, **changes: Any) -> Flag:
    """``flag`` with another help text (one command means something narrower by it)."""
    return replace(flag, help=text, **changes)


class RichBar:
    """A Rich progress bar on stderr, shown only on a terminal; subclasses give its columns and fields."""

    def __init__(self, enabled: bool, columns: tuple[Any, ...], **fields: Any) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        console = Console(stderr=True)
        self.enabled, self.task = enabled and console.is_terminal, None
        if self.enabled:
            title, *rest = columns
            self.progress = Progress(TextColumn(title), MofNCompleteColumn(), BarColumn(), *rest, console=console)
            self.task = self.progress.add_task(title, **fields)

    def __enter__(self) -> RichBar:
        if self.enabled:
            self.progress.__enter__()
            LIVE_BARS[0] += 1
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.enabled:
            LIVE_BARS[0] -= 1
            if exc[0] is not None:  # an error or Ctrl-C: the bar is erased, so its one line stands alone
                self.progress.live.transient = True
            self.progress.__exit__(*exc)


LIVE_BARS = [0]
"""How many progress bars are on screen in this process (two Rich displays on one terminal garble each other)."""


class GridBar:
    """The bar of an anatomy's distance grids (model §14.3: tens of seconds for a label map at 0.5 mm voxels),
    a listener of :data:`arcube.progress.GRIDS`: shown on a terminal while no other bar is,
    erased when the grids are built. ``stream``: stderr (tests give their own)."""

    def __init__(self, stream: Any = None) -> None:
        import sys

        self.stream = sys.stderr if stream is None else stream
        self.progress: Any = None

    def __call__(self, done: int, total: int) -> None:
        if done == 0 and self.progress is None and LIVE_BARS[0] == 0:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            console = Console(file=self.stream)
            if console.is_terminal:
                self.progress = Progress(
                    TextColumn("anatomy distance grids (model §14.3), parts"),
                    MofNCompleteColumn(),
                    BarColumn(),
                    TimeElapsedColumn(),
                    console=console,
                    transient=True,
                )
                self.task = self.progress.add_task("grids", total=total)
                self.progress.start()
        elif self.progress is not None:
            self.progress.update(self.task, completed=done)
            if done >= total:
                self.close()

    def close(self) -> None:
        """Erase the bar (the grids are built, or the command ended)."""
        if self.progress is not None:
            self.progress.stop()
            self.progress = None
