"""Figures of 6-D pose paths: the target path and the reached ones in 3-D, per-waypoint errors.

Everything is recomputed from the poses (:func:`ikbench.core.metrics.frame_errors`). Errors
are drawn on a log scale with CppFlow's validity thresholds (0.1 mm, 0.1 deg) as lines.
A task's obstacles (``Task.obstacles``) are drawn in the 3-D panel (boxes translucent, spheres
and capsules as wireframes, a half-space as a square of its surface around the path), and the
waypoints where a reached path collides (with an obstacle or the robot itself,
:mod:`ikbench.core.collision`) are marked red; a task without obstacles, or a robot without a
collision model, draws neither.
"""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.metrics import frame_errors, joint_changes
from ikbench.core.validity import (
    MAX_JOINT_CHANGE_DEG,
    MAX_POSITION_ERROR_MM,
    MAX_ROTATION_ERROR_DEG,
)
from ikbench.render.arm_plots import COLLISION_COLOR, colliding_waypoints, draw_obstacles
from ikbench.render.run_report import _equal_axes_3d, _matplotlib, frame_labels

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: Errors below this are drawn at it (a log scale has no zero) [mm or deg].
ERROR_FLOOR = 1e-7


def reached(robot: Robot, task: Task, poses_deg: npt.ArrayLike) -> dict[str, np.ndarray]:
    """{points_mm (n+1, 3), position_mm (n+1,), rotation_deg (n+1,), step_deg (n,): the
    largest revolute joint change into each waypoint (wrapped)} of poses on a task; with the
    task's obstacles and the robot's collision model also colliding (n+1,): True where the
    pose touches an obstacle or the robot itself, and when any does, collision_arm_mm
    (dof+2, 3): the arm's skeleton at the first colliding waypoint."""
    position, rotation, points = frame_errors(robot, task, poses_deg)
    revolute, _ = joint_changes(robot, poses_deg)
    step = np.abs(revolute).max(axis=1) if revolute.size else np.zeros(len(points) - 1)
    out = {"points_mm": points, "position_mm": position, "rotation_deg": rotation,
           "step_deg": step}
    colliding = colliding_waypoints(robot, poses_deg, task.required.obstacles)
    if colliding is not None:
        out["colliding"] = colliding
        if colliding.any():
            first = int(np.argmax(colliding))
            out["collision_arm_mm"] = robot.skeleton_mm(
                np.asarray(poses_deg, dtype=float)[first:first + 1])[0]
    return out


def plot_pose_path(task: Task, curves: dict[str, dict[str, np.ndarray]], title: str,
                   robot: Robot | None = None) -> Figure:
    """One pose path: the target (grey) and every reached path in 3-D; errors per waypoint.

    Args:
        task: the task (goal points [mm], goal rotations).
        curves: label -> :func:`reached` dict (e.g. one per method); may be empty. Its
            ``colliding`` waypoints (when given) are marked red.
        title: the figure's title.
        robot: the robot (axis labels and view from its config).
    """
    plt = _matplotlib()
    fig = plt.figure(figsize=(12, 6.4))
    grid = fig.add_gridspec(3, 2, width_ratios=[1.05, 1.0])
    ax3 = fig.add_subplot(grid[:, 0], projection="3d")
    goal = task.goal.points_mm
    ax3.plot(goal[:, 0], goal[:, 1], goal[:, 2], "-", color="0.6", lw=5, alpha=0.5,
             label="target path")
    ax3.scatter(*goal[0], color="k", s=25, label="first waypoint")
    colors = plt.cm.tab10(np.linspace(0, 1, 10))
    everything = [goal]
    for k, (label, curve) in enumerate(curves.items()):
        points = curve["points_mm"]
        ax3.plot(points[:, 0], points[:, 1], points[:, 2], "-", color=colors[k % 10], lw=1.2,
                 label=label)
        everything.append(points)
    obstacles = task.required.obstacles
    if obstacles:
        _, drawn = draw_obstacles(ax3, obstacles, np.vstack(everything))
        everything.append(drawn)
    everything += _mark_collisions(ax3, curves)
    everything.append(_frame_arrows(ax3, task))
    labels, (elev, azim) = frame_labels(robot)
    ax3.set_xlabel(labels[0], fontsize=8)
    ax3.set_ylabel(labels[1], fontsize=8)
    ax3.set_zlabel(labels[2], fontsize=8)
    ax3.tick_params(labelsize=7)
    _equal_axes_3d(ax3, np.vstack(everything))
    ax3.view_init(*(path_view(goal) or (elev, azim)))
    ax3.legend(loc="upper left", fontsize=7)
    ax3.set_title("end frame: target and reached (arrows: goal approach axis)", fontsize=9)
    for row, (key, unit, threshold) in enumerate((
            ("position_mm", "position error [mm]", MAX_POSITION_ERROR_MM),
            ("rotation_deg", "rotation error [deg]", MAX_ROTATION_ERROR_DEG),
            ("step_deg", "largest joint change\ninto the waypoint [deg]",
             MAX_JOINT_CHANGE_DEG))):
        ax = fig.add_subplot(grid[row, 1])
        for k, (label, curve) in enumerate(curves.items()):
            values = curve[key]
            x = np.arange(len(values)) + (1 if key == "step_deg" else 0)
            ax.plot(x, np.maximum(values, ERROR_FLOOR), "-", color=colors[k % 10], lw=1,
                    label=label)
        ax.axhline(threshold, color="r", ls="--", lw=1, label="valid below the red line")
        ax.set_yscale("log")
        if key == "step_deg":   # jumps of 180 deg and steps of 1 deg both stay readable
            ax.set_ylim(bottom=0.1)
        ax.set_ylabel(unit, fontsize=8)
        ax.grid(alpha=0.3, which="both")
        ax.tick_params(labelsize=7)
        if row == 2:
            ax.set_xlabel("waypoint", fontsize=8)
        elif row == 0:
            ax.legend(fontsize=7, ncol=3, loc="lower right")
    fig.suptitle(textwrap.fill(title, 150), fontsize=10)  # 12 in wide: ~150 characters
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    return fig


