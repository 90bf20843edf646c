"""A batched ours-lm solve split over an executor's workers, put back together in order.

Trajectories are solved independently (each one's iterations depend on it alone), so solving
a batch in parts gives each trajectory the same numbers as one call with all of them: the
studies (sweep, batch) get the same results from every executor.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.methods.ours_lm import BatchResult, solve_batch
from ikbench.runtime.executors import Executor, LocalExecutor, portable_robot, split

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.solver import BatchResult, LMSettings


@dataclass
class Part:
    """One part of a batch: what a worker needs (all picklable)."""

    robot: Any
    tasks: Sequence[Any]
    settings: Any
    weights: Sequence[Any]
    measure: Any = None      # optional fn(robot, tasks, weights, result) -> list of rows


def solve_parts(executor: Executor | None, robot: Robot, tasks: Sequence[Task],
                settings: LMSettings, weights: Sequence[dict[str, float]],
                measure: Callable[..., list[dict[str, Any]]] | None = None
                ) -> tuple[BatchResult, list[dict[str, Any]] | None]:
    """Solve ``tasks`` (with per-task ``weights``) by ours-lm on ``executor``.

    Args:
        executor: where to run (None or local: one call in this process, as before).
        robot, tasks, settings, weights: as for :func:`ikbench.methods.ours_lm.solve_batch`
            (``weights`` one dict per task).
        measure: optional module-level ``fn(robot, tasks, weights, result) -> list[dict]``
            run next to the solve (in the worker) on each part; its rows come back in order.

    Returns:
        (BatchResult of all tasks in order, rows or None); ``duration_s`` is the wall time of
        the whole (distributed) solve.
    """
    executor = executor or LocalExecutor()
    start = time.perf_counter()
    parts = [Part(robot, tasks, settings, weights, measure)] if executor.workers == 1 else [
        Part(portable_robot(robot), tasks[r.start:r.stop], settings, weights[r.start:r.stop],
             measure) for r in split(len(tasks), executor.workers)]
    done = list(executor.map(solve_part, parts, gpus=gpus_for(settings)))
    result = done[0][0] if len(done) == 1 else _concatenate([d[0] for d in done])
    result.duration_s = time.perf_counter() - start
    rows = None if measure is None else [row for _, part_rows in done for row in part_rows]
    return result, rows


def solve_part(part: Part) -> tuple[BatchResult, list[dict[str, Any]] | None]:
    """Solve one part (in a worker); returns (BatchResult, rows or None)."""

    result = solve_batch(part.robot, part.tasks, part.settings, weights=part.weights)
    rows = None if part.measure is None else part.measure(part.robot, part.tasks,
                                                          part.weights, result)
    return result, rows


def gpus_for(settings: object) -> float:
    """GPUs a task needs for ours-lm ``settings``: 1 on a CUDA device, else 0."""
    device = getattr(settings, "device", None)
    return 1.0 if device is not None and device.startswith("cuda") else 0.0


def _concatenate(results):
    def cat(name):
        return np.concatenate([getattr(r, name) for r in results])

    return BatchResult(cat("poses"), cat("loss"), cat("terms"), cat("iterations"),
                       cat("converged"), 0.0)
