"""The arm playing a run's trajectories: one animated GIF per run folder (``animation.gif``).

One small 3-D panel per trajectory, all on the same clock: the arm skeleton
(:meth:`ikbench.core.robot.Robot.skeleton_mm`), the goal path (dashed black, whole), the
fingertip's path so far (the trajectory's colour, as in ``trajectories_3d.png``) and the
current goal point (hollow circle). A task's obstacles (``Task.obstacles``) are drawn in
its panel (:func:`ikbench.render.arm_plots.draw_obstacles`), and the arm turns red in the
frames where it touches one or itself (:mod:`ikbench.core.collision`; checked only for tasks
with obstacles, on robots with a collision model). Every panel has the same limits and the
robot config's view. The GIF plays at the trajectory's real speed: frames are ``stride`` steps apart
(at most ``max_frames`` frames), each shown ``stride * T / n`` seconds, GIF delays rounded to
10 ms; the first frame is held 0.5 s and the last 1 s before it loops. Under ``timing``
``min-jerk`` or ``topp`` (:mod:`ikbench.core.timing`) frames are evenly apart in time (at most
``max_frames``) and each panel shows the solved pose nearest in time.

Cheap by construction: the axes, panes, ticks and goal paths are drawn once; each frame
restores that background and draws only the moving lines (matplotlib blitting on the Agg
canvas), and Pillow writes the frames with one shared palette.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.io import atomic_path
from ikbench.core.timing import check_timing, retime
from ikbench.render.arm_plots import (
    COLLISION_COLOR,
    GOAL_STYLE,
    colliding_waypoints,
    draw_obstacles,
    frame_labels,
    matplotlib_pyplot,
    style_axes_3d,
    task_colors,
)

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.core.timing import Limits

#: File name of a run folder's animation.
#: The most frames of one GIF (a 50-step trajectory plays every second step).
MAX_FRAMES = 26
HOLD_FIRST_S, HOLD_LAST_S = 0.5, 1.0
#: Colours in the GIF's shared palette.
PALETTE_COLORS = 96
#: The arm's colour, and in the frames where it collides.
ARM_COLOR, ARM_COLLIDING_COLOR = "0.2", COLLISION_COLOR


def frame_steps(steps: int, max_frames: int = MAX_FRAMES) -> tuple[np.ndarray, int]:
    """The steps shown (the first and last always) and the stride between them.

    Args:
        steps: number of segments n of the longest trajectory.
        max_frames: the most frames.
    """
    stride = max(1, math.ceil(steps / max(max_frames - 1, 1)))
    shown = np.arange(0, steps + 1, stride)
    return (shown if shown[-1] == steps else np.append(shown, steps)), stride


def _grid(count: int) -> tuple[int, int]:
    cols = count if count <= 4 else math.ceil(count / 2) if count <= 8 else 4
    return math.ceil(count / cols), cols


def _goal_paths(task) -> list[np.ndarray]:
    """The goal path as polylines [mm]: a curve's strokes (pen-up moves left out), else the
    goal points."""
    if task.goal.curve is not None:
        return list(task.goal.curve.strokes_mm)
    return [task.goal.points_mm]


class _Panel:
    """The moving artists of one trajectory's panel."""

    def __init__(self, ax, task, poses, robot, color):
        self.task, self.arms = task, robot.skeleton_mm(poses)  # (n+1, dof+2, 3)
        self.tip = self.arms[:, -1]
        #: (n+1,) True where the pose collides; None: not checked (no obstacles or model)
        self.colliding = colliding_waypoints(robot, poses, task.required.obstacles)
        (self.path,) = ax.plot([], [], [], "-", color=color, lw=2.4, zorder=2, animated=True)
        self.goals = [ax.plot(*path.T, **GOAL_STYLE, zorder=2, animated=True)[0]
                      for path in _goal_paths(task)]
        (self.arm,) = ax.plot([], [], [], "-o", color=ARM_COLOR, lw=2.6, ms=3, zorder=3,
                              animated=True)
        (self.goal,) = ax.plot([], [], [], "o", mfc="none", mec="k", ms=5, zorder=4,
                               animated=True)
        self.ax = ax

    def draw(self, t_s: float, dt_s: float, timed=None) -> None:
        if timed is not None:
            k = timed.index_at(t_s)
        else:
            k = min(int(round(t_s / dt_s)), len(self.tip) - 1) if dt_s > 0 else 0
        self.path.set_data_3d(*self.tip[:k + 1].T)
        self.arm.set_data_3d(*self.arms[k].T)
        hit = self.colliding is not None and bool(self.colliding[k])
        self.arm.set_color(ARM_COLLIDING_COLOR if hit else ARM_COLOR)
        goal = self.task.goal.points_mm[min(k, len(self.task.goal.points_mm) - 1)]
        self.goal.set_data_3d([goal[0]], [goal[1]], [goal[2]])
        for artist in (self.path, *self.goals, self.arm, self.goal):  # goal over the path
            self.ax.draw_artist(artist)


