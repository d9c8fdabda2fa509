"""Matplotlib figures (PNG) of an evaluation and of an optimization run.

* :func:`dexterity_png`: the paper's Fig 4, local inverted dexterity 100/eta_L (%) at every task
  point, trajectory after trajectory; points coloured by the limiting Jacobian (the argmax of
  the seven kappas of Eq 13), unreachable points as red crosses at 0.
* :func:`convergence_png`: best and mean eta_G and the feasible fraction per generation, read
  from a run folder's ``history.csv`` (:func:`read_history`).

The data of both figures is built here once (:func:`dexterity_series`, :class:`History`) and
reused by the plotly versions in :mod:`arcube.report.html`. Figures are drawn on a bare
:class:`matplotlib.figure.Figure` (no pyplot), so nothing touches global backend state, and are
written atomically.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from arcube.io.files import atomic_write_bytes
from arcube.io.tables import read_table
from arcube.evaluation.indices import JACOBIAN_NAMES

if TYPE_CHECKING:
    from arcube.evaluation.result import Evaluation

JACOBIAN_COLORS: dict[str, str] = {
    "J_LV": "#1f77b4",
    "J_AV": "#ff7f0e",
    "J_sigma": "#2ca02c",
    "J_AS": "#9467bd",
    "J_AP": "#8c564b",
    "J_rho": "#e377c2",
    "J_delta": "#17becf",
}
"""One colour per Jacobian (tab10 without red, which marks unreachable points)."""
UNREACHABLE_COLOR = "#d62728"


class DexteritySeries(NamedTuple):
    """Fig 4 data for P points of T trajectories (trajectory-major, as in :class:`arcube.evaluation.task.Task`)."""

    index: NDArray[np.intp]  # (P,) point index across trajectories
    dexterity: NDArray[np.float64]  # (P,) 100/eta_L in %, 0 where unreachable
    reachable: NDArray[np.bool_]  # (P,)
    limiting: NDArray[np.intp]  # (P,) index into JACOBIAN_NAMES of the largest kappa, -1 where unreachable
    failure: tuple[str, ...]  # (P,) first failure reason, "" where reachable
    boundaries: NDArray[np.float64]  # (T - 1,) x positions between trajectories (k = N - 0.5, ...)
    centres: NDArray[np.float64]  # (T,) x position of the middle of each trajectory
    labels: tuple[str, ...]  # (T,) "id level side" of each trajectory


def dexterity_series(report: Evaluation) -> DexteritySeries:
    """Per-point dexterity, reachability and limiting Jacobian of an evaluation report."""
    from arcube.evaluation.reference import failure_name

    pts = report.results.points
    task = report.task
    reach = np.asarray(pts.reachable, dtype=bool).reshape(-1)
    kappa = np.asarray(pts.kappa, dtype=float).reshape(len(task), len(JACOBIAN_NAMES))
    # argmax over NaN-free kappas only where the point is reachable (there all seven are finite).
    limiting = np.where(reach, np.argmax(np.nan_to_num(kappa, nan=-1.0, posinf=np.finfo(float).max), axis=-1), -1)
    n_traj = len(task.ids)
    starts = np.array([np.flatnonzero(task.trajectory == t)[0] for t in range(n_traj)], dtype=float)
    ends = np.array([np.flatnonzero(task.trajectory == t)[-1] for t in range(n_traj)], dtype=float)
    ts = report.trajectories
    labels = tuple(" ".join(s for s in (tid, ts.levels[i], ts.sides[i]) if s) for i, tid in enumerate(task.ids))
    return DexteritySeries(
        index=np.arange(len(task)),
        dexterity=np.asarray(pts.dexterity_pct, dtype=float).reshape(-1),
        reachable=reach,
        limiting=limiting.astype(np.intp),
        failure=tuple(failure_name(int(c)) or "" for c in np.asarray(pts.failure).reshape(-1)),
        boundaries=starts[1:] - 0.5,
        centres=(starts + ends) / 2.0,
        labels=labels,
    )


class History(NamedTuple):
    """Per-generation optimizer history; non-finite values (empty cells) are NaN."""

    generation: NDArray[np.float64]  # (G,)
    best_eta_G: NDArray[np.float64]  # (G,)
    mean_eta_G: NDArray[np.float64]  # (G,)
    feasible_fraction: NDArray[np.float64]  # (G,) in [0, 1]
    evaluations: NDArray[np.float64] | None = None  # (G,) designs evaluated so far, when the file has the column


_HISTORY_COLUMNS = ("generation", "best_eta_G", "mean_eta_G", "feasible_fraction")


def _norm(name: str) -> str:
    """Header normalisation so that 'best eta_G', 'Best-eta_G' and 'best_eta_g' all match."""
    return "_".join(name.strip().lower().replace("-", " ").replace("_", " ").split())


def read_history(path: str | os.PathLike[str]) -> History:
    """Read ``history.csv``: needs the columns generation, best_eta_G, mean_eta_G, feasible_fraction.

    Header names are matched case-insensitively, with spaces, '-' and '_' equivalent; other
    columns are ignored. The file is read as every CSV is (:mod:`arcube.io.tables`: a text file,
    every row as wide as the header, each column once, numbers in decimal notation); an empty cell
    (the optimizer's +inf: no feasible design yet) and a non-finite number are gaps (NaN). Raises
    :class:`InputError` (one line naming the file and row) for a missing, binary or damaged file.
    """
    table = read_table(path, pipes=False, key=_norm, required=[_norm(c) for c in _HISTORY_COLUMNS])
    names = [_norm(c) for c in _HISTORY_COLUMNS] + (["evaluations"] if "evaluations" in table.header else [])
    data = np.array(table.numbers(names, empty=math.nan, finite=False), dtype=float).reshape(-1, len(names))
    with np.errstate(invalid="ignore"):
        data[~np.isfinite(data)] = np.nan
    return History(*(data[:, j].copy() for j in range(len(names))))


def _png_bytes(fig: object) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)  # type: ignore[arg-type]  # attaches an Agg canvas to the bare Figure
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)  # type: ignore[attr-defined]
    return buf.getvalue()


def dexterity_png(report: Evaluation, path: str | os.PathLike[str]) -> Path:
    """Write the Fig 4 PNG of ``report`` to ``path`` (atomically); returns the path."""
    from matplotlib.figure import Figure

    s = dexterity_series(report)
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    ax = fig.add_subplot()
    for j, name in enumerate(JACOBIAN_NAMES):
        sel = s.limiting == j
        if sel.any():
            ax.scatter(
                s.index[sel], s.dexterity[sel], s=14, color=JACOBIAN_COLORS[name], label=f"limited by {name}", zorder=3
            )
    ax.plot(s.index, s.dexterity, color="0.7", lw=0.8, zorder=2)
    bad = ~s.reachable
    if bad.any():
        ax.scatter(
            s.index[bad],
            np.zeros(int(bad.sum())),
            marker="x",
            s=28,
            color=UNREACHABLE_COLOR,
            label="unreachable",
            zorder=4,
        )
    for b in s.boundaries:
        ax.axvline(b, color="0.4", lw=0.8, ls="--")
    top = max(float(np.max(s.dexterity, initial=0.0)), 1.0) * 1.18
    ax.set_ylim(-3.0, top)
    rotate = 90 if len(s.labels) > 12 else 0
    for x, label in zip(s.centres, s.labels):
        ax.text(x, top * 0.97, label, ha="center", va="top", fontsize=8, rotation=rotate)
    ax.set_xlim(-1.0, len(s.index))
    ax.set_xlabel("point index along the trajectories")
    ax.set_ylabel("local inverted dexterity 100/η_L (%)")
    mean = float(np.mean(s.dexterity)) if len(s.dexterity) else 0.0
    ax.set_title(f"Local inverted dexterity along the drilling trajectories (mean {mean:.2f} %, mode {report.mode})")
    ax.grid(True, axis="y", alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=8, ncols=8, frameon=False)
    out = Path(path)
    atomic_write_bytes(out, _png_bytes(fig))
    return out


def convergence_png(history: History, path: str | os.PathLike[str], best_known: float | None = None) -> Path:
    """Write the convergence PNG (eta_G best/mean, feasible fraction per generation); returns the path.

    ``best_known``: an eta_G to draw as a horizontal line (e.g. the best design known for the problem)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(history.generation, history.best_eta_G, color="#1f77b4", lw=1.6, label="best η_G")
    ax.plot(history.generation, history.mean_eta_G, color="#1f77b4", lw=1.0, ls="--", label="mean η_G (feasible)")
    _best_known_line(ax, best_known)
    ax.set_xlabel("generation")
    ax.set_ylabel("η_G (log scale)")
    ax.set_yscale("log")  # eta_G falls from tens to about 1.3: the last percent is where runs differ
    _plain_log_ticks(ax)
    ax2 = ax.twinx()
    ax2.plot(history.generation, 100.0 * history.feasible_fraction, color="#2ca02c", lw=1.0, label="feasible %")
    ax2.set_ylabel("feasible designs (%)", color="#2ca02c")
    ax2.set_ylim(-2.0, 102.0)
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [str(ln.get_label()) for ln in lines], loc="upper right", fontsize=8)
    ax.set_title("Optimization convergence")
    ax.grid(True, alpha=0.3)
    out = Path(path)
    atomic_write_bytes(out, _png_bytes(fig))
    return out


