"""The Table 1/2 figures of many line trajectories at once (vectorised numpy).

:func:`line_metrics` gives, for B line tasks, exactly the figures
:func:`ikbench.core.metrics.trajectory_metrics` gives one at a time (same definitions, same
keys), from the fingertip points and directions the caller already has: a dataset of a million
trajectories is measured in seconds instead of hours. The tests check it against
:mod:`ikbench.core.metrics` trajectory by trajectory.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Joint steps smaller than this [deg] do not count as a direction (as in metrics.smoothness).
STILL_DEG = 1e-3


def line_metrics(points_mm: npt.ArrayLike, directions: npt.ArrayLike, poses: npt.ArrayLike,
                 start_point_mm: npt.ArrayLike, end_point_mm: npt.ArrayLike,
                 start_pose: npt.ArrayLike, end_pose: npt.ArrayLike
                 ) -> dict[str, np.ndarray]:
    """Figures of B line trajectories against their lines from P^s to P^e.

    Args:
        points_mm: (B, N, 3) fingertip points [mm].
        directions: (B, N, 3) pointing directions (normalised here).
        poses: (B, N, dof) poses [pose units].
        start_point_mm / end_point_mm: (B, 3) P^s and P^e [mm]; the goal direction is the
            unit vector from P^s to P^e.
        start_pose / end_pose: (B, dof) the pinned start and touch poses.

    Returns:
        The keys of :func:`ikbench.core.metrics.trajectory_metrics`, each a (B,) array:
        line distance mean/std [mm], pointing deviation mean/std [deg], start/end point
        errors [mm], start/end pose errors [deg] and the smoothness figures.
    """
    points = np.asarray(points_mm, dtype=float)
    poses = np.asarray(poses, dtype=float)
    start = np.asarray(start_point_mm, dtype=float)[:, None, :]
    end = np.asarray(end_point_mm, dtype=float)[:, None, :]
    axis = (end - start) / np.linalg.norm(end - start, axis=-1, keepdims=True)
    rel = points - start
    distances = np.linalg.norm(rel - np.sum(rel * axis, axis=-1, keepdims=True) * axis, axis=-1)
    v = np.asarray(directions, dtype=float)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    g = np.broadcast_to(axis, v.shape)
    deviations = np.degrees(np.arctan2(np.linalg.norm(np.cross(v, g), axis=-1),
                                       np.sum(v * g, axis=-1)))
    return {
        "line_distance_mean_mm": distances.mean(axis=1),
        "line_distance_std_mm": distances.std(axis=1),
        "pointing_deviation_mean_deg": deviations.mean(axis=1),
        "pointing_deviation_std_deg": deviations.std(axis=1),
        "start_point_error_mm": np.linalg.norm(points[:, 0] - start[:, 0], axis=-1),
        "end_point_error_mm": np.linalg.norm(points[:, -1] - end[:, 0], axis=-1),
        "start_pose_error_deg": np.max(np.abs(poses[:, 0] - start_pose), axis=-1),
        "end_pose_error_deg": np.max(np.abs(poses[:, -1] - end_pose), axis=-1),
        **smoothness(poses),
    }


def smoothness(poses: npt.ArrayLike) -> dict[str, np.ndarray]:
    """:func:`ikbench.core.metrics.smoothness` of B trajectories (B, N, dof), (B,) each."""
    poses = np.asarray(poses, dtype=float)
    d1 = np.diff(poses, axis=1)
    d3 = np.diff(poses, n=3, axis=1)
    return {
        "mean_sq_joint_step_deg2": np.mean(d1**2, axis=(1, 2)),
        "max_joint_step_deg": np.max(np.abs(d1), axis=(1, 2)),
        "mean_sq_jerk_deg2": (np.mean(d3**2, axis=(1, 2)) if d3.shape[1]
                              else np.zeros(len(poses))),
        "velocity_sign_changes": velocity_sign_changes(d1),
    }


def velocity_sign_changes(steps: npt.ArrayLike) -> np.ndarray:
    """Sign changes of joint velocity summed over joints, ignoring steps below
    :data:`STILL_DEG`, for steps (B, n, dof); (B,) integers."""
    signs = np.sign(np.where(np.abs(steps) < STILL_DEG, 0.0, steps))
    last = np.zeros(signs[:, 0].shape)              # last non-zero sign per joint (0: none)
    changes = np.zeros(len(signs), dtype=np.int64)
    for i in range(signs.shape[1]):
        s = signs[:, i]
        changes += np.sum((s != 0) & (last != 0) & (s != last), axis=-1)
        last = np.where(s != 0, s, last)
    return changes
