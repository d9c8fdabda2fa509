"""Ctrl-C and SIGTERM on the command line: one line, exit code 130 (143 for SIGTERM), at any moment, and nothing
half-written; worker processes that stop with their parent.

The ``arcube`` script goes through three phases, each with its own handler of SIGINT (Ctrl-C) and SIGTERM
(``kill``, a batch scheduler's cancel, a time limit before its SIGKILL):

* **start-up** (:func:`start_up`, installed by the script's entry, :mod:`arcube.__main__`, before
  anything heavy is imported): a signal writes ``error: interrupted`` (``error: terminated``) and ends the
  process at once (``os._exit(130)``, ``143``). Nothing has been written yet, and no exception exists that a
  dependency could swallow: trimesh's optional imports catch ``BaseException`` (a ``KeyboardInterrupt`` there
  used to vanish and the job ran to its end), and a C extension interrupted while it initialises
  raises ``ImportError`` instead.
* **work** (:func:`arm`, once the CLI's handler is in place): a signal is recorded and raised as
  ``KeyboardInterrupt``, which unwinds through the writers (temporary files removed, locks released)
  to the CLI, which prints the one line (:func:`ending`). SIGTERM takes exactly Ctrl-C's way; and since a
  terminal's Ctrl-C reaches every process of the command while ``kill`` reaches one, each signal is passed on
  to the command's worker processes as SIGINT (:func:`forward`).
* an interrupt that a dependency swallowed, or turned into another exception, is not lost:
  :func:`check` raises it again; it runs after each ``import trimesh`` and before any output file is put in place (:mod:`arcube.io.files`), and
  the CLI reports any error that follows an interrupt as the interrupt.

A few system calls must not be split by an interrupt (a lock file created and written, the renames
that put several output files in place): :func:`deferred` holds SIGINT and SIGTERM off while they run; they
are delivered when they are done.

**Worker processes** (:class:`arcube.optimization.executors.WorkerProcess`: the pools of ``--workers``) start
with SIGINT and SIGTERM blocked, so that an interrupt while one imports and unpickles its task prints no traceback; then
:func:`worker_start` makes their first SIGINT or SIGTERM a ``KeyboardInterrupt`` (the task unwinds as in the
command's own process: a study's seed writes its checkpoint, a docking removes its temporary files) and ignores
the next ones, and starts a thread that watches the parent: when the parent is gone (killed, even by SIGKILL),
the worker is interrupted the same way. An interrupted worker takes no new task and ends within
:data:`WORKER_GRACE_S`, whatever it was doing.

Before the entry's first line (Python's own start, then ``import arcube``: some milliseconds, kept
light for that reason) Python's default handling applies, a ``KeyboardInterrupt`` traceback.

Library use (Python, notebooks) installs none of the command's handlers: :func:`check` is then a no-op.
"""

from __future__ import annotations

import os
import signal
import sys
import time

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing: this module loads first, keep it light
if TYPE_CHECKING:
    from types import FrameType
    from typing import Any

__all__ = [
    "EXIT_CODE",
    "MESSAGE",
    "TERM_EXIT_CODE",
    "TERM_MESSAGE",
    "WORKER_GRACE_S",
    "arm",
    "check",
    "deferred",
    "disarm",
    "ending",
    "forward",
    "pending",
    "start_up",
    "worker_interrupted",
    "worker_start",
]

MESSAGE = b"error: interrupted\n"
"""What the command line prints on Ctrl-C (on stderr), then exit code 130."""
EXIT_CODE = 130
"""128 + SIGINT: the shell's convention for a process ended by Ctrl-C."""
TERM_MESSAGE = b"error: terminated\n"
"""What the command line prints on SIGTERM (on stderr), then exit code 143."""
TERM_EXIT_CODE = 143
"""128 + SIGTERM: what a shell or a batch scheduler reports for a process ended by SIGTERM."""
WORKER_GRACE_S = 1.5
"""Seconds an interrupted worker process has to unwind (a checkpoint written, temporary files removed)
before it ends anyway (a task stuck in compiled code, or whose interrupt a dependency swallowed)."""