def render_frames(robot: Robot, tasks: Sequence[Task], poses_by_id: dict, title: str,
                  duration_s: float, max_frames: int = MAX_FRAMES, dpi: int = 80,
                  timing: str = "constant", limits: Limits | None = None
                  ) -> tuple[list[np.ndarray], list[int]]:
    """Frames (RGB uint8 arrays) and their durations [ms] of the run's animation.

    Args:
        robot: the robot (skeleton, labels, view).
        tasks: the solved tasks, one panel each.
        poses_by_id: trajectory id -> (n+1, dof) poses [pose units].
        title: the run's title (first line of the figure).
        duration_s: T [s] of every trajectory (poses T/n apart; ``min-jerk``: its T).
        max_frames: the most frames.
        dpi: pixels per inch of the frames.
        timing: ``constant``, ``min-jerk`` or ``topp`` (see the module doc).
        limits: the joint limits for ``topp``.
    """

    check_timing(timing)
    plt = matplotlib_pyplot()
    rows, cols = _grid(len(tasks))
    panel_in = 2.7 if len(tasks) > 2 else 3.6
    notes_in = 0.12 if any(t.required.obstacles for t in tasks) else 0.0  # 3rd line
    height_in = rows * (panel_in + 0.2) + 0.4 + notes_in
    fig = plt.figure(figsize=(cols * panel_in, height_in), dpi=dpi)
    fig.subplots_adjust(left=0.0, right=0.97, bottom=0.25 / height_in,
                        top=1 - (0.45 + notes_in) / height_in, wspace=0.05, hspace=0.2)
    panels = []
    for k, (task, color) in enumerate(zip(tasks, task_colors(len(tasks)))):
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        ax.computed_zorder = False
        panels.append(_Panel(ax, task, poses_by_id[task.name], robot, color))
    drawn = []
    for panel in panels:  # static: drawn once, into the background
        obstacles = panel.task.required.obstacles
        if obstacles:
            around = np.vstack([panel.arms.reshape(-1, 3), *_goal_paths(panel.task)])
            drawn.append(draw_obstacles(panel.ax, obstacles, around, label=False)[1])
    fit = np.vstack([p.arms.reshape(-1, 3) for p in panels]
                    + [g for t in tasks for g in _goal_paths(t)] + drawn)
    for panel in panels:
        style_axes_3d(panel.ax, fit, robot, fontsize=6, nbins=3, zoom=1.0)
        panel.ax.set(xlabel="", ylabel="", zlabel="")  # named once, in the caption
        for axis in (panel.ax.xaxis, panel.ax.yaxis, panel.ax.zaxis):
            axis.set_pane_color((1.0, 1.0, 1.0, 0.0))  # white: fewer colours, smaller GIF
        panel.ax.set_title(f"trajectory {panel.task.name}", fontsize=8, pad=-6)
    labels, _ = frame_labels(robot)
    notes = ("\nbrown: obstacles" if drawn else "") + (
        "; red arm: in collision" if any(p.colliding is not None for p in panels) else "")
    fig.suptitle(f"{textwrap.shorten(title, 70)}\n{', '.join(labels)}; dashed: goal path, "
                 f"o: current goal point{notes}", fontsize=7, x=0.01, ha="left", y=0.995)
    clock = fig.text(0.99, 0.995, "", fontsize=8, ha="right", va="top", animated=True)
    steps = max(len(p.tip) - 1 for p in panels)
    shown, stride = frame_steps(steps, max_frames)
    dt_s = duration_s / steps
    timed = _timings(robot, tasks, poses_by_id, timing, duration_s, limits)
    fig.canvas.draw()
    background = fig.canvas.copy_from_bbox(fig.bbox)
    frames = []
    if timed is None:
        instants = [(step * dt_s, f"t = {step * dt_s:.2f} s / {duration_s:g} s (step {step} / "
                     f"{steps})") for step in shown]
    else:
        total = max(t.duration_s for t in timed)
        instants = [(t, f"t = {t:.2f} s / {total:.3g} s ({timing})")
                    for t in np.linspace(0.0, total, max(2, max_frames))]
    for t_s, text in instants:
        fig.canvas.restore_region(background)
        for k, panel in enumerate(panels):
            panel.draw(t_s, dt_s, None if timed is None else timed[k])
        clock.set_text(text)
        fig.draw_artist(clock)
        frames.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
    plt.close(fig)
    frame_s = stride * dt_s if timed is None else instants[1][0] - instants[0][0]
    frame_ms = max(10, int(round(frame_s * 100)) * 10)
    durations = [frame_ms] * len(frames)
    durations[0] += int(HOLD_FIRST_S * 1000)
    durations[-1] += int(HOLD_LAST_S * 1000)
    return frames, durations


def _timings(robot, tasks, poses_by_id, timing, duration_s, limits):
    """The TimedPath of every panel, or None for the paper's timing."""
    if timing == "constant":
        return None

    return [retime(robot, poses_by_id[task.name], timing, duration_s=duration_s, limits=limits)
            for task in tasks]


def save_gif(path: str | os.PathLike, frames: Sequence[np.ndarray], durations: Sequence[int]
             ) -> Path:
    """Write frames (RGB arrays) as a looping GIF atomically, one palette for all frames."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    # a few frames across the whole clip, so a colour seen in some frames only (the red arm
    # of a collision) gets its palette entry
    sample = np.vstack([frames[k] for k in sorted({0, *np.linspace(0, len(frames) - 1, 8)
                                                   .round().astype(int).tolist()})])
    palette = Image.fromarray(sample).quantize(PALETTE_COLORS, method=Image.Quantize.FASTOCTREE)
    quantized = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    with atomic_path(path) as tmp:
        quantized[0].save(tmp, format="GIF", save_all=True, append_images=quantized[1:],
                          duration=durations, loop=0)
    return Path(path)


def write_animation(path: str | os.PathLike, robot: Robot, tasks: Sequence[Task],
                    poses_by_id: dict, title: str, duration_s: float,
                    timing: str = "constant", limits: Limits | None = None) -> Path:
    """Render the run's animation (see the module doc) and write it to ``path`` (GIF);
    ``timing`` and ``limits`` as :func:`render_frames` takes them."""
    frames, durations = render_frames(robot, tasks, poses_by_id, title, duration_s,
                                      timing=timing, limits=limits)
    return save_gif(path, frames, durations)
