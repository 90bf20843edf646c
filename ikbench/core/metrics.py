"""Quality figures of a trajectory, used by every method and every report.

All functions take plain arrays: points in mm, directions as unit vectors, poses in motor
degrees; they return mm and degrees. :func:`trajectory_metrics` gives the Table 1/2 columns;
:func:`shape_metrics` the figures of a general shape (polyline, spline, letter).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from ikbench.core.collision import check_trajectory
from ikbench.core.robot import pose_difference, wrap_continuous
from ikbench.core.rotations import geodesic_angle
from ikbench.core.validity import validity_failures

if TYPE_CHECKING:
    from ikbench.core.contract import Contract
    from ikbench.core.robot import Robot
    from ikbench.core.shapes import Curve
    from ikbench.core.task import Task

#: Window of the paper's criterion 2: the displacement of the last 10 segments is averaged.
CRITERION2_WINDOW = 10


def line_distances_mm(points_mm: npt.ArrayLike, start_mm: npt.ArrayLike,
                      end_mm: npt.ArrayLike) -> np.ndarray:
    """Perpendicular distance [mm] of each point (N, 3) from the line through start and end."""
    points = np.asarray(points_mm, dtype=float)
    start = np.asarray(start_mm, dtype=float)
    axis = np.asarray(end_mm, dtype=float) - start
    axis = axis / np.linalg.norm(axis)
    rel = points - start
    return np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)


def pointing_deviations_deg(directions: npt.ArrayLike,
                            goal_directions: npt.ArrayLike) -> np.ndarray:
    """Angle [deg] between each direction (N, 3) and its goal direction ((N, 3) or (3,))."""
    v = np.asarray(directions, dtype=float)
    g = np.broadcast_to(np.asarray(goal_directions, dtype=float), v.shape)
    v = v / np.linalg.norm(v, axis=1, keepdims=True)
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    # atan2(|v x g|, v.g) stays accurate near 0 and 180 deg, unlike arccos.
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(v, g), axis=1), np.sum(v * g, axis=1)))


def criterion2_mm(points_mm: npt.ArrayLike, touch_point_mm: npt.ArrayLike,
                  window: int = CRITERION2_WINDOW) -> np.ndarray:
    """The paper's criterion 2 (Fig. 2): where the movement so far points, per step.

    For step i the mean displacement m_i of segments j = max(0, i-window) .. min(i, n-1)
    (segment j runs from P_j to P_{j+1}) defines a ray P_i + t m_i, t >= 0. The value is the
    distance [mm] from the touch point to the ray's intersection with the horizontal plane
    z = z_touch; NaN where the ray does not reach that plane (it is horizontal or moves away).

    Args:
        points_mm: (n+1, 3) fingertip points.
        touch_point_mm: (3,) the touch point (goal end point).
        window: number of preceding segments averaged.
    """
    points = np.asarray(points_mm, dtype=float)
    touch = np.asarray(touch_point_mm, dtype=float)
    steps = np.diff(points, axis=0)
    n = len(steps)
    out = np.full(n + 1, np.nan)
    for i in range(n + 1):
        j1 = min(i, n - 1)
        j0 = min(max(0, i - window), j1)
        m = steps[j0 : j1 + 1].mean(axis=0)
        dz = touch[2] - points[i, 2]
        if abs(dz) < 1e-12:
            out[i] = np.linalg.norm(points[i, :2] - touch[:2])
            continue
        if abs(m[2]) < 1e-12 or dz / m[2] < 0:
            continue
        hit = points[i] + (dz / m[2]) * m
        out[i] = np.linalg.norm(hit[:2] - touch[:2])
    return out


def statistics(name: str, values: np.ndarray, *kinds: str) -> dict[str, float]:
    """``{name.format(kind): values.<kind>()}`` for each kind in order (``mean``, ``std``:
    the population std, ``max``), e.g. ``line_distance_mean_mm`` from
    ``"line_distance_{}_mm"``; ``name`` keeps the values' unit."""
    return {name.format(kind): float(getattr(values, kind)()) for kind in kinds}


