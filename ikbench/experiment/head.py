"""NICO's head: where its eye is and which motor angles make it look at a point.

The head is a pan-tilt chain (``head_z`` about the vertical, then ``head_y`` about the neck's
left axis) carrying an eye point whose line of sight is the head's forward axis. The model is
a data file, ``urdf/nico_head.json``: NICO's ``complete.urdf`` joints (metres, radians), the
placement of that model's torso in ikbench's ``torso_base`` (x behind, y right, z up), the
motor->joint map ``joint_deg = scale * motor_deg + offset_deg`` and the motor limits, the eye
point (an estimate, see the file) and the authors' published head poses.

Interfaces speak motor degrees ``[head_z, head_y]`` and millimetres in ``torso_base``.
:meth:`Head.gaze_at` is closed-form: the first joint is solved from the eye's lateral offset,
the second from its height above the line through the tilt axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import InputError, refuse_unknown_keys
from ikbench.core.io import read_json
from ikbench.core.robot import Robot, load_robot, robots_dir
from ikbench.core.targets import load_targets
from ikbench.hw.motors import MotorConfig, parse_motor_config

#: The shipped head model (in :func:`ikbench.core.robot.robots_dir`).
HEAD_FILE = "nico_head.json"
JOINT_NAMES = ("head_z", "head_y")
#: The axes the closed-form :meth:`Head.gaze_at` is written for, each in its joint's frame.
AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0))
GAZE_AXIS = (1.0, 0.0, 0.0)
#: Keys of the head file, top level and per table ("description": free text).
TOP_KEYS = ("kind", "name", "description", "root_link", "joint_names", "motors", "joints",
            "complete_urdf", "alignment", "eye", "poses_motor_deg", "authors")
JOINT_KEYS = ("name", "scale", "offset_deg", "lower_motor_deg", "upper_motor_deg")
URDF_JOINT_KEYS = ("parent", "child", "origin_xyz_m", "origin_rpy_rad", "axis", "limits_rad")
ALIGNMENT_KEYS = ("description", "rotation_torso_base_from_complete", "r_shoulder_z_torso_base_m")
EYE_KEYS = ("description", "point_m", "gaze_axis")
POSE_KEYS = ("description", "rest", "neutral")
AUTHOR_KEYS = ("description", "recorded_motor_deg", "used_motor_deg")
#: Motor limits are checked with this slack [motor deg] (a solve exactly at a limit passes).
LIMIT_TOLERANCE_DEG = 1e-9


def _frozen(values: npt.ArrayLike) -> np.ndarray:
    array = np.array(values, dtype=float)
    array.setflags(write=False)
    return array


def _rot_z(angle_rad: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) about z by angles (N,) [rad]."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                     np.stack([zero, zero, one], -1)], -2)


def _rot_y(angle_rad: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) about y by angles (N,) [rad]."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1),
                     np.stack([-s, zero, c], -1)], -2)


@dataclass(frozen=True, eq=False)
class Head:
    """A pan-tilt head with an eye, placed in the arm's ``torso_base`` frame.

    Attributes:
        name: the model's name (``"nico_head"``).
        joint_names: ``("head_z", "head_y")``, the order of every pose.
        scale, offset_deg: (2,) motor->joint map, ``joint_deg = scale * motor_deg + offset_deg``.
        lower_motor_deg, upper_motor_deg: (2,) motor limits [motor deg].
        R_base_z: (3, 3) orientation of head_z's joint frame in ``torso_base`` (at 0).
        p_base_z_m: (3,) origin of head_z's joint frame in ``torso_base`` [m].
        p_z_y_m: (3,) origin of head_y's joint frame in head_z's (child) frame [m]; the two
            frames have the same orientation at zero angles.
        eye_head_m: (3,) the eye point in the head's frame [m] (the line of sight is the head
            frame's x axis through it).
        rest_motor_deg, neutral_motor_deg: (2,) the authors' default pose ``[0, 0]`` and their
            pointing-only pose ``[0, 23]`` (looks up, at no target).
        authors_recorded_motor_deg, authors_used_motor_deg: target id -> (2,) the authors'
            recorded and played head poses per touch point [motor deg].
        motors_file: the Dynamixel config's path (:func:`load_head_motors`).
        source: the file the head was read from.
    """

    name: str
    joint_names: tuple[str, ...]
    scale: np.ndarray
    offset_deg: np.ndarray
    lower_motor_deg: np.ndarray
    upper_motor_deg: np.ndarray
    R_base_z: np.ndarray
    p_base_z_m: np.ndarray
    p_z_y_m: np.ndarray
    eye_head_m: np.ndarray
    rest_motor_deg: np.ndarray
    neutral_motor_deg: np.ndarray
    authors_recorded_motor_deg: dict[str, np.ndarray]
    authors_used_motor_deg: dict[str, np.ndarray]
    motors_file: str
    source: str

    @property
    def joint_origins_mm(self) -> np.ndarray:
        """(2, 3) head_z's and head_y's joint origins in ``torso_base`` at the rest pose [mm]."""
        p_y_m = self.p_base_z_m + self.R_base_z @ self.p_z_y_m
        return np.stack([self.p_base_z_m, p_y_m]) * 1000.0

    @property
    def joint_axes(self) -> np.ndarray:
        """(2, 3) head_z's and head_y's unit axes in ``torso_base`` at the rest pose."""
        return np.stack([self.R_base_z @ np.array(axis) for axis in AXES])

    def to_joint_rad(self, head_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Joint angles (..., 2) [rad] of poses (..., 2) [motor deg]."""
        q_motor_deg = np.asarray(head_motor_deg, dtype=float)
        return np.radians(self.scale * q_motor_deg + self.offset_deg)

    def to_motor_deg(self, q_rad: npt.ArrayLike) -> np.ndarray:
        """Poses (..., 2) [motor deg] of joint angles (..., 2) [rad]."""
        return (np.degrees(np.asarray(q_rad, dtype=float)) - self.offset_deg) / self.scale

    def eye_frame(self, head_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Transform ``torso_base <- eye``: (4, 4) for a pose (2,), (N, 4, 4) for (N, 2).

        The eye frame has the head's orientation (x: line of sight, y: the head's left, z: its
        up) and the eye point as origin; the translation is in millimetres.
        """
        poses, single = self._poses(head_motor_deg)
        q_rad = self.to_joint_rad(poses)                                  # (N, 2)
        R_base_neck = self.R_base_z @ _rot_z(q_rad[:, 0])                 # (N, 3, 3)
        R_base_head = R_base_neck @ _rot_y(q_rad[:, 1])                   # (N, 3, 3)
        p_m = self.p_base_z_m + R_base_neck @ self.p_z_y_m + R_base_head @ self.eye_head_m
        frames = np.tile(np.eye(4), (len(poses), 1, 1))
        frames[:, :3, :3] = R_base_head
        frames[:, :3, 3] = p_m * 1000.0
        return frames[0] if single else frames

    def eye_point_mm(self, head_motor_deg: npt.ArrayLike) -> np.ndarray:
        """The eye point in ``torso_base`` [mm]: (3,) for a pose (2,), (N, 3) for (N, 2)."""
        return self.eye_frame(head_motor_deg)[..., :3, 3]

    def gaze_direction(self, head_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Unit line of sight (the head's forward axis) in ``torso_base``: (3,) or (N, 3)."""
        return self.eye_frame(head_motor_deg)[..., :3, 0]

    def gaze_at(self, point_mm: npt.ArrayLike) -> np.ndarray:
        """The pose whose line of sight passes through a point (exact, closed form).

        Args:
            point_mm: (3,) the point in ``torso_base`` [mm].

        Returns:
            (2,) ``[head_z, head_y]`` [motor deg].

        Raises:
            InputError: a point the eye cannot look at (too close to the tilt axis, behind
                the eye) or one that needs a pose outside the motor limits.
        """
        point = self._point(point_mm)
        where = f"gaze_at: point {np.round(point, 3).tolist()} mm"
        # head_z: in head_z's frame the line of sight stays in the plane y = c (the eye's
        # lateral offset from the pan axis), so the point's y there must be c.
        q = self.R_base_z.T @ (point / 1000.0 - self.p_base_z_m)
        c = float(self.p_z_y_m[1] + self.eye_head_m[1])
        radius = math.hypot(q[0], q[1])
        if radius <= abs(c):
            raise InputError(f"{where} lies on the head's vertical (head_z) axis or within "
                             f"{abs(c) * 1000:.1f} mm of it; no head_z angle aims the eye there")
        theta_z = math.atan2(q[1], q[0]) - math.asin(c / radius)
        theta_z = math.remainder(theta_z, math.tau)
        # head_y: in the tilt joint's x-z plane the line of sight passes the tilt axis at the
        # eye's height h above it; the point must lie on that line, in front of the eye.
        p_neck = _rot_z(np.array([-theta_z]))[0] @ q - self.p_z_y_m
        wx, wz = p_neck[0], p_neck[2]
        rho, h = math.hypot(wx, wz), float(self.eye_head_m[2])
        if rho <= abs(h):
            raise InputError(f"{where} lies within {abs(h) * 1000:.1f} mm of the head's tilt "
                             "(head_y) axis; no head_y angle aims the eye there")
        alpha = math.asin(h / rho)
        if rho * math.cos(alpha) <= float(self.eye_head_m[0]):
            raise InputError(f"{where} is behind the eye, which looks along the head's "
                             "forward axis; give a point in front of the eye")
        theta_y = math.remainder(alpha - math.atan2(wz, wx), math.tau)
        pose = self.to_motor_deg([theta_z, theta_y])
        self._check_limits(pose, where)
        return pose

    def angle_to_point_deg(self, head_motor_deg: npt.ArrayLike, point_mm: npt.ArrayLike) -> float:
        """Angle [deg] between the line of sight of a pose (2,) and the ray eye -> point (3,)
        [mm]; 0 when the head looks exactly at the point."""
        poses, single = self._poses(head_motor_deg)
        if not single:
            raise InputError(f"angle_to_point_deg: head_motor_deg has shape {poses.shape}; give "
                             "one pose (2,) (angles_to_points_deg takes batches)")
        return float(self.angles_to_points_deg(poses, self._point(point_mm)[None])[0])

    def angles_to_points_deg(self, head_motor_deg: npt.ArrayLike,
                             points_mm: npt.ArrayLike) -> np.ndarray:
        """Angles (N,) [deg] between the lines of sight of poses (N, 2) and the rays from the
        eye to points (N, 3) [mm] (either may be a single row, broadcast)."""
        poses, _ = self._poses(head_motor_deg)
        points = np.asarray(points_mm, dtype=float).reshape(-1, 3)
        frames = self.eye_frame(poses).reshape(-1, 4, 4)
        rays = points - frames[:, :3, 3]
        gaze = frames[:, :3, 0]
        cross = np.linalg.norm(np.cross(gaze, rays), axis=-1)
        dot = np.sum(gaze * rays, axis=-1)
        return np.degrees(np.arctan2(cross, dot))

    def _poses(self, head_motor_deg: npt.ArrayLike) -> tuple[np.ndarray, bool]:
        """Poses (N, 2) [motor deg] and whether one pose (2,) was given."""
        poses = _floats(head_motor_deg)
        if poses.ndim not in (1, 2) or poses.shape[-1] != 2 or not np.all(np.isfinite(poses)):
            raise InputError(f"head pose {head_motor_deg!r}: give finite [head_z, head_y] motor "
                             "degrees, shape (2,) or (N, 2)")
        return poses.reshape(-1, 2), poses.ndim == 1

    @staticmethod
    def _point(point_mm: npt.ArrayLike) -> np.ndarray:
        point = _floats(point_mm)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise InputError(f"point {point_mm!r}: give three finite numbers [x, y, z] in mm "
                             "(torso_base)")
        return point

    def _check_limits(self, pose: np.ndarray, where: str) -> None:
        for name, value, low, high in zip(self.joint_names, pose, self.lower_motor_deg,
                                          self.upper_motor_deg):
            if not low - LIMIT_TOLERANCE_DEG <= value <= high + LIMIT_TOLERANCE_DEG:
                raise InputError(f"{where} needs {name} = {value:.2f} motor deg, outside its "
                                 f"limits [{low:g}, {high:g}]")


