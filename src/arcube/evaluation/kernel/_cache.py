"""Numba's on-disk cache of the kernel, kept in step with what the kernel compiles.

Numba keys a cached function by its own file's timestamp only: when ``_points.py`` changes, the
cached ``_kernel`` of ``_driver.py`` would go on running the old ``_design_points`` compiled into
it. And the module-level constants that compiled code freezes can change with no kernel file
changing at all: the row layouts of ``_layout`` follow the result types of
:mod:`arcube.evaluation.reference` and :data:`arcube.model.design.SLICES`, the body's sizes come
from :mod:`arcube.model.body`. So :func:`ensure_fresh`, called once per process before the first
compiled call (``evaluate_task_numba`` and ``warm_up`` do), drops the kernel's cache files when the
:func:`fingerprint` of those sources and constants differs from the one stamped when they were
written. :func:`clear_cache` drops them unconditionally. Importing the kernel touches no file.

Only the cache next to the sources (``kernel/__pycache__``) is managed: with ``NUMBA_CACHE_DIR``
set, or a read-only install, Numba caches elsewhere (or compiles in memory) and that is left alone.
"""

from __future__ import annotations

import hashlib
import importlib
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
_CACHE = _HERE / "__pycache__"
_STAMP = "arcube_kernel_sources.sha256"
_PACKAGE = __name__.rsplit(".", 1)[0]
_checked = False


def _constant(value: object) -> str | None:
    """A process-independent text of a constant Numba may freeze (None for anything else)."""
    if isinstance(value, (bool, int, float, str, bytes, np.generic)):
        return repr(value)
    if isinstance(value, np.ndarray):
        return f"{value.dtype.str}{value.shape}{np.ascontiguousarray(value).tobytes().hex()}"
    if isinstance(value, tuple):
        items = [_constant(v) for v in value]
        return None if any(v is None for v in items) else "(" + ",".join(items) + ")"  # type: ignore[arg-type]
    return None


def fingerprint() -> str:
    """SHA-256 of the kernel package's Python sources (file-name order), and of the module-level
    constants of its compiled modules (numbers, strings, tuples, arrays: what Numba freezes)."""
    h = hashlib.sha256()
    for path in sorted(_HERE.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
        if path.stem in ("__init__", "_cache"):
            continue
        module = importlib.import_module(f"{_PACKAGE}.{path.stem}")
        for name, value in sorted(vars(module).items()):
            text = None if name.startswith("__") else _constant(value)
            if text is not None:
                h.update(f"{path.stem}.{name}={text}\n".encode())
    return h.hexdigest()


def clear_cache() -> int:
    """Delete the kernel's cache files (``.nbi``, ``.nbc`` in ``kernel/__pycache__``); returns how many.

    Code this process already loaded stays in use; what is compiled next is cached afresh.
    """
    removed = 0
    for f in list(_CACHE.glob("*.nbi")) + list(_CACHE.glob("*.nbc")):
        try:
            f.unlink()
            removed += 1
        except OSError:
            pass  # gone already (another process), or read-only
    return removed


def ensure_fresh() -> None:
    """Once per process: :func:`clear_cache` if the cache files were written for another
    :func:`fingerprint` (or it is unknown), then stamp the current one."""
    global _checked
    if _checked:
        return
    _checked = True
    stamp = _CACHE / _STAMP
    current = fingerprint()
    try:
        if stamp.read_text() == current:
            return
    except OSError:
        pass
    clear_cache()
    try:
        _CACHE.mkdir(exist_ok=True)
        stamp.write_text(current)
    except OSError:
        pass  # a read-only install: Numba then caches elsewhere or compiles in memory
