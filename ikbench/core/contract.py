"""The task contract: what a trajectory must satisfy, and how it is judged.

A comparison is only worth reading when every method solves the same stated task and
"success" means that task was done. A :class:`Contract` states it:

- **fixed poses**: the touch pose always; the start pose too on the paper's track
  (``track="paper"``, the paper's Sec. 3: every trajectory starts at the same recorded pose),
  not on the touch-pose-only track (``track="touch"``, the authors' walk from the touch pose);
- **the path**: the goal points (a line from FK(start) to FK(touch) for the paper's task);
  judged by the largest distance of the fingertip from the line;
- **pointing**: whether the end frame's pointing axis must point along the motion, judged by
  the mean deviation over the last part of the path only (from ``pointing_judged_from`` of
  the steps on; no method can point along the line while it is still at a given start
  pose). Off for robots whose config names no pointing axis (a bare URDF's tool axis need not
  point along the motion) unless asked for;
- **playability**: every segment within the joints' speed limits when the trajectory is
  played in ``duration_s`` (n segments of duration_s / n each). NICO: 270 motor deg/s from its
  Dynamixel table, T = 2 s, n = 50: at most 10.8 motor deg per segment; other robots: their
  URDF's ``<limit velocity>`` (rad/s or m/s, turned into pose units);
- **tolerances** for each criterion (:data:`DEFAULT_TOLERANCES`), printed above every
  leaderboard and overridable (``--tolerance start_pose_deg=0.5,...``);
- **collisions**, only when the tasks carry obstacles (``Contract.obstacles``: a targets
  file's ``obstacles``, ``ikbench compare --obstacles``): no waypoint in collision with the
  obstacles nor with the robot itself (:mod:`ikbench.core.collision`; figures
  ``self_collisions`` and ``env_collisions`` of
  :func:`ikbench.core.metrics.contract_metrics`). Without obstacles the criterion does not
  exist and nothing changes.

Success is computed by the study from the written trajectory (:func:`judge`), never reported
by the method. A method whose scheme cannot honour a fixed pose says so
(``Method.fixed_poses``) and its rows read "does not honour: start pose", never success.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: The tracks: which poses a trajectory must start and end at.
TRACKS = {"paper": ("start_pose", "touch_pose"), "touch": ("touch_pose",)}
#: What each track is, in words (leaderboard headers).
TRACK_TITLES = {"paper": "the paper's task: start and touch poses both fixed",
                "touch": "touch pose only: the start pose is free (the authors' walk)"}
#: Default tolerances, all must hold. Pose errors: max |p - p_goal| over joints [pose units,
#: motor deg for NICO]; line distance: the largest over the steps [mm]; pointing: the mean
#: deviation over the judged steps [deg]; speed: the largest joint step over its allowed step
#: (1.0: at the limit).
DEFAULT_TOLERANCES = {"start_pose_deg": 0.5, "end_pose_deg": 0.5, "line_distance_max_mm": 5.0,
                      "pointing_judged_mean_deg": 15.0, "speed_limit_use": 1.0}
#: Default start of the judged part of the pointing, as a fraction of the steps.
DEFAULT_POINTING_FROM = 0.2
#: The criteria, in the order the tables show them: name -> (metric column, tolerance key).
CRITERIA = {
    "start_pose": ("start_pose_error_deg", "start_pose_deg"),
    "end_pose": ("end_pose_error_deg", "end_pose_deg"),
    "limits": ("within_limits", None),
    "speed": ("speed_limit_use", "speed_limit_use"),
    "line": ("line_distance_max_mm", "line_distance_max_mm"),
    "pointing": ("pointing_deviation_judged_mean_deg", "pointing_judged_mean_deg"),
}
#: The criterion judged only when the tasks carry obstacles (after :data:`CRITERIA`): no
#: waypoint in collision, with itself or with an obstacle (both figures must be 0).
COLLISION_CRITERION = "collisions"
#: The figures the collision criterion reads (waypoints in collision).
COLLISION_FIGURES = ("self_collisions", "env_collisions")
POINTING_CHOICES = ("auto", "on", "off")


@dataclass(frozen=True)
class Contract:
    """What every method is asked to do and how success is judged (see the module doc).

    Attributes:
        track: ``"paper"`` (start and touch poses fixed) or ``"touch"`` (touch pose only).
        pointing: whether the pointing axis must point along the path (judged).
        pointing_judged_from: pointing is judged on steps i >= ceil(this * n).
        duration_s: the trajectory's duration T [s]; segments last T / n.
        max_speed: (dof,) joint speed limits [pose units per s], or None when unknown.
        speed_source: where ``max_speed`` comes from (a sentence).
        tolerances: criterion tolerances (keys of :data:`DEFAULT_TOLERANCES`).
        obstacles: True when the tasks carry obstacles: collisions are judged
            (:data:`COLLISION_CRITERION`).
    """

    track: str = "paper"
    pointing: bool = True
    pointing_judged_from: float = DEFAULT_POINTING_FROM
    duration_s: float = DEFAULT_DURATION_S
    max_speed: np.ndarray | None = None
    speed_source: str = "no speed limit known"
    tolerances: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_TOLERANCES))
    obstacles: bool = False

    def __post_init__(self):
        if self.track not in TRACKS:
            raise InputError(f"track: {self.track!r} is not one of {', '.join(TRACKS)}")
        if not 0.0 <= self.pointing_judged_from < 1.0:
            raise InputError(f"pointing_judged_from: {self.pointing_judged_from!r} must be in "
                             "[0, 1)")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise InputError(f"duration_s: {self.duration_s!r} must be a positive number [s]")

    @property
    def fixed_poses(self) -> tuple[str, ...]:
        """The poses a trajectory must start/end at: ``start_pose`` and/or ``touch_pose``."""
        return TRACKS[self.track]

    def criteria(self) -> list[str]:
        """The criteria judged on this track (names of :data:`CRITERIA`, then
        :data:`COLLISION_CRITERION` when the tasks carry obstacles)."""
        out = []
        for name in CRITERIA:
            if name == "start_pose" and "start_pose" not in self.fixed_poses:
                continue
            if name == "speed" and self.max_speed is None:
                continue
            if name == "pointing" and not self.pointing:
                continue
            out.append(name)
        if self.obstacles:
            out.append(COLLISION_CRITERION)
        return out

    def criterion_names(self) -> list[str]:
        """Every criterion a table of this contract has a column for, on any track:
        :data:`CRITERIA`, then :data:`COLLISION_CRITERION` when the tasks carry obstacles."""
        return [*CRITERIA, *([COLLISION_CRITERION] if self.obstacles else [])]

    def max_step(self, steps: int) -> np.ndarray | None:
        """(dof,) the largest joint change per segment [pose units] at T / n per segment."""
        if self.max_speed is None:
            return None
        return np.asarray(self.max_speed, dtype=float) * self.duration_s / steps

    def judged_from(self, steps: int) -> int:
        """The first step whose pointing is judged: ceil(pointing_judged_from * n)."""
        return int(math.ceil(self.pointing_judged_from * steps - 1e-9))

    def with_track(self, track: str) -> Contract:
        """The same contract on another track."""
        return replace(self, track=track)

    def to_dict(self) -> dict:
        """Plain values (run.json); ``obstacles`` only when True (obstacle-free contracts
        are written as before)."""
        out = {"track": self.track, "fixed_poses": list(self.fixed_poses),
               "pointing": self.pointing, "pointing_judged_from": self.pointing_judged_from,
               "duration_s": self.duration_s,
               "max_speed": None if self.max_speed is None else
               [float(v) for v in self.max_speed],
               "speed_source": self.speed_source, "tolerances": dict(self.tolerances),
               "criteria": self.criteria()}
        if self.obstacles:
            out["obstacles"] = True
        return out

    @classmethod
    def from_dict(cls, spec: Mapping) -> Contract:
        """The contract :meth:`to_dict` wrote (run.json's ``contract``)."""
        speed = spec.get("max_speed")
        return cls(track=spec["track"], pointing=spec["pointing"],
                   pointing_judged_from=spec["pointing_judged_from"],
                   duration_s=spec["duration_s"],
                   max_speed=None if speed is None else np.asarray(speed, dtype=float),
                   speed_source=spec["speed_source"], tolerances=dict(spec["tolerances"]),
                   obstacles=bool(spec.get("obstacles", False)))

    def describe(self, steps: int, unit: str = "deg") -> str:
        """The contract in a few sentences (leaderboard headers)."""
        tol = self.tolerances
        parts = [f"Track **{self.track}**: {TRACK_TITLES[self.track]}."]
        poses = [f"touch pose within {tol['end_pose_deg']:g} {unit} (every joint)"]
        if "start_pose" in self.fixed_poses:
            poses.insert(0, f"start pose within {tol['start_pose_deg']:g} {unit}")
        parts.append("Success needs: the method honours the fixed poses and the solve "
                     "returned; " + ", ".join(poses) + "; every pose within the joint limits")
        step = self.max_step(steps)
        if step is not None:
            low, high = float(np.min(step)), float(np.max(step))
            shown = f"{low:.3g}" if np.isclose(low, high) else f"{low:.3g}-{high:.3g}"
            parts[-1] += (f"; every segment within the speed limits at T = {self.duration_s:g} s"
                          f" (n = {steps}: at most {shown} {unit} per segment; "
                          f"{self.speed_source})")
        else:
            parts[-1] += "; no speed criterion (no speed limit known for this robot)"
        parts[-1] += (f"; the fingertip within {tol['line_distance_max_mm']:g} mm of the "
                      "line at every step")
        if self.pointing:
            parts[-1] += (f"; pointing along the line within "
                          f"{tol['pointing_judged_mean_deg']:g} deg on average over the "
                          f"judged part (steps {self.judged_from(steps)}-{steps}, the last "
                          f"{100 * (1 - self.pointing_judged_from):.0f} %)")
        else:
            parts[-1] += "; pointing not judged"
        if self.obstacles:
            parts[-1] += ("; no waypoint in collision with the obstacles or with the robot "
                          "itself (its collision model)")
        parts[-1] += "."
        return " ".join(parts)


def parse_tolerances(text: str | Mapping | None,
                     base: Mapping[str, float] | None = None) -> dict[str, float]:
    """``"start_pose_deg=0.5,line_distance_max_mm=2"`` over ``base`` (default
    :data:`DEFAULT_TOLERANCES`); InputError naming a bad key or value."""
    out = dict(base if base is not None else DEFAULT_TOLERANCES)
    if text is None or text == "":
        return out
    items = text.items() if isinstance(text, Mapping) else (
        part.partition("=")[::2] for part in str(text).split(",") if part.strip())
    for key, value in items:
        key = str(key).strip()
        if key not in DEFAULT_TOLERANCES:
            raise InputError(f"tolerance: unknown criterion {key!r}; known: "
                             f"{', '.join(DEFAULT_TOLERANCES)} (e.g. start_pose_deg=0.5)")
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if not (math.isfinite(number) and number >= 0):
            raise InputError(f"tolerance: {key}={value!r} must be a number >= 0")
        out[key] = number
    return out


def pointing_declared(robot: Robot) -> bool:
    """True when the robot's config names its pointing axis (shipped robots); a bare URDF's
    end frame has no declared pointing axis."""
    config = getattr(robot, "config", None)
    return config is not None and config.pointing_axis is not None


def speed_limits(robot: Robot) -> tuple[np.ndarray | None, str]:
    """The robot's joint speed limits (dof,) [pose units per s] and where they come from.

    Order: the robot's hardware table (``max_speed_deg_s`` per joint, motor deg/s: NICO's
    Dynamixel table), else the URDF's ``<limit velocity>`` of each chain joint (rad/s or m/s,
    turned into pose units), else None (no limit known, or one joint without one).
    """
    cache = getattr(robot, "_cache", None)
    if cache is not None and "speed_limits" in cache:
        return cache["speed_limits"]
    found = _read_speed_limits(robot)
    if cache is not None:
        cache["speed_limits"] = found
    return found


def _read_speed_limits(robot) -> tuple[np.ndarray | None, str]:
    """:func:`speed_limits` read from the robot's files."""
    config = getattr(robot, "config", None)
    hardware = config.hardware if config is not None else None
    if hardware and config is not None and config.config_path is not None:
        path = config.config_path.parent / hardware
        motors = json.loads(path.read_text(encoding="utf-8")).get("motors", {})
        speeds = [motors.get(name, {}).get("max_speed_deg_s") for name in robot.joint_names]
        if all(v is not None for v in speeds):
            return (np.array(speeds, dtype=float),
                    f"max_speed_deg_s of {path.name}")
    si = robot.urdf_model.velocity_limits(robot.joint_names)
    if not np.all(np.isfinite(si)):
        return None, "no speed limit known (a chain joint has no URDF velocity limit)"
    # joint units per s -> pose units per s: a pose unit is (scale) joint units (deg or mm)
    per_unit = np.where(np.asarray(robot.prismatic), 1000.0, np.degrees(1.0))
    scale = np.abs(np.asarray(robot.scale, dtype=float))
    return si * per_unit / scale, f"<limit velocity> of {Path(robot.urdf_path).name}"


def contract_for(robot: Robot, track: str = "paper", tolerances: str | Mapping | None = None,
                 pointing: str | bool = "auto", duration_s: float = DEFAULT_DURATION_S,
                 pointing_judged_from: float = DEFAULT_POINTING_FROM) -> Contract:
    """The contract of a robot's line tasks (see the module doc).

    Args:
        robot: the robot (its speed limits and whether it declares a pointing axis).
        track: ``"paper"`` or ``"touch"``.
        tolerances: overrides of :data:`DEFAULT_TOLERANCES` (``"key=value,..."`` or a dict).
        pointing: ``"auto"`` (on when the robot's config names a pointing axis), ``"on"``,
            ``"off"`` or a bool.
        duration_s: T [s].
        pointing_judged_from: the judged part's start as a fraction of the steps.
    """
    if isinstance(pointing, str):
        if pointing not in POINTING_CHOICES:
            raise InputError(f"pointing: {pointing!r} is not one of "
                             f"{', '.join(POINTING_CHOICES)}")
        pointing = pointing_declared(robot) if pointing == "auto" else pointing == "on"
    max_speed, source = speed_limits(robot)
    return Contract(track=track, pointing=bool(pointing),
                    pointing_judged_from=float(pointing_judged_from),
                    duration_s=float(duration_s), max_speed=max_speed, speed_source=source,
                    tolerances=parse_tolerances(tolerances))


def judge(contract: Contract, figures: Mapping) -> dict[str, bool]:
    """criterion -> met, for the criteria of ``contract`` (:meth:`Contract.criteria`), from a
    trajectory's figures (:func:`ikbench.core.metrics.contract_metrics`). A NaN figure fails;
    the collision criterion holds when both :data:`COLLISION_FIGURES` are 0."""
    out = {}
    for name in contract.criteria():
        if name == COLLISION_CRITERION:
            out[name] = all(_is_zero(figures.get(column)) for column in COLLISION_FIGURES)
            continue
        column, key = CRITERIA[name]
        value = figures.get(column)
        if key is None:
            out[name] = bool(value is True or value == 1)
            continue
        try:
            number = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            number = math.nan
        out[name] = bool(number <= contract.tolerances[key])
    return out


def _is_zero(value: object) -> bool:
    """True for a figure equal to 0 (a count of waypoints in collision); NaN, None: False."""
    try:
        return float(value) == 0.0  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
