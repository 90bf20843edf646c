"""Figures and Markdown reports of a method's run, from the written trajectories.

Every number and figure here is computed by :mod:`ikbench.core.metrics` from the poses read back
from the trajectory CSVs. Paper values appear only in columns labelled as the paper's.
"""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.metrics import criterion2_mm
from ikbench.render.arm_plots import (  # noqa: F401  (plot_trajectories_3d: re-exported)
    frame_labels,
    matplotlib_pyplot,
    plot_trajectories_3d,
    style_axes_3d,
)
from ikbench.render.sections import add_report_section, report_sections  # noqa: F401

if TYPE_CHECKING:
    from collections.abc import Sequence

    from matplotlib.figure import Figure

    from ikbench.core.task import Task

TABLE_COLUMNS = [
    "trajectory", "method", "iterations", "duration_s", "loss",
    "line_distance_mean_mm", "line_distance_std_mm",
    "pointing_deviation_mean_deg", "pointing_deviation_std_deg",
    "start_point_error_mm", "end_point_error_mm", "start_pose_error_deg", "end_pose_error_deg",
]
#: The table of a general shape (polyline, spline, letter); see ikbench.core.metrics.shape_metrics.
SHAPE_TABLE_COLUMNS = [
    "trajectory", "method", "iterations", "duration_s", "loss",
    "drawn", "curve_distance_mean_mm", "curve_distance_std_mm", "curve_distance_max_mm",
    "stroke_coverage_pct", "point_error_mean_mm", "point_error_max_mm",
    "pointing_deviation_mean_deg", "pointing_deviation_std_deg", "pointing_deviation_max_deg",
    "mean_sq_joint_step_deg2", "max_joint_step_deg",
]
#: The table of a 6-D pose path (a Cartesian path problem); see
#: ikbench.core.metrics.frame_metrics. time_to_valid_s: duration_s of a valid solution, else
#: empty (every method stops at its first valid solution or gives up).
FRAME_TABLE_COLUMNS = [
    "trajectory", "method", "iterations", "duration_s", "loss",
    "position_error_mean_mm", "position_error_max_mm",
    "rotation_error_mean_deg", "rotation_error_max_deg",
    "max_joint_change_deg", "max_joint_change_mm",
    "joint_path_length_deg", "prismatic_path_length_mm", "cartesian_path_length_mm",
    "valid", "time_to_valid_s",
]


def _matplotlib():
    return matplotlib_pyplot()


def plot_shapes(tasks: Sequence[Task], points_by_id: dict[str, np.ndarray], title: str
                ) -> Figure:
    """Drawn curves over their target curves: on the drawing plane (top) and in 3-D (bottom).

    One column per task. The plane is the task curve's own (a letter's frontal plane, seen
    from the front) or the best-fit plane of the target curve.

    Args:
        tasks: tasks with a target ``curve``.
        points_by_id: trajectory id -> (n+1, 3) fingertip points [mm].
        title: figure title.
    """
    plt = _matplotlib()
    fig = plt.figure(figsize=(4.2 * len(tasks), 8.4))
    for k, task in enumerate(tasks):
        curve, points = task.goal.curve, points_by_id[task.name]
        assert curve is not None, f"task {task.name} has no target curve"
        plane = curve.drawing_plane()
        ax = fig.add_subplot(2, len(tasks), k + 1)
        vertices, pen = curve.path()
        for j in np.flatnonzero(~pen):  # pen-up moves
            ax.plot(*plane.project(vertices[j:j + 2]).T, ":", color="0.6", lw=1)
        for stroke in curve.strokes_mm:
            ax.plot(*plane.project(stroke).T, "-", color="0.75", lw=4, solid_capstyle="round")
        drawn = plane.project(points)
        ax.plot(*drawn.T, "-", color="tab:blue", lw=1)
        ax.plot(*drawn[task.goal.pen_down].T, "o", color="tab:blue", ms=2.5)
        ax.plot(*drawn[~task.goal.pen_down].T, "o", mfc="none", color="tab:blue", ms=3)
        ax.plot(0, 0, "k+", ms=10)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("u [mm] (right, seen from the front)")
        ax.set_ylabel("v [mm] (up)")
        ax.set_title(f"{task.goal.shape} {task.name}: drawing plane")
        ax3 = fig.add_subplot(2, len(tasks), len(tasks) + k + 1, projection="3d")
        for stroke in curve.strokes_mm:
            ax3.plot(*stroke.T, "-", color="0.6", lw=2)
        ax3.plot(*points.T, "-o", color="tab:blue", ms=1.5, lw=1)
        ax3.set_xlabel("x [mm]")
        ax3.set_ylabel("y [mm]")
        ax3.set_zlabel("z [mm]")
        _equal_axes_3d(ax3, np.vstack([points, *curve.strokes_mm]))
        ax3.view_init(elev=20, azim=-150)
        ax3.set_title(f"{task.name}: 3-D (torso frame)")
    width = max(40, int(14 * 4.2 * len(tasks)))  # characters of fontsize 9 the figure holds
    fig.suptitle(textwrap.fill(f"{title}", width) + "\n" + textwrap.fill(
        "grey: target curve (dotted: pen-up move), blue: fingertip (hollow: pen up), +: plane "
        "origin (letters: fingertip at the start pose)", width), fontsize=9)
    fig.tight_layout()
    return fig


def _equal_axes_3d(ax, points_mm) -> None:
    """One scale on all three axes (a flat curve looks flat; deviations keep their size)."""
    lo, hi = points_mm.min(axis=0), points_mm.max(axis=0)
    centre, half = (lo + hi) / 2, max(np.max(hi - lo) / 2, 1.0)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))


def plot_pointing_error(tasks: Sequence[Task], points_by_id: dict[str, np.ndarray], title: str
                        ) -> Figure:
    """The paper's Fig. 2: criterion 2 [mm] per step for every trajectory."""
    plt = _matplotlib()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for task in tasks:
        values = criterion2_mm(points_by_id[task.name], task.goal.end_point_mm)
        ax.plot(np.arange(len(values)), values, "-", lw=1.3, label=f"trajectory {task.name}")
    ax.set_xlabel("step")
    ax.set_ylabel("criterion 2: pointing error [mm]")
    ax.set_yscale("symlog", linthresh=10)
    ax.grid(alpha=0.3)
    ax.set_title(f"{textwrap.fill(title, 90)}\ndistance of the touch point from where the "
                 "last 10 segments aim, on the touch plane", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    return fig


def _fmt(value, digits=2):
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{value:.{digits}f}"


def markdown_table(frame: pd.DataFrame, digits: dict | None = None) -> str:
    """A DataFrame as a Markdown table (floats to 2 decimals unless ``digits`` says)."""
    digits = digits or {}
    lines = ["| " + " | ".join(frame.columns) + " |",
             "|" + "|".join("---" for _ in frame.columns) + "|"]
    for _, row in frame.iterrows():
        cells = [_fmt(row[c], digits.get(c, 2)) if not isinstance(row[c], str) else row[c]
                 for c in frame.columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
