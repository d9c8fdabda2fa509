"""Structural guarantees of the library layout (issue "A library first").

The import graph is read from the source with :mod:`ast`, never by importing, so a cycle is
found even where the import order happens to hide it today.

Nodes are the modules of ``src/arcube`` (a package is its ``__init__``). An edge A -> B is an
``import`` or ``from ... import`` statement in A that names B:

* relative imports are resolved against A's package;
* ``from P import n`` is an edge to the submodule ``P.n`` when that file exists (Python imports
  the submodule even while ``P`` is half-initialised), else to ``P`` itself (the name lives in
  ``P/__init__.py``);
* imports under ``if TYPE_CHECKING:`` never run and are ignored;
* the implicit import of every ancestor package (``import a.b.c`` first runs ``a`` and ``a.b``)
  is not an edge: Python puts a package in ``sys.modules`` before running its ``__init__``, so a
  module reaching for an ancestor that is still initialising only fails if it uses a *name*
  from it, and that is an explicit ``from ancestor import name`` edge, which is counted.

Cycle rule. **Every** import counts: module-level ones (those that run when the module is
imported, including inside ``if``/``try``/class bodies) and function-level ones alike. An import
inside a function runs at call time, after every module is initialised, so it cannot deadlock an
import; the library uses them to defer heavy dependencies (plotly, trimesh, the compiled kernel).
But a deferred import is still a dependency: a loop closed through one means the lower module
knows the upper one (``Evaluation.write_report`` importing the HTML renderer, which imports
``Evaluation`` back), so it is reported too. Only imports under ``if TYPE_CHECKING:`` are left
out. With the edges above, every strongly connected component of more than one module is a
dependency cycle:

* a package ``__init__`` importing its own submodules (parent -> child) is fine on its own;
* a child importing a name from its parent ``__init__`` (child -> parent) is fine on its own
  (``arcube.model.stages.rts`` takes ``solve_harmonic`` from ``arcube.model.stages``);
* both together, or any loop through siblings or unrelated modules, is a cycle whose outcome
  depends on which module is imported first, and is reported.

The same graph collapsed to the top-level packages (``arcube.model``, ``arcube.evaluation``,
...) must also be acyclic: the library is a stack of layers. The pipeline runs model / io ->
evaluation -> optimization -> report, with ``arcube.api`` and ``arcube.cli`` on top, so the lower
layers (:data:`LOWER_LAYERS`) never import the report, the API or the CLI, not even inside a
function (:data:`UPPER_LAYERS`).
"""

from __future__ import annotations

import ast
import inspect
import itertools
from collections.abc import Iterator
from pathlib import Path

import pytest

import arcube

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = SRC / "arcube"

MAX_LINES = 250
"""Statements (logical lines: what ``ruff format`` cannot change by wrapping) of a module without a reason; about
400 formatted lines. The dense, unformatted code kept modules under 400 physical lines; formatted, the same code
takes half again as many lines, while its statements stay as they were."""
LONG_REASON = "Long module:"
"""A module over :data:`MAX_LINES` statements says why in its docstring, on a line starting with this."""

CLI_ALLOWED_PREFIXES = ("arcube.cli",)
CLI_ALLOWED_MODULES = {"arcube.__main__"}

LAYERS = (
    "arcube.caches",
    "arcube.arrays",
    "arcube.summary",
    "arcube.interrupts",
    "arcube.progress",
    "arcube.errors",
    "arcube.metrics",
    "arcube.io",
    "arcube.model",
    "arcube.validation",
    "arcube.options",
    "arcube.patients",
    "arcube.evaluation",
    "arcube.coerce",
    "arcube.request",
    "arcube.accuracy",
    "arcube.optimization",
    "arcube.motion",
    "arcube.report",
    "arcube.calibrate",
    "arcube.pedicles",
    "arcube.export",
    "arcube.design_job",
    "arcube.api",
    "arcube.explorer",
    "arcube.cli",
)
"""Every package (and top-level module) of src/arcube, bottom first: the pipeline io -> evaluation ->
optimization -> program (motion) -> report / export -> the design job -> api -> the explorer and the CLI."""
LOWER_LAYERS = LAYERS[: LAYERS.index("arcube.report")]
"""Packages (and modules) below the report: they compute and write data, and never draw or parse flags."""
UPPER_LAYERS = ("arcube.report", "arcube.cli", "arcube.api")
"""What the lower layers must not import; nor the root ``arcube`` itself, whose ``__init__`` imports the API."""


# ----------------------------------------------------------------------------- the graph