_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_pending = 0
"""The signal (SIGINT or SIGTERM) received since :func:`arm`; 0 if none."""


def ending(signum: int | None = None) -> tuple[bytes, int]:
    """The line and the exit code for ``signum`` (default: the signal received since :func:`arm`; Ctrl-C's if none)."""
    signum = signum or _pending
    return (TERM_MESSAGE, TERM_EXIT_CODE) if signum == signal.SIGTERM else (MESSAGE, EXIT_CODE)


def _exit_now(signum: int, frame: FrameType | None) -> None:
    """A signal before the work starts: one line, exit 130 (143), at once (nothing to clean up yet)."""
    message, code = ending(signum)
    try:
        os.write(2, message)
    finally:
        os._exit(code)


_workers: Any = None
"""The worker processes this process started (a WeakSet, made by :func:`started_worker`), for :func:`forward`."""


def started_worker(process: Any) -> None:
    """Record ``process``, a worker this process started: :func:`forward` passes interrupts on to it."""
    global _workers
    if _workers is None:
        import weakref

        _workers = weakref.WeakSet()
    _workers.add(process)


def forward() -> None:
    """Send SIGINT to the live worker processes this process started (:func:`started_worker`): they unwind as on
    Ctrl-C. A terminal's Ctrl-C has reached them already: a worker takes its first interrupt only."""
    for process in list(_workers or ()):
        popen = getattr(process, "_popen", None)
        if popen is not None and getattr(popen, "returncode", 0) is None:  # not reaped: the pid is still its own
            try:
                os.kill(popen.pid, signal.SIGINT)
            except OSError:
                pass


def _record_and_raise(signum: int, frame: FrameType | None) -> None:
    global _pending
    _pending = _pending or signum  # the first one names the ending
    forward()
    raise KeyboardInterrupt


def _install(handler: Any) -> Any:
    """``signal.signal(sig, handler)`` for SIGINT and SIGTERM; the previous handlers (SIGINT's first), or None
    outside the main thread (where Python allows no handler)."""
    try:
        return [signal.signal(sig, handler) for sig in _SIGNALS]
    except ValueError:
        return None


def start_up() -> None:
    """Make Ctrl-C and SIGTERM end the process at once with one line and exit code 130 / 143 (start-up and shut-down)."""
    _install(_exit_now)


def _quiet_unraisable(unraisable: Any) -> None:
    """An interrupt raised inside a finalizer (``__del__``, e.g. llvmlite's) cannot propagate; Python would print
    "Exception ignored in ..." with a traceback before the one line. It is recorded (:func:`pending`) and the CLI
    reports it, so it is dropped here; anything else goes to Python's own hook."""
    if not issubclass(unraisable.exc_type, KeyboardInterrupt):
        sys.__unraisablehook__(unraisable)


def arm() -> Any:
    """Make Ctrl-C and SIGTERM raise ``KeyboardInterrupt`` and be remembered (:func:`pending`); returns the handlers
    they replaced, for :func:`disarm`. Call it inside the ``try`` that handles the interrupt."""
    global _pending
    _pending = 0
    previous = _install(_record_and_raise)
    if previous is not None:
        sys.unraisablehook = _quiet_unraisable
    return previous


def disarm(previous: Any) -> None:
    """Put back the handlers :func:`arm` replaced (in-process callers, e.g. tests, keep theirs)."""
    if previous is not None:
        for sig, handler in zip(_SIGNALS, previous):
            if handler is not None:  # None: a handler not installed from Python, which cannot be put back
                signal.signal(sig, handler)
        sys.unraisablehook = sys.__unraisablehook__


def pending() -> bool:
    """Whether Ctrl-C was pressed (or SIGTERM received) since :func:`arm` (even if a dependency swallowed the
    exception); in a worker process, whether it was interrupted (:func:`worker_start`)."""
    return bool(_pending)


