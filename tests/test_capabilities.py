"""A method's capabilities are one value (``Method.capabilities``), the same as the flags of 0.2
said for every built-in method."""

from __future__ import annotations

from dataclasses import FrozenInstanceError

import pytest

from ikbench.methods.base import Capabilities, Method
from ikbench.methods.registry import available_methods, get_method

#: The flags of 0.2 -> the field of Capabilities each became.
FLAGS = {"requires_touch_pose": "needs_touch_pose", "supports_frames": "frames",
         "avoids_obstacles": "obstacles", "batched": "batched", "warm_starts": "warm_starts"}
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
    can = {alias for alias, field in FLAGS.items() if getattr(cls.capabilities, field)}
    assert can == BEFORE[name]


def test_capabilities_are_frozen_and_the_old_flags_are_gone():
    """The 0.2 flags (``supports_frames``, ...) were deprecated in 0.3.0 and are removed in
    0.4.0: a class that still sets one gets nothing folded in."""
    cls = get_method("ours-lm")
    with pytest.raises(FrozenInstanceError):
        cls.capabilities.frames = False  # type: ignore[misc]
    assert not hasattr(Method, "supports_frames") and not hasattr(cls, "requires_touch_pose")

    class Old(Method):
        name = "old-flags"
        supports_frames = True

        def solve(self, robot, task, progress=None):  # pragma: no cover - never called
            raise NotImplementedError

    assert Old.capabilities == Capabilities()
