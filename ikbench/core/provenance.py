"""Versions, machine and git revision, recorded next to every result."""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import subprocess
import sys
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

#: Distributions whose versions are recorded (scipy: ours-lm's banded Cholesky, LAPACK pbsv).
PACKAGES = ("ikbench", "torch", "pytorch-kinematics", "pin", "numpy", "scipy", "pandas",
            "matplotlib", "yourdfpy", "numba", "llvmlite", "dynamixel-sdk")
REPO = Path(__file__).resolve().parents[2]


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def cpu_model() -> str:
    """The CPU's model name (Linux /proc/cpuinfo), else platform.processor()."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=10).stdout.strip()


def git_state() -> tuple[str, bool] | None:
    """(the checkout's full commit hash, whether the code is unmodified), or None outside a
    git checkout (an installed wheel).

    Changes under ``results*/`` do not count: regenerating the committed results changes only
    them, and the code that produced them is still the commit named. Untracked files do not
    count either (a new file changes nothing until something imports it, and the tests that
    would are tracked).
    """
    if not (REPO / ".git").exists():  # an installed wheel, not a checkout
        return None
    try:
        commit = _git("rev-parse", "HEAD")
        changed = _git("status", "--porcelain", "--untracked-files=no", "--", ".",
                       ":(exclude,glob)results*/**")
    except (OSError, subprocess.SubprocessError):
        return None
    if not commit:
        return None
    return commit, not changed


def git_revision() -> str | None:
    """The checkout's commit (12 hex digits), with ``-dirty`` if code is modified; None
    outside git (see :func:`git_state`)."""
    state = git_state()
    if state is None:
        return None
    return state[0][:12] + ("" if state[1] else "-dirty")


def load_average() -> list[float] | None:
    """The machine's 1, 5 and 15 min load averages (other jobs slow every timing), or None
    where the platform has none."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def command_line() -> str:
    """The command that is running, as a reader would type it (``ikbench compare ...``)."""
    program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    if program in ("ikbench", "__main__.py"):  # the console script or python -m ikbench.cli
        return shlex.join(["ikbench", *sys.argv[1:]])
    script = Path(sys.argv[0]) if sys.argv and sys.argv[0] else None
    repo = Path(__file__).resolve().parents[2]
    if script is not None and script.is_absolute() and script.resolve().is_relative_to(repo):
        # a script of the checkout (reproduce --all runs them by absolute path): as typed
        # from its root, so that no record names the folder the clone happens to be in
        return shlex.join(["python", str(script.resolve().relative_to(repo)), *sys.argv[1:]])
    return shlex.join(["python", *sys.argv])


def library_versions(names: Iterable[str]) -> dict[str, str | None]:
    """PyPI distribution -> installed version (None when not installed)."""
    return {name: _version(name) for name in names}


#: The keys :func:`provenance` writes, in order.
KEYS = ("created_utc", "python", "platform", "cpu", "cpu_count", "torch_threads", "git_revision",
        "git_commit", "git_clean", "load_average", "command_line", "packages")


def provenance(extra: Iterable[str] = ()) -> dict[str, Any]:
    """A JSON-able record of what produced a result.

    Args:
        extra: further PyPI distributions whose versions to record (a method's library).
    """
    import torch

    state = git_state()
    return {
        "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "git_revision": (state[0][:12] + ("" if state[1] else "-dirty")) if state else None,
        "git_commit": state[0] if state else None,
        "git_clean": state[1] if state else None,
        "load_average": load_average(),
        "command_line": command_line(),
        "packages": library_versions(dict.fromkeys([*PACKAGES, *extra])),
    }
