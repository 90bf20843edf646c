"""Shared fixtures. Tests are seeded and run in float64 where they check numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikbench import load_robot, load_targets

REPO = Path(__file__).resolve().parents[1]

PAPER_START = [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67]


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture(scope="session")
def paper_targets():
    return load_targets()


def blocked_output(tmp_path: Path, blocked_by: str, name: str) -> tuple[Path, str]:
    """An output path that cannot be written, and the reason the error must name.

    ``blocked_by="file"``: ``name`` under a regular file; ``"directory"``: a directory itself.
    """
    blocker = tmp_path / "blocker"
    if blocked_by == "file":
        blocker.write_text("not a folder")
        return blocker / name, f"{blocker} is a file, not a directory"
    blocker.mkdir()
    return blocker, "it is a directory"


def register_temporarily(monkeypatch, cls) -> None:
    """Make the method class ``cls`` available by its name for one test."""
    from ikbench.methods.registry import MethodStatus, method_status

    monkeypatch.setitem(method_status(), cls.name, MethodStatus(cls.name, cls))
