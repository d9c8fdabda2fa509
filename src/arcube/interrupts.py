"""Ctrl-C on the command line: exit code 130 and one line, at any moment, and nothing half-written.

The ``arcube`` script goes through three phases, each with its own SIGINT handler:

* **start-up** (:func:`start_up`, installed by the script's entry, :mod:`arcube.__main__`, before
  anything heavy is imported): an interrupt writes ``error: interrupted`` and ends the process at once
  (``os._exit(130)``). Nothing has been written yet, and no exception exists that a dependency
  could swallow: trimesh's optional imports catch ``BaseException`` (a ``KeyboardInterrupt`` there
  used to vanish and the job ran to its end), and a C extension interrupted while it initialises
  raises ``ImportError`` instead.
* **work** (:func:`arm`, once the CLI's handler is in place): an interrupt is recorded and raised as
  ``KeyboardInterrupt``, which unwinds through the writers (temporary files removed, locks released)
  to the CLI, which prints the one line.
* an interrupt that a dependency swallowed, or turned into another exception, is not lost:
  :func:`check` raises it again; it runs after each ``import trimesh`` and before any output file is put in place (:mod:`arcube.io.files`), and
  the CLI reports any error that follows an interrupt as the interrupt.

A few system calls must not be split by an interrupt (a lock file created and written, the renames
that put several output files in place): :func:`deferred` holds SIGINT off while they run; it is
delivered when they are done.

Before the entry's first line (Python's own start, then ``import arcube``: some milliseconds, kept
light for that reason) Python's default handling applies, a ``KeyboardInterrupt`` traceback.

Library use (Python, notebooks) installs none of this: :func:`check` is then a no-op.
"""

from __future__ import annotations

import os
import signal
import sys

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing: this module loads first, keep it light
if TYPE_CHECKING:
    from types import FrameType
    from typing import Any

__all__ = ["EXIT_CODE", "MESSAGE", "arm", "check", "deferred", "disarm", "pending", "start_up"]

MESSAGE = b"error: interrupted\n"
"""What the command line prints on Ctrl-C (on stderr), then exit code 130."""
EXIT_CODE = 130
"""128 + SIGINT: the shell's convention for a process ended by Ctrl-C."""

_pending = False


def _exit_now(signum: int, frame: FrameType | None) -> None:
    """SIGINT before the work starts: one line, exit 130, at once (nothing to clean up yet)."""
    try:
        os.write(2, MESSAGE)
    finally:
        os._exit(EXIT_CODE)


def _record_and_raise(signum: int, frame: FrameType | None) -> None:
    global _pending
    _pending = True
    raise KeyboardInterrupt


def _install(handler: Any) -> Any:
    """``signal.signal(SIGINT, handler)``; None outside the main thread (where Python allows no handler)."""
    try:
        return signal.signal(signal.SIGINT, handler)
    except ValueError:
        return None


def start_up() -> None:
    """Make Ctrl-C end the process at once with one line and exit code 130 (start-up and shut-down)."""
    _install(_exit_now)


def _quiet_unraisable(unraisable: Any) -> None:
    """An interrupt raised inside a finalizer (``__del__``, e.g. llvmlite's) cannot propagate; Python would print
    "Exception ignored in ..." with a traceback before the one line. It is recorded (:func:`pending`) and the CLI
    reports it, so it is dropped here; anything else goes to Python's own hook."""
    if not issubclass(unraisable.exc_type, KeyboardInterrupt):
        sys.__unraisablehook__(unraisable)


def arm() -> Any:
    """Make Ctrl-C raise ``KeyboardInterrupt`` and be remembered (:func:`pending`); returns the handler
    it replaced, for :func:`disarm`. Call it inside the ``try`` that handles the interrupt."""
    global _pending
    _pending = False
    previous = _install(_record_and_raise)
    if previous is not None:
        sys.unraisablehook = _quiet_unraisable
    return previous


def disarm(previous: Any) -> None:
    """Put back the handler :func:`arm` replaced (in-process callers, e.g. tests, keep theirs)."""
    if previous is not None:
        _install(previous)
        sys.unraisablehook = sys.__unraisablehook__


def pending() -> bool:
    """Whether Ctrl-C was pressed since :func:`arm` (even if a dependency swallowed the exception)."""
    return _pending


def check() -> None:
    """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed since :func:`arm` (a dependency may have swallowed it)."""
    if _pending:
        raise KeyboardInterrupt


class deferred:
    """Context manager: SIGINT is held off (blocked) inside, delivered on leaving (POSIX; elsewhere a no-op)."""

    def __enter__(self) -> deferred:
        try:
            self._old: Any = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        except (AttributeError, OSError, ValueError):
            self._old = None
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._old)
