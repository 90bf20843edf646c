"""The study seen from the participant's seat: NICO, its head and the touchscreen projected by a
pinhole camera, as flat shapes that a browser canvas (the online page) or matplotlib (stimulus
videos) draws.

Geometry (millimetres, ``torso_base``): the right arm is the chain's skeleton
(:meth:`ikbench.core.robot.Robot.skeleton_mm`, every joint origin) drawn as capsules of stated
radii; the left arm is its start pose mirrored (it does not move); the head is a box in the
eye frame (:meth:`ikbench.experiment.head.Head.eye_frame`) with a face plate and two eyes on
its front, so the line of sight is the face's normal; the torso a box; the screen and its
targets the goal set's (:class:`ikbench.experiment.layout.Screen`), on a table in the screen's
plane.

The camera is a pinhole at the viewpoint (the participant's eyes, design.json ``viewpoint_mm``)
aimed at the middle of the screen's centre and the head's eye, its focal length chosen so the
screen, the head and the arm fill :data:`FILL` of the view; no roll (the world's z is up in
the image). Shapes are painted far to near (painter's algorithm, by each part's depth), faces
turned away from the camera are dropped. A shape is a dict: ``{"type": "poly", "pts":
[[x, y], ...], "fill": "#rrggbb", "stroke": "#rrggbb" | None, "lw": w, "z": depth}`` or
``{"type": "line", "pts": ..., "color": "#rrggbb", "lw": w, "z": depth}`` in view units
(:data:`VIEW_SIZE`, x right, y down; ``lw`` in view units too).

The motion of a trial follows the lab's back-end (:class:`ikbench.experiment.play.BusPresenter`):
the head turns from rest to the trial's pose over ``gaze_lead_s`` (at least
:data:`HEAD_TURN_MIN_S`), then the arm plays its trajectory up to the stop pose over
``duration_s``, evenly in time per pose, interpolated in motor degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ikbench.core.robot import Robot
from ikbench.experiment.design import stop_of
from ikbench.experiment.head import Head
from ikbench.experiment.layout import GoalSet

#: The view's size [view units]; the page scales it to its window, videos render it 1:1 [px].
VIEW_SIZE = (1200, 800)
#: Share of the view the screen, head and arm span.
FILL = 0.9
#: Frames per second of the motion sent to the page.
FPS = 30
#: The shortest head turn [s] (the bus back-end's, so the lab and the page agree).
HEAD_TURN_MIN_S = 0.3
#: Radius of a target on the screen [screen px].
TARGET_RADIUS_PX = 60
#: Capsule radii of the right arm's segments [mm], skeleton point i -> i+1 (0: none drawn).
ARM_RADII_MM = (0.0, 0.0, 34.0, 31.0, 26.0, 26.0, 21.0, 7.0)
#: The table: a horizontal plane under the screen, from x[0] to x[1] and +-half width [mm].
TABLE_X_MM, TABLE_HALF_WIDTH_MM = (-1400.0, 260.0), 750.0
#: Torso box in torso_base [mm]: (x, y, z) lower and upper corners (its bottom: the table).
TORSO_MM = ((-45.0, -100.0, 0.0), (80.0, 100.0, 215.0))
#: The head: an ellipsoid in the eye frame [mm] (x: line of sight, y: head's left, z: up),
#: its centre and semi-axes; the eye point lies on its front.
HEAD_CENTRE_MM, HEAD_AXES_MM = (-60.0, 0.0, 8.0), (66.0, 70.0, 82.0)
#: The face plate: the part of the ellipsoid whose normalised x exceeds this.
FACE_CAP = 0.5
#: The eyes' centres on the face (y, z) [mm, eye frame] and their radii [mm].
EYES_MM = ((30.0, 4.0), (-30.0, 4.0))
EYE_RADIUS_MM, PUPIL_RADIUS_MM = 13.0, 6.5
COLORS = {"table": "#cdbb9e", "bezel": "#202226", "display": "#3a3f47", "target": "#f2f2f2",
          "target_ring": "#9aa3ad", "body": "#e4e7eb", "body_dark": "#8d949c",
          "face": "#2d3138", "eye": "#fafafa", "pupil": "#14161a", "arm": "#eef0f2",
          "arm_edge": "#6f7780", "left_arm": "#d3d7dc", "neck": "#b9bfc6"}
BACKGROUND = "#f4f5f7"
#: Depth of the shapes drawn first (the table, then the screen and its targets).
FAR = 1e9


@dataclass(frozen=True)
class Camera:
    """A pinhole camera.

    Attributes:
        eye_mm: (3,) the centre of projection [mm, torso_base].
        rotation: (3, 3) rows: the image's right, down and forward axes in torso_base.
        focal: focal length [view units].
        size: the view's (width, height) [view units].
    """

    eye_mm: np.ndarray
    rotation: np.ndarray
    focal: float
    size: tuple[int, int] = VIEW_SIZE

    @property
    def intrinsics(self) -> np.ndarray:
        """(3, 3) K: camera coordinates -> homogeneous view coordinates."""
        return np.array([[self.focal, 0.0, self.size[0] / 2], [0.0, self.focal, self.size[1] / 2],
                         [0.0, 0.0, 1.0]])

    def camera_mm(self, points_mm: npt.ArrayLike) -> np.ndarray:
        """Points (..., 3) in the camera frame [mm] (x right, y down, z forward)."""
        return (np.asarray(points_mm, float) - self.eye_mm) @ self.rotation.T

    def project(self, points_mm: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """View coordinates (..., 2) and depths (...,) [mm] of points (..., 3) [mm]."""
        c = self.camera_mm(points_mm)
        depth = np.maximum(c[..., 2], 1.0)
        xy = self.focal * c[..., :2] / depth[..., None] + np.asarray(self.size, float) / 2
        return xy, c[..., 2]

    def homography(self, screen_px_to_mm_origin: np.ndarray, axis_x_mm: np.ndarray,
                   axis_y_mm: np.ndarray) -> np.ndarray:
        """(3, 3) H: homogeneous screen pixels (x, y, 1) -> homogeneous view coordinates, for a
        plane ``origin + x * axis_x + y * axis_y`` [mm]."""
        columns = np.stack([axis_x_mm, axis_y_mm, screen_px_to_mm_origin - self.eye_mm], axis=1)
        return self.intrinsics @ self.rotation @ columns


def look_at(eye_mm: npt.ArrayLike, target_mm: npt.ArrayLike) -> np.ndarray:
    """(3, 3) the rotation of a camera at ``eye_mm`` looking at ``target_mm``, z up."""
    eye, target = np.asarray(eye_mm, float), np.asarray(target_mm, float)
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:                      # looking straight down or up
        right = np.array([0.0, -1.0, 0.0])
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(forward, right), forward])


def _box_corners(low: npt.ArrayLike, high: npt.ArrayLike) -> np.ndarray:
    """(8, 3) corners of an axis-aligned box, index bits (x, y, z)."""
    lo, hi = np.asarray(low, float), np.asarray(high, float)
    return np.array([[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1],
                      (hi if i & 4 else lo)[2]] for i in range(8)])


#: Faces of a box (corner indices, counter-clockwise seen from outside) and their outward axes.
BOX_FACES = (((0, 2, 6, 4), (-1, 0, 0)), ((1, 5, 7, 3), (1, 0, 0)),
             ((0, 4, 5, 1), (0, -1, 0)), ((2, 3, 7, 6), (0, 1, 0)),
             ((0, 1, 3, 2), (0, 0, -1)), ((4, 6, 7, 5), (0, 0, 1)))


def _sphere(n_lat: int = 18, n_lon: int = 36) -> np.ndarray:
    """(k, 3) points on the unit sphere (latitude rings and the poles)."""
    lat = np.linspace(-math.pi / 2, math.pi / 2, n_lat + 1)
    lon = np.linspace(0.0, 2 * math.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat[1:-1], lon, indexing="ij")
    ring = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1)
    return np.vstack([ring.reshape(-1, 3), [[0, 0, -1.0], [0, 0, 1.0]]])


_SPHERE = _sphere()
_CIRCLE = np.c_[np.cos(np.linspace(0, 2 * math.pi, 24, endpoint=False)),
                np.sin(np.linspace(0, 2 * math.pi, 24, endpoint=False))]


def _hull(points: np.ndarray) -> np.ndarray:
    """The convex hull (m, 2) of points (k, 2), counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.round(np.asarray(points, float), 3)))
    if len(pts) < 3:
        return np.asarray(pts, float)

    def half(seq):  # type: ignore[no-untyped-def]
        out: list = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.asarray(lower[:-1] + upper[:-1], float)


