"""Library errors name what the Python caller wrote, never a command-line flag (issue "One settings
model", item 2).

A library error about one parameter names it as the caller writes it (``points``, ``side``,
``BodyRadii.link``) and carries that name in ``InputError.param``; only ``src/arcube/cli/`` knows the
flags and turns the name into its flag when it prints the error. This test reads every module of
the library outside ``cli/`` with :mod:`ast` and fails on any string literal that looks like a flag
(``--`` then a letter) inside an error: the arguments of a ``raise``, and of any call that builds an
exception (``InputError(...)``, ``InputError.of(...)``, ``ValueError(...)``, ...), f-string parts
included. Docstrings, comments and help texts are not errors and are not read.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "src" / "arcube"
FLAG_RE = re.compile(r"(?<![\w<!-])--[a-z]")
"""``--points``, ``--c-z``; not ``<!--`` (an XML comment) nor ``a--b``."""


def _builds_exception(call: ast.Call) -> bool:
    func = call.func
    name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
    if name == "of" and isinstance(func, ast.Attribute):  # InputError.of(param, problem)
        owner = func.value
        name = owner.id if isinstance(owner, ast.Name) else owner.attr if isinstance(owner, ast.Attribute) else ""
    return name.endswith(("Error", "Exception"))


def _strings(node: ast.AST) -> Iterator[ast.Constant]:
    for sub in ast.walk(node):
        if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            yield sub


def flags_in_errors(path: Path, root: Path = PKG.parent) -> list[str]:
    """``"file:line: literal"`` for every flag-like literal inside an error built in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: dict[tuple[int, int], str] = {}
    for node in ast.walk(tree):
        roots: list[ast.AST] = []
        if isinstance(node, ast.Raise) and node.exc is not None:
            roots.append(node.exc)
        elif isinstance(node, ast.Call) and _builds_exception(node):
            roots.extend([*node.args, *(k.value for k in node.keywords)])
        for expr in roots:
            for const in _strings(expr):
                if FLAG_RE.search(const.value):
                    found[(const.lineno, const.col_offset)] = const.value
    rel = path.relative_to(root)
    return [f"{rel}:{line}: {text!r}" for (line, _), text in sorted(found.items())]


def library_modules() -> list[Path]:
    return sorted(p for p in PKG.rglob("*.py") if "cli" not in p.relative_to(PKG).parts)


def test_the_scanner_sees_a_flag_in_an_error(tmp_path: Path) -> None:
    """The scanner itself: flags in raise / InputError(...) / .of(...) / f-strings are found; help
    texts, docstrings, comments and XML comments are not."""
    src = tmp_path / "m.py"
    src.write_text(
        '"""Uses ``--points``."""\n'
        "from arcube.errors import InputError\n"
        "HELP = '--points N'  # --points\n"
        "def f(n):\n"
        "    if n < 2:\n"
        "        raise InputError(f'--points must be >= 2, got {n}')\n"
        "    if n > 9:\n"
        "        raise InputError.of('--c-z', 'bad')\n"
        "    err = ValueError('see --mode')\n"
        "    return '<!--' + str(err)\n",
        encoding="utf-8",
    )
    hits = flags_in_errors(src, tmp_path)
    assert [h.split(":")[1] for h in hits] == ["6", "8", "9"], hits


def test_no_library_error_names_a_command_line_flag() -> None:
    modules = library_modules()
    assert len(modules) > 40, "the scan found too few modules: wrong root?"
    hits = [hit for path in modules for hit in flags_in_errors(path)]
    assert not hits, (
        f"{len(hits)} error message(s) outside src/arcube/cli/ name a command-line flag; name the parameter "
        "as the Python caller writes it (InputError.of(param, problem)) and let the CLI map it to its flag:\n"
        + "\n".join(hits)
    )
