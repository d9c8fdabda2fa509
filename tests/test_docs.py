"""The documentation site: every Python example runs, every quoted command line parses, the site builds.

* Each page under ``docs/`` with fenced ```` ```python ```` blocks runs as one session: its blocks
  in order, in one shared namespace, in a fresh interpreter whose working directory is a temporary
  folder (files the examples write land there). A failing block is reported with its page, its
  number on the page and its line in the Markdown file. A fresh interpreter per page is what a
  reader has, and keeps the pages independent of each other and of this test process.
  Blocks that must not run use another info string: ```` ```{.python .no-run} ````, ```` ```text ````.
* Shell blocks (```` ```bash ````) are not executed, but every ``arcube ...`` command in them must
  parse: known command, known options, values of the right type, required arguments present.
* The option lists pasted into ``docs/cli.md`` must name the same options as the live ``--help``.
* ``mkdocs build --strict`` must succeed (broken links, bad nav entries and mkdocstrings warnings fail).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`\n]*?)[ \t]*$")


@dataclass(frozen=True)
class Block:
    """One fenced code block of a Markdown page."""

    page: Path
    info: str  # the info string after the fence ("python", "bash", "{.python .no-run}", "")
    line: int  # 1-based line of the first code line in the Markdown file
    code: str  # dedented by the fence's indentation


def fenced_blocks(page: Path) -> list[Block]:
    """Every fenced block of ``page`` in order (fences may be indented, e.g. inside admonitions)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m.group("indent"), m.group("fence"), m.group("info").strip()
        closing = re.compile(rf"^{re.escape(indent)}{fence[0]}{{{len(fence)},}}[ \t]*$")
        body: list[str] = []
        j = i + 1
        while j < len(lines) and not closing.match(lines[j]):
            body.append(lines[j][len(indent) :] if lines[j].startswith(indent) else lines[j].lstrip())
            j += 1
        if j == len(lines):
            raise AssertionError(f"{page.relative_to(ROOT)}:{i + 1}: unclosed code fence")
        blocks.append(Block(page, info, i + 2, "\n".join(body) + "\n"))
        i = j + 1
    return blocks


def python_blocks(page: Path) -> list[Block]:
    """The blocks that run: info string exactly ``python``."""
    return [b for b in fenced_blocks(page) if b.info == "python"]


# The runner executes in a fresh interpreter: blocks in order, one namespace, line numbers of the page.
_RUNNER = textwrap.dedent(
    """
    import json, sys, traceback
    blocks = json.load(sys.stdin)
    namespace = {"__name__": "__main__"}
    for n, block in enumerate(blocks, start=1):
        # Pad with newlines so that tracebacks give the line number in the Markdown file.
        source = "\\n" * (block["line"] - 1) + block["code"]
        try:
            exec(compile(source, block["page"], "exec"), namespace)
        except BaseException:
            sys.stdout.flush()
            sys.stderr.write(f"\\n{block['page']}: python block {n} (line {block['line']}) raised:\\n")
            traceback.print_exc()
            sys.exit(1)
    """
)


def _page_id(page: Path) -> str:
    return str(page.relative_to(DOCS))


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p)], ids=_page_id)
def test_python_examples_run(page: Path, tmp_path: Path) -> None:
    """All ```python blocks of one page run in order, in one namespace, in a temporary folder."""
    blocks = [{"page": str(b.page.relative_to(ROOT)), "line": b.line, "code": b.code} for b in python_blocks(page)]
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", _RUNNER],
        input=json.dumps(blocks),
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    if proc.returncode != 0:
        pytest.fail(f"{proc.stderr}\n--- stdout (last 3000 characters) ---\n{proc.stdout[-3000:]}", pytrace=False)


def test_every_page_has_a_known_fence() -> None:
    """Code blocks carry an info string, and Python that is not meant to run says so explicitly."""
    allowed = {"python", "{.python .no-run}", "bash", "text", "json", "toml", "csv", "yaml"}
    bad = [
        f"{b.page.relative_to(ROOT)}:{b.line - 1}: {b.info!r}"
        for p in PAGES
        for b in fenced_blocks(p)
        if b.info not in allowed
    ]
    assert not bad, (
        "unexpected code fence info strings (use python, {.python .no-run}, bash, text, ...):\n" + "\n".join(bad)
    )


# --- command lines quoted in shell blocks ---------------------------------------------------------------


