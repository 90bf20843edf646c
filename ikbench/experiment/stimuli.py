"""``ikbench experiment stimuli``: every distinct stimulus of a design as a video from the
participant's seat, for studies hosted elsewhere (a survey tool that shows a video and asks).

A stimulus is a (target, condition, fraction, gaze_target) of the design's trials (every
participant's, practice included) with a method's arm trajectories (the design's by default;
another method's trajectories are solved for the same goal set). Each is the motion the online
page plays (:mod:`ikbench.experiment.scene`: head turn, then the arm to its stop), drawn by
matplotlib from the same shapes and written as an animated GIF (matplotlib's PillowWriter; no
MP4 encoder ships on PyPI with the project's dependencies), ending on the stop frame held for
``hold_s``. ``OUT/manifest.csv`` lists them: file, condition, fraction, target, gaze_target,
method, frames, duration_s, viewpoint_mm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_csv, staged_folder
from ikbench.experiment.design import cell_name, solve_trajectories
from ikbench.experiment.records import participants, read_trials
from ikbench.experiment.scene import (
    BACKGROUND,
    VIEW_SIZE,
    arm_path,
    motion,
    sort_shapes,
)
from ikbench.experiment.study_view import StudyView

MANIFEST = "manifest.csv"
MANIFEST_COLUMNS = ("file", "condition", "fraction", "target", "gaze_target", "method",
                    "frames", "duration_s", "viewpoint_mm")
#: Frames per second of the videos, and how long the stop frame is held [s].
VIDEO_FPS = 25
HOLD_S = 1.0


def draw(ax, shapes: Sequence[dict]) -> None:  # type: ignore[no-untyped-def]
    """Draw view shapes (:mod:`ikbench.experiment.scene`) on matplotlib axes spanning the view
    (1 view unit = 1 pixel at 100 dpi)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    points_per_unit = 72.0 / 100.0
    for order, shape in enumerate(sort_shapes(list(shapes))):   # paint in this order
        pts = np.asarray(shape["pts"], float)
        if shape["type"] == "poly":
            ax.add_patch(Polygon(pts, closed=True, facecolor=shape["fill"],
                                 edgecolor=shape.get("stroke") or "none",
                                 linewidth=shape.get("lw", 1.0) * points_per_unit,
                                 zorder=order))
        else:
            ax.add_line(Line2D(pts[:, 0], pts[:, 1], color=shape["color"],
                               linewidth=shape["lw"] * points_per_unit,
                               solid_capstyle="round", zorder=order))


def figure():  # type: ignore[no-untyped-def]
    """A matplotlib figure and axes covering the view, pixel for pixel at 100 dpi."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(VIEW_SIZE[0] / 100, VIEW_SIZE[1] / 100), dpi=100)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0, VIEW_SIZE[0])
    ax.set_ylim(VIEW_SIZE[1], 0)
    ax.set_axis_off()
    fig.patch.set_facecolor(BACKGROUND)
    return fig, ax


@dataclass(frozen=True)
class Stimulus:
    """One distinct stimulus of a design."""

    condition: str
    fraction: float | None
    target: int
    gaze_target: int | None
    head_pose: tuple[float, float]
    duration_s: float
    gaze_lead_s: float

    @property
    def name(self) -> str:
        gaze = f"_gaze{self.gaze_target}" if self.condition == "I" else ""
        return f"{cell_name(self.condition, self.fraction)}_target{self.target}{gaze}"


def design_stimuli(folder: Path) -> list[Stimulus]:
    """The distinct (target, condition, fraction, gaze_target) of every trial list, in a
    stable order."""
    seen: dict[tuple, Stimulus] = {}
    for path in participants(folder):
        for _, row in read_trials(path).iterrows():
            fraction = None if pd.isna(row["fraction"]) else float(row["fraction"])
            gaze = None if pd.isna(row["gaze_target"]) else int(row["gaze_target"])
            key = (str(row["condition"]), fraction, int(row["target"]), gaze)
            seen.setdefault(key, Stimulus(key[0], fraction, key[2], gaze,
                                          (float(row["head_z_motor_deg"]),
                                           float(row["head_y_motor_deg"])),
                                          float(row["duration_s"]), float(row["gaze_lead_s"])))
    order = {"G": 0, "P": 1, "GP": 2, "I": 3}
    return sorted(seen.values(), key=lambda s: (order.get(s.condition, 9), s.fraction or 0.0,
                                                s.target, s.gaze_target or 0))


def render_video(view: StudyView, stimulus: Stimulus, poses: np.ndarray | None, path: Path,
                 hold_s: float = HOLD_S, fps: float = VIDEO_FPS) -> tuple[int, float]:
    """Write one stimulus as a GIF; returns (frames, the motion's duration [s])."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import PillowWriter

    scene = view.scene
    path_poses = arm_path(view.robot, poses if stimulus.condition != "G" else None,
                          stimulus.fraction, scene.start_pose)
    played = motion(path_poses, np.asarray(view.head.rest_motor_deg, float),
                    np.asarray(stimulus.head_pose, float), stimulus.gaze_lead_s,
                    stimulus.duration_s, fps=fps)
    static = scene.static_shapes()
    fig, ax = figure()
    writer = PillowWriter(fps=int(round(fps)))
    frames = 0
    holds = int(round(hold_s * fps))
    with writer.saving(fig, str(path), dpi=100):
        for k in range(len(played.times_s) + holds):
            i = min(k, len(played.times_s) - 1)
            ax.clear()
            ax.set_xlim(0, VIEW_SIZE[0])
            ax.set_ylim(VIEW_SIZE[1], 0)
            ax.set_axis_off()
            draw(ax, static + scene.dynamic_shapes(played.arm_poses[i], played.head_poses[i]))
            writer.grab_frame(facecolor=BACKGROUND)
            frames += 1
    plt.close(fig)
    return frames, played.duration_s


def export(folder: Path, out: Path, view: StudyView, methods: Sequence[str] | None = None,
           hold_s: float = HOLD_S, log=print) -> pd.DataFrame:  # type: ignore[no-untyped-def]
    """Write every stimulus of the design in ``folder`` for each method into ``out`` (the
    folder whole or not at all) with its manifest; returns the manifest."""
    stimuli = design_stimuli(folder)
    methods = list(methods or [view.method])
    rows = []
    with staged_folder(out) as stage:
        for method in methods:
            trajectories = (view.trajectories if method == view.method
                            else solve_trajectories(view.robot, view.goals, method)[0])
            for stimulus in stimuli:
                name = f"{method}/{stimulus.name}.gif"
                (stage / method).mkdir(parents=True, exist_ok=True)
                poses = trajectories.get(stimulus.target)
                frames, duration = render_video(view, stimulus, poses, stage / name, hold_s)
                rows.append({"file": name, "condition": stimulus.condition,
                             "fraction": stimulus.fraction, "target": stimulus.target,
                             "gaze_target": stimulus.gaze_target, "method": method,
                             "frames": frames, "duration_s": round(duration, 4),
                             "viewpoint_mm": " ".join(f"{x:g}" for x in view.viewpoint_mm)})
                log(f"{name}: {frames} frames")
        table = pd.DataFrame(rows, columns=list(MANIFEST_COLUMNS))
        table["gaze_target"] = table["gaze_target"].astype("Int64")
        atomic_write_csv(stage / MANIFEST, table)
    return table


def check_hold(hold_s: float) -> float:
    if not (math.isfinite(hold_s) and 0 <= hold_s <= 30):
        raise InputError(f"--hold {hold_s}: give seconds in [0, 30]")
    return hold_s