def smoothness(poses: npt.ArrayLike) -> dict[str, float]:
    """Fluency figures of a trajectory (n+1, dof) [motor deg], per step (time-free).

    Returns:
        ``mean_sq_joint_step_deg2``: mean over steps and joints of (p_{i+1} - p_i)^2 (= L6);
        ``max_joint_step_deg``: largest absolute joint change in one step;
        ``mean_sq_jerk_deg2``: mean squared third difference of the poses (joint-space jerk
        per step^3); ``velocity_sign_changes``: number of sign changes of joint velocity
        summed over joints, ignoring steps smaller than 1e-3 deg (a "shaking" count).
    """
    poses = np.asarray(poses, dtype=float)
    d1 = np.diff(poses, axis=0)
    d3 = np.diff(poses, n=3, axis=0)
    signs = np.sign(np.where(np.abs(d1) < 1e-3, 0.0, d1))
    changes = 0
    for column in signs.T:
        nonzero = column[column != 0]
        changes += int(np.sum(nonzero[1:] != nonzero[:-1]))
    return {
        "mean_sq_joint_step_deg2": float(np.mean(d1**2)),
        "max_joint_step_deg": float(np.max(np.abs(d1))),
        "mean_sq_jerk_deg2": float(np.mean(d3**2)) if len(d3) else 0.0,
        "velocity_sign_changes": changes,
    }


def _end_errors_and_smoothness(robot, task, points_mm, poses) -> dict[str, float]:
    """Start/end point errors [mm], start/end pose errors [deg] (NaN where the task fixes no
    such pose; a continuous joint's the short way round) and the :func:`smoothness` figures."""

    def pose_error(pose, goal):
        return (float("nan") if goal is None
                else float(np.max(np.abs(pose_difference(robot, pose, goal)))))

    return {
        "start_point_error_mm": float(np.linalg.norm(points_mm[0] - task.goal.start_point_mm)),
        "end_point_error_mm": float(np.linalg.norm(points_mm[-1] - task.goal.end_point_mm)),
        "start_pose_error_deg": pose_error(poses[0], task.required.start_pose),
        "end_pose_error_deg": pose_error(poses[-1], task.required.end_pose),
        **smoothness(poses),
    }


def trajectory_metrics(robot: Robot, task: Task, poses: npt.ArrayLike
                       ) -> dict[str, float]:
    """The Table 1/2 figures of one trajectory against its task.

    Points and directions come from FK (Pinocchio, float64) of the poses. Line distance and
    pointing deviation use only the task's pen-down points; for a line task the line runs
    through P^s and P^e and the goal direction is d.

    Returns:
        dict with ``line_distance_mean_mm``, ``line_distance_std_mm`` (population std),
        ``pointing_deviation_mean_deg``, ``pointing_deviation_std_deg``,
        ``start_point_error_mm`` = |P_0 - P^s|, ``end_point_error_mm`` = |P_n - P^e|,
        ``start_pose_error_deg`` / ``end_pose_error_deg`` = max |p - p^s| / |p - p^e| (NaN
        when the task does not fix that pose), and the :func:`smoothness` figures.
    """
    poses = np.asarray(poses, dtype=float)
    return _line_metrics(robot, task, poses, robot.fk(poses))


def _line_metrics(robot, task, poses, fk) -> dict[str, float]:
    """:func:`trajectory_metrics` from the poses' FK (computed once by the caller)."""
    mask = task.goal.pen_down
    distances = line_distances_mm(fk.point_mm[mask], task.goal.start_point_mm,
                                  task.goal.end_point_mm)
    deviations = pointing_deviations_deg(fk.direction[mask], task.goal.directions[mask])

    return {
        **statistics("line_distance_{}_mm", distances, "mean", "std"),
        **statistics("pointing_deviation_{}_deg", deviations, "mean", "std"),
        **_end_errors_and_smoothness(robot, task, fk.point_mm, poses),
    }