def module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def find_modules(src: Path, package: str) -> dict[str, Path]:
    """Dotted name -> file for every ``.py`` under ``src/package``."""
    return {module_name(p, src): p for p in sorted((src / package).rglob("*.py"))}


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def iter_imports(tree: ast.AST, typed: bool = False) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Every import statement with ``lazy`` = it sits inside a function (runs at call time); with
    ``typed``, only the imports under ``if TYPE_CHECKING:`` (which never run, but still tie two modules)."""

    def walk(node: ast.AST, lazy: bool, checking: bool = False) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                yield from walk(ast.Module(child.body, []), lazy, True)
                yield from ((n, lazy) for stmt in child.orelse for n, _ in walk(ast.Module([stmt], []), lazy, checking))
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                if checking == typed:
                    yield child, lazy
                continue
            yield from walk(
                child, lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)), checking
            )

    yield from walk(tree, False)


def import_targets(
    module: str, is_package: bool, node: ast.Import | ast.ImportFrom, modules: dict[str, Path]
) -> list[str]:
    """The modules an import statement in ``module`` names (see the module docstring)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    return [f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target for a in node.names]


def import_graph(
    src: Path, package: str, typed: bool = False
) -> tuple[dict[str, set[str]], dict[str, set[str]], dict[str, Path]]:
    """(module-level edges, function-level edges, modules), restricted to ``package`` modules; with
    ``typed``, the edges of the ``TYPE_CHECKING`` imports instead."""
    modules = find_modules(src, package)
    eager: dict[str, set[str]] = {m: set() for m in modules}
    lazy: dict[str, set[str]] = {m: set() for m in modules}
    for mod, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node, is_lazy in iter_imports(tree, typed):
            for target in import_targets(mod, path.name == "__init__.py", node, modules):
                if target == package or target.startswith(package + "."):
                    (lazy if is_lazy else eager)[mod].add(target)
    return eager, lazy, modules


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative); nodes outside ``graph`` are leaves."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = itertools.count()
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = next(counter)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = next(counter)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    out.append(sorted(comp))
    return out


def merged(*graphs: dict[str, set[str]]) -> dict[str, set[str]]:
    """The union of edge sets, e.g. module-level and function-level imports."""
    out: dict[str, set[str]] = {}
    for g in graphs:
        for m, ts in g.items():
            out.setdefault(m, set()).update(ts)
    return out


