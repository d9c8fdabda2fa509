"""Atomic file writes: never leave a half-written output behind, never replace a special file.

A regular file (or a new one) is written through a temporary file in the same folder, then
renamed over the target: a reader sees the old content or the new, never a mix. A FIFO or a
character device (``/dev/null``, ``/dev/stdout``, a shell's ``>(...)``) is written in place,
as a shell redirection would (a FIFO must have a reader already: the write never waits for one);
a folder, block device or socket is refused. Errors are :class:`OSError` naming the caller's
path, never the temporary file.

An output of several files (a program's CSV, JSON and PNG; a model and its replay) is written by
:func:`atomic_write_files` as one: every target must be a regular file or absent (a folder, FIFO,
device or socket among them is refused, naming it, before anything is written), every new file is
complete in its temporary file before the first rename, and if a rename fails the files already
replaced are put back, so the user's existing files survive a failed write. Before any output is
put in place, a Ctrl-C that a dependency swallowed is raised again (:func:`arcube.interrupts.check`).
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

from arcube import interrupts
from arcube.io.inputs import file_kind, what_is

__all__ = ["as_mkdir", "atomic_write_bytes", "atomic_write_files", "atomic_write_text", "check_targets", "write_folder"]


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder, then rename."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


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
    tmp = _stage(target, data)
    try:
        interrupts.check()
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


def check_targets(paths: Iterable[str | os.PathLike[str]]) -> None:
    """OSError naming the first of ``paths`` that exists and is not a regular file (a folder, FIFO,
    device or socket): the targets of an output of several files, checked before anything is written."""
    for path in paths:
        try:
            st = os.stat(path)
        except (FileNotFoundError, NotADirectoryError):
            continue
        if not stat.S_ISREG(st.st_mode):
            code = errno.EISDIR if stat.S_ISDIR(st.st_mode) else errno.EINVAL
            raise OSError(
                code,
                f"is {file_kind(st.st_mode)}, not a file arcube can replace (an output of several files is "
                "written to regular files only)",
                os.fspath(path),
            )


def _stage(target: Path, data: bytes) -> str:
    """A complete temporary copy of ``data`` beside ``target`` (its path)."""
    _make_parent(target.parent, target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)  # mkstemp creates 0600 files; outputs are meant to be shared like any other file
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return tmp


def _keep(target: Path) -> str | None:
    """A hard link to the existing ``target`` (its old content, to put back), or None if there is none."""
    if not target.exists():
        return None
    keep = os.fspath(target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(6)}.old"))
    try:
        os.link(target, keep)
    except OSError:  # a file system without hard links: a copy
        import shutil

        shutil.copy2(target, keep)
    return keep


def atomic_write_files(files: Mapping[str | os.PathLike[str], bytes]) -> None:
    """Write every ``path -> bytes`` of ``files`` as one output (module docstring): all or none.

    Raises:
        OSError: naming the target at fault (a folder, FIFO, device or socket where a file goes;
            a folder that cannot be written); the existing files are then as they were.
    """
    items = [(Path(p), data) for p, data in files.items()]
    check_targets(p for p, _ in items)
    staged: list[tuple[Path, str]] = []
    kept: dict[Path, str | None] = {}
    done: list[Path] = []
    try:
        for target, data in items:
            try:
                staged.append((target, _stage(target, data)))
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror, os.fspath(target)) from exc
        interrupts.check()
        with interrupts.deferred():  # the renames are not split by Ctrl-C (a failure is still rolled back)
            for target, _ in staged:
                kept[target] = _keep(target)
            for target, tmp in staged:
                os.replace(tmp, target)
                done.append(target)
    except BaseException:
        for target in reversed(done):  # put the user's files back
            old = kept.get(target)
            try:
                os.replace(old, target) if old is not None else target.unlink(missing_ok=True)
            except OSError:
                pass
        for _, tmp in staged:
            Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        for old in kept.values():
            if old is not None and Path(old).exists():
                Path(old).unlink(missing_ok=True)


def write_folder(files: Mapping[str, bytes], out_dir: str | os.PathLike[str]) -> Path:
    """Write ``files`` (name -> bytes) as the folder ``out_dir`` (new or empty), all or nothing: the files go
    into a temporary folder beside it, which is then renamed; returns its path.

    Raises:
        InputError: ``out_dir`` is a link, a file or a folder that is not empty, or cannot be made there (a parent
            is a file, no permission) (named ``out``).
        OSError: the file system refuses a write (nothing is left behind, not even the parents it made).
    """
    import shutil

    from arcube.errors import InputError

    out = Path(out_dir)
    if out.exists() or out.is_symlink():
        if out.is_symlink():  # renaming onto it would replace the link, not fill the folder it points to
            raise InputError.of("out", f"{out}: is a link, not a folder (give a new or empty folder)")
        if not out.is_dir():
            raise InputError.of("out", f"{out}: is {what_is(out)}, not a folder (give a new or empty folder)")
        if any(out.iterdir()):
            raise InputError.of("out", f"{out}: the folder is not empty (give a new or empty folder)")
    made = [a for a in reversed(out.parents) if not a.exists()]
    try:  # the folder is named, not the temporary one beside it: it is what the user gave
        _make_parent(out.parent, out)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    except OSError as exc:
        _remove_made(made)
        raise InputError.of("out", f"{out}: cannot create ({exc.strerror or exc})") from None
    try:
        for name, data in files.items():
            (tmp / name).write_bytes(data)
        os.chmod(tmp, 0o755)  # mkdtemp makes it private; an output folder is shared like any other
        if out.is_dir():
            out.rmdir()  # empty (checked above)
        interrupts.check()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        _remove_made(made)
        raise
    return out


def _remove_made(made: list[Path]) -> None:
    """Remove the folders a writer made (parents first in ``made``), deepest first, while they are empty."""
    for folder in reversed(made):
        try:
            folder.rmdir()
        except OSError:
            break


def as_mkdir(folder: Path) -> Path:
    """``folder`` with the permissions ``mkdir`` would give it (0777 less the umask), e.g. after ``tempfile.mkdtemp``
    (0700); returns it."""
    umask = os.umask(0)
    os.umask(umask)
    folder.chmod(0o777 & ~umask)
    return folder
