"""One shard of a dataset: sample touch poses, solve their lines, measure, make the tables.

A shard is a pure function of its :class:`ShardSpec`: the touch poses come from the batch
sampler seeded by (dataset seed, shard index) (:func:`shard_seed`), so a shard's content does
not depend on which other shards exist, on resumption or on the executor that ran it.

Tables (Arrow, written as Parquet by :mod:`.dataset`):

- steps, long form, one row per trajectory and step: ``trajectory``, ``step``, one column
  per joint [pose units: motor deg for NICO], ``x_mm``, ``y_mm``, ``z_mm`` (fingertip, base
  frame), ``dir_x``, ``dir_y``, ``dir_z`` (unit pointing direction);
- trajectories, one row per trajectory: ids, start and touch poses and points, the loss and
  its terms, iterations and convergence, and the line figures of
  :func:`ikbench.core.metrics_batch.line_metrics` (those of ``trajectory_metrics``).
"""

from __future__ import annotations

import importlib
import json
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.losses import MM_PER_CM, TERMS
from ikbench.core.metrics_batch import line_metrics
from ikbench.core.robot import MM_PER_M, RANGE_TOLERANCE_DEG, unwrap_continuous
from ikbench.core.task import Goal, Requirements, Task
from ikbench.methods.ours_lm import solve_problem
from ikbench.methods.ours_lm.devices import cpu_backend
from ikbench.methods.ours_lm.problem import Problem
from ikbench.studies.batch import sample_touch_poses

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.methods.ours_lm.problem import Problem
    from ikbench.methods.ours_lm.solver import BatchResult

#: Dataset format name and version, written into every shard and the manifest.
FORMAT = "ikbench-dataset"
VERSION = 1
#: Key of the shard description in each Parquet file's metadata.
METADATA_KEY = b"ikbench"


@dataclass(frozen=True)
class ShardSpec:
    """What one shard holds (picklable; sent to the worker that builds it).

    Attributes:
        robot: the robot (without caches).
        start_pose: (dof,) the start pose of every line [pose units].
        steps: segments n per trajectory.
        seed: the dataset's seed.
        shard: shard index.
        first: global id of the shard's first trajectory.
        count: trajectories in the shard.
        settings: the ours-lm settings (complete weights dict).
        workspace: the batch sampler's workspace filter.
        config_hash: hash of everything that determines the content (the manifest's).
    """

    robot: Any
    start_pose: np.ndarray
    steps: int
    seed: int
    shard: int
    first: int
    count: int
    settings: Any
    workspace: Any
    config_hash: str

    def metadata(self, table: str) -> dict:
        """The description stored in the shard's Parquet files."""
        return {"format": FORMAT, "version": VERSION, "config_hash": self.config_hash,
                "table": table, "shard": self.shard, "first": self.first, "count": self.count,
                "steps": self.steps}


@dataclass
class ShardResult:
    """The two tables of a shard and how long it took (the times are not in the files)."""

    steps: Any              # pyarrow.Table
    trajectories: Any       # pyarrow.Table
    draws: int              # poses drawn to find ``count`` in the workspace
    solve_s: float          # wall time of the batched solve [s]
    total_s: float          # wall time of the whole shard [s]


def shard_seed(seed: int, shard: int) -> int:
    """The sampler seed of a shard, in [0, 2^63), from (dataset seed, shard index)."""
    state = np.random.SeedSequence([seed, shard]).generate_state(1, np.uint64)[0]
    return int(state) >> 1


def line_tasks(robot: Robot, start_pose: npt.ArrayLike, touch_poses: np.ndarray,
               steps: int, first: int = 0) -> tuple[list[Task], np.ndarray, np.ndarray]:
    """The paper's line tasks (as :func:`ikbench.core.task.line_task`) for many touch poses,
    with one vectorised FK; task names are the global ids ``first``, ``first + 1``, ...

    Returns:
        (tasks, start_point_mm (3,), touch_points_mm (B, 3)).
    """
    kin = robot.chain_kinematics()
    start = np.asarray(start_pose, dtype=float)
    point_m, _, _, _ = kin(np.vstack([start, touch_poses]), jacobian=False)
    start_mm, touch_mm = point_m[0] * MM_PER_M, point_m[1:] * MM_PER_M
    t = np.linspace(0.0, 1.0, steps + 1)[:, None]
    tasks = []
    for k, (pose, end_mm) in enumerate(zip(touch_poses, touch_mm)):
        line = end_mm - start_mm
        direction = line / np.linalg.norm(line)
        tasks.append(Task(str(first + k), Goal(start_mm + t * line,
                                               np.repeat(direction[None], steps + 1, axis=0)),
                          Requirements(start, pose)))
    return tasks, start_mm, touch_mm