def _shell_commands(block: Block) -> list[tuple[int, list[str]]]:
    """``arcube`` invocations of a shell block as (line, argv without the program name)."""
    out: list[tuple[int, list[str]]] = []
    logical, start = "", 0
    for k, raw in enumerate(block.code.splitlines()):
        if not logical:
            start = block.line + k
        if raw.rstrip().endswith("\\"):
            logical += raw.rstrip()[:-1] + " "
            continue
        logical += raw
        words = shlex.split(logical, comments=True)
        logical = ""
        segment: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", "||", ";", "|"):
                if segment and Path(segment[0]).name == "arcube":
                    out.append((start, segment[1:]))
                segment = []
            else:
                segment.append(word)
    return out


SHELL_COMMANDS = [
    pytest.param(argv, id=f"{_page_id(b.page)}:{line}:{' '.join(argv)[:60]}")
    for p in PAGES
    for b in fenced_blocks(p)
    if b.info == "bash"
    for line, argv in _shell_commands(b)
]


def _run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run ``arcube argv`` in-process through the real entry point; (exit code, stdout, stderr)."""
    from arcube.cli import main

    try:
        main(argv)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err


def test_docs_quote_commands() -> None:
    assert len(SHELL_COMMANDS) >= 10, "the pages should quote arcube command lines in ```bash blocks"


@pytest.mark.parametrize("argv", SHELL_COMMANDS)
def test_quoted_command_line_parses(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """Parse (do not run) the command line: a known command, known options, well-typed values."""
    import typer

    from arcube.cli import app

    root = typer.main.get_command(app)  # typer's click group (typer may vendor its own click)
    if not argv or argv[0].startswith("-") or "--help" in argv:
        # arcube --version, arcube --help, arcube CMD --help: these are cheap, run them for real.
        code, out, err = _run_cli(argv, capsys)
        assert code == 0, f"arcube {shlex.join(argv)} exited {code}: {err}"
        return
    commands = root.commands  # type: ignore[attr-defined]
    name, rest = argv[0], argv[1:]
    assert name in commands, f"arcube {name}: no such command (known: {', '.join(commands)})"
    command = commands[name]
    parent = root.context_class(root, info_name="arcube")
    try:
        command.make_context(name, list(rest), parent=parent)
    except Exception as exc:  # click's UsageError / BadParameter / MissingParameter
        message = exc.format_message() if hasattr(exc, "format_message") else repr(exc)
        pytest.fail(f"arcube {shlex.join(argv)}: {message}", pytrace=False)


def _documented_commands() -> set[str]:
    return {
        argv[0]
        for p in PAGES
        for b in fenced_blocks(p)
        if b.info == "bash"
        for _, argv in _shell_commands(b)
        if argv and not argv[0].startswith("-")
    }


def test_every_command_is_documented_and_has_help(capsys: pytest.CaptureFixture[str]) -> None:
    """Each command of the CLI appears in the docs' examples, and ``arcube COMMAND --help`` works."""
    import typer

    from arcube.cli import app

    commands = set(typer.main.get_command(app).commands)  # type: ignore[attr-defined]
    documented = _documented_commands()
    assert commands <= documented, f"commands without an example in the docs: {sorted(commands - documented)}"
    for name in sorted(documented):
        code, out, err = _run_cli([name, "--help"], capsys)
        assert code == 0, f"arcube {name} --help exited {code}: {err}"
        assert f"Usage: arcube {name}" in out


_OPTION = re.compile(r"^\s{2}(--[a-z][a-z0-9-]*)", re.MULTILINE)


def _help_blocks() -> dict[str, str]:
    """The pasted ``arcube COMMAND --help`` outputs of cli.md, by command ('' for the root)."""
    out: dict[str, str] = {}
    for b in fenced_blocks(DOCS / "cli.md"):
        m = re.match(r"Usage: arcube (?:\[OPTIONS\] COMMAND|(\w+(?: \w+)?))", b.code)
        if b.info == "text" and m:
            out[m.group(1) or ""] = b.code
    return out


