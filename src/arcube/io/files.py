"""Atomic file writes: never leave a half-written output behind, never replace a special file.

A regular file (or a new one) is written through a temporary file in the same folder, then
renamed over the target: a reader sees the old content or the new, never a mix. A FIFO or a
character device (``/dev/null``, ``/dev/stdout``, a shell's ``>(...)``) is written in place,
as a shell redirection would (a FIFO must have a reader already: the write never waits for one);
a folder, block device or socket is refused. Errors are :class:`OSError` naming the caller's
path, never the temporary file.
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path

from arcube.io.inputs import file_kind

__all__ = ["atomic_write_bytes", "atomic_write_text"]


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder, then rename."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _write_in_place(target: Path, data: bytes, fifo: bool) -> None:
    """Write into an existing FIFO or character device (no temporary file, no rename)."""
    try:
        fd = os.open(target, os.O_WRONLY | (os.O_NONBLOCK if fifo else 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        if fifo and exc.errno == errno.ENXIO:
            raise OSError(errno.ENXIO, "a FIFO (named pipe) that no process reads", os.fspath(target)) from None
        raise
    try:
        if fifo:
            os.set_blocking(fd, True)
        _write_all(fd, data)
    finally:
        os.close(fd)


def _make_parent(folder: Path, target: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        blocker = next((a for a in (folder, *folder.parents) if a.exists() and not a.is_dir()), folder)
        raise NotADirectoryError(errno.ENOTDIR, f"{blocker} is a file, not a folder", os.fspath(target)) from None


def _atomic_write(target: Path, data: bytes) -> None:
    try:
        st = os.stat(target)
    except (FileNotFoundError, NotADirectoryError):
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISFIFO(st.st_mode) or stat.S_ISCHR(st.st_mode):
            _write_in_place(target, data, fifo=stat.S_ISFIFO(st.st_mode))
            return
        code = errno.EISDIR if stat.S_ISDIR(st.st_mode) else errno.EINVAL
        raise OSError(code, f"is {file_kind(st.st_mode)}, not a file arcube can write", os.fspath(target))
    _make_parent(target.parent, target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        # mkstemp creates 0600 files; outputs are meant to be shared like any other file.
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (same-folder temporary file + ``os.replace``); a FIFO or
    character device is written in place, a folder, block device or socket refused.

    Raises:
        OSError: the file system refuses; its ``filename`` is ``path`` (not the temporary file)
            and its ``strerror`` says why.
    """
    target = Path(path)
    try:
        _atomic_write(target, data)
    except OSError as exc:
        if exc.errno is None or exc.filename == os.fspath(target):
            raise
        raise OSError(exc.errno, exc.strerror, os.fspath(target)) from exc
