"""Obstacles: boxes, spheres, capsules and half-spaces in the robot's base frame [mm].

A task may carry obstacles (``Task.obstacles``); :mod:`ikbench.core.collision` checks a
trajectory against them and against the robot itself. Obstacles come from

- a CppFlow problem file (``obstacles`` boxes in metres with roll/pitch/yaw [rad], shifted by
  ``obstacle_xyz_offset``; :func:`cppflow_obstacles`), or
- an obstacle file (JSON or YAML, :func:`read_obstacles`; ``--obstacles FILE``) or a named
  set of the robot's collision config (``--obstacles touchscreen`` for NICO). Its format, in
  mm and degrees::

      {"obstacles": [
        {"type": "box", "name": "table", "center_mm": [x, y, z], "size_mm": [sx, sy, sz],
         "rpy_deg": [roll, pitch, yaw]},
        {"type": "sphere", "center_mm": [x, y, z], "radius_mm": r},
        {"type": "capsule", "a_mm": [x, y, z], "b_mm": [x, y, z], "radius_mm": r},
        {"type": "halfspace", "point_mm": [x, y, z], "normal": [nx, ny, nz]}
      ]}

  ``rpy_deg`` (optional, default 0) rotates a box about the base frame's x, then y, then z
  (R = Rz(yaw) Ry(pitch) Rx(roll), as URDF's rpy). A half-space is solid on the side opposite
  its normal: the normal points into free space. ``name`` is optional (default
  ``<type><index>``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.collision_file import collision_config
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

KINDS = ("box", "sphere", "capsule", "halfspace")
#: Keys each kind of obstacle item may hold (besides ``type`` and ``name``).
ITEM_KEYS = {"box": ("center_mm", "size_mm", "rpy_deg"), "sphere": ("center_mm", "radius_mm"),
             "capsule": ("a_mm", "b_mm", "radius_mm"), "halfspace": ("point_mm", "normal")}
#: Keys of a CppFlow obstacle (a box).
CPPFLOW_KEYS = ("x", "y", "z", "roll", "pitch", "yaw", "size_x", "size_y", "size_z")
MM_PER_M = 1000.0


@dataclass(frozen=True, eq=False)
class Obstacle:
    """One obstacle in the robot's base frame.

    Attributes:
        kind: ``box``, ``sphere``, ``capsule`` or ``halfspace``.
        name: a name for reports (``box0``, ``touchscreen``).
        center_mm: (3,) the centre (box, sphere, capsule); a point on a half-space's surface.
        rotation: (3, 3) orientation (a box's edges, a capsule's axis = its local z).
        size_mm: (3,) a box's full edge lengths along its local x, y, z; None otherwise.
        radius_mm: a sphere's or capsule's radius (0 otherwise).
        length_mm: a capsule's distance between its end-sphere centres (0 otherwise).
        normal: (3,) a half-space's unit normal, pointing out of the solid; None otherwise.
    """

    kind: str
    name: str
    center_mm: np.ndarray
    rotation: np.ndarray
    size_mm: np.ndarray | None = None
    radius_mm: float = 0.0
    length_mm: float = 0.0
    normal: np.ndarray | None = None

    def transform(self) -> np.ndarray:
        """(4, 4) base <- obstacle [mm] (a half-space's local z is its normal)."""
        T = np.eye(4)
        T[:3, :3] = self.rotation
        T[:3, 3] = self.center_mm
        return T

    def to_dict(self) -> dict[str, Any]:
        """The obstacle in the file format of the module docstring (mm, degrees)."""
        out: dict[str, Any] = {"type": self.kind, "name": self.name}
        if self.kind == "box":
            assert self.size_mm is not None
            out |= {"center_mm": _list(self.center_mm), "size_mm": _list(self.size_mm),
                    "rpy_deg": _list(np.degrees(matrix_to_rpy(self.rotation)))}
        elif self.kind == "sphere":
            out |= {"center_mm": _list(self.center_mm), "radius_mm": self.radius_mm}
        elif self.kind == "capsule":
            half = 0.5 * self.length_mm * self.rotation[:, 2]
            out |= {"a_mm": _list(self.center_mm - half), "b_mm": _list(self.center_mm + half),
                    "radius_mm": self.radius_mm}
        else:
            assert self.normal is not None
            out |= {"point_mm": _list(self.center_mm), "normal": _list(self.normal)}
        return out

    def describe(self) -> str:
        """One line: kind, name, centre and size [mm]."""
        where = ", ".join(f"{v:.0f}" for v in self.center_mm)
        if self.kind == "box":
            assert self.size_mm is not None
            size = " x ".join(f"{v:.0f}" for v in self.size_mm)
            return f"box {self.name}: {size} mm at ({where}) mm"
        if self.kind == "halfspace":
            assert self.normal is not None
            normal = ", ".join(f"{v:.3f}" for v in self.normal)
            return f"half-space {self.name}: surface through ({where}) mm, normal ({normal})"
        extra = f", length {self.length_mm:.0f} mm" if self.kind == "capsule" else ""
        return f"{self.kind} {self.name}: radius {self.radius_mm:.0f} mm{extra} at ({where}) mm"


def _list(values) -> list[float]:
    return [round(float(v), 9) for v in values]


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) [rad] (URDF's and CppFlow's convention)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                              math.sin(pitch), math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) [rad] of a rotation matrix (inverse of :func:`rpy_to_matrix`)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    if abs(math.cos(pitch)) < 1e-9:  # gimbal lock: put it all in yaw
        return np.array([0.0, pitch, math.atan2(-float(R[0, 1]), float(R[1, 1]))])
    return np.array([math.atan2(float(R[2, 1]), float(R[2, 2])), pitch,
                     math.atan2(float(R[1, 0]), float(R[0, 0]))])


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _vector3(item: dict, key: str, where: str) -> np.ndarray:
    value = item.get(key)
    if not (isinstance(value, (list, tuple)) and len(value) == 3 and all(map(_finite, value))):
        raise InputError(f"{where}: {key} = {value!r} must be three finite numbers")
    return np.array(value, dtype=float)


