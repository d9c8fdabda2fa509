"""Issue "Hardening IV": single-file outputs are never replaced without --force (evaluate --report, explore --html
replaced an existing file without a word; every other single-file output refuses), and --force alone is refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness import cli_error, run_cli

CASES = [
    (["evaluate", "--ids", "1", "--points", "3", "--report"], "--report"),
    (["explore", "--ids", "1", "--points", "3", "--html"], "--html"),
]


@pytest.mark.parametrize("argv, flag", CASES)
def test_an_existing_file_is_replaced_only_with_force(argv: list[str], flag: str, tmp_path: Path, capsys) -> None:
    target = tmp_path / "kept.html"
    target.write_text("a report someone kept")
    code, err = cli_error([*argv, str(target)], capsys)
    assert code == 2 and err == f"error: {flag} {target}: exists; give --force to replace it\n", err
    assert target.read_text() == "a report someone kept"
    code, _, err = run_cli([*argv, str(target), "--force"], capsys)
    assert code == 0, err
    assert target.read_text().lstrip().lower().startswith("<!doctype html")


@pytest.mark.parametrize("argv, flag", CASES)
def test_force_without_the_file_is_refused(argv: list[str], flag: str, capsys) -> None:
    code, err = cli_error([*argv[:-1], "--force"], capsys)
    assert code == 2 and f"--force replaces the {flag} file" in err and err.count("\n") == 1, err


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--algorithm", "ga", "--compactness", "bbox"], "--compactness: the second objective of nsga2 and nsga3; ga"),
        (["--compactness", "links"], "mscmaes would ignore it"),
        (["--objectives", "eta_G,links", "--compactness", "bbox"], "--compactness and --objectives"),
        (["--eliminate-duplicates"], "--eliminate-duplicates: drops ga's duplicate offspring; mscmaes"),
        (["--algorithm", "nsga2", "--eliminate-duplicates"], "nsga2 would ignore it"),
    ],
)
def test_a_flag_the_algorithm_would_ignore_is_refused(args: list[str], needle: str, tmp_path: Path, capsys) -> None:
    """--compactness with ga (or any single-objective search, or beside --objectives), --eliminate-duplicates with
    anything but ga: each was taken and ignored."""
    out = tmp_path / "run"
    code, err = cli_error(["optimize", "--trajectories", "reference", *args, "--out", str(out)], capsys)
    assert code == 2 and needle in err and err.count("\n") == 1, err
    assert not out.exists()


def test_the_flags_stay_taken_where_they_count(tmp_path: Path, capsys) -> None:
    for args in (["--algorithm", "ga", "--eliminate-duplicates"], ["--algorithm", "nsga2", "--compactness", "bbox"]):
        argv = ["optimize", "--trajectories", "reference", "--ids", "1", "--points", "3", *args]
        code, _, err = run_cli(
            [*argv, "--population", "8", "--generations", "2", "--out", str(tmp_path / args[1])], capsys
        )
        assert code == 0, err
