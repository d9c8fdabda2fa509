"""Griffe extension for the API reference: render the reST bits of the docstrings as Markdown.

The docstrings in ``src/arcube`` use Sphinx roles (``:func:`evaluate```, ``:class:`~a.b.Design```)
and reST literal blocks introduced by ``::``. mkdocstrings interprets neither, so they would appear
literally (":class:" followed by code, a stray "::"). When griffe loads the package, this extension
rewrites each role to a plain code span (``~a.b.Design`` becomes ``Design``, as in Sphinx) and
turns the ``::`` that opens an indented block into ``:``. It changes what the site shows, not the
sources.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|attr|data|exc|obj|const|ref):`(~?)([^`<]*?)(?:\s*<([^>]+)>)?`")


def _code(match: re.Match[str]) -> str:
    tilde, text, target = match.group(1), match.group(2).strip(), match.group(3)
    shown = text or (target or "")
    if tilde:
        shown = shown.rsplit(".", 1)[-1]
    return f"`{shown}`"


_LITERAL_BLOCK = re.compile(r"(\S)::(\n[ \t]*\n[ \t]+\S)")


def rewrite(text: str) -> str:
    """``:role:`~pkg.mod.Name``` -> ```Name```; ``:role:`pkg.mod.Name``` -> ```pkg.mod.Name```;
    ``text::`` before an indented block -> ``text:`` (the block stays an indented code block)."""
    return _LITERAL_BLOCK.sub(r"\1:\2", _ROLE.sub(_code, text))


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles in every docstring of a loaded package."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        seen: set[int] = set()
        stack: list[griffe.Object] = [pkg]
        while stack:
            obj = stack.pop()
            if id(obj) in seen:
                continue
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = rewrite(obj.docstring.value)
            stack.extend(member for member in obj.members.values() if not member.is_alias)
