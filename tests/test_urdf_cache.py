"""Parsed URDFs kept on disk (issue 63: a new process's first answer waited for yourdfpy and
trimesh to import): the same model comes back without yourdfpy, ``to_xml`` gives the same
texts, a changed file is parsed again, and the cache can be turned off."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from ikbench.core import urdf_model
from ikbench.core.urdf_model import CACHE_SWITCH, load_urdf_model
from tests.conftest import REPO

URDF = REPO / "urdf" / "nico_right_arm.urdf"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A disk cache of its own, and an empty in-memory one."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(CACHE_SWITCH, raising=False)
    monkeypatch.setattr(urdf_model, "_MODELS", type(urdf_model._MODELS)())
    return tmp_path / "cache" / "ikbench" / "urdf"


def _copy(tmp_path):
    path = tmp_path / "arm.urdf"
    shutil.copy(URDF, path)
    return path


def test_a_model_read_back_without_yourdfpy_is_the_same(cache, tmp_path, monkeypatch):
    path = _copy(tmp_path)
    parsed = load_urdf_model(path)
    written = parsed.to_xml(fixed={"r_indexfinger_x": 0.25}, unit_axes=True)
    assert len(list(cache.glob("*.pickle"))) == 1
    urdf_model._MODELS.clear()
    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # importing it now fails
    read = load_urdf_model(path)
    assert read is not parsed
    assert (read.name, read.links, read.root_link) == (parsed.name, parsed.links,
                                                       parsed.root_link)
    for a, b in zip(read.joints, parsed.joints, strict=True):
        assert (a.name, a.type, a.parent, a.child, a.mimic) == (b.name, b.type, b.parent,
                                                                 b.child, b.mimic)
        np.testing.assert_array_equal(a.origin, b.origin)
        assert (a.lower, a.upper) == (b.lower, b.upper)
    assert read.to_xml(fixed={"r_indexfinger_x": 0.25}, unit_axes=True) == written
    with pytest.raises(ImportError):  # a text not written before needs yourdfpy's tree
        read.to_xml(visuals=True)
    monkeypatch.delitem(sys.modules, "yourdfpy")
    assert read.to_xml(visuals=True) == parsed.to_xml(visuals=True)


def test_a_changed_file_is_parsed_again(cache, tmp_path):
    path = _copy(tmp_path)
    before = load_urdf_model(path)
    path.write_text(URDF.read_text().replace('name="nico_right_arm"', 'name="renamed"', 1))
    urdf_model._MODELS.clear()
    after = load_urdf_model(path)
    assert before.name != "renamed" and after.name == "renamed"
    assert len(list(cache.glob("*.pickle"))) == 2


def test_a_broken_cache_file_is_parsed_again(cache, tmp_path):
    path = _copy(tmp_path)
    load_urdf_model(path)
    (stored,) = cache.glob("*.pickle")
    stored.write_bytes(b"not a pickle")
    urdf_model._MODELS.clear()
    assert load_urdf_model(path).name == load_urdf_model(URDF).name
    assert stored.read_bytes() != b"not a pickle"  # written anew


def test_the_cache_can_be_turned_off(cache, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_SWITCH, "0")
    load_urdf_model(_copy(tmp_path))
    assert not cache.exists()


def test_it_keeps_at_most_its_number_of_files(cache, tmp_path, monkeypatch):
    monkeypatch.setattr(urdf_model, "CACHE_FILES", 2)
    for k in range(4):
        folder = tmp_path / f"arm{k}"
        folder.mkdir()
        load_urdf_model(_copy(folder))
    assert len(list(cache.glob("*.pickle"))) == 2


def test_a_new_process_reads_a_cached_robot_without_yourdfpy_or_trimesh(tmp_path):
    """The first answer of a new process (issue 63): with the cache warm, neither library is
    imported to load a robot and solve a pose with ours-lm."""
    code = ("import sys, numpy as np, ikbench\n"
            "robot = ikbench.load_robot('nico_right_arm')\n"
            "T = np.eye(4); T[:3, 3] = robot.fk(robot.sample_lower * 0.5 + robot.sample_upper"
            " * 0.5).point_mm[0] / 1000\n"
            "ikbench.solve_pose(robot, T, robot.sample_lower * 0.5 + robot.sample_upper * 0.5,"
            " kind='position')\n"
            "print(sorted(m for m in ('yourdfpy', 'trimesh') if m in sys.modules))\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "PYTHONPATH": str(REPO)}
    env.pop(CACHE_SWITCH, None)
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=env, cwd=tmp_path, timeout=600) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[-1].stderr[-2000:]
    assert runs[0].stdout.strip().endswith("['trimesh', 'yourdfpy']")  # the cold cache
    assert runs[1].stdout.strip().endswith("[]"), runs[1].stdout
