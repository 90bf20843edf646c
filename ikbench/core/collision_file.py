"""A robot's collision file (``urdf/*.collision.json``, named by its config's ``collision``):
its capsules in link frames, the link pairs never checked, its named obstacle sets.

Read once per robot (cached on it) and checked with one-line errors. The checker
(:mod:`ikbench.core.collision`) builds its geometry from the capsules; the obstacles module
(:mod:`ikbench.core.obstacles`) takes a robot's named obstacle sets from here.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.errors import InputError, refuse_unknown_keys

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: Keys a robot's collision file may hold.
CONFIG_KEYS = ("description", "source", "licence", "capsules", "never_collide",
               "obstacle_sets")
CAPSULE_KEYS = ("link", "a_mm", "b_mm", "radius_mm")


@dataclass(frozen=True, eq=False)
class Capsule:
    """A robot capsule in its link's frame: the points within ``radius_mm`` of the segment
    ``a_mm`` - ``b_mm`` (3,) [mm]."""

    link: str
    a_mm: np.ndarray
    b_mm: np.ndarray
    radius_mm: float


def collision_config(robot: Robot) -> dict | None:
    """The robot's collision file as a dict (with ``path``), or None when it names none."""
    name = robot.config.collision
    if not name:
        return None
    key = "collision_config"
    if key not in robot._cache:
        base = robot.config.folder or robot.urdf_path.parent
        path = (base / name).resolve()
        robot._cache[key] = _read_collision_file(path)
    return robot._cache[key]


def _read_collision_file(path: Path) -> dict:
    where = f"collision file {str(path)!r}"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {where}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: not valid JSON (line {exc.lineno}): {exc.msg}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{where}: must be a JSON object with keys {', '.join(CONFIG_KEYS)}")
    refuse_unknown_keys(doc, CONFIG_KEYS, where)
    capsules = []
    for k, item in enumerate(doc.get("capsules", [])):
        if not isinstance(item, dict) or sorted(item) != sorted(CAPSULE_KEYS):
            raise InputError(f"{where}: capsule {k} must have exactly the keys "
                             f"{', '.join(CAPSULE_KEYS)}")
        a, b = np.array(item["a_mm"], dtype=float), np.array(item["b_mm"], dtype=float)
        radius = float(item["radius_mm"])
        if a.shape != (3,) or b.shape != (3,) or not (radius > 0 and math.isfinite(radius)):
            raise InputError(f"{where}: capsule {k} ({item['link']}): a_mm and b_mm must be "
                             "three numbers and radius_mm positive")
        capsules.append(Capsule(str(item["link"]), a, b, radius))
    pairs = doc.get("never_collide", [])
    if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
        raise InputError(f"{where}: never_collide must be a list of [link, link] pairs")
    return {**doc, "path": str(path), "capsules": capsules,
            "never_collide": [tuple(p) for p in pairs]}