def _positive(item: dict, key: str, where: str) -> float:
    value = item.get(key)
    if not (_finite(value) and float(value) > 0):  # type: ignore[arg-type]  # _finite: a number
        raise InputError(f"{where}: {key} = {value!r} must be a positive number [mm]")
    return float(value)  # type: ignore[arg-type]


def box(name: str, center_mm: npt.ArrayLike, size_mm: npt.ArrayLike,
        rotation: npt.ArrayLike | None = None) -> Obstacle:
    """A box of full edge lengths ``size_mm`` (3,) centred at ``center_mm`` (3,)."""
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    return Obstacle("box", name, np.asarray(center_mm, dtype=float), R,
                    size_mm=np.asarray(size_mm, dtype=float))


def sphere(name: str, center_mm: npt.ArrayLike, radius_mm: float) -> Obstacle:
    """A sphere of ``radius_mm`` at ``center_mm``."""
    return Obstacle("sphere", name, np.asarray(center_mm, dtype=float), np.eye(3),
                    radius_mm=float(radius_mm))


def capsule(name: str, a_mm: npt.ArrayLike, b_mm: npt.ArrayLike, radius_mm: float) -> Obstacle:
    """A capsule: the points within ``radius_mm`` of the segment from ``a_mm`` to ``b_mm``."""
    a, b = np.asarray(a_mm, dtype=float), np.asarray(b_mm, dtype=float)
    return Obstacle("capsule", name, 0.5 * (a + b), frame_with_z(b - a),
                    radius_mm=float(radius_mm), length_mm=float(np.linalg.norm(b - a)))


def halfspace(name: str, point_mm: npt.ArrayLike, normal: npt.ArrayLike) -> Obstacle:
    """The half-space behind the plane through ``point_mm`` with (outward) ``normal``."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    return Obstacle("halfspace", name, np.asarray(point_mm, dtype=float), frame_with_z(n),
                    normal=n)


def frame_with_z(axis: npt.ArrayLike) -> np.ndarray:
    """A rotation whose z column is ``axis`` normalised (identity for a zero axis)."""
    z = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(z)
    if norm < 1e-12:
        return np.eye(3)
    z = z / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def parse_obstacle(item: object, index: int, where: str) -> Obstacle:
    """One item of an obstacle file (see the module docstring)."""
    here = f"{where}: obstacle {index}"
    if not isinstance(item, dict):
        raise InputError(f"{here}: {item!r} must be a mapping with a type "
                         f"({', '.join(KINDS)})")
    kind = item.get("type")
    if kind not in KINDS:
        raise InputError(f"{here}: type = {kind!r} is not one of {', '.join(KINDS)}")
    unknown = [k for k in item if k not in ("type", "name", *ITEM_KEYS[kind])]
    if unknown:
        raise InputError(f"{here}: unknown key(s) {', '.join(map(repr, unknown))} for a "
                         f"{kind}; allowed: type, name, {', '.join(ITEM_KEYS[kind])}")
    name = str(item.get("name") or f"{kind}{index}")
    if kind == "box":
        size = _vector3(item, "size_mm", here)
        if np.any(size <= 0):
            raise InputError(f"{here}: size_mm = {size.tolist()} must be positive [mm]")
        rpy = _vector3(item, "rpy_deg", here) if "rpy_deg" in item else np.zeros(3)
        return box(name, _vector3(item, "center_mm", here), size,
                   rpy_to_matrix(*np.radians(rpy)))
    if kind == "sphere":
        return sphere(name, _vector3(item, "center_mm", here), _positive(item, "radius_mm", here))
    if kind == "capsule":
        return capsule(name, _vector3(item, "a_mm", here), _vector3(item, "b_mm", here),
                       _positive(item, "radius_mm", here))
    normal = _vector3(item, "normal", here)
    if np.linalg.norm(normal) < 1e-9:
        raise InputError(f"{here}: normal = {list(normal)} must not be zero")
    return halfspace(name, _vector3(item, "point_mm", here), normal)


def parse_obstacles(items: object, where: str) -> tuple[Obstacle, ...]:
    """Obstacles from a file's content: ``{"obstacles": [...]}`` or a bare list."""
    if isinstance(items, dict):
        extra = [k for k in items if k not in ("obstacles", "description")]
        if extra or "obstacles" not in items:
            raise InputError(f"{where}: expected a list of obstacles or a mapping with an "
                             f"'obstacles' list (and an optional 'description'), got keys "
                             f"{', '.join(map(repr, items)) or 'none'}")
        items = items["obstacles"]
    if not isinstance(items, list):
        raise InputError(f"{where}: obstacles must be a list, got {type(items).__name__}")
    obstacles = tuple(parse_obstacle(item, k, where) for k, item in enumerate(items))
    names = [o.name for o in obstacles]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"{where}: obstacle name(s) {', '.join(twice)} used twice")
    return obstacles


