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