def _plain_log_ticks(ax: Any) -> None:
    """Tick labels of a log axis as plain numbers (1.25, 1.3), not powers of ten (1.25 x 10^0)."""
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:.3g}")
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain)


def _best_known_line(ax: Any, best_known: float | None) -> None:
    if best_known is not None and math.isfinite(best_known) and best_known > 0.0:
        ax.axhline(best_known, color="#d62728", lw=1.0, ls=":", label=f"best known {best_known:g}")


def study_convergence_png(
    histories: dict[int, History],
    path: str | os.PathLike[str],
    best_seed: int | None = None,
    best_known: float | None = None,
) -> Path:
    """Write the convergence of a study: best eta_G against evaluations (or generations), one line per seed, log scale."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    by_evals = all(h.evaluations is not None for h in histories.values()) and bool(histories)
    finals = []
    for seed, h in sorted(histories.items()):
        x = h.evaluations if by_evals and h.evaluations is not None else h.generation
        last = h.best_eta_G[np.isfinite(h.best_eta_G)]
        final = float(last[-1]) if len(last) else math.nan
        finals.append(final)
        ax.plot(
            x,
            h.best_eta_G,
            lw=2.2 if seed == best_seed else 1.0,
            label=f"seed {seed}: {final:.4f}" if math.isfinite(final) else f"seed {seed}: none feasible",
        )
    _best_known_line(ax, best_known)
    ax.set_xlabel("design evaluations" if by_evals else "generation")
    ax.set_ylabel("best η_G (log scale)")
    ax.set_yscale("log")
    ok = np.array([f for f in finals if math.isfinite(f)])
    if len(ok):  # the early values run into the hundreds: show the last 30 % above the worst final, where seeds differ
        low = min(
            float(ok.min()),
            best_known if best_known is not None and math.isfinite(best_known) and best_known > 0 else math.inf,
        )
        ax.set_ylim(low / 1.005, float(ok.max()) * 1.3)
    _plain_log_ticks(ax)
    spread = f", spread {100.0 * (ok.max() - ok.min()) / ok.min():.1f} %" if len(ok) > 1 else ""
    ax.set_title(
        f"Convergence over {len(histories)} seeds (median final {np.median(ok):.4f}{spread})"
        if len(ok)
        else "Convergence over seeds"
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncols=2 if len(histories) > 8 else 1)
    out = Path(path)
    atomic_write_bytes(out, _png_bytes(fig))
    return out


class ParetoFront(NamedTuple):
    """An NSGA-II run's front, sorted by size: each field ``(F,)``."""

    eta_G: NDArray[np.float64]
    links_sum_mm: NDArray[np.float64]
    bbox_volume_L: NDArray[np.float64]
    objectives: dict[str, NDArray[np.float64]] | None = None
    """The run's objectives by name (pareto.csv's ``objective_<name>`` columns), None for older runs
    (eta_G against compactness)."""

    @property
    def chosen(self) -> int:
        """Row of ``best_design.json``: the lowest first objective (eta_G for older runs)."""
        first = next(iter(self.objectives.values())) if self.objectives else self.eta_G
        return int(np.argmin(first))


