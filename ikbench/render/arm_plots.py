"""3-D figures of trajectories with the arm drawn: the run's overview and shared axes styling.

The arm is its skeleton (:meth:`ikbench.core.robot.Robot.skeleton_mm`): lines from the base
through every joint's origin to the end frame. Every 3-D figure here is drawn with one scale
on all three axes, a few readable millimetre ticks and the robot config's view (``[frame]
view``: elevation and azimuth, chosen to show depth), so a line that looks straight is.
"""

from __future__ import annotations

import textwrap
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.collision import collision_model

if TYPE_CHECKING:
    from collections.abc import Sequence

    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D

    from ikbench.core.obstacles import Obstacle
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: View (elevation, azimuth) [deg] of robots whose config names none: from the front-right,
#: above, for a base frame with x forward, y left, z up (matplotlib's default azimuth).
DEFAULT_VIEW = (22.0, -60.0)
#: Axis labels of robots whose config names none.
DEFAULT_LABELS = ("x [mm]", "y [mm]", "z [mm]")
GOAL_STYLE = {"color": "k", "linestyle": (0, (4, 3)), "lw": 0.9}


def matplotlib_pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def frame_labels(robot: Robot | None = None) -> tuple[list[str], tuple[float, float]]:
    """Axis labels and (elevation, azimuth) [deg] of 3-D figures from the robot config's
    ``[frame]`` (NICO: the torso frame seen from the front-right, above), else plain
    x/y/z [mm] and :data:`DEFAULT_VIEW`."""
    section = robot.config.frame if robot is not None else None
    labels = (list(section.axis_labels) if section is not None and section.axis_labels
              is not None else list(DEFAULT_LABELS))
    view = section.view if section is not None and section.view is not None else DEFAULT_VIEW
    return list(labels), (float(view[0]), float(view[1]))


def task_colors(count: int) -> list:
    """One tab10 colour per trajectory, in order (repeating after ten)."""
    plt = matplotlib_pyplot()
    return [plt.get_cmap("tab10")(k % 10) for k in range(count)]


def style_axes_3d(ax: Axes3D, points_mm: np.ndarray, robot: Robot | None = None, *,
                  fontsize: float = 8.0,
                  nbins: int = 4, zoom: float = 1.0) -> None:
    """Cube limits around ``points_mm`` (N, 3) (one scale on every axis), at most ``nbins``
    ticks per axis in whole mm, the robot's axis labels and view.

    Args:
        ax: a matplotlib ``Axes3D``.
        points_mm: everything drawn [mm], to fit.
        robot: the robot (labels and view from its config; None: plain x/y/z).
        fontsize: tick and label size [pt].
        nbins: the most ticks per axis.
        zoom: ``set_box_aspect`` zoom (1: matplotlib's).
    """
    from matplotlib.ticker import MaxNLocator

    labels, (elev, azim) = frame_labels(robot)
    lo, hi = points_mm.min(axis=0), points_mm.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 10.0) * 1.04
    for k, axis in enumerate((ax.xaxis, ax.yaxis, ax.zaxis)):
        getattr(ax, f"set_{'xyz'[k]}lim")(centre[k] - half, centre[k] + half)
        axis.set_major_locator(MaxNLocator(nbins=nbins, steps=[1, 2, 2.5, 5, 10]))
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    ax.tick_params(labelsize=fontsize, pad=0)
    for setter, label in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), labels):
        setter(label, fontsize=fontsize, labelpad=1)
    ax.view_init(elev=elev, azim=azim)


