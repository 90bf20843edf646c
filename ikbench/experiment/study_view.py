"""A design folder loaded for drawing: its goal set, NICO's arm and head, the arm's
trajectories, and the scene from the participant's seat (:mod:`ikbench.experiment.scene`).

Shared by the online page, the researcher's preview and the stimulus export, so all three show
the same motion from the same viewpoint.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.experiment.design import (
    CONDITIONS,
    check_fractions,
    read_design,
    read_trajectory,
    trajectory_path,
)
from ikbench.experiment.head import load_head
from ikbench.experiment.layout import GoalSet, load_goals
from ikbench.experiment.scene import Motion, Scene, arm_path, motion, sort_shapes


def parse_viewpoint(text: str) -> np.ndarray:
    """``"x,y,z"`` [mm, torso_base] -> (3,), one line naming a bad value."""
    words = [w.strip() for w in str(text).split(",")]
    try:
        values = np.array([float(w) for w in words])
    except ValueError:
        raise InputError(f"--viewpoint-mm {text!r}: give three numbers x,y,z [mm]") from None
    if values.shape != (3,) or not np.all(np.isfinite(values)) or np.abs(values).max() > 1e5:
        raise InputError(f"--viewpoint-mm {text!r}: give three finite numbers x,y,z [mm, "
                         "torso frame: x behind NICO, y its right, z up]")
    return values


def design_goals(record: Mapping) -> GoalSet:
    """The goal set a design was made with."""
    goals = load_goals()
    if [int(i) for i in record["goals"]["ids"]] != list(goals.ids):
        goals = load_goals(record["goals"]["targets_file"])
    return goals


class StudyView:
    """A design folder ready to draw.

    Args:
        folder: the design folder (design.json, trajectories/).
        viewpoint_mm: (3,) the participant's eyes [mm, torso_base] (default: design.json's).
    """

    def __init__(self, folder: str | Path, viewpoint_mm: npt.ArrayLike | None = None):
        self.folder = Path(folder)
        self.record = read_design(self.folder)
        self.robot, self.head = load_robot(), load_head()
        self.goals = design_goals(self.record)
        self.method = str(self.record["method"])
        self.viewpoint_mm = np.asarray(viewpoint_mm if viewpoint_mm is not None
                                       else self.record["viewpoint_mm"], float)
        self.trajectories = {t: read_trajectory(self.folder, trajectory_path(self.method, t),
                                                self.robot) for t in self.goals.ids}
        self.scene = Scene(self.robot, self.head, self.goals, self.viewpoint_mm)
        self.static = self.scene.static_shapes()

    @property
    def response_window_s(self) -> float:
        return float(self.record.get("response_window_s", self.goals.response_window_s))

    def trial_motion(self, trial: Mapping) -> Motion:
        """The motion of a trials.csv row."""
        fraction = trial.get("fraction")
        fraction = None if fraction is None or pd.isna(fraction) else float(fraction)
        poses = None if trial["condition"] == "G" else self.trajectories[int(trial["target"])]
        path = arm_path(self.robot, poses, fraction, self.scene.start_pose)
        head_pose = np.array([float(trial["head_z_motor_deg"]), float(trial["head_y_motor_deg"])])
        return motion(path, np.asarray(self.head.rest_motor_deg, float), head_pose,
                      float(trial["gaze_lead_s"]), float(trial["duration_s"]))

    def frames(self, played: Motion) -> dict:
        """The page's payload of a motion: the static shapes, every frame's moving shapes
        and their times, the view's size and the screen's homography."""
        return {"view": list(self.scene.camera.size), "static": sort_shapes(self.static),
                "times_s": np.round(played.times_s, 4).tolist(),
                "frames": [self.scene.dynamic_shapes(a, h)
                           for a, h in zip(played.arm_poses, played.head_poses)],
                "homography": np.round(self.scene.screen_homography, 9).tolist(),
                "screen_px": list(self.goals.screen.size_px)}

    def preview_trial(self, condition: str, target: int, fraction: float | None,
                      gaze_target: int | None) -> dict:
        """A trials.csv-like row for any (condition, target, fraction, gaze_target), with the
        design's timing; a bad value is refused in one line."""
        if condition not in CONDITIONS:
            raise InputError(f"condition {condition!r}: one of {', '.join(CONDITIONS)}")
        goals = self.goals
        goals.index(target)
        if condition != "G":
            if fraction is None:
                raise InputError(f"condition {condition}: give fraction= in (0, 1]")
            check_fractions([fraction])
        if condition == "I":
            if gaze_target is None:
                others = [t for t in goals.ids if t != target]
                here = goals.pixels[goals.index(target)]
                gaze_target = min(others, key=lambda t: (
                    float(np.linalg.norm(goals.pixels[goals.index(t)] - here)), t))
            goals.index(gaze_target)
            if gaze_target == target:
                raise InputError(f"gaze_target {gaze_target}: under I the head looks at another "
                                 "target than the arm's")
        else:
            gaze_target = None if condition == "P" else target
        if gaze_target is None:
            head_pose = np.asarray(self.head.neutral_motor_deg, float)
        else:
            head_pose = self.head.gaze_at(goals.points_mm[goals.index(gaze_target)])
        share = 0.0 if condition == "G" or fraction is None else fraction
        return {"condition": condition, "target": int(target),
                "fraction": math.nan if condition == "G" else fraction,
                "gaze_target": gaze_target, "head_z_motor_deg": float(head_pose[0]),
                "head_y_motor_deg": float(head_pose[1]),
                "duration_s": float(self.record["duration_s"]) * share,
                "gaze_lead_s": float(self.record["gaze_lead_s"])}
