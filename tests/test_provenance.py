"""Provenance: the git revision names the code, and regenerated results do not dirty it."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from ikbench.core import provenance


@pytest.fixture()
def repo(tmp_path, monkeypatch):
    if shutil.which("git") is None:
        pytest.skip("git not installed")

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "code.py").write_text("x = 1\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "table.csv").write_text("a\n1\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "init")
    monkeypatch.setattr(provenance, "REPO", tmp_path)
    return tmp_path


def test_clean_checkout_and_regenerated_results_are_not_dirty(repo):
    rev = provenance.git_revision()
    assert rev and len(rev) == 12 and not rev.endswith("-dirty")
    (repo / "results" / "table.csv").write_text("a\n2\n")  # results regenerated
    (repo / "results" / "table.csv.new").write_text("")    # untracked files do not count
    assert provenance.git_revision() == rev


def test_modified_code_is_dirty(repo):
    (repo / "code.py").write_text("x = 2\n")
    assert provenance.git_revision().endswith("-dirty")