def _shade(color: str, factor: float) -> str:
    rgb = np.array([int(color[i:i + 2], 16) for i in (1, 3, 5)], float)
    out = np.clip(rgb * factor, 0, 255).round().astype(int)
    return "#" + "".join(f"{c:02x}" for c in out)


def _pts(xy: np.ndarray) -> list[list[float]]:
    return np.round(xy, 1).tolist()


class Scene:
    """NICO, its head, the screen and the targets seen by ``camera``.

    Args:
        robot: NICO's right arm.
        head: NICO's head.
        goals: the goal set (screen and targets).
        viewpoint_mm: (3,) the participant's eyes [mm, torso_base].
    """

    def __init__(self, robot: Robot, head: Head, goals: GoalSet, viewpoint_mm: npt.ArrayLike):
        self.robot, self.head, self.goals = robot, head, goals
        self.viewpoint_mm = np.asarray(viewpoint_mm, float)
        self.start_pose = np.asarray(goals.targets.start_pose, float)
        self.camera = self._frame_camera()

    # ----- the camera -------------------------------------------------------------------
    def _key_points(self) -> np.ndarray:
        screen = self.goals.screen
        w, h = screen.size_px
        corners = screen.px_to_mm(np.array([[0, 0], [w, 0], [w, h], [0, h]], float))
        head = self._in(self.head.eye_frame(self.head.rest_motor_deg),
                        np.asarray(HEAD_CENTRE_MM) + np.asarray(HEAD_AXES_MM) * np.vstack(
                            [np.eye(3), -np.eye(3)]))
        arm = self.robot.skeleton_mm(self.start_pose)[0]
        return np.vstack([corners, head, arm, arm * [1, -1, 1]])

    def _frame_camera(self) -> Camera:
        screen = self.goals.screen
        centre = screen.px_to_mm(np.asarray(screen.size_px, float) / 2)
        aim = 0.5 * (centre + self.head.eye_point_mm(self.head.rest_motor_deg))
        rotation = look_at(self.viewpoint_mm, aim)
        c = (self._key_points() - self.viewpoint_mm) @ rotation.T
        slope = np.abs(c[:, :2] / np.maximum(c[:, 2:], 1.0)).max(axis=0)      # tan of half-angles
        half = np.array(VIEW_SIZE, float) / 2 * FILL
        return Camera(self.viewpoint_mm, rotation, float(np.min(half / slope)))

    @property
    def screen_homography(self) -> np.ndarray:
        """(3, 3) screen pixels -> view coordinates (homogeneous)."""
        screen = self.goals.screen
        s = screen.mm_per_px
        return self.camera.homography(screen.origin_mm, screen.u * s[0], screen.v * s[1])

    def view_to_screen_px(self, view_xy: npt.ArrayLike) -> np.ndarray:
        """Screen pixels (..., 2) under view coordinates (..., 2)."""
        xy = np.asarray(view_xy, float)
        h = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1) @ np.linalg.inv(
            self.screen_homography).T
        return h[..., :2] / h[..., 2:]

    def screen_px_to_view(self, px: npt.ArrayLike) -> np.ndarray:
        """View coordinates (..., 2) of screen pixels (..., 2)."""
        xy = np.asarray(px, float)
        h = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1) @ self.screen_homography.T
        return h[..., :2] / h[..., 2:]

    # ----- shapes -----------------------------------------------------------------------
    def _poly(self, points_mm: np.ndarray, fill: str, z: float, stroke: str | None = None,
              lw: float = 1.0) -> dict:
        xy, _ = self.camera.project(points_mm)
        return {"type": "poly", "pts": _pts(xy), "fill": fill, "stroke": stroke, "lw": lw,
                "z": round(float(z), 1)}

    def _circle_on_screen(self, centre_px: np.ndarray, radius_px: float, fill: str, z: float,
                          stroke: str | None = None, lw: float = 1.0) -> dict:
        angle = np.linspace(0.0, 2 * math.pi, 40, endpoint=False)
        px = centre_px + radius_px * np.c_[np.cos(angle), np.sin(angle)]
        return self._poly(self.goals.screen.px_to_mm(px), fill, z, stroke, lw)

    def static_shapes(self) -> list[dict]:
        """The table, the screen, the targets, the torso and the left arm (they never move)."""
        screen = self.goals.screen
        w, h = screen.size_px
        corners = screen.px_to_mm(np.array([[0, 0], [w, 0], [w, h], [0, h]], float))
        top = float(corners[:, 2].min()) - 8.0                       # the table under the screen
        table = np.array([[TABLE_X_MM[1], -TABLE_HALF_WIDTH_MM, top],
                          [TABLE_X_MM[1], TABLE_HALF_WIDTH_MM, top],
                          [TABLE_X_MM[0], TABLE_HALF_WIDTH_MM, top],
                          [TABLE_X_MM[0], -TABLE_HALF_WIDTH_MM, top]])
        bezel = 18.0 / screen.mm_per_px
        bezel_px = np.array([[-bezel[0], -bezel[1]], [w + bezel[0], -bezel[1]],
                             [w + bezel[0], h + bezel[1]], [-bezel[0], h + bezel[1]]])
        shapes = [self._poly(self._clip_near(table), COLORS["table"], FAR + 3),
                  self._poly(screen.px_to_mm(bezel_px), COLORS["bezel"], FAR + 2),
                  self._poly(screen.px_to_mm(np.array([[0, 0], [w, 0], [w, h], [0, h]], float)),
                             COLORS["display"], FAR + 1)]
        shapes += [self._circle_on_screen(p, TARGET_RADIUS_PX, COLORS["target"], FAR,
                                          COLORS["target_ring"], 1.5) for p in self.goals.pixels]
        low, high = TORSO_MM
        shapes += self._box(np.eye(4), ((low[0], low[1], top), high), COLORS["body"])
        left = self.robot.skeleton_mm(self.start_pose)[0] * [1.0, -1.0, 1.0]
        shapes += self._capsules(left, COLORS["left_arm"])
        return shapes

    def _clip_near(self, points_mm: np.ndarray, near_mm: float = 150.0) -> np.ndarray:
        """A convex polygon (k, 3) cut to the part at least ``near_mm`` in front of the camera
        (the table reaches under the participant)."""
        depth = self.camera.camera_mm(points_mm)[:, 2] - near_mm
        out = []
        for i in range(len(points_mm)):
            a, b, da, db = points_mm[i], points_mm[(i + 1) % len(points_mm)], depth[i], depth[
                (i + 1) % len(points_mm)]
            if da >= 0:
                out.append(a)
            if (da >= 0) != (db >= 0):
                out.append(a + (b - a) * da / (da - db))
        return np.array(out)

    def _box(self, frame: np.ndarray, box_mm: tuple, color: str) -> list[dict]:
        """The faces of a box (given in ``frame``, a (4, 4) transform [mm]) that face the
        camera, shaded by their tilt to a light above the viewer."""
        corners = (frame @ np.c_[_box_corners(*box_mm), np.ones(8)].T).T[:, :3]
        light = self.viewpoint_mm + [0.0, 0.0, 800.0] - corners.mean(axis=0)
        light /= np.linalg.norm(light)
        depth = float(self.camera.camera_mm(corners.mean(axis=0))[2])
        shapes = []
        for index, axis in BOX_FACES:
            normal = frame[:3, :3] @ np.asarray(axis, float)
            face = corners[list(index)]
            if np.dot(face.mean(axis=0) - self.viewpoint_mm, normal) >= 0:
                continue
            shade = 0.62 + 0.38 * max(float(np.dot(normal, light)), 0.0)
            shapes.append(self._poly(face, _shade(color, shade), depth, _shade(color, 0.55), 1.0))
        return shapes

    def _capsules(self, skeleton_mm: np.ndarray, color: str) -> list[dict]:
        """The arm's segments as round-capped lines, an edge under each, width by depth."""
        shapes = []
        for i, radius in enumerate(ARM_RADII_MM):
            if radius <= 0:
                continue
            ends = skeleton_mm[i:i + 2]
            xy, depth = self.camera.project(ends)
            mid = float(depth.mean())
            width = 2 * radius * self.camera.focal / max(mid, 1.0)
            shapes.append({"type": "line", "pts": _pts(xy), "color": COLORS["arm_edge"],
                           "lw": round(width + 3.0, 2), "z": round(mid + 0.05, 2)})
            shapes.append({"type": "line", "pts": _pts(xy), "color": color,
                           "lw": round(width, 2), "z": round(mid, 2)})
        return shapes

    def head_shapes(self, head_motor_deg: npt.ArrayLike) -> list[dict]:
        """The neck, the head (an ellipsoid's outline), its face plate and eyes at a head pose
        [motor deg]; the face and eyes only where they face the camera."""
        frame = self.head.eye_frame(np.asarray(head_motor_deg, float))
        origins = self.head.joint_origins_mm
        xy, depth = self.camera.project(origins)
        neck_width = 2 * 26.0 * self.camera.focal / max(float(depth.mean()), 1.0)
        centre, axes = np.asarray(HEAD_CENTRE_MM), np.asarray(HEAD_AXES_MM)
        head_depth = float(self.camera.camera_mm(self._in(frame, centre[None]))[0, 2])
        shapes = [{"type": "line", "pts": _pts(xy), "color": COLORS["neck"],
                   "lw": round(neck_width, 2), "z": round(head_depth + 40.0, 1)}]
        unit = _SPHERE                                                  # (k, 3) on the unit sphere
        surface = self._in(frame, centre + unit * axes)
        normals = (frame[:3, :3] @ (unit / axes).T).T
        facing = np.einsum("ij,ij->i", surface - self.viewpoint_mm, normals) < 0
        outline, _ = self.camera.project(surface)
        shapes.append({"type": "poly", "pts": _pts(_hull(outline)), "fill": COLORS["body"],
                       "stroke": COLORS["body_dark"], "lw": 1.2, "z": round(head_depth, 1)})
        cap = facing & (unit[:, 0] > FACE_CAP)
        if cap.sum() >= 3:
            shapes.append({"type": "poly", "pts": _pts(_hull(outline[cap])),
                           "fill": COLORS["face"], "stroke": None, "lw": 1.0,
                           "z": round(head_depth, 1)})
        for y, z in EYES_MM:
            for radius, color in ((EYE_RADIUS_MM, COLORS["eye"]),
                                  (PUPIL_RADIUS_MM, COLORS["pupil"])):
                disc = self._on_head(y + radius * _CIRCLE[:, 0], z + radius * _CIRCLE[:, 1])
                middle = self._on_head(np.array([y]), np.array([z]))
                normal = frame[:3, :3] @ ((middle[0] - centre) / axes**2)
                if np.dot(self._in(frame, middle)[0] - self.viewpoint_mm, normal) < 0:
                    shapes.append(self._poly(self._in(frame, disc), color, head_depth))
        return shapes

    @staticmethod
    def _on_head(y_mm: np.ndarray, z_mm: np.ndarray) -> np.ndarray:
        """Points (k, 3) on the head ellipsoid's front at (y, z) [mm, eye frame]."""
        centre, axes = np.asarray(HEAD_CENTRE_MM), np.asarray(HEAD_AXES_MM)
        rest = 1.0 - ((y_mm - centre[1]) / axes[1]) ** 2 - ((z_mm - centre[2]) / axes[2]) ** 2
        x = centre[0] + axes[0] * np.sqrt(np.clip(rest, 0.0, None)) + 0.5
        return np.c_[x, y_mm, z_mm]

    @staticmethod
    def _in(frame: np.ndarray, points: np.ndarray) -> np.ndarray:
        return (frame @ np.c_[points, np.ones(len(points))].T).T[:, :3]

    def dynamic_shapes(self, arm_pose: npt.ArrayLike, head_motor_deg: npt.ArrayLike) -> list[dict]:
        """The right arm at a pose [motor deg] and the head at its pose."""
        skeleton = self.robot.skeleton_mm(np.asarray(arm_pose, float))[0]
        return self._capsules(skeleton, COLORS["arm"]) + self.head_shapes(head_motor_deg)


