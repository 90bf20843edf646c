"""Versions, machine and git revision, recorded next to every result."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

#: Distributions whose versions are recorded (scipy: ours-lm's banded Cholesky, LAPACK pbsv).
PACKAGES = ("ikbench", "torch", "pytorch-kinematics", "pin", "numpy", "scipy", "pandas",
            "matplotlib", "yourdfpy", "dynamixel-sdk")
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


def git_revision() -> str | None:
    """The checkout's commit, with ``-dirty`` if code is modified; None outside git.

    Changes under ``results*/`` do not count: regenerating the committed results changes only
    them, and the code that produced them is still the commit named.
    """
    def git(*args):
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              timeout=10).stdout.strip()

    if not (REPO / ".git").exists():  # an installed wheel, not a checkout
        return None
    try:
        rev = git("rev-parse", "--short=12", "HEAD")
        changed = git("status", "--porcelain", "--untracked-files=no", "--", ".",
                      ":(exclude,glob)results*/**")
    except (OSError, subprocess.SubprocessError):
        return None
    if not rev:
        return None
    return rev + ("-dirty" if changed else "")


def library_versions(names: Iterable[str]) -> dict[str, str | None]:
    """PyPI distribution -> installed version (None when not installed)."""
    return {name: _version(name) for name in names}


def provenance(extra: Iterable[str] = ()) -> dict[str, Any]:
    """A JSON-able record of what produced a result.

    Args:
        extra: further PyPI distributions whose versions to record (a method's library).
    """
    import torch

    return {
        "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "git_revision": git_revision(),
        "packages": library_versions(dict.fromkeys([*PACKAGES, *extra])),
    }
