"""Atomic file writing: a result file is either complete or absent, never half-written."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ikbench.core.errors import InputError, OutputError

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_writable(path: str | os.PathLike) -> Path:
    """Fail early, before any long work, if ``path`` cannot be written; return it as a Path.

    Probes the folder with a temporary file, as :func:`atomic_path` would write it, and
    removes it again. Missing parent folders are created for the probe and removed again
    (deepest first, each only if still empty), so a check, failed or not, leaves nothing
    behind; the later write creates them.

    Raises:
        OutputError: the path is a directory or its folder cannot be created or written.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"cannot write {path}: it is a directory")
    created = []  # deepest first: the missing folders the probe will create
    for folder in path.parents:
        if folder.exists() or folder.is_symlink():
            break
        created.append(folder)
    try:
        with atomic_path(path) as tmp:
            tmp.unlink()  # nothing to move: only the folder was probed
    finally:
        for folder in created:
            try:
                folder.rmdir()
            except OSError:  # not created (the probe failed first) or no longer empty
                pass
    return path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it onto ``path`` only on success.

    The file gets the usual permissions (0666 less the umask), not mkstemp's 0600.

    Args:
        path: final destination. Its parent directory is created if missing.

    Raises:
        OutputError: the folder cannot be created or written, or the move fails.
    """
    path = Path(path)
    blocker = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        raise OutputError(f"cannot write {path}: {blocker} is a file, not a directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():
            os.chmod(tmp_path, 0o666 & ~_umask())
            try:
                os.replace(tmp_path, path)
            except OSError as exc:
                raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def atomic_write_csv(path: str | os.PathLike, frame: pd.DataFrame,
                     float_format: str | None = None) -> Path:
    """Write a pandas DataFrame as CSV (no index) atomically; return the path."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, float_format=float_format)
    return Path(path)


def atomic_savefig(path: str | os.PathLike, fig: Figure, dpi: int = 120) -> Path:
    """Save a matplotlib figure as PNG atomically and close it; return the path."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png", bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def read_json(path: str | os.PathLike, what: str) -> Any:
    """The JSON value of a file; one-line :class:`InputError` naming ``what`` (``"head
    file"``) and the path when it is missing or not readable JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{what} {str(path)!r} not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{what} {str(path)!r} is not readable JSON: {exc}") from None


def atomic_write_json(path: str | os.PathLike, value: Any) -> Path:
    """Write ``value`` as JSON (indented by 2, a final newline) atomically; return the path."""
    return atomic_write_text(path, json.dumps(value, indent=2) + "\n")


def write_study_files(output: str | os.PathLike, stem: str,
                      tables: Mapping[str, tuple[pd.DataFrame, str]], record: Any,
                      markdown: Callable[[], str],
                      figures: Mapping[str, Callable[[], Figure]] | None = None) -> Path:
    """A study's files in ``output``, each atomically, in this order: the ``tables``
    (``{file name: (frame, float format)}``) as CSVs, ``record`` as ``<stem>.json``, the
    ``figures`` (``{file name: function drawing it}``) as PNGs and ``markdown()`` as
    ``<stem>.md``. Returns the first table's path."""
    out = Path(output)
    for name, (frame, float_format) in tables.items():
        atomic_write_csv(out / name, frame, float_format=float_format)
    atomic_write_json(out / f"{stem}.json", record)
    for name, draw in (figures or {}).items():
        atomic_savefig(out / name, draw())
    atomic_write_text(out / f"{stem}.md", markdown())
    return out / next(iter(tables))


def check_folder_writable(path: str | os.PathLike) -> Path:
    """Fail early if the folder ``path`` cannot be (re)placed: it is a file, or its parent
    cannot hold a new folder. Leaves nothing behind (missing parents are removed again)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"cannot write {path}: it is a file, not a directory")
    return check_writable(path.parent / f".{path.name}.probe")


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike,
                  keep: Callable[[Path], bool] | None = None) -> Iterator[Path]:
    """Write a folder whole or not at all.

    Yields an empty temporary folder beside ``path``. When the block succeeds, the files of
    an existing ``path`` for which ``keep(relative_path)`` is true and that the new content
    does not hold are copied in (files the folder's earlier writer did not make, e.g. a
    user's notes), then the new folder takes the place of the old one. When the block
    raises (Ctrl-C included), the temporary folder is removed and ``path`` is untouched.

    Args:
        path: the folder to (re)place.
        keep: ``keep(relative_path: Path) -> bool`` for files of the old folder to carry over
            (default: none).
    """
    import shutil

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"cannot write {path}: it is a file, not a directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.tmp-", dir=path.parent))
        os.chmod(tmp, 0o777 & ~_umask())
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        yield tmp
        if path.is_dir() and keep is not None:
            for old in sorted(p for p in path.rglob("*") if p.is_file()):
                rel = old.relative_to(path)
                if keep(rel) and not (tmp / rel).exists():
                    (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(old, tmp / rel)
        retired = None
        try:
            if path.exists():
                retired = Path(tempfile.mkdtemp(prefix=f".{path.name}.old-", dir=path.parent))
                os.replace(path, retired / path.name)
            os.replace(tmp, path)
        except OSError as exc:
            if retired is not None and not path.exists():  # put the old folder back
                os.replace(retired / path.name, path)
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
        if retired is not None:
            shutil.rmtree(retired, ignore_errors=True)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