def check() -> None:
    """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed since :func:`arm` (a dependency may have swallowed it)."""
    if _pending:
        raise KeyboardInterrupt


class deferred:
    """Context manager: SIGINT and SIGTERM are held off (blocked) inside, delivered on leaving (POSIX; elsewhere a
    no-op)."""

    def __enter__(self) -> deferred:
        try:
            self._old: Any = signal.pthread_sigmask(signal.SIG_BLOCK, set(_SIGNALS))
        except (AttributeError, OSError, ValueError):
            self._old = None
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._old)


# ----------------------------------------------------------------------------- in a worker process
_interrupted_at: float | None = None
"""When this worker process took its first interrupt (``time.monotonic()``); None before."""


def worker_interrupted() -> bool:
    """In a worker process (:func:`worker_start`): whether it was interrupted (it then takes no new task)."""
    return _interrupted_at is not None


def _worker_signal(signum: int, frame: FrameType | None) -> None:
    """A worker's SIGINT / SIGTERM: the first is a ``KeyboardInterrupt``; the next ones (a terminal's Ctrl-C and
    the parent's :func:`forward`, the pool's terminate) are ignored, so the first one's unwinding is not cut."""
    global _interrupted_at, _pending
    if _interrupted_at is None:
        _interrupted_at = time.monotonic()
        _pending = signal.SIGINT  # check() raises it again where a dependency swallowed it
        raise KeyboardInterrupt


def worker_start(parent_pid: int, parent_sentinel: int | None) -> None:
    """Set up the signals of a worker process (module docstring); call it first in the worker's main thread.

    Args:
        parent_pid: the process that started this one.
        parent_sentinel: a descriptor that becomes readable when that process is gone
            (``multiprocessing.parent_process().sentinel``), or None: then its pid is polled.
    """
    import threading

    for sig in _SIGNALS:
        signal.signal(sig, _worker_signal)
    sys.unraisablehook = _quiet_unraisable
    wake: int | None = None
    try:  # the signals' C handler writes here at once, even while the main thread runs compiled code
        wake, wake_w = os.pipe()
        os.set_blocking(wake_w, False)
        signal.set_wakeup_fd(wake_w, warn_on_full_buffer=False)
    except (OSError, ValueError):  # elsewhere than POSIX: the interrupt is seen when the handler runs
        wake = None
    # started while the signals are blocked (the worker started so): the thread never takes them
    threading.Thread(
        target=_watch, args=(parent_pid, parent_sentinel, wake), name="arcube-watch-parent", daemon=True
    ).start()
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, set(_SIGNALS))


def _watch(parent_pid: int, parent_sentinel: int | None, wake: int | None) -> None:
    """The watch of a worker process: interrupt it when its parent is gone; end it :data:`WORKER_GRACE_S` after its
    first signal whatever it is doing."""
    import threading
    from multiprocessing.connection import wait

    since: float | None = None
    alone = False
    while True:
        watched = [fd for fd in (wake, None if alone else parent_sentinel) if fd is not None]
        if watched:
            ready = wait(watched, timeout=0.2)
        else:
            time.sleep(0.2)
            ready = []
        if wake is not None and wake in ready and set(os.read(wake, 512)) & set(_SIGNALS):  # signal numbers
            since = since or time.monotonic()
        if _interrupted_at is not None:  # the handler ran (the only sign where there is no wake-up descriptor)
            since = since or _interrupted_at
        if not alone and ((parent_sentinel is not None and parent_sentinel in ready) or os.getppid() != parent_pid):
            alone = True
            since = since or time.monotonic()
            if hasattr(signal, "pthread_kill"):  # as Ctrl-C: the task unwinds, then the worker ends
                signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)  # type: ignore[arg-type]
            else:
                import _thread

                _thread.interrupt_main()
        if since is not None and time.monotonic() - since > WORKER_GRACE_S:
            os._exit(EXIT_CODE)
