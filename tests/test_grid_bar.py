"""The command line's bar while an anatomy's distance grids are built (a label map takes tens of seconds)."""

from __future__ import annotations

import io

from arcube.cli.common import LIVE_BARS, GridBar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_grid_bar_shows_on_a_terminal_and_is_gone_when_the_grids_are_built() -> None:
    out = Terminal()
    bar = GridBar(out)
    bar(0, 4)
    assert bar.progress is not None
    for k in range(1, 5):
        bar(k, 4)
    assert bar.progress is None  # stopped at the last part
    assert "anatomy distance grids" in out.getvalue()


def test_grid_bar_stays_silent_off_a_terminal_and_under_another_bar() -> None:
    plain = io.StringIO()
    GridBar(plain)(0, 4)
    assert plain.getvalue() == ""
    out = Terminal()
    LIVE_BARS[0] += 1  # an optimizer's bar on screen: two live displays would garble each other
    try:
        bar = GridBar(out)
        bar(0, 4)
        bar(1, 4)
        assert bar.progress is None and out.getvalue() == ""
    finally:
        LIVE_BARS[0] -= 1
