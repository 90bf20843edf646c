"""Rotation helpers the library adapters share (numpy only; rotations are (3, 3) matrices whose
columns are the rotated frame's axes)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Below this |a x b| (unit vectors) two directions count as parallel.
PARALLEL_EPS = 1e-12


def skew(v: npt.ArrayLike) -> np.ndarray:
    """(3, 3) matrix of the cross product with ``v`` (3,)."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_about(axis: npt.ArrayLike, angle_rad: float) -> np.ndarray:
    """Rotation by ``angle_rad`` about ``axis`` (3,) (Rodrigues)."""
    k = skew(np.asarray(axis, dtype=float) / np.linalg.norm(axis))
    return np.eye(3) + np.sin(angle_rad) * k + (1.0 - np.cos(angle_rad)) * (k @ k)


def rotation_between(a: npt.ArrayLike, b: npt.ArrayLike) -> np.ndarray:
    """The smallest rotation R with R a = b for directions ``a``, ``b`` (3,); for opposite
    directions a half turn about an axis orthogonal to ``a``, chosen deterministically."""
    a = np.asarray(a, dtype=float) / np.linalg.norm(a)
    b = np.asarray(b, dtype=float) / np.linalg.norm(b)
    cross = np.cross(a, b)
    sin = float(np.linalg.norm(cross))
    cos = float(a @ b)
    if sin < PARALLEL_EPS:
        if cos > 0:
            return np.eye(3)
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        axis = np.cross(a, helper)
        return rotation_about(axis, np.pi)
    return rotation_about(cross, float(np.arctan2(sin, cos)))


def closest_rotation_with_axis(rotation: np.ndarray, axis_local: npt.ArrayLike,
                               direction: npt.ArrayLike) -> np.ndarray:
    """The rotation nearest ``rotation`` (3, 3) whose local ``axis_local`` (3,) points along
    ``direction`` (3,): ``rotation`` tilted by the smallest angle, its roll kept."""
    rotation = np.asarray(rotation, dtype=float)
    return rotation_between(rotation @ np.asarray(axis_local, dtype=float), direction) @ rotation


def roll_between_rad(a: np.ndarray, b: np.ndarray, axis_local: npt.ArrayLike) -> float:
    """Signed angle [rad] in (-pi, pi] of the turn about the local ``axis_local`` (3,, unit)
    that takes rotation ``a`` (3, 3) to ``b`` (3, 3), whose ``axis_local`` point the same way:
    ``b = a @ rotation_about(axis_local, angle)``."""
    relative = np.asarray(a, dtype=float).T @ np.asarray(b, dtype=float)
    axis = np.asarray(axis_local, dtype=float)
    vee = np.array([relative[2, 1] - relative[1, 2], relative[0, 2] - relative[2, 0],
                    relative[1, 0] - relative[0, 1]])
    return float(np.arctan2(axis @ vee / 2.0, (np.trace(relative) - 1.0) / 2.0))


def frame_with_z_on(axis_local: npt.ArrayLike) -> np.ndarray:
    """A constant rotation R_EP (end frame E -> a pointing frame P) whose z-axis is
    ``axis_local`` (3,): libraries that free the roll about a frame's z-axis act on
    P = E R_EP. The identity for the default axis +z."""
    return rotation_between([0.0, 0.0, 1.0], axis_local)


def angle_between_rad(u: np.ndarray, v: np.ndarray) -> float:
    """Angle [rad] between two vectors (3,) (atan2 form, accurate near 0)."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), u @ v))


def rotation_angle_rad(a: np.ndarray, b: np.ndarray) -> float:
    """Angle [rad] of the relative rotation a^T b of two rotations (3, 3)."""
    cos = (np.trace(np.asarray(a, dtype=float).T @ np.asarray(b, dtype=float)) - 1.0) / 2.0
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


def quaternion_xyzw(rotation: npt.ArrayLike) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation (3, 3) (Shepperd: the largest of w, x, y, z
    is computed from the trace, the others from it)."""
    r = np.asarray(rotation, dtype=float)
    diagonal = [np.trace(r), r[0, 0], r[1, 1], r[2, 2]]
    k = int(np.argmax(diagonal))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + diagonal[0])
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    elif k == 1:
        s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif k == 2:
        s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4, (r[1, 0] - r[0, 1]) / s]
    out = np.array(q) / np.linalg.norm(q)
    return float(out[0]), float(out[1]), float(out[2]), float(out[3])
