"""``ikbench recommend --task path``: pose paths placed in the robot's reachable workspace,
solved by every installed method that follows goal frames, judged by CppFlow's validity.

Each path (:func:`place_paths`) starts at the end-frame pose of a configuration drawn uniformly
within the joint limits and free of self-collision (seeded; it is the task's
``reference_pose``, a starting guess, not a required start) and holds
that orientation: a **circle** (in the plane of the start frame's x and y axes, through the
start) or a **line** (along a random direction from the start), its size a fixed share of the
robot's reach at that pose. The start is reachable; the rest of the path need not be (there is
no ground truth for a path): a path no method solves says so in every row.

Every method solves every path through the study harness (:func:`ikbench.runtime.harness.
solve_tasks`: set-up untimed, each solve timed); success is CppFlow's validity of the written
trajectory (:func:`ikbench.core.metrics.frame_metrics`), never the method's own claim. The rows
have the columns :mod:`ikbench.studies.verdict` reads (``method``, ``seed``, ``success``,
``failure``, ``time_s``, ``joint_distance_deg``) and the path's figures.
"""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.collision import check_trajectory
from ikbench.core.errors import IkbenchError
from ikbench.core.metrics import frame_metrics
from ikbench.core.task import Task, frame_task
from ikbench.methods.registry import get_method
from ikbench.runtime.harness import describe, solve_tasks
from ikbench.studies.cartesian import as_written, build_method, parse_methods

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: Segments of each path (waypoints - 1).
SEGMENTS = 40
#: The circle's radius and the line's length, as shares of the distance from the base to the
#: start pose (the reach there).
CIRCLE_RADIUS_SHARE, LINE_LENGTH_SHARE = 0.08, 0.25
#: The generator stream of the paths: ``default_rng([seed, PATH_STREAM, k])``.
PATH_STREAM = 47
KINDS = ("circle", "line")
#: Draws of a start configuration before one in self-collision is kept anyway.
START_DRAWS = 50


def path_methods(names: str | Sequence[str] | None) -> list[str]:
    """The methods that follow goal frames (``names`` checked; None: every installed one)."""
    return parse_methods(names)


def place_paths(robot: Robot, seed: int, count: int) -> list[Task]:
    """``count`` paths (circles and lines alternating) for ``seed`` (see the module
    docstring); each task's name says its kind and index."""
    tasks = []
    for k in range(count):
        rng = np.random.default_rng([int(seed), PATH_STREAM, k])
        q = _free_start(robot, rng)
        T = robot.fk_transform(q[None])[0]  # (4, 4) [m]
        start_m, R = T[:3, 3], T[:3, :3]
        reach_m = max(float(np.linalg.norm(start_m)), 0.05)
        s = np.linspace(0.0, 1.0, SEGMENTS + 1)
        kind = KINDS[k % len(KINDS)]
        if kind == "circle":
            u, v = R[:, 0], R[:, 1]
            radius = CIRCLE_RADIUS_SHARE * reach_m
            theta = 2 * np.pi * s
            points_m = (start_m + radius * (np.outer(1 - np.cos(theta), u)
                                            - np.outer(np.sin(theta), v)))
        else:
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            points_m = start_m + np.outer(s * LINE_LENGTH_SHARE * reach_m, d)
        rotations = np.repeat(R[None], len(s), axis=0)
        tasks.append(frame_task(robot, f"{kind}{k}", points_m * 1000.0, rotations,
                                reference_pose=q,
                                joint_limits=(robot.validity_lower, robot.validity_upper)))
    return tasks