def read_pareto(path: str | os.PathLike[str]) -> ParetoFront:
    """Read ``pareto.csv`` (columns eta_G, links_sum_mm, bbox_volume_L); InputError naming the file otherwise."""
    base = ("eta_G", "links_sum_mm", "bbox_volume_L")
    table = read_table(
        path, pipes=False, required=base
    )  # arcube.io.tables: a text file, rows as wide as the header, each column once
    names = [k[len("objective_") :] for k in table.header if k.startswith("objective_")]
    data = np.array(table.numbers([*base, *("objective_" + n for n in names)], finite=False), dtype=float).reshape(
        -1, len(base) + len(names)
    )
    cols = {k: data[:, j].copy() for j, k in enumerate(base)}
    objs = {n: data[:, len(base) + j].copy() for j, n in enumerate(names)}
    if objs:  # a run with --objectives: rows as written (sorted by the first objective)
        return ParetoFront(**cols, objectives=objs)
    order = np.argsort(cols["links_sum_mm"], kind="stable")
    return ParetoFront(**{k: v[order] for k, v in cols.items()})


def pareto_png(front: ParetoFront, path: str | os.PathLike[str]) -> Path:
    """PNG of eta_G against the sum of link lengths, colored by bounding-box volume (older runs), or of
    each pair of the run's objectives, with the chosen design (best_design.json) marked."""
    from matplotlib.figure import Figure

    if front.objectives:
        names = list(front.objectives)
        pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]
        fig = Figure(figsize=(4.2 * len(pairs), 4.0), layout="constrained")
        for j, (a, b) in enumerate(pairs):
            ax = fig.add_subplot(1, len(pairs), j + 1)
            ax.scatter(front.objectives[b], front.objectives[a], s=12, c=front.bbox_volume_L, cmap="viridis")
            c = front.chosen
            ax.scatter(
                [front.objectives[b][c]],
                [front.objectives[a][c]],
                marker="*",
                s=160,
                color="#d62728",
                label="best_design.json",
            )
            ax.set_xlabel(b)
            ax.set_ylabel(a)
            ax.legend(fontsize=8)
        fig.suptitle("Pareto front (colour: bounding box, L)")
        out = Path(path)
        atomic_write_bytes(out, _png_bytes(fig))
        return out
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(front.links_sum_mm, front.eta_G, color="#bbbbbb", lw=1, zorder=1)
    sc = ax.scatter(front.links_sum_mm, front.eta_G, c=front.bbox_volume_L, cmap="viridis", zorder=2)
    fig.colorbar(sc, ax=ax, label="bounding box (L)")
    ax.set_xlabel("sum of link lengths (mm)")
    ax.set_ylabel("η_G (lower is better)")
    ax.set_title("Pareto front: dexterity against size")
    out = Path(path)
    atomic_write_bytes(out, _png_bytes(fig))
    return out
