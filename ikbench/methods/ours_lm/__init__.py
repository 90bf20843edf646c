"""Fast second-order solver ("ours-lm"): the paper's objective by Levenberg-Marquardt.

Minimises exactly the loss of ``ours`` (:mod:`ikbench.core.losses`, cm and motor degrees,
weights c0..c6) over the poses p (n+1, dof) within the joint limits, written as a sum of
squared residuals (:mod:`.problem`), with analytic Jacobians from the vectorised chain
kinematics (:mod:`ikbench.core.kinematics.chain`), a banded solve of the block-tridiagonal
normal equations (:mod:`.linalg`) and a projected LM loop batched over trajectories
(:mod:`.solver`). The same loop compiled with numba (:mod:`.compiled`, the ``[fast]`` extra)
runs by default when numba is installed (``--lm-backend auto|numpy|numba``, ``--lm-threads``);
the numpy solver is the reference and the fallback.

Weights: as in ``ours``, a task may name the weights it is meant for
(``Task.hints.default_weights``, e.g. a letter's c0=1, c1=50, c6=1, others 0); ``--weights`` changes
then apply on top of those instead of the paper's, per task in one batch.

6-D pose paths (tasks with goal frames, e.g. the CppFlow problems) are solved on their own
objective (:mod:`.frames`: position [mm], rotation by the SO(3) log map [deg], smoothness)
after a start search (:mod:`.start_search`: IK seeds for the first waypoint, each carried
along the path, the best refined by this LM), one task at a time.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.collision import CollisionModel, collision_model
from ikbench.core.kinematics.chain_torch import torch_chain_kinematics
from ikbench.core.losses import TERMS, format_weights, resolve_weights
from ikbench.methods.base import Capabilities, Method, Solution, report_fraction
from ikbench.methods.ours_lm.avoidance import (
    Avoidance,
    avoidance_for,
    collision_checker,
    self_colliding,
)
from ikbench.methods.ours_lm.devices import (
    BACKENDS,
    cpu_backend,
    numba_threads,
    numba_unavailable,
    torch_dtype,
    torch_threads,
)
from ikbench.methods.ours_lm.frames import FrameProblem, evaluate_frames
from ikbench.methods.ours_lm.pose_solver import OursLMSolver
from ikbench.methods.ours_lm.problem import Evaluation, Problem, evaluate
from ikbench.methods.ours_lm.solver import (
    KINEMATICS,
    LINEAR_SOLVERS,
    BatchResult,
    LMSettings,
    initial_poses,
    solve_batch,
    solve_problem,
)
from ikbench.methods.ours_lm.start_search import OursLMSettings, check_paths, search, warm_up_search
from ikbench.methods.registry import Adapter

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.base import Progress
    from ikbench.methods.ours_lm.settings import LMProgress

__all__ = ["BACKENDS", "KINEMATICS", "LINEAR_SOLVERS", "BatchResult", "Evaluation", "LMSettings",
           "OursLM", "OursLMSettings", "Problem", "cpu_backend", "evaluate", "initial_poses",
           "search", "solve_batch", "solve_problem"]


class OursLM(Method):
    """The paper's objective minimised by Levenberg-Marquardt (block-tridiagonal, batched)."""

    name = "ours-lm"
    description = ("the paper's objective (same L0..L6, units, weights) by batched "
                   "Levenberg-Marquardt with analytic Jacobians and joint-limit boxes; 6-D pose "
                   "paths: seeded start search, then the same LM")
    Settings = OursLMSettings
    # obstacles: on 6-D pose paths (:mod:`.avoidance`); 3-D tasks: none
    capabilities = Capabilities(frames=True, obstacles=True, batched=True, warm_starts=True)

    def settings_for(self, task: Task) -> LMSettings:
        """The settings for one task, with its complete weights."""
        return replace(self.settings, weights=resolve_weights(self.settings.weights, task))

    def runtime(self) -> dict[str, Any]:
        """The solver these settings run here (see :func:`.devices.cpu_backend`): numba or
        numpy on the CPU, or the torch backend on ``--device``; and its threads."""
        s = self.settings
        if s.device is not None:
            return {"backend": f"torch ({s.device}, {s.dtype})", "threads": torch_threads()}
        backend = cpu_backend(s)
        if backend == "numba":
            return {"backend": "numba", "threads": s.threads or numba_threads()}
        why = numba_unavailable() if s.backend == "auto" else None
        return {"backend": "numpy", "threads": 1, **({"numba": why} if why else {})}

    def prepare(self, robot: Robot) -> None:
        if self.settings.device is not None:  # the torch backend's kinematics on its device

            torch_chain_kinematics(robot, torch_dtype(self.settings.dtype), self.settings.device)
        elif self.settings.kinematics == "numpy":
            robot.chain_kinematics().frames(np.zeros((1, robot.dof)))
            if cpu_backend(self.settings) == "numba":  # compiled (or loaded) outside timing
                if not self._only_pose_paths_ahead:
                    importlib.import_module("ikbench.methods.ours_lm.compiled").warm_up(robot)
                if self._pose_paths_ahead:

                    warm_up_search(robot, self.settings)
        else:
            robot.pinocchio_fk()
        import scipy.linalg.lapack  # noqa: F401  the banded solver's import is not timed

    #: The tasks checked last hold a pose path (the search's kernels are then warmed up too),
    #: or only pose paths (the 3-D solver's are not: about a second of loading saved).
    _pose_paths_ahead = False
    _only_pose_paths_ahead = False

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        super().check_tasks(robot, tasks)
        frames = [t.goal.rotations is not None for t in tasks]
        self._pose_paths_ahead = any(frames)
        self._only_pose_paths_ahead = bool(frames) and all(frames)

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        return self.solve_many(robot, [task])[0]

    def solve_many(self, robot: Robot, tasks: Sequence[Task],
                   progress: Progress | None = None) -> list[Solution]:
        """One batched solve of every task (each with :meth:`settings_for`'s weights); each
        Solution's duration_s is its share of the batch's wall time. Tasks with goal frames
        are solved one at a time by :func:`.start_search.search`."""
        if any(t.goal.rotations is not None for t in tasks):
            by_index: dict[int, Solution] = {}
            for k, task in enumerate(tasks):
                if task.goal.rotations is None:
                    continue
                if progress:
                    progress.start(task, k, len(tasks))
                by_index[k] = self._solve_path(robot, task)
                if progress:
                    progress.done(task, by_index[k])
            rest = [k for k in range(len(tasks)) if k not in by_index]
            if rest:
                solved = self.solve_many(robot, [tasks[k] for k in rest], progress)
                by_index.update(zip(rest, solved))
            return [by_index[k] for k in range(len(tasks))]
        weights = [resolve_weights(self.settings.weights, task) for task in tasks]
        if progress:
            for k, task in enumerate(tasks):
                progress.start(task, k, len(tasks))
        result = solve_batch(robot, tasks, self.settings, weights=weights,
                             progress=self._report_iterations())
        started = time.perf_counter()
        again = self._without_self_collisions(robot, tasks, result, weights)
        result.duration_s += time.perf_counter() - started
        solutions = []
        for k, task in enumerate(tasks):
            solutions.append(_solution(result, k, weights[k]))
            solutions[-1].info["solved_again_without_self_collision"] = k in again
            if progress:
                progress.done(task, solutions[-1])
        return solutions

    def _report_iterations(self) -> LMProgress | None:
        """The batch's iterations of the cap as :func:`report_fraction` (the numpy loop calls
        it every iteration, the compiled one once, at the end); None on a device, where asking
        each iteration would wait for the device."""
        if self.settings.device is not None:
            return None
        cap = self.settings.max_iterations
        return lambda iteration, active, losses: report_fraction(iteration, cap)

    def collision_avoidance(self, robot: Robot) -> str | None:
        """What this method does about collisions on ``robot``, inside its own time (the
        leaderboard's label), e.g. "avoids self-collision (convex hulls of the URDF meshes,
        coal)"; None when the robot has no collision model."""
        checker, model = collision_checker(robot), collision_model(robot)
        if checker is None or model is None:
            return None
        engine = "coal" if isinstance(checker, CollisionModel) else "compiled capsules"
        return f"avoids self-collision ({model.geometry}, {engine})"

    def _without_self_collisions(self, robot: Robot, tasks: Sequence[Task],
                                 result: BatchResult, weights: list[dict]) -> list[int]:
        """Solve the trajectories that touch the robot itself again, from their poses, by the
        numpy solver with the clearance penalty between the robot's links
        (:class:`.avoidance.Avoidance`); ``result`` is updated in place where that touches
        itself at fewer waypoints. Returns those trajectories' indices. A trajectory clear of
        itself, or a robot without a collision model, is left as it is."""

        checker = collision_checker(robot)
        if checker is None:
            return []
        before = self_colliding(checker, result.poses)
        again = [int(k) for k in np.flatnonzero(before)]
        if not again:
            return []
        avoid = Avoidance(checker, (), self.settings.clearance_mm, self.settings.collision_weight)
        sub = solve_batch(robot, [tasks[k] for k in again], replace(self.settings, backend="numpy"),
                          weights=[weights[k] for k in again],
                          initial=result.poses[again], evaluator=avoid.evaluator(evaluate))
        after = self_colliding(checker, sub.poses)
        kept = []
        for j, k in enumerate(again):
            if after[j] < before[k]:
                result.poses[k], result.loss[k] = sub.poses[j], sub.loss[j]
                result.terms[k], result.converged[k] = sub.terms[j], sub.converged[j]
                result.iterations[k] += sub.iterations[j]
                kept.append(k)
        return kept

    def solve_from(self, robot: Robot, task: Task, initial_poses: np.ndarray) -> Solution:
        """The task's LM solve from ``initial_poses`` (n+1, dof) [pose units] instead of the
        joint interpolation (6-D pose paths: the same LM on their objective, no start
        search; ``converged``: the path is valid)."""
        weights = resolve_weights(self.settings.weights, task)
        initial = np.asarray(initial_poses, dtype=float)[None]
        if task.goal.rotations is None:
            return _solution(solve_batch(robot, [task], self.settings, weights=[weights],
                                         initial=initial), 0, weights)
        frames = robot.chain_kinematics().frames
        avoid = avoidance_for(robot, task, self.settings.clearance_mm,
                              self.settings.collision_weight)
        result = solve_batch(
            robot, [task], replace(self.settings, weights=weights), [weights], initial=initial,
            problem=FrameProblem.from_tasks(robot, [task], [weights], frames),
            evaluator=evaluate_frames if avoid is None else avoid.evaluator(evaluate_frames))
        solution = _solution(result, 0, weights)
        solution.converged = bool(check_paths(robot, task, result.poses, frames, 1.0,
                                              avoid)[0][0])
        return solution

    def _solve_path(self, robot, task) -> Solution:
        """A 6-D pose path by the start search; ``converged``: a valid path was found."""
        started = time.perf_counter()
        weights = resolve_weights(self.settings.weights, task)
        result = search(robot, task, self.settings, weights)
        return Solution(
            poses=result.poses, iterations=result.iterations,
            duration_s=time.perf_counter() - started, loss=result.loss,
            converged=result.valid,
            info={"valid_by_search": result.valid, "lm_converged": result.converged,
                  "weights": format_weights(weights), **result.info,
                  **{t: float(v) for t, v in zip(TERMS, result.terms)}})


def _solution(result: BatchResult, k: int, weights: dict) -> Solution:
    """Trajectory ``k`` of a batch as a Solution (duration_s: its share of the batch)."""
    size = len(result.poses)
    return Solution(
        poses=result.poses[k], iterations=int(result.iterations[k]),
        duration_s=result.duration_s / size, loss=float(result.loss[k]),
        converged=bool(result.converged[k]),
        info={"batch_size": size, "batch_wall_time_s": result.duration_s,
              "weights": format_weights(weights),
              **{f"{t}": float(v) for t, v in zip(TERMS, result.terms[k])}})


#: What ikbench brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="ikbench", requires=("scipy", "pinocchio"),
                  methods=(OursLM,), solvers=(OursLMSolver,), rank=20)
