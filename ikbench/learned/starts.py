"""Learned starts for whole trajectories (issue 61, part 2): a trajectory model of
``ikbench learn --kind trajectory`` proposes the initial trajectory that a method with warm
starts (``Capabilities(warm_starts=True)``: ours-lm, ours-exact) refines.

- :func:`learned_start`: the model's trajectory for a line task, (n + 1, dof) [pose units]:
  the heaviest mixture component's mean from the task's start pose to its end point
  (``LearnedModel.predict``), resampled to the task's n where the model learned another,
  and, where the task fixes its touch pose, bent onto it by a linear ramp (row i moves by
  i / n of the difference at the last row: the start stays, the end lands on the pose).
- :class:`LearnedStart`: a :class:`~ikbench.methods.base.Method` that wraps one with warm
  starts: each ``solve`` queries the model, then calls the wrapped method's ``solve_from``;
  its ``duration_s`` is the query and the refinement together (``info``: each apart). It is
  what ``ikbench run --init-model MODEL`` runs.

The model reads only the start pose and the end point [mm] of a task; a task without a start
pose, or not a line (letters, pose paths), is refused with one line.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot
from ikbench.core.task import Task
from ikbench.learned.model import LearnedModel
from ikbench.methods.base import Method, Progress, Solution


def resample(poses: np.ndarray, steps: int) -> np.ndarray:
    """``poses`` (m + 1, dof) at n = ``steps`` segments, (n + 1, dof): linear in the
    normalised time of the rows (the first and last rows kept)."""
    poses = np.asarray(poses, dtype=float)
    if len(poses) == steps + 1:
        return poses.copy()
    have = np.linspace(0.0, 1.0, len(poses))
    want = np.linspace(0.0, 1.0, steps + 1)
    return np.stack([np.interp(want, have, poses[:, j]) for j in range(poses.shape[1])],
                    axis=1)


def check_task(task: Task) -> None:
    """InputError unless ``task`` is a line task with a start pose (what the model reads)."""
    if task.goal.shape != "line" or task.goal.has_frames:
        raise InputError(f"trajectory {task.name!r}: a learned start needs a line task (the "
                         f"trajectory model learned lines); this one is a {task.goal.shape}")
    if task.required.start_pose is None:
        raise InputError(f"trajectory {task.name!r}: a learned start needs the task's start "
                         "pose (the model's input); give targets with a start pose")


def learned_start(model: LearnedModel, task: Task) -> np.ndarray:
    """The model's initial trajectory for a line task (see the module doc), (n + 1, dof)
    [pose units], within the joint limits; InputError for a model of the pose kind or a task
    :func:`check_task` refuses."""
    if model.kind != "trajectory":
        raise InputError(f"model: a {model.kind} model; a learned start for a trajectory "
                         "needs a model of ikbench learn --kind trajectory")
    check_task(task)
    start = np.asarray(task.required.start_pose, dtype=float)
    poses = resample(model.predict(start, task.goal.end_point_mm), len(task.goal.points_mm) - 1)
    poses[0] = start
    end = task.required.end_pose
    if end is not None:
        ramp = np.linspace(0.0, 1.0, len(poses))[:, None]
        poses += ramp * (np.asarray(end, dtype=float) - poses[-1])
    robot = model.robot
    return np.clip(poses, robot.lower, robot.upper)


class LearnedStart(Method):
    """``method`` (with warm starts) refining a trajectory model's start on every task.

    Args:
        method: a configured method whose ``capabilities.warm_starts`` is True.
        model: a loaded trajectory model, or the path of a model file (read against the
            robot at :meth:`check_tasks`, before any solve).
    """

    description = "a method refining a learned trajectory model's start"
    library = "ikbench"

    def __init__(self, method: Method, model: LearnedModel | str | Path) -> None:
        if not method.capabilities.warm_starts:
            from ikbench.methods.registry import available_methods

            able = [name for name, cls in available_methods().items()
                    if cls.capabilities.warm_starts]
            raise InputError(f"--init-model: --method {method.name} cannot start from given "
                             f"poses; methods that can: {', '.join(able)}")
        self.method, self.settings = method, method.settings
        self._model = model
        # A Method keeps these on its class; this wrapper's depend on the method it wraps,
        # so they are the instance's own. Batched off: one task at a time, the model's query
        # and the refinement timed per task.
        vars(self).update(name=f"{method.name}-learned",
                          description=f"{method.name} from a learned trajectory model's start",
                          library=method.library,
                          capabilities=replace(method.capabilities, batched=False))

    def model(self, robot: Robot) -> LearnedModel:
        """The loaded model (read now if a path was given; InputError for a file that is not
        a trajectory model of ``robot``)."""
        if not isinstance(self._model, LearnedModel):
            from ikbench.learned.train import load_model

            self._model = load_model(self._model, robot, kind="trajectory")
        return self._model

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        self.method.check_tasks(robot, tasks)
        model = self.model(robot)
        if model.robot.name != robot.name:
            raise InputError(f"model: trained for {model.robot.name}, not {robot.name}")
        for task in tasks:
            check_task(task)

    def prepare(self, robot: Robot) -> None:
        self.method.prepare(robot)

    def runtime(self) -> dict[str, Any]:
        return {**self.method.runtime(), "initial": "learned trajectory model"}

    def fixed_poses(self) -> frozenset[str]:
        return self.method.fixed_poses()

    def scheme_label(self) -> str:
        return f"{self.method.scheme_label()}, learned start"

    def settings_for(self, task: Task) -> Any:
        return self.method.settings_for(task)

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        model = self.model(robot)
        began = time.perf_counter()
        initial = learned_start(model, task)
        queried = time.perf_counter()
        solution = self.method.solve_from(robot, task, initial)
        ended = time.perf_counter()
        solution.info = {**solution.info, "initial": "learned",
                         "model_query_s": queried - began, "refine_s": ended - queried,
                         "model_training_samples": model.meta.get("samples", {}).get("train")}
        solution.duration_s = ended - began
        return solution