def plot_trajectories_3d(tasks: Sequence[Task], points_by_id: dict[str, np.ndarray], title: str,
                         robot: Robot | None = None,
                         poses_by_id: dict[str, np.ndarray] | None = None) -> Figure:
    """The paper's Fig. 1, readable: fingertip paths over their goal lines, with the arm.

    Each trajectory has its colour: the fingertip path solid and thick, the goal line dashed
    black on top of it (both show where they coincide), the touch point an X; the start
    point is a black dot. With ``robot`` and ``poses_by_id`` the arm is drawn faintly at the
    first pose (grey; once per distinct first pose) and at each last pose (the trajectory's
    colour), and the base origin is marked.

    Args:
        tasks: the tasks (goal points [mm]).
        points_by_id: trajectory id -> (n+1, 3) fingertip points [mm].
        title: figure title.
        robot: the robot (axis labels, view, skeleton); None: plain axes, no arm.
        poses_by_id: trajectory id -> (n+1, dof) poses [pose units], for the arm.
    """
    plt = matplotlib_pyplot()
    fig = plt.figure(figsize=(8.6, 6.4))
    ax = fig.add_subplot(projection="3d")
    ax.computed_zorder = False  # draw in zorder: goal dashes over paths, arms beneath
    fig.subplots_adjust(left=0.0, right=0.76, bottom=0.05, top=0.93)
    drawn: list[np.ndarray] = []
    firsts: list[np.ndarray] = []
    for task, color in zip(tasks, task_colors(len(tasks))):
        points, goal = points_by_id[task.name], task.goal.points_mm
        if robot is not None and poses_by_id is not None:
            poses = poses_by_id[task.name]
            arms = robot.skeleton_mm(poses[[0, -1]])
            if not any(np.allclose(arms[0], seen, atol=1e-3) for seen in firsts):
                ax.plot(*arms[0].T, "-o", color="0.4", lw=2.4, ms=3, alpha=0.35, zorder=1,
                        label=None if firsts else "arm at the first pose")
                firsts.append(arms[0])
            ax.plot(*arms[1].T, "-o", color=color, lw=2.0, ms=2.5, alpha=0.3, zorder=1)
            drawn.append(arms.reshape(-1, 3))
        ax.plot(*points.T, "-", color=color, lw=2.6, zorder=2, label=f"trajectory {task.name}")
        ax.plot(*goal.T, **GOAL_STYLE, zorder=3)
        ax.scatter(*goal[-1], marker="X", s=60, color=color, edgecolors="k", linewidths=0.6,
                   zorder=4, depthshade=False)
        drawn += [points, goal]
    ax.scatter(*tasks[0].goal.points_mm[0], marker="o", s=22, color="k", zorder=4,
               depthshade=False, label="start point")
    ax.plot([], [], **GOAL_STYLE, label="goal line")
    ax.scatter([], [], marker="X", s=60, color="w", edgecolors="k", label="touch point")
    if firsts and robot is not None:  # arms are drawn only with the robot
        ax.scatter(0, 0, 0, marker="s", s=20, color="0.3", zorder=4, depthshade=False,
                   label=f"base origin ({robot.root_link})")
        ax.plot([], [], "-o", color="0.5", lw=2.0, ms=2.5, alpha=0.35,
                label="arm at the last pose")
        drawn.append(np.zeros((1, 3)))
    style_axes_3d(ax, np.vstack(drawn), robot, zoom=1.05)
    fig.suptitle(textwrap.fill(title, 100), fontsize=10, x=0.02, ha="left")
    fig.legend(*ax.get_legend_handles_labels(), loc="center left", bbox_to_anchor=(0.77, 0.5),
               fontsize=8, frameon=False)
    fig.text(0.01, 0.012, "solid: fingertip path; dashed: goal line; X: touch point; faint: "
             "the arm (base, joint origins, end frame) at the first and last poses",
             fontsize=7.5, color="0.25")
    return fig


# ----- obstacles and collisions (Task.obstacles, ikbench.core.collision) ----------------------

#: Obstacles in the figures: translucent brown faces, darker edges and wireframes.
OBSTACLE_FACE = (0.60, 0.45, 0.30, 0.16)
OBSTACLE_EDGE = (0.45, 0.30, 0.15, 0.85)
#: Colliding waypoints and arms.
COLLISION_COLOR = "red"
#: A box's faces as corner indices (corner k: its x, y, z half-size signs from k's bits 2, 1,
#: 0, see :func:`box_corners`), each face a cycle.
BOX_FACES = np.array([[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4],
                      [1, 3, 7, 5]])


def box_corners(obstacle: Obstacle) -> np.ndarray:
    """(8, 3) [mm] a box obstacle's corners in the base frame (see :data:`BOX_FACES`)."""
    bits = (np.arange(8)[:, None] >> np.array([2, 1, 0])) & 1
    local = (bits - 0.5) * np.asarray(obstacle.size_mm, dtype=float)
    return local @ np.asarray(obstacle.rotation, dtype=float).T + obstacle.center_mm