def _mark_collisions(ax, curves: dict) -> list[np.ndarray]:
    """Red crosses at every curve's colliding waypoints, one legend entry per curve that
    was checked: ``collision (N waypoints)`` (the curve's label first when there are
    several), or ``collision-free``; the arm at the first colliding waypoint faintly red.
    Returns the arms drawn (to fit the axes)."""
    arms = []
    for label, curve in curves.items():
        colliding = curve.get("colliding")
        if colliding is None:
            continue
        prefix = f"{label}: " if len(curves) > 1 else ""
        count = int(np.count_nonzero(colliding))
        if not count:
            ax.plot([], [], " ", label=f"{prefix}collision-free")
            continue
        hits = curve["points_mm"][np.asarray(colliding, dtype=bool)]
        ax.scatter(*hits.T, marker="x", s=28, color=COLLISION_COLOR, linewidths=1.4,
                   depthshade=False, zorder=5, gid="collisions",
                   label=f"{prefix}collision ({count} waypoint{'s' if count != 1 else ''})")
        arm = curve.get("collision_arm_mm")
        if arm is not None:
            first = int(np.argmax(colliding))
            ax.plot(*arm.T, "-o", color=COLLISION_COLOR, lw=2.0, ms=2.5, alpha=0.35, zorder=1,
                    gid="collision arm", label=f"{prefix}arm at the first collision "
                    f"(waypoint {first})")
            arms.append(arm)
    return arms


def path_view(points_mm: np.ndarray, tilt_deg: float = 20.0) -> tuple[float, float] | None:
    """(elevation, azimuth) [deg] that show a flat path face on, from the side of the base
    (as the robot sees it), tilted a little; None for a path that is not flat or is a point."""
    centred = points_mm - points_mm.mean(axis=0)
    _, sizes, axes = np.linalg.svd(centred, full_matrices=False)
    if sizes[0] < 1.0 or sizes[2] > 0.1 * sizes[1]:
        return None
    normal, centre = axes[2], points_mm.mean(axis=0)
    towards_base = float(np.dot(normal, -centre / max(np.linalg.norm(centre), 1e-9)))
    if abs(towards_base) > 0.3:          # the plane faces the base: look from the base's side
        normal = normal if towards_base > 0 else -normal
    elif normal[2] < 0:                  # edge-on to the base: look from above
        normal = -normal
    elev = np.degrees(np.arcsin(np.clip(normal[2], -1, 1))) + tilt_deg
    azim = np.degrees(np.arctan2(normal[1], normal[0])) + tilt_deg
    return float(np.clip(elev, -30.0, 60.0)), float(azim)


def _frame_arrows(ax, task, count: int = 12) -> np.ndarray:
    """Goal pointing axes at ``count`` waypoints along the path, 8 % of the path's size long
    (at least 50 mm, so a pure rotation shows); returns the arrow tips (count, 3) [mm]."""
    goal = task.goal.points_mm
    length = max(0.08 * float(np.ptp(goal, axis=0).max()), 50.0)
    index = np.linspace(0, len(goal) - 1, min(count, len(goal))).round().astype(int)
    d = task.goal.directions[index] * length
    ax.quiver(*goal[index].T, *d.T, color="0.3", lw=0.8, arrow_length_ratio=0.2)
    return goal[index] + d
