"""Joint velocity and acceleration limits for ``--timing topp``, in pose units.

Where they come from (the first that applies; ``--max-velocity`` and ``--max-acceleration``
override either):

- a robot with servos (NICO): its motor table (``max_speed_deg_s`` and
  ``max_acceleration_deg_s2`` per motor, :mod:`ikbench.hw.motors`), read by
  :func:`ikbench.hw.limits.timing_limits`;
- any other robot: velocities from the URDF's ``<limit velocity=...>`` [rad/s, m/s], and
  accelerations from ``<config>.limits.json`` next to the robot config (Panda:
  ``panda.limits.json``, MoveIt's panda_moveit_config values) [rad/s^2, m/s^2]; a joint without
  a stated acceleration gets its velocity limit / :data:`DEFAULT_ACCELERATION_TIME_S` (full
  speed in half a second: an assumption, said so in the limits' ``source``).

Pose units per URDF unit follow the robot's map: ``q_urdf = (scale * q + offset) * si`` with
si = pi/180 rad per deg (0.001 m per mm for prismatic joints), so a URDF rate r is
``r / (|scale| * si)`` pose units per second.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.timing import Limits

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: Time [s] to reach full speed assumed for a joint without a stated acceleration limit.
DEFAULT_ACCELERATION_TIME_S = 0.5
LIMITS_SUFFIX = ".limits.json"


def urdf_units_per_pose_unit(robot: Robot) -> np.ndarray:
    """(dof,) signed factor from a rate in pose units to the same rate in URDF units
    (``scale * si``, the derivative of the robot's map)."""
    si = np.array([1e-3 if t == "prismatic" else math.pi / 180.0 for t in robot.joint_types])
    return np.asarray(robot.scale, dtype=float) * si


def pose_units_per_urdf_unit(robot: Robot) -> np.ndarray:
    """(dof,) pose units per URDF unit of each joint's rate (deg per rad / |scale|, or mm per
    m for prismatic joints)."""
    return 1.0 / np.abs(urdf_units_per_pose_unit(robot))


def urdf_velocity_limits(robot: Robot) -> np.ndarray:
    """(dof,) the URDF's joint velocity limits [URDF units/s]; NaN where a joint has none
    (or a non-positive one)."""
    return robot.urdf_model.velocity_limits(robot.joint_names)


def limits_file(robot: Robot) -> Path | None:
    """``<config stem>.limits.json`` next to the robot's config, if there is one."""
    config = robot.config.config_path
    if not config:
        return None
    path = Path(config)
    path = path.with_name(path.name.split(".")[0] + LIMITS_SUFFIX)
    return path if path.is_file() else None


def urdf_limits(robot: Robot, velocity: npt.ArrayLike | None = None) -> Limits:
    """The robot's limits from its URDF and limits file (see the module doc) [pose units].

    Args:
        velocity: (dof,) velocity limits [pose units/s] to use instead of the URDF's (the
            acceleration assumed for a joint without a stated one follows them).
    """
    velocity_urdf = urdf_velocity_limits(robot)
    if velocity is not None:
        velocity_urdf = np.asarray(velocity, dtype=float) / pose_units_per_urdf_unit(robot)
    missing = [n for n, v in zip(robot.joint_names, velocity_urdf) if not np.isfinite(v)]
    if missing:
        raise InputError(f"max_velocity: {robot.urdf_path.name} gives no velocity limit for "
                         f"joint(s) {', '.join(missing)}; give one")
    acceleration_urdf = velocity_urdf / DEFAULT_ACCELERATION_TIME_S
    path, stated = limits_file(robot), []
    if path is not None:
        spec = _read(path)
        given = spec.get("max_acceleration", {})
        for j, name in enumerate(robot.joint_names):
            if name in given:
                acceleration_urdf[j] = _positive(given[name], f"{path.name}: {name}")
                stated.append(name)
    per_unit = pose_units_per_urdf_unit(robot)
    assumed = [n for n in robot.joint_names if n not in stated]
    source = f"velocity: {'--max-velocity' if velocity is not None else robot.urdf_path.name}"
    if stated:
        source += f"; acceleration: {path.name if path else ''} ({_source(path)})"
    if assumed:
        source += (f"; acceleration assumed velocity limit / {DEFAULT_ACCELERATION_TIME_S:g} s "
                   f"for {', '.join(assumed)}")
    return Limits(velocity_urdf * per_unit, acceleration_urdf * per_unit, source)


def parse_limit_option(text: str | None, dof: int, field: str) -> np.ndarray | None:
    """``--max-velocity 90`` or ``--max-velocity 90,90,120,...`` (one value per joint) ->
    (dof,) values; None when not given."""
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"{field}: {text!r}; give one positive number or {dof} "
                         "comma-separated ones (pose units, per second)") from None
    if len(values) not in (1, dof) or not (np.all(np.isfinite(values)) and np.all(values > 0)):
        raise InputError(f"{field}: {text!r}; give one positive number or {dof} "
                         "comma-separated ones (pose units, per second)")
    return np.broadcast_to(values, (dof,)).astype(float)


def with_overrides(limits: Limits, velocity: npt.ArrayLike | None = None,
                   acceleration: npt.ArrayLike | None = None) -> Limits:
    """``limits`` with the velocity and/or acceleration limits replaced where given."""
    source = limits.source
    if velocity is not None:
        source += "; velocity from --max-velocity"
    if acceleration is not None:
        source += "; acceleration from --max-acceleration"
    return Limits(limits.velocity if velocity is None else np.asarray(velocity, float),
                  limits.acceleration if acceleration is None else np.asarray(acceleration,
                                                                              float),
                  source)


def _read(path: Path) -> dict:
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"limits file {str(path)!r} is not readable JSON: {exc}") from None
    if not isinstance(spec, dict) or not isinstance(spec.get("max_acceleration", {}), dict):
        raise InputError(f"{path}: needs an object with \"max_acceleration\": {{joint: value}}")
    return spec


def _source(path: Path | None) -> str:
    if path is None:
        return ""
    return str(_read(path).get("source", "no source given"))


def _positive(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 \
            or not math.isfinite(value):
        raise InputError(f"{where} = {value!r}; give a positive number")
    return float(value)