def halfspace_patch(obstacle: Obstacle, around_mm: np.ndarray | None, minimum_mm: float = 100.0
                    ) -> np.ndarray:
    """(4, 3) [mm] a square of a half-space's surface around ``around_mm`` (N, 3): centred
    where their centre projects onto the surface, 1.2 times their extent wide (at least
    ``2 * minimum_mm``)."""
    n = np.asarray(obstacle.normal, dtype=float)
    R = np.asarray(obstacle.rotation, dtype=float)  # its z is the normal
    if around_mm is None or not len(around_mm):
        around_mm = np.asarray(obstacle.center_mm, dtype=float)[None]
    centre = around_mm.mean(axis=0)
    centre = centre - float(np.dot(centre - obstacle.center_mm, n)) * n
    half = max(0.6 * float(np.ptp(around_mm, axis=0).max()), minimum_mm)
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * half
    return centre + square @ R[:, :2].T


def _round_polylines(centre, rotation, radius: float, half_length: float = 0.0,
                     count: int = 6, samples: int = 33) -> list[np.ndarray]:
    """Wireframe of a sphere (``half_length`` 0) or a capsule along the local z: ``count``
    meridians through both poles and the equator (and both end circles of a capsule)."""
    t = np.linspace(0.0, 2.0 * np.pi, samples)
    lines = []
    for a in np.linspace(0.0, np.pi, count, endpoint=False):  # meridians, a stadium each
        u = np.array([np.cos(a), np.sin(a), 0.0])
        s, c = np.sin(t), np.cos(t)
        offset = np.where(c >= 0, half_length, -half_length)
        lines.append(radius * (s[:, None] * u + c[:, None] * [0.0, 0.0, 1.0])
                     + offset[:, None] * [0.0, 0.0, 1.0])
    for z in ([0.0] if half_length == 0.0 else [-half_length, half_length]):
        lines.append(np.column_stack([radius * np.cos(t), radius * np.sin(t),
                                      np.full_like(t, z)]))
    R, c0 = np.asarray(rotation, dtype=float), np.asarray(centre, dtype=float)
    return [line @ R.T + c0 for line in lines]


def draw_obstacles(ax: Axes3D, obstacles: Sequence[Obstacle],
                   around_mm: np.ndarray | None = None, *, label: bool = True,
                   zorder: float = 0.5) -> tuple[list, np.ndarray]:
    """Draw obstacles on a 3-D axes: boxes and half-spaces (a square of the surface around
    ``around_mm``, :func:`halfspace_patch`) as translucent faces, spheres and capsules as
    wireframes; a legend entry ``obstacle`` (``obstacles (k)``) when ``label``.

    Returns:
        (the artists added, (M, 3) the points drawn [mm], to fit the axes).
    """
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    artists: list = []
    points: list = []
    for obstacle in obstacles:
        if obstacle.kind in ("box", "halfspace"):
            if obstacle.kind == "box":
                corners = box_corners(obstacle)
                faces = [corners[f] for f in BOX_FACES]
            else:
                faces = [halfspace_patch(obstacle, around_mm)]
            art = Poly3DCollection(faces, facecolors=[OBSTACLE_FACE], edgecolors=[OBSTACLE_EDGE],
                                   linewidths=0.8, zorder=zorder)
            ax.add_collection3d(art)
            points += faces
        else:
            half = 0.5 * obstacle.length_mm if obstacle.kind == "capsule" else 0.0
            lines = _round_polylines(obstacle.center_mm, obstacle.rotation, obstacle.radius_mm,
                                     half)
            art = Line3DCollection(lines, colors=[OBSTACLE_EDGE], linewidths=0.6,
                                   zorder=zorder)
            ax.add_collection3d(art)
            points += lines
        art.set_gid(f"obstacle:{obstacle.name}")
        artists.append(art)
    if artists and label:  # one legend entry for all of them
        artists[0].set_label("obstacle" if len(artists) == 1 else
                             f"obstacles ({len(artists)})")
    return artists, (np.vstack(points) if points else np.zeros((0, 3)))


def colliding_waypoints(robot: Robot | None, poses: npt.ArrayLike,
                        obstacles: Sequence[Obstacle]) -> np.ndarray | None:
    """(N,) True at the poses (N, dof) [pose units] that touch an obstacle or the robot
    itself (:meth:`ikbench.core.collision.CollisionModel.check`); None without obstacles
    or without the robot's collision model (nothing checked, nothing to draw)."""
    if robot is None or not obstacles:
        return None

    model = collision_model(robot)
    if model is None:
        return None
    report = model.check(np.atleast_2d(np.asarray(poses, dtype=float)), tuple(obstacles))
    return np.asarray(report.env_colliding | report.self_colliding, dtype=bool)
