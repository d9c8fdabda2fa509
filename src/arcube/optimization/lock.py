"""One process at a time in a run folder: the ``.running`` lock file.

A run (new or resumed) holds ``RUN_DIR/.running`` (JSON: host, pid) while it writes history,
checkpoints and results, and removes it when it stops, also on an error or Ctrl-C. A second
``arcube resume`` of the same folder, for example while an interrupted study's remote dask task
still runs a seed, is refused with one line instead of interleaving two writers. A lock left by a
killed process on this host (its pid is gone) is stale and taken over; one from another host
cannot be checked from here, so the message says which file to delete once that process is known
to be gone.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from arcube.errors import InputError

LOCK_FILE = ".running"

__all__ = ["LOCK_FILE", "acquire", "release"]


def _alive(pid: object) -> bool:
    """True when process ``pid`` exists on this host (or cannot be checked)."""
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: it exists
        return True
    return True


def acquire(run_dir: Path) -> Path:
    """Create the lock of ``run_dir`` for this process; InputError when another live process holds it."""
    path = Path(run_dir) / LOCK_FILE
    me = {"host": socket.gethostname(), "pid": os.getpid()}
    for _ in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                other = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                other = {}
            if not isinstance(other, dict):
                other = {}
            if other.get("host") == me["host"] and not _alive(other.get("pid")):
                path.unlink(missing_ok=True)  # stale: the process that held it is gone (killed)
                continue
            raise InputError(
                f"{run_dir}: in use by process {other.get('pid', '?')} on {other.get('host', '?')} "
                f"(delete {path} if that process is gone)"
            ) from None
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(me, fh)
        return path
    raise InputError(f"{run_dir}: cannot take the run's lock {path}")


def release(lock: Path) -> None:
    """Remove a lock this process holds."""
    lock.unlink(missing_ok=True)
