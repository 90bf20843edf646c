"""A method's capabilities are one value (``Method.capabilities``); the flags it replaced still
read it, deprecated, and a method that sets them the old way (a script, an entry-point plugin)
gets them folded into its capabilities."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import FrozenInstanceError

import pytest

from ikbench.methods.base import CAPABILITY_ALIASES, Capabilities, Method
from ikbench.methods.registry import available_methods, get_method
from tests.conftest import REPO

#: What each built-in method said with the flags of 0.2 (name -> the flags that were True).
BEFORE = {
    "ours": {"supports_frames"},
    "ours-lm": {"supports_frames", "avoids_obstacles", "batched", "warm_starts"},
    "ours-exact": {"supports_frames", "batched", "warm_starts"},
    "sequential-ik": {"requires_touch_pose", "supports_frames"},
    "ikpy": {"requires_touch_pose", "supports_frames"},
    "pink": {"requires_touch_pose", "supports_frames", "avoids_obstacles"},
    "mink": {"requires_touch_pose", "supports_frames", "avoids_obstacles"},
    "drake-ik": {"requires_touch_pose", "supports_frames", "avoids_obstacles"},
    "drake-trajopt": {"requires_touch_pose", "supports_frames", "avoids_obstacles"},
    "pyroki": {"requires_touch_pose"},
}


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_the_built_in_methods_can_what_their_flags_said(name):
    if name not in available_methods():
        pytest.skip(f"{name} is not installed here")
    cls = get_method(name)
    can = {alias for alias, field in CAPABILITY_ALIASES.items()
           if getattr(cls.capabilities, field)}
    assert can == BEFORE[name]


def test_an_old_flag_reads_the_capability_with_a_deprecation_warning():
    cls = get_method("ours-lm")
    with pytest.warns(DeprecationWarning, match="read Method.capabilities.frames"):
        assert cls.supports_frames is True
    with pytest.warns(DeprecationWarning, match="capabilities.needs_touch_pose"):
        assert cls().requires_touch_pose is False
    with pytest.raises(AttributeError, match="read-only"):
        cls().batched = False
    with pytest.raises(FrozenInstanceError):
        cls.capabilities.frames = False  # type: ignore[misc]


def test_a_method_that_sets_the_old_flags_gets_them_folded_in():
    with pytest.warns(DeprecationWarning, match=r"sets supports_frames, batched, deprecated; "
                      r"set capabilities = Capabilities\(frames=True, batched=True\)"):
        class Old(Method):
            name = "old-flags"
            supports_frames = True
            batched = True

            def solve(self, robot, task, progress=None):  # pragma: no cover - never called
                raise NotImplementedError

    assert Old.capabilities == Capabilities(frames=True, batched=True)
    assert not Method.capabilities.frames  # the base class is untouched

    with pytest.warns(DeprecationWarning, match="sets warm_starts"):
        class Older(Old):
            warm_starts = True

    assert Older.capabilities == Capabilities(frames=True, batched=True, warm_starts=True)


def test_an_entry_point_plugin_with_the_old_flags_still_works(tmp_path):
    (tmp_path / "plugin_old.py").write_text(
        "from ikbench.methods.ours_lm import OursLM\n\n"
        "class OldFlags(OursLM):\n"
        "    name = 'old-flags'\n"
        "    description = 'ours-lm, flags set the 0.2 way'\n"
        "    supports_frames = False\n"
        "    requires_touch_pose = True\n")
    info = tmp_path / "old_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: old-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[ikbench.methods]\nold-flags = plugin_old:OldFlags\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    listing = subprocess.run([sys.executable, "-m", "ikbench.cli", "methods", "--json"],
                             capture_output=True, text=True, env=env, cwd=tmp_path)
    assert listing.returncode == 0, listing.stderr
    rows = {row["method"]: row for row in json.loads(listing.stdout)["methods"]}
    assert rows["old-flags"]["available"] and not rows["old-flags"]["goal_frames"]
    assert rows["ours-lm"]["goal_frames"]
    letters = subprocess.run([sys.executable, "-m", "ikbench.cli", "letters", "P", "--method",
                              "old-flags", "--output", "out"], capture_output=True, text=True,
                             env=env, cwd=tmp_path)
    assert letters.returncode == 2 and "old-flags" in letters.stderr.splitlines()[-1]
