"""Progress of long steps deep below the commands, heard by whoever listens (the command line's bars).

A step that takes long where no caller can pass a callback (the distance grids of an anatomy, built on first use
inside an evaluation, model §14.3) tells its progress here; :func:`listening` hears it within a block. The module
imports nothing heavy: the command line installs its listener before any command runs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["GRIDS", "listening", "tell"]

GRIDS = "grids"
"""The topic of an anatomy's distance grids: ``total`` is twice (two grids) the shells plus one (the nodes outside
every shell), ``done`` counts the parts filled; told once with ``done == 0`` before the first part."""

_listeners: dict[str, list[Callable[[int, int], None]]] = {}


@contextmanager
def listening(topic: str, listener: Callable[[int, int], None]) -> Iterator[None]:
    """Within the block, ``listener(done, total)`` hears every :func:`tell` of ``topic`` in this process."""
    _listeners.setdefault(topic, []).append(listener)
    try:
        yield
    finally:
        _listeners[topic].remove(listener)


def tell(topic: str, done: int, total: int) -> None:
    """Tell the listeners of ``topic`` that ``done`` of ``total`` parts are done."""
    for listener in list(_listeners.get(topic, ())):
        listener(done, total)