def sort_shapes(shapes: list[dict]) -> list[dict]:
    """Far to near (stable: the parts of one shape keep their order)."""
    return sorted(shapes, key=lambda s: -s["z"])


@dataclass(frozen=True)
class Motion:
    """A trial's motion, sampled in time.

    Attributes:
        times_s: (n,) the time of each sample from the motion's start [s].
        arm_poses: (n, dof) the right arm [motor deg].
        head_poses: (n, 2) the head [motor deg].
        head_turn_s: when the head has reached its pose [s].
        duration_s: when the motion ends (the stop) [s].
    """

    times_s: np.ndarray
    arm_poses: np.ndarray
    head_poses: np.ndarray
    head_turn_s: float
    duration_s: float


def arm_path(robot: Robot, poses: np.ndarray | None, fraction: float | None,
             start_pose: np.ndarray) -> np.ndarray:
    """The poses (k, dof) the arm plays to its stop: the trajectory's poses up to the stop
    step and the stop pose; the start pose alone when the arm stays (G)."""
    if poses is None or fraction is None or not math.isfinite(fraction):
        return start_pose[None].copy()
    stop, step, _ = stop_of(robot, poses, float(fraction))
    return np.vstack([poses[:step + 1], stop[None]])


def motion(path: np.ndarray, head_rest: np.ndarray, head_pose: np.ndarray, gaze_lead_s: float,
           duration_s: float, fps: float = FPS) -> Motion:
    """Sample the head's turn, then the arm's motion along ``path`` (k, dof) [motor deg]."""
    turn = max(float(gaze_lead_s), HEAD_TURN_MIN_S)
    move = float(duration_s) if len(path) >= 2 else 0.0
    end = turn + move
    times = np.append(np.arange(0.0, end, 1.0 / fps), end)
    share_head = np.clip(times / turn, 0.0, 1.0)[:, None]
    heads = head_rest + share_head * (head_pose - head_rest)
    if len(path) >= 2 and move > 0:
        s = np.clip((times - turn) / move, 0.0, 1.0) * (len(path) - 1)
        i = np.minimum(s.astype(int), len(path) - 2)
        arms = path[i] + (s - i)[:, None] * (path[i + 1] - path[i])
    else:
        arms = np.repeat(path[:1], len(times), axis=0)
    return Motion(times, arms, heads, turn, end)


def trial_head_pose(trial: Mapping) -> np.ndarray:
    """(2,) a trial row's head pose [motor deg]."""
    return np.array([float(trial["head_z_motor_deg"]), float(trial["head_y_motor_deg"])])
