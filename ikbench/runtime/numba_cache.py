"""Where numba keeps the compiled kernels of ikbench (ours-lm, ours-exact, the capsules).

The kernels are ``@njit(cache=True)``: numba writes each compiled kernel to disk and later
processes load it (about a second) instead of compiling again (minutes). numba (0.68) picks
the folder itself, in this order, per source file:

1. ``NUMBA_CACHE_DIR`` when it is set (the user's choice; ikbench never sets it);
2. ``__pycache__`` beside the ``.py`` file, when that folder can be written (a clone, an
   editable install, a virtual environment the user owns);
3. otherwise numba's per-user folder, ``$XDG_CACHE_HOME/numba`` (``~/.cache/numba`` by
   default; ``%LOCALAPPDATA%\\numba`` on Windows), under a subfolder named after the source
   folder: a wheel installed into a read-only ``site-packages`` caches there.

So a read-only install still caches, and ikbench sets nothing (setting ``NUMBA_CACHE_DIR``
would move the cache of every other numba user in the process as well). :func:`cache_dir`
says which folder ikbench's kernels use, without importing numba, for ``ikbench warmup``
and the compile announcement to print. A clone's cache lives in its own tree: each clone
(or git worktree) compiles once.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

#: The package folder whose ``__pycache__`` numba uses when it can write it.
PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: A folder holding kernels (``cache=True``), the one :func:`cache_dir` checks.
KERNEL_DIR = PACKAGE_DIR / "methods" / "ours_lm"


def writable(folder: Path) -> bool:
    """True when ``folder`` exists (or can be made) and a file can be written in it: numba's
    own test (``os.makedirs`` and a temporary file)."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def user_cache_root() -> Path:
    """numba's per-user cache folder (its ``appdirs.user_cache_dir("numba")``)."""
    if sys.platform.startswith("win"):
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "numba"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "numba"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba"


def cache_dir(source_dir: Path = KERNEL_DIR) -> tuple[Path, str]:
    """(the folder numba caches the kernels of ``source_dir`` in, why that one): the rules of
    the module docstring, in numba's order."""
    chosen = os.environ.get("NUMBA_CACHE_DIR", "")
    if chosen:
        return Path(chosen) / _subpath(source_dir), "NUMBA_CACHE_DIR"
    in_tree = source_dir / "__pycache__"
    if writable(in_tree):
        return in_tree, "beside the source, its __pycache__ being writable"
    return (user_cache_root() / _subpath(source_dir),
            "numba's per-user folder, the install being read-only")


def _subpath(source_dir: Path) -> str:
    """numba's ``get_suitable_cache_subpath``: the folder's name and a SHA1 of its path."""
    import hashlib

    folder = os.path.abspath(source_dir)
    return f"{os.path.basename(folder)}_{hashlib.sha1(folder.encode()).hexdigest()}"