#: The drawn-shape judge of a general shape (letters): a shape is drawn when every pen-down
#: fingertip point lies within this distance [mm] of the target curve and at least
#: :data:`DRAWN_COVERAGE_MIN_PCT` of the curve's strokes lie within it of the fingertip's
#: path. 10 mm is a thirtieth of the letters' default 300 mm height (the line's contract
#: asks 5 mm of a 10-30 cm line); the optimiser's convergence judges nothing of the shape.
DRAWN_TOLERANCE_MM = 10.0
#: The share [%] of a shape's strokes its drawing must come within the tolerance of.
DRAWN_COVERAGE_MIN_PCT = 95.0


def shape_metrics(robot: Robot, task: Task, poses: npt.ArrayLike
                  ) -> dict[str, float]:
    """Figures of a trajectory against a general shape (its task has a ``curve``).

    Points and directions come from FK (Pinocchio, float64) of the poses; distances and
    deviations use only the pen-down points.

    Returns:
        dict with ``curve_distance_{mean,std,max}_mm``: distance of each fingertip point from
        the target curve (the nearest point of any pen-down stroke; std is the population
        std); ``point_error_{mean,max}_mm``: |P_i - P^g_i| from the goal points;
        ``pointing_deviation_{mean,std,max}_deg`` from the goal directions;
        ``stroke_coverage_pct``: the share of the curve's strokes within
        :data:`DRAWN_TOLERANCE_MM` of the fingertip's pen-down path
        (:meth:`~ikbench.core.shapes.Curve.coverage`); ``drawn``: True when the largest curve
        distance is within that tolerance and the coverage at least
        :data:`DRAWN_COVERAGE_MIN_PCT` (a bool);
        ``start_point_error_mm`` / ``end_point_error_mm``; ``start_pose_error_deg`` /
        ``end_pose_error_deg`` (NaN when the task fixes no pose); the :func:`smoothness`
        figures.
    """
    poses = np.asarray(poses, dtype=float)
    fk = robot.fk(poses)
    mask = task.goal.pen_down
    distances = cast("Curve", task.goal.curve).distances_mm(fk.point_mm[mask])  # a shape task
    errors = np.linalg.norm(fk.point_mm - task.goal.points_mm, axis=1)[mask]
    deviations = pointing_deviations_deg(fk.direction[mask], task.goal.directions[mask])
    curve = cast("Curve", task.goal.curve)
    runs = np.split(np.arange(len(mask)), np.flatnonzero(np.diff(mask.astype(int))) + 1)
    drawn_paths = [fk.point_mm[run] for run in runs if mask[run[0]]]
    coverage_pct = 100.0 * curve.coverage(drawn_paths, DRAWN_TOLERANCE_MM)
    drawn = bool(distances.max() <= DRAWN_TOLERANCE_MM and coverage_pct >= DRAWN_COVERAGE_MIN_PCT)

    return {
        **statistics("curve_distance_{}_mm", distances, "mean", "std", "max"),
        "stroke_coverage_pct": coverage_pct, "drawn": drawn,
        **statistics("point_error_{}_mm", errors, "mean", "max"),
        **statistics("pointing_deviation_{}_deg", deviations, "mean", "std", "max"),
        **_end_errors_and_smoothness(robot, task, fk.point_mm, poses),
    }