def load_head(path: str | Path | None = None) -> Head:
    """Read and validate a head model (default: the shipped ``urdf/nico_head.json``).

    Raises:
        InputError: a missing or unreadable file, or an entry naming the bad value and what is
            allowed.
    """
    path = Path(path) if path is not None else robots_dir() / HEAD_FILE
    return parse_head(read_json(path, "head file"), str(path))


def parse_head(spec: Any, source: str) -> Head:
    """Validate a head model (the parsed JSON); see :func:`load_head`."""
    if not isinstance(spec, dict) or spec.get("kind") != "robot-head":
        raise InputError(f"{source}: needs a JSON object with \"kind\": \"robot-head\"")
    refuse_unknown_keys(spec, TOP_KEYS, source)
    names = tuple(_table(spec, "joint_names", source, list))
    if names != JOINT_NAMES:
        raise InputError(f"{source}: joint_names = {list(names)!r}; allowed: {list(JOINT_NAMES)}")
    joints = _parse_joints(_table(spec, "joints", source, list), source)
    urdf = _table(spec, "complete_urdf", source)
    head_z = _urdf_joint(urdf, "head_z", source, AXES[0])
    head_y = _urdf_joint(urdf, "head_y", source, AXES[1])
    shoulder = _vector(_table(urdf, "r_shoulder_z", f"{source}: complete_urdf"), "origin_xyz_m",
                       f"{source}: complete_urdf.r_shoulder_z")
    alignment = _table(spec, "alignment", source)
    refuse_unknown_keys(alignment, ALIGNMENT_KEYS, f"{source}: alignment")
    rotation = _rotation(alignment.get("rotation_torso_base_from_complete"),
                         f"{source}: alignment.rotation_torso_base_from_complete")
    shoulder_base = _vector(alignment, "r_shoulder_z_torso_base_m", f"{source}: alignment")
    translation = shoulder_base - rotation @ shoulder
    eye = _table(spec, "eye", source)
    refuse_unknown_keys(eye, EYE_KEYS, f"{source}: eye")
    if _vector(eye, "gaze_axis", f"{source}: eye").tolist() != list(GAZE_AXIS):
        raise InputError(f"{source}: eye.gaze_axis = {eye.get('gaze_axis')!r}; allowed: "
                         f"{list(GAZE_AXIS)} (the head frame's x axis)")
    poses = _table(spec, "poses_motor_deg", source)
    refuse_unknown_keys(poses, POSE_KEYS, f"{source}: poses_motor_deg")
    authors = _table(spec, "authors", source)
    refuse_unknown_keys(authors, AUTHOR_KEYS, f"{source}: authors")
    motors = spec.get("motors", "")
    if not isinstance(motors, str):
        raise InputError(f"{source}: motors = {motors!r}; give the Dynamixel config's file name")
    return Head(
        name=str(spec.get("name", Path(source).stem)), joint_names=names,
        scale=_frozen([j[0] for j in joints]), offset_deg=_frozen([j[1] for j in joints]),
        lower_motor_deg=_frozen([j[2] for j in joints]),
        upper_motor_deg=_frozen([j[3] for j in joints]),
        R_base_z=_frozen(rotation), p_base_z_m=_frozen(rotation @ head_z + translation),
        p_z_y_m=_frozen(head_y),
        eye_head_m=_frozen(_vector(eye, "point_m", f"{source}: eye")),
        rest_motor_deg=_frozen(_pose(poses, "rest", f"{source}: poses_motor_deg")),
        neutral_motor_deg=_frozen(_pose(poses, "neutral", f"{source}: poses_motor_deg")),
        authors_recorded_motor_deg=_pose_table(authors, "recorded_motor_deg", source),
        authors_used_motor_deg=_pose_table(authors, "used_motor_deg", source),
        motors_file=str(Path(source).parent / motors) if motors else "", source=source)


