"""The experiment's touchscreen and goal set: where the targets are, in pixels and in the torso
frame.

The screen's size and the targets' pixels are the authors' (``urdf/nico_right_arm.experiment.json``,
from github andylucny/nico2). The screen is placed in NICO's torso frame (mm) by a rigid fit:
pixels are turned into millimetres by the screen's size, then rotated (a reflection allowed:
the pixel rows run toward the participant) and translated in the touchscreen plane of
``nico_right_arm.touchscreen.json`` to best match the fingertip points of the touch poses
(FK); :attr:`Screen.fit_residuals_mm` says how well it fits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.io import read_json
from ikbench.core.robot import Robot, load_robot, robots_dir
from ikbench.core.targets import Targets, load_targets

#: The shipped layout of NICO's experiment.
LAYOUT_FILE = "nico_right_arm.experiment.json"
TOUCHSCREEN_FILE = "nico_right_arm.touchscreen.json"
ROBOT = "nico_right_arm"


@dataclass(frozen=True)
class Screen:
    """A flat screen in the robot frame.

    Attributes:
        size_px: (width, height) [px].
        size_mm: (width, height) [mm].
        origin_mm: (3,) the point of pixel (0, 0) [mm, robot frame].
        u: (3,) unit vector along +x in pixels; v: (3,) along +y in pixels.
        fit_residuals_mm: (k,) distance of each fitted target's pixel, placed on the screen,
            to its fingertip point projected on the screen plane [mm].
    """

    size_px: tuple[float, float]
    size_mm: tuple[float, float]
    origin_mm: np.ndarray
    u: np.ndarray
    v: np.ndarray
    fit_residuals_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def mm_per_px(self) -> np.ndarray:
        """(2,) millimetres per pixel along x and y."""
        return np.asarray(self.size_mm, float) / np.asarray(self.size_px, float)

    @property
    def normal(self) -> np.ndarray:
        """(3,) unit normal of the screen."""
        n = np.cross(self.u, self.v)
        return n / np.linalg.norm(n)

    def px_to_mm(self, px: npt.ArrayLike) -> np.ndarray:
        """Points (..., 3) [mm, robot frame] of pixels (..., 2)."""
        s = np.asarray(px, float) * self.mm_per_px
        return self.origin_mm + s[..., :1] * self.u + s[..., 1:2] * self.v

    def mm_to_px(self, point_mm: npt.ArrayLike) -> np.ndarray:
        """Pixels (..., 2) of points (..., 3) [mm] projected on the screen."""
        d = np.asarray(point_mm, float) - self.origin_mm
        s = np.stack([d @ self.u, d @ self.v], axis=-1)
        return s / self.mm_per_px

    def ray_hit_mm(self, origin_mm: npt.ArrayLike, direction: npt.ArrayLike) -> np.ndarray:
        """Where rays (..., 3) from ``origin_mm`` along ``direction`` meet the screen's plane
        [mm]; NaN where a ray runs parallel to it or away from it."""
        o = np.asarray(origin_mm, float)
        d = np.asarray(direction, float)
        n = self.normal
        denom = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.origin_mm - o) @ n) / denom
        t = np.where((np.abs(denom) > 1e-12) & (t > 0), t, np.nan)
        return o + t[..., None] * d


@dataclass(frozen=True)
class GoalSet:
    """The targets a participant chooses among.

    Attributes:
        ids: target ids (integers, as the authors number them).
        pixels: (k, 2) the targets on the screen [px].
        points_mm: (k, 3) the targets on the screen [mm, robot frame] (the pixels placed by
            the screen's fit).
        touch_points_mm: (k, 3) the fingertip at each touch pose (FK) [mm].
        targets: the touch poses (the arm's trajectories end there).
        screen: the screen.
        viewpoint_mm: (3,) the participant's eyes [mm, robot frame] (an estimate).
        response_window_s, duration_s, gaze_lead_s: the authors' timing [s].
        source: the layout file.
    """

    ids: tuple[int, ...]
    pixels: np.ndarray
    points_mm: np.ndarray
    touch_points_mm: np.ndarray
    targets: Targets
    screen: Screen
    viewpoint_mm: np.ndarray
    response_window_s: float
    duration_s: float
    gaze_lead_s: float
    source: str

    def index(self, target: int) -> int:
        """The row of target ``target`` in :attr:`ids`."""
        try:
            return self.ids.index(int(target))
        except ValueError:
            raise InputError(f"target {target!r} is not in the goal set; ids: "
                             f"{', '.join(map(str, self.ids))}") from None

    def nearest(self, point_mm: npt.ArrayLike) -> np.ndarray:
        """Index (...) of the goal nearest to each point (..., 3) [mm] on the screen."""
        p = np.asarray(point_mm, float)
        d = np.linalg.norm(p[..., None, :] - self.points_mm, axis=-1)
        return np.argmin(d, axis=-1)

    def describe(self) -> dict:
        """The goal set as design.json records it."""
        return {"ids": list(self.ids), "source": self.source,
                "targets_file": self.targets.source,
                "pixels": {str(i): [round(float(x), 3) for x in p]
                           for i, p in zip(self.ids, self.pixels)},
                "points_mm": {str(i): [round(float(x), 3) for x in p]
                              for i, p in zip(self.ids, self.points_mm)},
                "touch_points_mm": {str(i): [round(float(x), 3) for x in p]
                                    for i, p in zip(self.ids, self.touch_points_mm)},
                "screen_fit_residuals_mm": [round(float(r), 3)
                                            for r in self.screen.fit_residuals_mm]}


def _read(path: Path) -> dict:
    return read_json(path, "layout file")


def _plane(robot_folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """The touchscreen plane (point [mm], unit normal) of the shipped collision file."""
    spec = _read(robot_folder / TOUCHSCREEN_FILE)
    screen = next(o for o in spec["obstacles"] if o["name"] == "touchscreen")
    normal = np.asarray(screen["normal"], float)
    return np.asarray(screen["point_mm"], float), normal / np.linalg.norm(normal)


def fit_screen(size_px: tuple[float, float], size_mm: tuple[float, float], pixels: np.ndarray,
               points_mm: np.ndarray, plane_point_mm: np.ndarray, plane_normal: np.ndarray
               ) -> Screen:
    """Place a screen of known size so that ``pixels`` (k, 2) land nearest to ``points_mm``
    (k, 3) projected on the plane: a 2-D rigid fit (Kabsch), reflection allowed."""
    n = plane_normal / np.linalg.norm(plane_normal)
    e1 = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    basis = np.stack([e1, e2], axis=1)                          # (3, 2)
    projected = points_mm - np.outer((points_mm - plane_point_mm) @ n, n)
    target = (projected - plane_point_mm) @ basis               # (k, 2) in the plane
    source = pixels * (np.asarray(size_mm, float) / np.asarray(size_px, float))
    sc, tc = source.mean(0), target.mean(0)
    u_, _, vt = np.linalg.svd((source - sc).T @ (target - tc))
    best = None
    for flip in (1.0, -1.0):                       # the two orthogonal fits: turned, mirrored
        rotation = vt.T @ np.diag([1.0, flip]) @ u_.T             # target ~ R @ source
        residual = np.linalg.norm((source - sc) @ rotation.T + tc - target, axis=1)
        if best is None or residual.sum() < best[1].sum():
            best = (rotation, residual)
    assert best is not None
    rotation, residual = best
    origin_2d = tc - rotation @ sc
    u = basis @ rotation[:, 0]
    v = basis @ rotation[:, 1]
    origin = plane_point_mm + basis @ origin_2d
    return Screen(tuple(map(float, size_px)), tuple(map(float, size_mm)),  # type: ignore[arg-type]
                  origin, u, v, residual)


def _pair(spec: dict, key: str, path: Path) -> tuple[float, float]:
    value = spec.get(key)
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(x, (int, float)) and np.isfinite(x) and x > 0 for x in value)):
        raise InputError(f"{path.name}: screen.{key} {value!r} must be two positive numbers")
    return float(value[0]), float(value[1])


def _integer_ids(targets: Targets) -> tuple[int, ...]:
    ids = []
    for name in targets.ids:
        if not str(name).isdigit():
            raise InputError(f"target id {name!r} of {targets.source}: the experiment numbers "
                             "its targets; ids must be positive integers")
        ids.append(int(name))
    return tuple(ids)


def load_goals(goals: str | Path | Targets | None = None, robot: Robot | None = None,
               layout: str | Path | None = None) -> GoalSet:
    """The goal set: NICO's seven targets by default, or the touch poses of a targets file.

    A target the layout file gives no pixel for is placed where its fingertip point projects
    onto the fitted screen (the fit uses the targets that have pixels; at least three).

    Raises:
        InputError: a robot other than NICO's right arm, a non-integer target id, a layout
            file that is missing or malformed, fewer than three targets with pixels.
    """
    robot = robot or load_robot(ROBOT)
    if robot.name != ROBOT:
        raise InputError(f"--robot {robot.name!r}: the pointing experiment runs on NICO "
                         f"({ROBOT}), whose head gives the gaze cue")
    targets = goals if isinstance(goals, Targets) else load_targets(goals, robot)
    ids = _integer_ids(targets)
    if len(ids) < 2:
        raise InputError(f"{targets.source}: a goal set needs at least two targets, got "
                         f"{len(ids)}")
    folder = robots_dir()
    path = Path(layout) if layout is not None else folder / LAYOUT_FILE
    spec = _read(path)
    screen_spec = spec.get("screen", {})
    size_px, size_mm = _pair(screen_spec, "size_px", path), _pair(screen_spec, "size_mm", path)
    pixels_given = {int(k): np.asarray(v, float) for k, v in spec.get("targets_px", {}).items()}
    poses = np.array([targets.touch_poses[name] for name in targets.ids], float)
    touch = robot.fk(poses).point_mm
    fitted = [i for i, t in enumerate(ids) if t in pixels_given]
    if len(fitted) < 3:
        raise InputError(f"{path.name}: targets_px gives pixels for {len(fitted)} of the goal "
                         f"set's targets ({', '.join(map(str, ids))}); the screen's fit needs "
                         "at least three")
    plane_point, plane_normal = _plane(folder)
    screen = fit_screen(size_px, size_mm, np.array([pixels_given[ids[i]] for i in fitted]),
                        touch[fitted], plane_point, plane_normal)
    pixels = np.array([pixels_given[t] if t in pixels_given else screen.mm_to_px(touch[i])
                       for i, t in enumerate(ids)])
    viewpoint = np.asarray(spec.get("viewpoint_mm", [-1000.0, 30.0, 450.0]), float)
    return GoalSet(ids, pixels, screen.px_to_mm(pixels), touch, targets, screen, viewpoint,
                   float(spec.get("response_window_s", 2.0)), float(spec.get("duration_s", 2.0)),
                   float(spec.get("gaze_lead_s", 0.5)), path.name)