# ----- 6-D pose paths (tasks with goal frames) ------------------------------------------------
def frame_errors(robot: Robot, task: Task, poses: npt.ArrayLike
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-waypoint errors of poses (n+1, dof) against a task with goal frames.

    Returns:
        (position errors (n+1,) [mm], rotation errors (n+1,) [deg]: the SO(3) geodesic angle
        |log(R_goal^T R)|, end points (n+1, 3) [mm]); FK by Pinocchio in float64.
    """

    T = robot.fk_transform(np.asarray(poses, dtype=float))
    points_mm = T[:, :3, 3] * 1000.0
    position = np.linalg.norm(points_mm - task.goal.points_mm, axis=1)
    rotation = np.degrees(geodesic_angle(cast(np.ndarray, task.goal.rotations), T[:, :3, :3]))
    return position, rotation, points_mm


def joint_changes(robot: Robot, poses: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Joint changes between consecutive poses in joint units: (revolute (n, r) [deg], wrapped
    to [-180, 180) as CppFlow does, so a continuous joint crossing +-180 moves a little;
    prismatic (n, p) [mm])."""
    q = robot.to_urdf(np.asarray(poses, dtype=float))
    steps = np.diff(q, axis=0)
    prismatic = robot.prismatic
    revolute = np.degrees(np.remainder(steps[:, ~prismatic] + np.pi, 2 * np.pi) - np.pi)
    return revolute, steps[:, prismatic] * 1000.0


def frame_metrics(robot: Robot, task: Task, poses: npt.ArrayLike) -> dict[str, Any]:
    """Figures of a trajectory against a 6-D pose path, with CppFlow's validity.

    Returns:
        dict with ``position_error_{mean,max}_mm``, ``rotation_error_{mean,max}_deg``,
        ``max_joint_change_deg`` (revolute and continuous joints, wrapped) and
        ``max_joint_change_mm`` (prismatic joints; NaN without one), ``joint_path_length_deg``
        (sum of the absolute wrapped revolute changes) and ``prismatic_path_length_mm``,
        ``cartesian_path_length_mm`` (the end point's path) and ``target_path_length_mm``,
        ``within_limits`` (the task's limits, e.g. CppFlow's bounds; a continuous joint by
        its turn within [-180, 180] deg, :func:`ikbench.core.robot.wrap_continuous`, since
        trajectory files are written unwrapped: a solver's raw 200 deg now passes as -160 deg
        where jrl's raw check refused it), the collision figures
        of :func:`ikbench.core.collision.check_trajectory` (``self_collisions``,
        ``env_collisions``, ``min_clearance_mm`` ..., ``collision_model``),
        ``initial_configuration_distance`` (rad, m; NaN when the task gives none), ``valid``
        (all of :func:`ikbench.core.validity.validity_failures`) and ``failed_criteria``
        (their names, ``""`` when valid).
    """

    poses = np.asarray(poses, dtype=float)
    position, rotation, points_mm = frame_errors(robot, task, poses)
    revolute, prismatic = joint_changes(robot, poses)
    lower, upper = task.limits(robot)
    judged = wrap_continuous(robot, poses)  # an unwrapped continuous joint: its turn in range
    within = bool(np.all(judged >= lower - 1e-9) and np.all(judged <= upper + 1e-9))
    out = {
        **statistics("position_error_{}_mm", position, "mean", "max"),
        **statistics("rotation_error_{}_deg", rotation, "mean", "max"),
        "max_joint_change_deg": float(np.abs(revolute).max()) if revolute.size else 0.0,
        "max_joint_change_mm": float(np.abs(prismatic).max()) if prismatic.size else np.nan,
        "joint_path_length_deg": float(np.abs(revolute).sum()),
        "prismatic_path_length_mm": float(np.abs(prismatic).sum()) if prismatic.size
        else np.nan,
        "cartesian_path_length_mm": float(np.linalg.norm(np.diff(points_mm, axis=0),
                                                         axis=1).sum()),
        "target_path_length_mm": float(np.linalg.norm(np.diff(task.goal.points_mm, axis=0),
                                                      axis=1).sum()),
        "within_limits": within,
        **check_trajectory(robot, poses, task.required.obstacles),
        "initial_configuration_distance": initial_distance(robot, task, poses),
    }
    failures = validity_failures(out)
    return {**out, "valid": not failures, "failed_criteria": ",".join(failures)}


def initial_distance(robot: Robot, task: Task, poses: npt.ArrayLike) -> float:
    """Euclidean distance (URDF units: rad, m) of the first pose from the task's initial pose
    (CppFlow's ``initial_q_norm_dist``); NaN when the task gives none."""
    initial = task.required.initial_pose
    if initial is None:
        return float("nan")
    first = robot.to_urdf(np.asarray(poses, dtype=float)[0])
    return float(np.linalg.norm(first - robot.to_urdf(np.asarray(initial, dtype=float))))


# ----- the task contract (ikbench.core.contract) -----------------------------------------------
def speed_limit_use(poses: npt.ArrayLike, max_step: npt.ArrayLike | None) -> float:
    """The largest joint change per segment over its allowed change (1.0: at the limit).

    Args:
        poses: (n+1, dof) poses [pose units].
        max_step: (dof,) allowed change per segment [pose units], or None (then NaN).
    """
    if max_step is None:
        return float("nan")
    steps = np.abs(np.diff(np.asarray(poses, dtype=float), axis=0))
    return float(np.max(steps / np.asarray(max_step, dtype=float), initial=0.0))


def contract_metrics(robot: Robot, task: Task, poses: npt.ArrayLike,
                     contract: Contract) -> dict[str, Any]:
    """The figures a :class:`ikbench.core.contract.Contract` judges, with the Table 1/2 ones.

    Returns:
        :func:`trajectory_metrics`'s figures and ``line_distance_max_mm`` (the largest
        distance of a pen-down point from the line), ``pointing_deviation_judged_mean_deg`` /
        ``_max_deg`` (over the judged steps i >= ``contract.judged_from(n)``; NaN when the
        contract does not judge pointing), ``speed_limit_use`` (:func:`speed_limit_use` at
        the contract's duration; NaN without speed limits), ``max_step_limit_deg`` (the
        smallest allowed change per segment over the joints) and ``within_limits`` (every
        pose within the task's limits). When the task carries obstacles (``Task.obstacles``)
        also ``self_collisions`` and ``env_collisions`` (waypoints in collision with the robot
        itself, with an obstacle), ``min_clearance_mm`` (the smallest signed distance to an
        obstacle), ``first_collision_waypoint`` (NaN: none), ``first_collision_pair``,
        ``collision_geometry`` and ``collision_check_ms`` (the check's geometry and wall time)
        (:func:`ikbench.core.collision.check_trajectory`; all NaN, "" for the pair, on a robot
        without a collision model: nothing can be checked, so the collision criterion fails).
        Obstacle-free tasks get none of these.
    """
    poses = np.asarray(poses, dtype=float)
    fk = robot.fk(poses)
    out: dict[str, Any] = _line_metrics(robot, task, poses, fk)
    mask = np.asarray(task.goal.pen_down, dtype=bool)
    out["line_distance_max_mm"] = float(line_distances_mm(
        fk.point_mm[mask], task.goal.start_point_mm, task.goal.end_point_mm).max())
    judged = np.zeros(len(poses), dtype=bool)
    judged[contract.judged_from(task.goal.steps):] = True
    judged &= mask
    if contract.pointing and judged.any():
        deviations = pointing_deviations_deg(fk.direction[judged], task.goal.directions[judged])
        out.update(statistics("pointing_deviation_judged_{}_deg", deviations, "mean", "max"))
    else:
        out["pointing_deviation_judged_mean_deg"] = float("nan")
        out["pointing_deviation_judged_max_deg"] = float("nan")
    max_step = contract.max_step(task.goal.steps)
    out["speed_limit_use"] = speed_limit_use(poses, max_step)
    out["max_step_limit_deg"] = float("nan") if max_step is None else float(np.min(max_step))
    lower, upper = task.limits(robot)
    out["within_limits"] = bool(np.all(poses >= lower - 1e-6) and np.all(poses <= upper + 1e-6))
    if task.required.obstacles:
        found = check_trajectory(robot, poses, task.required.obstacles)
        checked = found["collision_model"] != "none"
        for key in ("self_collisions", "env_collisions", "min_clearance_mm",
                    "first_collision_waypoint"):
            out[key] = found[key] if checked else float("nan")
        out["first_collision_pair"] = found["first_collision_pair"]
        out["collision_geometry"] = found["collision_geometry"]
        out["collision_check_ms"] = found["collision_check_ms"]
    return out


# ----- legibility, predictability, smoothness (ikbench.core.legibility) ------------------------
from ikbench.core.legibility import (  # noqa: E402,F401  (re-exported: ikbench.core.metrics.*)
    LEGIBILITY_COLUMNS,
    dimensionless_jerk,
    legibility_metrics,
    peak_joint_jerk,
    pointing_legibility,
    pointing_probabilities,
    position_legibility,
    position_probabilities,
    predictability,
)