def line_problem(robot: Robot, start_pose: npt.ArrayLike, touch_poses: npt.ArrayLike,
                 steps: int, weights: dict[str, float]
                 ) -> tuple[Problem, np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares problem of the lines of :func:`line_tasks` and their initial poses,
    made with array operations (no Task per line; the same numbers as
    ``Problem.from_tasks(robot, line_tasks(...)[0], weights)`` and ``initial_poses``).

    Returns:
        (problem, initial poses (B, N, dof), start_point_mm (3,), touch_points_mm (B, 3)).
    """

    kin = robot.chain_kinematics()
    start = np.asarray(start_pose, dtype=float)
    touch = np.asarray(touch_poses, dtype=float)
    point_m, _, _, _ = kin(np.vstack([start, touch]), jacobian=False)
    start_mm, touch_mm = point_m[0] * MM_PER_M, point_m[1:] * MM_PER_M
    t = np.linspace(0.0, 1.0, steps + 1)[:, None]
    line = touch_mm - start_mm                                           # (B, 3)
    length = np.array([np.linalg.norm(v) for v in line])               # as line_tasks
    direction = line / length[:, None]
    goal_mm = start_mm + t[None] * line[:, None, :]                      # (B, N, 3)
    b = len(touch)
    w = np.tile([float(weights.get(k, 0.0)) for k in TERMS], (b, 1))
    starts = np.broadcast_to(start, touch.shape).copy()
    problem = Problem(goal_mm / MM_PER_CM, np.repeat(direction[:, None], steps + 1, axis=1),
                      starts, touch.copy(), w, robot.lower, robot.upper)
    initial = np.clip(start[None, None] + t[None] * (touch - start)[:, None, :],
                      robot.lower, robot.upper)
    return problem, initial, start_mm, touch_mm


def build_shard(spec: ShardSpec) -> ShardResult:
    """Sample, solve and measure one shard (runs in a worker); see the module docstring."""
    began = time.perf_counter()
    prepared = prepare_shard(spec)
    return finish_shard(spec, prepared, solve_shard(spec, prepared), began)


@dataclass
class _Prepared:
    """A shard's sampled lines, ready to solve."""

    touch: np.ndarray           # (B, dof) touch poses
    draws: int
    problem: Any                # ikbench.methods.ours_lm.problem.Problem
    initial: np.ndarray         # (B, N, dof)
    start_mm: np.ndarray        # (3,)
    touch_mm: np.ndarray        # (B, 3)


def prepare_shard(spec: ShardSpec) -> _Prepared:
    """The shard's touch poses (the batch sampler) and their line problem."""
    touch, draws = sample_touch_poses(spec.robot, spec.start_pose, spec.count,
                                      shard_seed(spec.seed, spec.shard), spec.workspace)
    problem, initial, start_mm, touch_mm = line_problem(
        spec.robot, spec.start_pose, touch, spec.steps, spec.settings.weights)
    return _Prepared(touch, draws, problem, initial, start_mm, touch_mm)


def solve_shard(spec: ShardSpec, prepared: _Prepared
                ) -> tuple[BatchResult, np.ndarray, np.ndarray]:
    """(the solver's BatchResult, end points [m] (B*N, 3), directions (B*N, 3))."""

    result = solve_problem(spec.robot, prepared.problem, prepared.initial, spec.settings)
    point_m, direction = _forward(spec.robot, result.poses.reshape(-1, spec.robot.dof),
                                  spec.settings)
    return result, point_m, direction


def finish_shard(spec: ShardSpec, prepared: _Prepared,
                 solved: tuple[BatchResult, np.ndarray, np.ndarray], began: float) -> ShardResult:
    """The shard's tables from its solution (metrics by array operations)."""
    result, point_m, direction = solved
    robot, touch, start_mm, touch_mm = spec.robot, prepared.touch, prepared.start_mm, \
        prepared.touch_mm
    poses = unwrap_continuous(robot, result.poses)              # (B, N, dof), as written
    b, n_poses, dof = poses.shape
    points_mm = (point_m * MM_PER_M).reshape(b, n_poses, 3)
    directions = direction.reshape(b, n_poses, 3)
    start_pose = np.broadcast_to(spec.start_pose, (b, dof))
    metrics = line_metrics(points_mm, directions, poses, np.broadcast_to(start_mm, (b, 3)),
                           touch_mm, start_pose, touch)
    ids = np.arange(spec.first, spec.first + b, dtype=np.int64)
    steps = _steps_table(spec, robot, ids, poses, points_mm, directions)
    trajectories = _trajectories_table(spec, robot, ids, start_pose, touch, start_mm, touch_mm,
                                       result, metrics)
    return ShardResult(steps, trajectories, prepared.draws, result.duration_s,
                       time.perf_counter() - began)


def pipelined(specs: Iterable[ShardSpec]) -> Iterator[ShardResult]:
    """:func:`build_shard` of each spec, in order, in this process, in a pipeline: while one
    shard is solved (in a second thread; the numba backend runs without the GIL), the next
    one is sampled and the previous one measured and handed on (to be written). The results
    are those of :func:`build_shard`; ``total_s`` spans a shard's overlapping stages."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="ikbench-solve") as pool:
        running: tuple[Any, ...] | None = None  # (spec, prepared, began, future) being solved
        for spec in specs:
            began = time.perf_counter()
            prepared = prepare_shard(spec)                  # during the previous shard's solve
            previous: tuple[Any, ...] | None = running
            solved: Any = running[3].result() if running else None
            running = (spec, prepared, began, pool.submit(solve_shard, spec, prepared))
            if previous is not None:                        # measured during this solve
                yield finish_shard(previous[0], previous[1], solved, previous[2])
        if running is not None:
            yield finish_shard(running[0], running[1], running[3].result(), running[2])


def _forward(robot, poses, settings):
    """End points [m] and directions of poses (M, dof): compiled with the numba backend."""

    if settings.device is None and cpu_backend(settings) == "numba":
        try:
            forward = importlib.import_module("ikbench.methods.ours_lm.compiled").forward
        except ImportError:  # as the solver: auto falls back to numpy
            pass
        else:
            return forward(robot, poses, settings.threads)
    point_m, direction, _, _ = robot.chain_kinematics()(poses, False)
    return point_m, direction


def _table(columns: dict, metadata: dict):
    import pyarrow as pa

    table = pa.table(columns)
    return table.replace_schema_metadata({METADATA_KEY: json.dumps(metadata, sort_keys=True)})


def _steps_table(spec, robot, ids, poses, points_mm, directions):
    b, n_poses, dof = poses.shape
    columns: dict[str, np.ndarray] = {
        "trajectory": np.repeat(ids, n_poses),
        "step": np.tile(np.arange(n_poses, dtype=np.int32), b)}
    for j, name in enumerate(robot.joint_names):
        columns[name] = poses[..., j].ravel()
    for k, axis in enumerate("xyz"):
        columns[f"{axis}_mm"] = points_mm[..., k].ravel()
    for k, axis in enumerate("xyz"):
        columns[f"dir_{axis}"] = directions[..., k].ravel()
    return _table(columns, spec.metadata("steps"))


def _trajectories_table(spec, robot, ids, start_pose, touch, start_mm, touch_mm, result,
                        metrics):
    b = len(ids)
    columns: dict[str, np.ndarray] = {
        "trajectory": ids, "shard": np.full(b, spec.shard, dtype=np.int32)}
    for j, name in enumerate(robot.joint_names):
        columns[f"start_{name}"] = np.ascontiguousarray(start_pose[:, j])
    for j, name in enumerate(robot.joint_names):
        columns[f"touch_{name}"] = np.ascontiguousarray(touch[:, j])
    for k, axis in enumerate("xyz"):
        columns[f"start_{axis}_mm"] = np.full(b, start_mm[k])
    for k, axis in enumerate("xyz"):
        columns[f"touch_{axis}_mm"] = np.ascontiguousarray(touch_mm[:, k])
    columns["line_length_mm"] = np.linalg.norm(touch_mm - start_mm, axis=1)
    columns["loss"] = result.loss
    for k, term in enumerate(TERMS):
        columns[term] = np.ascontiguousarray(result.terms[:, k])
    columns["iterations"] = result.iterations.astype(np.int32)
    columns["converged"] = result.converged.astype(bool)
    lower, upper = robot.lower, robot.upper
    tol = RANGE_TOLERANCE_DEG  # as Robot.within_limits
    columns["within_limits"] = np.all((result.poses >= lower - tol)
                                      & (result.poses <= upper + tol), axis=(1, 2))
    columns.update(metrics)
    return _table(columns, spec.metadata("trajectories"))