def cppflow_obstacles(items: object, xyz_offset_m: npt.ArrayLike | None,
                      where: str) -> tuple[Obstacle, ...]:
    """CppFlow's boxes (metres, roll/pitch/yaw [rad]; each a mapping or, as its YAML files
    write them, a list of one-key mappings), shifted by ``obstacle_xyz_offset`` [m]."""
    if items is None:
        return ()
    if not isinstance(items, list):
        raise InputError(f"{where}: obstacles must be a list of boxes, got {items!r}")
    offset = np.zeros(3) if xyz_offset_m is None else np.asarray(xyz_offset_m, dtype=float)
    out = []
    for k, item in enumerate(items):
        here = f"{where}: obstacle {k}"
        parsed = _merge_one_key_maps(item, here)
        missing = [key for key in CPPFLOW_KEYS if key not in parsed]
        unknown = [key for key in parsed if key not in CPPFLOW_KEYS]
        if missing or unknown:
            raise InputError(f"{here}: " + (f"missing {', '.join(missing)}" if missing else
                             f"unknown key(s) {', '.join(unknown)}")
                             + f"; a CppFlow obstacle has {', '.join(CPPFLOW_KEYS)}")
        bad = [key for key in CPPFLOW_KEYS if not _finite(parsed[key])]
        if bad:
            raise InputError(f"{here}: {bad[0]} = {parsed[bad[0]]!r} must be a finite number")
        size = np.array([parsed["size_x"], parsed["size_y"], parsed["size_z"]], dtype=float)
        if np.any(size <= 0):
            raise InputError(f"{here}: size_x, size_y, size_z = {size.tolist()} must be positive")
        center = np.array([parsed["x"], parsed["y"], parsed["z"]], dtype=float) + offset
        R = rpy_to_matrix(parsed["roll"], parsed["pitch"], parsed["yaw"])
        out.append(box(f"box{k}", center * MM_PER_M, size * MM_PER_M, R))
    return tuple(out)


def _merge_one_key_maps(item, where: str) -> dict:
    if isinstance(item, dict):
        return dict(item)
    if isinstance(item, list) and all(isinstance(d, dict) for d in item):
        merged: dict = {}
        for d in item:
            merged.update(d)
        return merged
    raise InputError(f"{where}: {item!r} is not a CppFlow obstacle (x, y, z, roll, pitch, yaw, "
                     "size_x, size_y, size_z)")


def load_file(path: Path) -> Any:
    """The parsed content of a JSON or YAML file; InputError naming it when unreadable."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read obstacle file {str(path)!r}: {exc}") from None
    if path.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"{path}: not valid JSON (line {exc.lineno}): {exc.msg}") from None
    import yaml

    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None


def read_obstacles(spec: str | Path | Sequence[Obstacle] | None,
                   robot: Robot | None = None) -> tuple[Obstacle, ...]:
    """Obstacles from ``spec``: a file (``*.json``, ``*.yaml``, ``*.yml``), a named set of
    ``robot``'s collision config (e.g. ``touchscreen``), ``none``/None/"" (no obstacles), or
    obstacles already parsed.

    Raises:
        InputError: naming the bad value and what is allowed.
    """
    if spec is None or (isinstance(spec, str) and spec.strip().lower() in ("", "none")):
        return ()
    if isinstance(spec, (list, tuple)):
        return tuple(spec)
    text = str(spec)
    sets = named_sets(robot) if robot is not None else {}
    if text in sets:
        return parse_obstacles(load_file(sets[text]), str(sets[text]))
    path = Path(text)
    if path.suffix.lower() in (".json", ".yaml", ".yml"):
        if not path.is_file():
            raise InputError(f"obstacles: file {text!r} not found")
        return parse_obstacles(load_file(path), text)
    named = (f"a named set of {robot.name} ({', '.join(sets)}), "
             if sets and robot is not None else "")  # sets only come from a robot
    raise InputError(f"obstacles: {text!r} is neither {named}nor an obstacle file "
                     "(*.json, *.yaml), nor none")


def named_sets(robot: Robot) -> dict[str, Path]:
    """name -> file of the obstacle sets the robot's collision config names."""

    config = collision_config(robot)
    if not config:
        return {}
    base = Path(config["path"]).parent
    return {name: base / file for name, file in config.get("obstacle_sets", {}).items()}