def _within(module: str, prefixes: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def upward_imports(graph: dict[str, set[str]], lower: tuple[str, ...], upper: tuple[str, ...], root: str) -> list[str]:
    """``"A -> B"`` for every edge from a module of ``lower`` to one of ``upper`` or to the ``root`` package."""
    return sorted(
        f"{m} -> {t}" for m, ts in graph.items() if _within(m, lower) for t in ts if t == root or _within(t, upper)
    )


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node, or a node importing itself."""
    return [c for c in strongly_connected(graph) if len(c) > 1 or c[0] in graph.get(c[0], ())]


def top_package(module: str, depth: int = 2) -> str:
    return ".".join(module.split(".")[:depth])


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for mod, targets in graph.items():
        out.setdefault(top_package(mod), set()).update(
            top_package(t) for t in targets if top_package(t) != top_package(mod)
        )
    return out


@pytest.fixture(scope="module")
def graph() -> tuple[dict[str, set[str]], dict[str, set[str]], dict[str, Path]]:
    return import_graph(SRC, "arcube")


# ----------------------------------------------------------------------------- the rule, on a made-up package


def _write_package(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def test_cycle_rule_on_a_made_up_package(tmp_path: Path) -> None:
    """The detector flags exactly the import loops that can break, on a package built for it."""
    _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "from pkg.base import thing\n",
            "pkg/base.py": "thing = 1\n",
            # parent -> child only, child -> parent only: fine.
            "pkg/ok/__init__.py": "from .leaf import f\n",
            "pkg/ok/leaf.py": "from pkg.base import thing\nf = thing\n",
            "pkg/ok2/__init__.py": "def helper():\n    return 1\n",
            "pkg/ok2/child.py": "from pkg.ok2 import helper\nfrom . import sibling\n",
            "pkg/ok2/sibling.py": "x = 1\n",
            # child -> parent name while the parent imports the child: a cycle.
            "pkg/bad/__init__.py": "from .child import g\ndef helper():\n    return 2\n",
            "pkg/bad/child.py": "from pkg.bad import helper\ng = 1\n",
            # siblings importing each other (relative, two levels): a cycle.
            "pkg/sib/__init__.py": "",
            "pkg/sib/a.py": "from ..sib import b\n",
            "pkg/sib/b.py": "import pkg.sib.c\n",
            "pkg/sib/c.py": "from .a import x\n",
            # a loop closed only inside a function: a cycle of the full graph; only for type checkers: none.
            "pkg/lazy/__init__.py": "",
            "pkg/lazy/p.py": "from pkg.lazy.q import y\nx = 1\n",
            "pkg/lazy/q.py": "y = 2\ndef f():\n    from pkg.lazy.p import x\n    return x\n",
            "pkg/tc/__init__.py": "",
            "pkg/tc/p.py": "from typing import TYPE_CHECKING\nfrom pkg.tc.q import y\nif TYPE_CHECKING:\n    from pkg.tc.q import z\n",
            "pkg/tc/q.py": "import typing\nif typing.TYPE_CHECKING:\n    from pkg.tc.p import x\ny = z = 1\n",
        },
    )
    eager, lazy, modules = import_graph(tmp_path, "pkg")
    assert sorted(cycles(eager)) == [["pkg.bad", "pkg.bad.child"], ["pkg.sib.a", "pkg.sib.b", "pkg.sib.c"]]
    assert eager["pkg.ok2.child"] == {"pkg.ok2", "pkg.ok2.sibling"}  # submodule vs name in __init__
    assert eager["pkg.sib.a"] == {"pkg.sib.b"}  # relative import, resolved
    assert lazy["pkg.lazy.q"] == {"pkg.lazy.p"} and eager["pkg.lazy.q"] == set()
    assert eager["pkg.tc.q"] == set() and lazy["pkg.tc.q"] == set()
    assert cycles({m: eager[m] | lazy[m] for m in modules}) == sorted(cycles(eager) + [["pkg.lazy.p", "pkg.lazy.q"]])
    assert cycles(merged(eager, lazy)) == sorted(cycles(eager) + [["pkg.lazy.p", "pkg.lazy.q"]])


def test_layer_rule_on_a_made_up_package(tmp_path: Path) -> None:
    """A lower layer importing an upper one is caught at module level and inside a function, through
    a relative import and through the root package; under ``TYPE_CHECKING`` it is not."""
    _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "from pkg.top.api import run\n",
            "pkg/top/__init__.py": "",
            "pkg/top/api.py": "from pkg.low.core import f\ndef run():\n    return f()\n",
            "pkg/top/draw.py": "from pkg.low import core\n",
            "pkg/low/__init__.py": "",
            "pkg/low/core.py": "def f():\n    from pkg.top.draw import core\n    return core\n",
            "pkg/low/eager.py": "from ..top import api\n",
            "pkg/low/root.py": "def g():\n    from pkg import run\n    return run\n",
            "pkg/low/typed.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.top.draw import core\n",
            "pkg/low/fine.py": "from pkg.low.core import f\n",
        },
    )
    eager, lazy, _ = import_graph(tmp_path, "pkg")
    assert upward_imports(merged(eager, lazy), ("pkg.low",), ("pkg.top",), "pkg") == [
        "pkg.low.core -> pkg.top.draw",
        "pkg.low.eager -> pkg.top.api",
        "pkg.low.root -> pkg",
    ]
    assert upward_imports(eager, ("pkg.low",), ("pkg.top",), "pkg") == ["pkg.low.eager -> pkg.top.api"]


# ----------------------------------------------------------------------------- the library


def test_import_graph_was_read(graph) -> None:
    """Sanity: the parser sees the library's real imports (else the checks below pass vacuously)."""
    eager, lazy, modules = graph
    assert len(modules) > 30
    assert "arcube.model.frames" in eager["arcube.model.mechanism"]  # ``from arcube.model import frames``
    assert "arcube.model.stages" in eager["arcube.model.stages.rts"]  # ``solve_harmonic`` from the __init__
    assert sum(map(len, lazy.values())) > 10


def test_every_arcube_import_names_an_existing_module(graph) -> None:
    eager, lazy, modules = graph
    broken = sorted(f"{m} -> {t}" for g in (eager, lazy) for m, ts in g.items() for t in ts if t not in modules)
    assert not broken, f"imports of arcube modules that do not exist: {broken}"


def test_no_import_cycles_between_modules(graph) -> None:
    """No dependency cycle, function-level and ``TYPE_CHECKING`` imports included: a module that only
    names another's type for the checker still depends on it."""
    eager, lazy, _ = graph
    typed_eager, typed_lazy, _ = import_graph(SRC, "arcube", typed=True)
    found = cycles(merged(eager, lazy, typed_eager, typed_lazy))
    assert not found, (
        "import cycles, deferred and type-checking imports included (strongly connected components): "
        + "; ".join(" <-> ".join(c) for c in found)
    )


def test_every_package_has_its_layer(graph) -> None:
    """The packages form one stack, :data:`LAYERS` from the bottom: a package imports only the layers
    below its own (deferred and type-checking imports included); every package of src/arcube is placed."""
    eager, lazy, modules = graph
    typed_eager, typed_lazy, _ = import_graph(SRC, "arcube", typed=True)
    packages = {top_package(m) for m in modules} - {"arcube", "arcube.__main__"}
    assert sorted(packages - set(LAYERS)) == [], "packages missing from LAYERS"
    rank = {p: i for i, p in enumerate(LAYERS)}
    upward = sorted(
        f"{m} -> {t}"
        for g in (eager, lazy, typed_eager, typed_lazy)
        for m, ts in g.items()
        for t in ts
        if top_package(m) in rank and top_package(t) in rank and rank[top_package(t)] > rank[top_package(m)]
    )
    assert not upward, f"imports of a higher layer: {upward}"


def test_top_level_packages_form_layers(graph) -> None:
    eager, lazy, _ = graph
    found = cycles(package_graph(merged(eager, lazy)))
    assert not found, f"cycles between arcube's top-level packages (deferred imports included): {found}"


def test_lower_layers_never_import_the_report_api_or_cli(graph) -> None:
    """model, io, evaluation, optimization (and errors, options, patients) never import arcube.report,
    arcube.api, arcube.cli or the root package, even inside a function: a result does not know its renderer."""
    eager, lazy, modules = graph
    assert any(_within(m, ("arcube.optimization",)) for m in modules) and any(
        _within(m, ("arcube.report",)) for m in modules
    )
    offenders = upward_imports(merged(eager, lazy), LOWER_LAYERS, UPPER_LAYERS, "arcube")
    assert not offenders, f"lower layers importing the report, the API or the CLI: {offenders}"


def test_library_never_imports_the_cli(graph) -> None:
    """Only ``arcube/cli/`` and ``arcube/__main__.py`` may import ``arcube.cli``, even lazily."""
    eager, lazy, _ = graph
    offenders = sorted(
        f"{m} -> {t}"
        for g in (eager, lazy)
        for m, ts in g.items()
        for t in ts
        if (t == "arcube.cli" or t.startswith("arcube.cli."))
        and m not in CLI_ALLOWED_MODULES
        and not any(m == p or m.startswith(p + ".") for p in CLI_ALLOWED_PREFIXES)
    )
    assert not offenders, f"library modules importing the CLI: {offenders}"


def _statements(text: str) -> int:
    """Logical lines: one per statement however it is wrapped (a docstring is one)."""
    import io
    import tokenize

    return sum(1 for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type == tokenize.NEWLINE)


def test_statements_count_logical_lines() -> None:
    wrapped = 'x = f(\n    1,\n    2,\n)\n"""doc\nstring"""\nif x:\n    y = [\n        3\n    ]  # note\n\n# comment\n'
    assert _statements(wrapped) == 4  # the call, the docstring, the if, the list


def _line_counts() -> dict[str, int]:
    return {
        p.relative_to(PKG).as_posix(): _statements(p.read_text(encoding="utf-8")) for p in sorted(PKG.rglob("*.py"))
    }


def _long_reason(rel: str) -> str | None:
    doc = ast.get_docstring(ast.parse((PKG / rel).read_text(encoding="utf-8"))) or ""
    return next((line[len(LONG_REASON) :].strip() for line in doc.splitlines() if line.startswith(LONG_REASON)), None)


def test_module_size() -> None:
    """No module over :data:`MAX_LINES` statements (~400 formatted lines) without a reason written at its top."""
    too_long = {rel: n for rel, n in _line_counts().items() if n > MAX_LINES and not _long_reason(rel)}
    assert not too_long, (
        f"modules over {MAX_LINES} lines without a '{LONG_REASON} ...' line in their docstring: {too_long}"
    )


def test_long_module_reasons_are_not_stale() -> None:
    """A module that says why it is long is long: the reason goes when the module shrinks."""
    counts = _line_counts()
    stale = {rel: n for rel, n in counts.items() if n <= MAX_LINES and _long_reason(rel)}
    assert not stale, f"modules within {MAX_LINES} lines still carry a '{LONG_REASON}' line; remove it: {stale}"


# ----------------------------------------------------------------------------- the public API


def _attribute_docstring(module: str, name: str, seen: frozenset[str] = frozenset()) -> str | None:
    """The string literal right after ``name = ...`` in ``module`` (following re-exports)."""
    path = find_modules(SRC, "arcube").get(module)
    if path is None or module in seen:
        return None
    body = ast.parse(path.read_text(encoding="utf-8")).body
    for stmt in list(body):  # a lazy package names its sources for the type checker (``if TYPE_CHECKING:``)
        if isinstance(stmt, ast.If) and isinstance(stmt.test, ast.Name) and stmt.test.id == "TYPE_CHECKING":
            body += stmt.body
    for stmt, nxt in zip(body, body[1:] + [None]):
        targets = (
            stmt.targets if isinstance(stmt, ast.Assign) else [stmt.target] if isinstance(stmt, ast.AnnAssign) else []
        )
        if any(isinstance(t, ast.Name) and t.id == name for t in targets):
            if isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) and isinstance(nxt.value.value, str):
                return nxt.value.value
            return None
    for stmt in body:
        if isinstance(stmt, ast.ImportFrom) and any((a.asname or a.name) == name for a in stmt.names):
            src_name = next(a.name for a in stmt.names if (a.asname or a.name) == name)
            for target in import_targets(module, path.name == "__init__.py", stmt, find_modules(SRC, "arcube")):
                doc = _attribute_docstring(target, src_name, seen | {module})
                if doc is not None:
                    return doc
    return None


