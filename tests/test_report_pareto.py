"""The Pareto front plot of an NSGA-II run: the data drawn are the rows of pareto.csv."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.report.figures import pareto_png, read_pareto
from arcube.report.html import pareto_figure

ROWS = [(1.9, 1100.0, 12.0), (1.5, 1600.0, 25.0), (1.7, 1300.0, 18.0)]


def _write(path: Path) -> Path:
    lines = ["eta_G,links_sum_mm,bbox_volume_L,feasible"] + [f"{a},{b},{c},True" for a, b, c in ROWS]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_front_is_read_sorted_by_size_and_drawn_as_is(tmp_path: Path) -> None:
    front = read_pareto(_write(tmp_path / "pareto.csv"))
    np.testing.assert_array_equal(front.links_sum_mm, [1100.0, 1300.0, 1600.0])
    np.testing.assert_array_equal(front.eta_G, [1.9, 1.7, 1.5])
    trace = pareto_figure(front).data[0]
    assert list(trace.x) == [1100.0, 1300.0, 1600.0] and list(trace.y) == [1.9, 1.7, 1.5]
    assert list(trace.marker.color) == [12.0, 18.0, 25.0]
    png = pareto_png(front, tmp_path / "front.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unreadable_front_names_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "pareto.csv"
    bad.write_text("eta_G,links_sum_mm\n1.5,1000\n")
    with pytest.raises(InputError, match="pareto.csv"):
        read_pareto(bad)


def test_front_of_the_run_objectives_marks_the_chosen_design(tmp_path: Path) -> None:
    rows = [(1.3, 0.045, 1.3, 1700.0, 22.0), (1.8, 0.025, 1.8, 1500.0, 13.0), (2.6, 0.011, 2.6, 1100.0, 9.0)]
    path = tmp_path / "pareto.csv"
    path.write_text(
        "objective_eta_G,objective_lateral_error,eta_G,links_sum_mm,bbox_volume_L\n"
        + "".join(",".join(map(str, r)) + "\n" for r in rows)
    )
    front = read_pareto(path)
    assert list(front.objectives) == ["eta_G", "lateral_error"] and front.chosen == 0
    fig = pareto_figure(front)
    assert list(fig.data[0].x) == [0.045, 0.025, 0.011] and list(fig.data[0].y) == [1.3, 1.8, 2.6]
    assert list(fig.data[1].x) == [0.045] and list(fig.data[1].y) == [1.3] and fig.data[1].name == "best_design.json"
    assert pareto_png(front, tmp_path / "front.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