def test_cli_reference_lists_the_live_options(capsys: pytest.CaptureFixture[str]) -> None:
    """The option lists in cli.md were pasted from ``--help``; they must still name the same options.

    Regenerate a block with ``.venv/bin/arcube COMMAND --help`` when this fails.
    """
    import typer

    from arcube.cli import app

    pasted = _help_blocks()
    commands = ["", *typer.main.get_command(app).commands]  # type: ignore[attr-defined]
    assert set(commands) <= set(pasted), f"cli.md lacks the --help output of: {sorted(set(commands) - set(pasted))}"
    for name in commands:
        code, live, err = _run_cli([name, "--help"] if name else ["--help"], capsys)
        assert code == 0, err
        assert set(_OPTION.findall(pasted[name])) == set(_OPTION.findall(live)), (
            f"docs/cli.md: the options of 'arcube {name} --help' changed; paste the new output:\n{live}"
        )


def test_error_convention(capsys: pytest.CaptureFixture[str]) -> None:
    """What the CLI reference says: a bad input prints one line 'error: ...' on stderr and exits with 2."""
    for argv in (
        ["evaluate", "--points", "1"],
        ["evaluate", "--mode=+,+"],
        ["evaluate", "--no-such-flag"],
        ["evaluate", "--design", "missing-design.json"],
    ):
        code, out, err = _run_cli(argv, capsys)
        assert code == 2, argv
        assert err.startswith("error: ") and err.count("\n") == 1, (argv, err)


def test_installed_script_prints_its_version() -> None:
    import arcube

    script = Path(sys.executable).with_name("arcube")
    if not script.exists():
        pytest.skip(f"no arcube script beside {sys.executable}")
    proc = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == f"arcube {arcube.__version__}"


# --- the site --------------------------------------------------------------------------------------------


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    """``mkdocs build --strict`` succeeds: nav, links, and the API pages mkdocstrings generates."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (tmp_path / "site" / "index.html").exists()
    assert (tmp_path / "site" / "api" / "index.html").exists()


def test_griffe_extension_renders_sphinx_roles_as_code() -> None:
    """docs/griffe_sphinx_roles.py (used by the API pages) turns reST roles and '::' into Markdown."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("griffe_sphinx_roles", DOCS / "griffe_sphinx_roles.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.rewrite("An :class:`Evaluation`, :func:`~arcube.io.load.load_trajectories`.") == (
        "An `Evaluation`, `load_trajectories`."
    )
    assert (
        module.rewrite("See :mod:`arcube.api`::\n\n    import arcube\n") == "See `arcube.api`:\n\n    import arcube\n"
    )


# --- citation and changelog --------------------------------------------------------------------------


def test_citation_and_changelog_match_the_version() -> None:
    """CITATION.cff is valid YAML with the CFF 1.2.0 essentials; both files name the package's version."""
    import yaml

    import arcube

    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0"
    assert cff["title"] == "arcube" and cff["license"] == "MIT" and cff["message"]
    assert str(cff["version"]) == arcube.__version__
    assert cff["authors"] == [{"name": "arcube contributors"}]
    paper = cff["preferred-citation"]
    assert paper["title"] == "Optimization of an Augmented R-CUBE mechanism for Cervical Surgery"
    assert [a["family-names"] for a in paper["authors"]] == ["Essomba", "Wu", "Chaker", "Laribi"]
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert f"## [{arcube.__version__}]" in changelog and "## [0.1.0]" in changelog


def test_the_architecture_layout_names_every_package_and_top_level_module() -> None:
    """House II: docs/architecture.md's layout is held to the code: every package and top-level module of src/arcube
    appears in it (it missed accuracy/, calibrate/ and most benchmarks)."""
    src = Path(__file__).resolve().parents[1] / "src" / "arcube"
    text = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text(encoding="utf-8")
    layout = text[text.index("## Layout") :]
    names = [f"{p.name}/" for p in src.iterdir() if p.is_dir() and (p / "__init__.py").exists()]
    names += [p.name for p in src.glob("*.py") if p.name not in ("__init__.py", "__main__.py")]
    missing = [n for n in names if n not in layout]
    assert not missing, f"docs/architecture.md's layout misses {missing}"


def test_griffe_warns_of_every_docstring_problem() -> None:
    """The API reference is built with griffe's warnings on (mkdocs --strict fails on a parameter documented under a
    name the signature lacks, or without a type): nothing in mkdocs.yml silences them."""
    text = (Path(__file__).resolve().parents[1] / "mkdocs.yml").read_text(encoding="utf-8")
    assert "warn_unknown_params: false" not in text and "warn_missing_types: false" not in text
    assert "warn_" not in text.replace("warn_unknown_params: true", "").replace("warn_missing_types: true", "")
