"""Atomic writing: complete or absent, usual permissions, one-line errors for bad paths."""

from __future__ import annotations

import os
import stat

import pandas as pd
import pytest

from ikbench.core.errors import OutputError
from ikbench.core.io import atomic_path, atomic_write_csv, atomic_write_text, check_writable


def test_write_is_complete_and_leaves_no_temporary(tmp_path):
    path = atomic_write_csv(tmp_path / "sub" / "t.csv", pd.DataFrame({"a_mm": [1.5, 2.5]}))
    assert pd.read_csv(path)["a_mm"].tolist() == [1.5, 2.5]
    assert sorted(p.name for p in path.parent.iterdir()) == ["t.csv"]


def test_failed_write_leaves_the_old_file(tmp_path):
    path = atomic_write_text(tmp_path / "r.md", "old")
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("solver failed mid-write")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.md"]


def test_files_get_the_usual_permissions_not_mkstemps_0600(tmp_path):
    mask = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "r.md", "x")
    finally:
        os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def test_unwritable_paths_raise_one_line_output_errors(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match=r"cannot write .*file/x\.csv: .*file is a file, not a"):
        atomic_write_text(blocker / "x.csv", "x")
    with pytest.raises(OutputError, match="it is a directory"):
        check_writable(tmp_path)


def test_check_writable_leaves_nothing_behind(tmp_path):
    path = tmp_path / "new" / "deeper" / "x.csv"
    assert check_writable(path) == path
    assert list(tmp_path.iterdir()) == []  # the folders made for the probe are gone again
    (tmp_path / "kept").mkdir()
    check_writable(tmp_path / "kept" / "x.csv")
    assert [p.name for p in tmp_path.iterdir()] == ["kept"]  # existing folders stay
    assert list((tmp_path / "kept").iterdir()) == []
    atomic_write_text(path, "x")  # the real write creates the folders
    assert path.read_text() == "x"


def test_failed_check_removes_the_folders_it_created(tmp_path, monkeypatch):
    import tempfile

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(OutputError, match=r"cannot write .*x\.csv: Permission denied"):
        check_writable(tmp_path / "a" / "b" / "x.csv")
    assert list(tmp_path.iterdir()) == []


def test_check_below_a_file_creates_nothing(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match="is a file, not a directory"):
        check_writable(blocker / "sub" / "x.csv")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