def _free_start(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """A configuration drawn uniformly within the limits, redrawn (up to
    :data:`START_DRAWS` times) while the robot's collision model finds it in self-collision."""
    for _ in range(START_DRAWS):
        q = rng.uniform(robot.sample_lower, robot.sample_upper)
        if not check_trajectory(robot, q[None])["self_collisions"]:
            return q
    return q


def solve_paths(robot: Robot, name: str, tasks: Sequence[Task], seed: int) -> pd.DataFrame:
    """``name`` on every task (one harness call: set-up once, each solve timed); one row each,
    judged by CppFlow's validity."""
    method = build_method(name, seed)
    try:
        outcomes = solve_tasks(method, robot, list(tasks))
    except IkbenchError as exc:  # refused before solving (e.g. it cannot take the robot)
        return not_run(name, seed, tasks, f"refused: {exc}")
    except Exception as exc:  # the library failed to set up (e.g. MuJoCo cannot compile it)
        return not_run(name, seed, tasks, f"cannot run (prepare: {describe(exc)})")
    rows = []
    for outcome in outcomes:
        if outcome.solution is None:
            rows.append(_row(name, seed, outcome.task, outcome.failure or "no solution",
                             outcome.wall_s, None))
            continue
        poses = as_written(outcome.solution.poses)
        rows.append(_row(name, seed, outcome.task, "", outcome.wall_s,
                         frame_metrics(robot, outcome.task, poses)))
    return pd.DataFrame(rows)


def not_run(name: str, seed: int, tasks: Sequence[Task], why: str) -> pd.DataFrame:
    """Rows for a method that was not run on ``tasks`` (``why``: the reason, kept)."""
    return pd.DataFrame([_row(name, seed, task, why, np.nan, None) for task in tasks])


def _row(name: str, seed: int, task: Task, failure: str, time_s: float, metrics: dict | None
         ) -> dict:
    metrics = metrics or {}
    return {"method": name, "seed": seed, "path": task.name, "success":
            bool(metrics.get("valid", False)), "failure": failure, "time_s": time_s,
            "joint_distance_deg": np.nan,
            "position_error_max_mm": metrics.get("position_error_max_mm", np.nan),
            "rotation_error_max_deg": metrics.get("rotation_error_max_deg", np.nan),
            "max_joint_change_deg": metrics.get("max_joint_change_deg", np.nan),
            "failed_criteria": metrics.get("failed_criteria", "failure" if failure else "")}


def facts(names: Sequence[str]) -> dict[str, dict]:
    """name -> the facts the report shows (library, deterministic)."""
    out = {}
    for name in names:
        cls = get_method(name)
        out[name] = {"library": getattr(cls, "library", "") or "",
                     "deterministic": None,  # not stated by path methods
                     "first_call": {"error": "not measured for path methods"}}
    return out


def pilot(robot: Robot, names: Sequence[str], seed: int, deadline: float = np.inf
          ) -> dict[str, float]:
    """One path per method, each in a forked child (set-up included, so the estimate holds
    it): seconds per path. Each pilot gets an equal share of half the time left before
    ``deadline`` (perf_counter seconds); one that passes it is stopped and costs inf (a
    single path solve cannot be interrupted otherwise: ours-lm's path search took 40 s on
    a UR5 path, a one-minute run on a 7-joint arm did not end in ten)."""
    tasks = place_paths(robot, seed, 1)
    context = multiprocessing.get_context("fork")
    cost = {}
    for k, name in enumerate(names):
        share_s = 0.5 * (deadline - time.perf_counter()) / (len(names) - k) \
            if np.isfinite(deadline) else None
        if share_s is not None and share_s <= 0:
            cost[name] = np.inf
            continue
        receive, send = context.Pipe(duplex=False)
        child = context.Process(target=_pilot_child, args=(robot, name, tasks, seed, send),
                                daemon=True)
        t0 = time.perf_counter()
        child.start()
        send.close()
        got = receive.poll(share_s)
        cost[name] = time.perf_counter() - t0 if got else np.inf
        if got:
            receive.recv()
        child.join(0 if not got else 5)
        if child.is_alive():
            child.kill()
            child.join()
        receive.close()
    return cost


def _pilot_child(robot: Robot, name: str, tasks: Sequence[Task], seed: int, send) -> None:
    """In the forked child: solve the pilot path, say done."""
    try:
        solve_paths(robot, name, tasks, seed)
    finally:
        send.send(True)
        send.close()