def _own_docstring(obj: object) -> str | None:
    """The docstring written in the source for a function or class (not one generated by
    dataclasses, NamedTuple or pydantic, nor inherited)."""
    module = inspect.getmodule(obj)
    path = find_modules(SRC, "arcube").get(module.__name__ if module else "")
    if path is None:
        return None
    scope: list[ast.stmt] = ast.parse(path.read_text(encoding="utf-8")).body
    node: ast.AST | None = None
    for part in obj.__qualname__.split("."):  # type: ignore[attr-defined]
        node = next(
            (
                s
                for s in scope
                if isinstance(s, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and s.name == part
            ),
            None,
        )
        if node is None:
            return None
        scope = node.body  # type: ignore[attr-defined]
    return ast.get_docstring(node)  # type: ignore[arg-type]


def test_public_names_are_importable_and_unique() -> None:
    assert len(set(arcube.__all__)) == len(arcube.__all__), "duplicates in arcube.__all__"
    namespace: dict[str, object] = {}
    exec("from arcube import *", namespace)  # noqa: S102 - exactly what a user's star import does
    assert sorted(set(namespace) - {"__builtins__"}) == sorted(arcube.__all__)


@pytest.mark.parametrize("name", arcube.__all__)
def test_public_name_has_a_docstring(name: str) -> None:
    """Functions and classes need their own docstring; data constants an attribute docstring
    (the string after the assignment, which mkdocstrings shows). Dunders such as ``__version__``
    are metadata, not API, and only need to exist."""
    obj = getattr(arcube, name)
    if name.startswith("__"):
        assert isinstance(obj, str) and obj
        return
    if inspect.ismodule(obj):  # a subpackage of the API (arcube.calibrate): its own docstring
        doc = obj.__doc__
    elif inspect.isclass(obj) or inspect.isfunction(obj):
        doc = _own_docstring(obj)
    else:
        doc = _attribute_docstring("arcube", name)
    assert doc and doc.strip(), f"arcube.{name} has no docstring"


# ----------------------------------------------------------------------------- form


def test_ruff_formats_and_lints_src_and_tests_clean() -> None:
    """``ruff format --check`` and ``ruff check`` pass on src/ and tests/ (pyproject.toml's [tool.ruff]), as .ci/run
    runs them before the suite; aligned tables keep their form by ``fmt: skip``, at most 20 of them."""
    import re
    import subprocess

    ruff = pytest.importorskip("ruff")
    binary = ruff.find_ruff_bin()
    root = SRC.parent
    for args in (("format", "--check"), ("check",)):
        done = subprocess.run([binary, *args, "src", "tests"], cwd=root, capture_output=True, text=True)
        assert done.returncode == 0, f"ruff {' '.join(args)}: {done.stdout[-2000:]}{done.stderr[-500:]}"
    ci = (root / ".ci" / "run").read_text()
    assert "ruff format --check src tests" in ci and "ruff check src tests" in ci
    marker = re.compile(r"#\s*fmt:\s*(skip|off)\b")
    files = [p for d in (SRC, root / "tests") for p in d.rglob("*.py")]
    skips = sum(len(marker.findall(p.read_text(encoding="utf-8"))) for p in files)
    assert skips <= 20, f"{skips} formatter suppressions (at most 20, for aligned tables)"
