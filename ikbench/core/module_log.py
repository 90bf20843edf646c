"""Which of the checkout's Python files a process ran: the record that lets a committed result
go stale only when code it ran changes.

``ikbench reproduce --all`` starts each study's command with :data:`ENV` naming a log file.
Every process of the study that imports ``ikbench`` (the command itself and the processes it
starts: they inherit the environment) appends to that file, at exit, the files of the
checkout it had loaded as modules (``ikbench``, ``baselines``, the script run), one
repository-relative path per line (:func:`install`). The runner reads them back
(:func:`read`) into the study's entry of ``regenerated.json`` (``modules``), and the
provenance test stales a result only when one of them changed since it was made
(``tests/test_result_provenance.py``).

What it cannot see, and why that is safe here: a process ended by a signal or by
``os._exit`` writes nothing (a forked worker of ``multiprocessing``; its parent loaded the
modules it runs); code read but not imported (a data file, a URDF) was never in the rule.
"""

from __future__ import annotations

import atexit
import os
import sys
from pathlib import Path

#: The environment variable naming the log file (absent: nothing is recorded).
ENV = "IKBENCH_MODULES_LOG"
#: The checkout: the folder above the ``ikbench`` package.
ROOT = Path(__file__).resolve().parents[2]


def loaded_files(root: Path = ROOT) -> list[str]:
    """The ``.py`` files under ``root`` this process has loaded as modules (and the script it
    runs), repository-relative with forward slashes, sorted; nothing from outside ``root``
    (the virtual environment's packages are outside it, or skipped when inside it)."""
    files = set()
    candidates = [getattr(m, "__file__", None) for m in list(sys.modules.values())]
    candidates.append(sys.argv[0] if sys.argv and sys.argv[0].endswith(".py") else None)
    for name in candidates:
        if not name or not str(name).endswith(".py"):
            continue
        try:
            path = Path(name).resolve().relative_to(root)
        except (OSError, ValueError):
            continue
        if path.parts and not path.parts[0].startswith(".") and "site-packages" not in path.parts:
            files.add(path.as_posix())
    return sorted(files)


def _append(log: str) -> None:
    lines = "".join(f"{path}\n" for path in loaded_files())
    try:  # one write of the whole list: O_APPEND keeps concurrent processes' lists whole
        fd = os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, lines.encode())
        finally:
            os.close(fd)
    except OSError:  # a log that cannot be written loses the record, never the study
        pass


def install() -> None:
    """Append this process's :func:`loaded_files` to the file :data:`ENV` names, at exit;
    nothing when it is unset or empty."""
    log = os.environ.get(ENV)
    if log:
        atexit.register(_append, log)


def read(log: str | os.PathLike) -> list[str]:
    """The files the processes of one study appended to ``log``: their union, sorted; empty
    when the log is absent (no process of the study imported ikbench)."""
    try:
        text = Path(log).read_text()
    except OSError:
        return []
    return sorted({line.strip() for line in text.splitlines() if line.strip()})