def load_head_motors(head: Head | None = None, path: str | Path | None = None) -> MotorConfig:
    """The head's Dynamixel config (default: the file its model names,
    ``urdf/nico_head.dynamixel.json``), in the ``ikbench.hw.motors`` format.

    Raises:
        InputError: an unreadable file, one whose motors are not exactly head_z and head_y, or
            whose angle limits differ from the head model's motor limits.
    """
    head = head or load_head()
    path = Path(path) if path is not None else Path(head.motors_file)
    spec = read_json(path, "head motor config")
    # parse_motor_config reads only the robot's joint names
    config = parse_motor_config(spec, cast(Robot, _Joints(head.joint_names)), str(path))
    if not (np.array_equal(config.lower_deg, head.lower_motor_deg)
            and np.array_equal(config.upper_deg, head.upper_motor_deg)):
        raise InputError(f"{path}: angle limits {config.lower_deg.tolist()} .. "
                         f"{config.upper_deg.tolist()} differ from {head.source}'s motor limits "
                         f"{head.lower_motor_deg.tolist()} .. {head.upper_motor_deg.tolist()}")
    return config


@dataclass(frozen=True)
class _Joints:
    joint_names: tuple[str, ...]


def authors_comparison(head: Head, robot: Robot | None = None) -> pd.DataFrame:
    """Our gaze poses at the touch points next to the authors' published head poses.

    The touch points are the forward kinematics of the robot's touch poses (its default
    targets; NICO's right arm by default). The angles are seen from the eye: the angle between
    the line of sight of the authors' pose and the ray from (that pose's) eye to the touch
    point, i.e. 0 for our :meth:`Head.gaze_at` pose.

    Returns:
        One row per touch point: target, point_{x,y,z}_mm, head_z_motor_deg and
        head_y_motor_deg (ours), authors_recorded_/authors_used_ head_z/head_y_motor_deg, and
        authors_recorded_angle_deg, authors_used_angle_deg.
    """
    robot = robot or load_robot("nico_right_arm")
    targets = load_targets(robot=robot)
    q_motor_deg = np.array([targets.touch_poses[i] for i in targets.ids], dtype=float)
    points_mm = robot.fk(q_motor_deg).point_mm                            # (T, 3)
    rows = []
    for target, point in zip(targets.ids, points_mm):
        pose = head.gaze_at(point)
        row: dict[str, Any] = {"target": int(target), "point_x_mm": point[0],
                               "point_y_mm": point[1], "point_z_mm": point[2],
                               "head_z_motor_deg": pose[0], "head_y_motor_deg": pose[1]}
        for kind, table in (("recorded", head.authors_recorded_motor_deg),
                            ("used", head.authors_used_motor_deg)):
            theirs = table.get(str(target), np.full(2, np.nan))
            row[f"authors_{kind}_head_z_motor_deg"] = theirs[0]
            row[f"authors_{kind}_head_y_motor_deg"] = theirs[1]
            row[f"authors_{kind}_angle_deg"] = (head.angle_to_point_deg(theirs, point)
                                                if np.all(np.isfinite(theirs)) else np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def _floats(values: Any) -> np.ndarray:
    """``values`` as a float array; an empty one (refused by the caller) when not numeric."""
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        return np.zeros(0)


def _table(spec: dict, key: str, where: str, kind: type = dict) -> Any:
    value = spec.get(key)
    if not isinstance(value, kind):
        raise InputError(f"{where}: {key} = {value!r}; give a JSON "
                         f"{'object' if kind is dict else 'list'}")
    return value


def _vector(table: dict, key: str, where: str) -> np.ndarray:
    value = table.get(key)
    array = np.asarray(value if isinstance(value, list) else [], dtype=object)
    if array.shape != (3,) or not all(_is_number(v) for v in array):
        raise InputError(f"{where}.{key} = {value!r}; give three finite numbers")
    return array.astype(float)


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _number(table: dict, key: str, where: str) -> float:
    value = table.get(key)
    if not _is_number(value):
        raise InputError(f"{where}.{key} = {value!r}; give a finite number")
    return float(cast(float, value))


def _parse_joints(entries: list, source: str) -> list[tuple[float, float, float, float]]:
    if [e.get("name") if isinstance(e, dict) else e for e in entries] != list(JOINT_NAMES):
        raise InputError(f"{source}: joints must be objects named {list(JOINT_NAMES)} in that "
                         "order")
    joints = []
    for entry in entries:
        where = f"{source}: joints.{entry['name']}"
        refuse_unknown_keys(entry, JOINT_KEYS, where)
        scale, offset, low, high = (_number(entry, key, where) for key in JOINT_KEYS[1:])
        if scale == 0.0:
            raise InputError(f"{where}.scale = 0; give a nonzero motor->joint scale")
        if not low < high:
            raise InputError(f"{where}: lower_motor_deg {low:g} must be below upper_motor_deg "
                             f"{high:g}")
        joints.append((scale, offset, low, high))
    return joints


def _urdf_joint(urdf: dict, name: str, source: str, axis: tuple[float, ...]) -> np.ndarray:
    """Origin (3,) [m] of a complete.urdf joint, checking its axis and zero rpy."""
    where = f"{source}: complete_urdf.{name}"
    entry = _table(urdf, name, f"{source}: complete_urdf")
    refuse_unknown_keys(entry, URDF_JOINT_KEYS, where)
    if _vector(entry, "axis", where).tolist() != list(axis):
        raise InputError(f"{where}.axis = {entry.get('axis')!r}; allowed: {list(axis)} (the "
                         "closed-form gaze_at assumes a pan about z, then a tilt about y)")
    rpy = _vector(entry, "origin_rpy_rad", where)
    if np.any(rpy != 0.0):
        raise InputError(f"{where}.origin_rpy_rad = {rpy.tolist()}; allowed: [0, 0, 0]")
    return _vector(entry, "origin_xyz_m", where)


def _rotation(value: Any, where: str) -> np.ndarray:
    try:
        matrix = np.array(value, dtype=float)
    except (TypeError, ValueError):
        matrix = np.zeros(0)
    if (matrix.shape != (3, 3) or not np.all(np.isfinite(matrix))
            or not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-9)
            or not np.isclose(np.linalg.det(matrix), 1.0)):
        raise InputError(f"{where} = {value!r}; give a 3x3 rotation matrix (orthonormal, "
                         "determinant +1)")
    return matrix


def _pose(table: dict, key: str, where: str) -> np.ndarray:
    value = table.get(key)
    if (not isinstance(value, list) or len(value) != 2
            or not all(_is_number(v) for v in value)):
        raise InputError(f"{where}.{key} = {value!r}; give [head_z, head_y] in motor degrees")
    return np.array(value, dtype=float)


def _pose_table(authors: dict, key: str, source: str) -> dict[str, np.ndarray]:
    table = _table(authors, key, f"{source}: authors")
    return {str(target): _frozen(_pose(table, target, f"{source}: authors.{key}"))
            for target in table}
