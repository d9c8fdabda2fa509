"""Keep Numba's on-disk cache of the kernel in step with the kernel's source.

Numba keys a cached function by its own file's timestamp only: when ``_points.py`` changes, the
cached ``_kernel`` of ``_driver.py`` would go on running the old ``_design_points`` compiled into
it. So the kernel's cache files are dropped whenever the fingerprint of all the kernel modules'
sources changes (checked once per process, before anything is compiled or loaded).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_HERE = Path(__file__).resolve().parent
_STAMP = "arcube_kernel_sources.sha256"


def fingerprint() -> str:
    """SHA-256 of the kernel package's Python sources, in file-name order."""
    h = hashlib.sha256()
    for path in sorted(_HERE.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def invalidate_stale_cache() -> None:
    """Remove the kernel's ``.nbi``/``.nbc`` files when the sources changed since they were written."""
    cache = _HERE / "__pycache__"
    stamp = cache / _STAMP
    current = fingerprint()
    try:
        if stamp.read_text() == current:
            return
    except OSError:
        pass
    try:
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        stamp.write_text(current)
    except OSError:
        pass  # a read-only install: Numba then caches elsewhere or compiles in memory
