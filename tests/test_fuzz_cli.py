"""Hypothesis over command-line flag values: whatever a user types, ``arcube`` answers with a result
(exit 0) or one line ``error: ...`` (exit 2), never a traceback, and leaves no file behind.

Runs in process (``arcube.cli.main``) with a fixed number of derandomized examples, so CI time and
results are stable; the count tried is printed (``-s``) and asserted.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness import cli_error as _run

EXAMPLES = 120
_tried = {"evaluate": 0, "joints": 0}

numbers = st.one_of(
    st.integers(min_value=-(10**30), max_value=10**30).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "nan", "inf", "-0", "1e400", "0x10", "1_000", "3,4", "٣", "1.5.2", "--x"]),
)
texts = st.one_of(numbers, st.text(max_size=12))
FLAGS = {
    "--points": numbers,
    "--mode": st.one_of(st.sampled_from(["+,+,-,+", "free", "+,+", "1,1,1,1"]), texts),
    "--thrust": numbers,
    "--lateral-force": numbers,
    "--encoder-deg": st.one_of(numbers, st.lists(numbers, max_size=6).map(",".join)),
    "--actuator-stiffness": numbers,
    "--link-radius": numbers,
    "--motor-length": numbers,
    "--side": st.one_of(st.sampled_from(["R", "L", "r", "X"]), texts),
    "--levels": st.one_of(st.sampled_from(["C3-C5", "C5-C3", "C9"]), texts),
    "--ids": st.one_of(st.sampled_from(["1,3", "99", "1,1"]), texts),
    "--engine": st.one_of(st.sampled_from(["numba", "numpy", "gpu"]), texts),
}


def _check(code: int, err: str) -> None:
    assert code in (0, 2), (code, err)
    assert "Traceback" not in err
    if code == 2:
        assert err.startswith("error: ") and err.count("\n") == 1, err


@settings(
    max_examples=EXAMPLES, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    chosen=st.dictionaries(st.sampled_from(sorted(FLAGS)), st.just(None), min_size=1, max_size=4).flatmap(
        lambda d: st.fixed_dictionaries({k: FLAGS[k] for k in d})
    )
)
def test_evaluate_flag_values(
    chosen: dict[str, str], capsys: pytest.CaptureFixture[str], tmp_path_factory: pytest.TempPathFactory
) -> None:
    _tried["evaluate"] += 1
    argv = ["evaluate", "--points", "3", "--ids", "1,2"]
    for flag, value in chosen.items():
        argv += [f"{flag}={value}"]
    code, err = _run([*argv, "--json"], capsys)
    _check(code, err)


@settings(
    max_examples=EXAMPLES // 3,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(points=numbers, speed=numbers, mode=FLAGS["--mode"])
def test_joints_flag_values_leave_no_file_on_error(
    points: str, speed: str, mode: str, capsys: pytest.CaptureFixture[str], tmp_path_factory: pytest.TempPathFactory
) -> None:
    _tried["joints"] += 1
    folder = tmp_path_factory.mktemp("joints")
    out = folder / "j.csv"
    code, err = _run(
        ["joints", f"--points={points}", f"--speed={speed}", f"--mode={mode}", "--ids", "1,2", "--out", str(out)],
        capsys,
    )
    _check(code, err)
    if code != 0:
        assert os.listdir(folder) == [], f"left behind: {os.listdir(folder)}"
    else:
        assert Path(out).is_file()


def test_the_fuzz_ran_its_examples() -> None:
    """Runs last in this file: every property above tried its fixed number of examples."""
    print(f"hypothesis examples tried: evaluate {_tried['evaluate']}, joints {_tried['joints']}")
    assert _tried["evaluate"] >= EXAMPLES and _tried["joints"] >= EXAMPLES // 3
