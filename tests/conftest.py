"""Shared fixtures. Tests are seeded and run in float64 where they check numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikbench import load_robot, load_targets

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
REFERENCE = SHARED / "reference"

PAPER_START = [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67]


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture(scope="session")
def paper_targets():
    return load_targets()
