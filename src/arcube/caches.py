"""Where Numba keeps the compiled kernels (``cache=True``) when the install cannot be written.

Numba caches a compiled function in ``__pycache__`` beside its source, else in ``~/.cache/numba``;
when neither can be written (a root-owned site-packages run by another user, with a read-only or
missing HOME) it refuses to compile at all (``RuntimeError: cannot cache function ...: no locator
available``). :func:`configure`, run by ``import arcube`` before anything imports Numba, leaves a
writable install alone; otherwise it points ``NUMBA_CACHE_DIR`` at the first folder that can be
written: ``$XDG_CACHE_HOME/arcube/numba``, ``~/.cache/arcube/numba``, then
``<tempdir>/arcube-numba-<uid>``. A ``NUMBA_CACHE_DIR`` the user set is always kept.
"""

from __future__ import annotations

import os
import sys

__all__ = ["COMPILED_FOLDERS", "cache_folder", "configure"]

_ROOT = os.path.dirname(os.path.abspath(__file__))
COMPILED_FOLDERS = (os.path.join("evaluation", "kernel"), os.path.join("evaluation", "sdf"), "accuracy")
"""The package folders (relative to ``arcube/``) holding ``@njit(cache=True)`` functions."""


def _writable(folder: str) -> bool:
    """Whether a file can be created in ``folder`` (made if missing, private), by trying; and whether
    the folder is this user's alone: Numba loads pickled code from its cache, so a folder that another
    user made or can write (a shared /tmp) is not used."""
    import tempfile  # here, not at the top: ``import arcube`` runs this module and must stay light

    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        st = os.stat(folder)
        if hasattr(os, "getuid") and (st.st_uid != os.getuid() or st.st_mode & 0o022):
            return False
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    return True


def _in_tree_writable() -> bool:
    for rel in COMPILED_FOLDERS:
        folder = os.path.join(_ROOT, rel)
        cache = os.path.join(folder, "__pycache__")
        target = cache if os.path.isdir(cache) else folder
        if not os.access(target, os.W_OK | os.X_OK):
            return False
    return True


def cache_folder() -> str | None:
    """The first writable per-user folder for Numba's cache (module docstring), or None."""
    import tempfile

    uid = os.getuid() if hasattr(os, "getuid") else "user"
    candidates = []
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        candidates.append(os.path.join(xdg, "arcube", "numba"))
    home = os.path.expanduser("~")
    if home and home != "~":
        candidates.append(os.path.join(home, ".cache", "arcube", "numba"))
    candidates.append(os.path.join(tempfile.gettempdir(), f"arcube-numba-{uid}"))
    return next((c for c in candidates if _writable(c)), None)


def configure() -> str | None:
    """Set ``NUMBA_CACHE_DIR`` when the package folders cannot be written (module docstring);
    returns the folder chosen, or None when nothing was changed."""
    if os.environ.get("NUMBA_CACHE_DIR") or _in_tree_writable():
        return None
    folder = cache_folder()
    if folder is None:
        return None
    os.environ["NUMBA_CACHE_DIR"] = folder
    if "numba" in sys.modules:  # imported before arcube: its configuration was read already
        config = sys.modules.get("numba.core.config")
        if config is not None:
            config.CACHE_DIR = folder  # type: ignore[attr-defined]
    return folder
