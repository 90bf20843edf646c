"""The designer's live judgement: each requirement of the task, its figure, its limit, met or not.

Lines are judged by the task contract exactly as ``ikbench compare`` judges them
(:func:`ikbench.core.metrics.contract_metrics`, :func:`ikbench.core.contract.judge`): touch
and start pose, joint limits, the speed limit, the distance from the line, pointing over the
judged part, and collisions when the task has obstacles; the speed limit at the designer's
duration T. Under ``min-jerk`` or ``topp`` the speed is the timed motion's: each segment's
joint change over the time the timing gives it, against the joints' speed limits. Letters are
judged by their curve distance and pointing (the contract's line and pointing tolerances),
6-D pose paths by CppFlow's validity (:mod:`ikbench.core.validity`). Every task also gets the
joint limits with the joint closest to one, and, where the robot has a collision model and
the task no obstacles, self-collisions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ikbench.core.collision import check_trajectory, collision_model
from ikbench.core.contract import (
    COLLISION_CRITERION,
    CRITERIA,
    DEFAULT_TOLERANCES,
    Contract,
    contract_for,
    judge,
)
from ikbench.core.metrics import contract_metrics, frame_metrics, shape_metrics
from ikbench.core.robot import Robot, wrap_continuous
from ikbench.core.task import Task
from ikbench.core.timing import TimedPath
from ikbench.core.validity import (
    MAX_JOINT_CHANGE_DEG,
    MAX_POSITION_ERROR_MM,
    MAX_ROTATION_ERROR_DEG,
)

#: How the panel names each criterion.
LABELS = {"start_pose": "start pose", "end_pose": "touch pose", "limits": "joint limits",
          "speed": "max step vs speed limit", "line": "line distance",
          "pointing": "pointing", COLLISION_CRITERION: "collisions", "curve": "curve distance",
          "position": "position error", "rotation": "rotation error",
          "joint_change": "joint change per waypoint", "reach": "distance from the point"}
#: The unit of a figure that is a share of a limit (1.0: at the limit).
SHARE = "x limit"


@dataclass(frozen=True)
class Criterion:
    """One requirement as the panel shows it.

    Attributes:
        name: the criterion (a key of :data:`LABELS`).
        value: its figure (NaN: not measurable), in ``unit``.
        limit: the tolerance it is held to (None: a yes/no criterion).
        unit: ``"mm"``, ``"deg"``, ``"x limit"`` (a share of a limit), ``""``...
        ok: met.
        note: a detail (the joint closest to its limit, the first colliding pair...).
        shown: the figure in words, where a number says less (``none``, ``within``).
    """

    name: str
    value: float
    limit: float | None
    unit: str
    ok: bool
    note: str = ""
    shown: str = ""

    @property
    def label(self) -> str:
        """The criterion in words."""
        return LABELS.get(self.name, self.name.replace("_", " "))

    def text(self) -> str:
        """``OK line distance: 2.31 mm (limit 5 mm)``, or ``FAIL ...`` when not met; a share
        of a limit in per cent (``53 % of the limit``)."""
        sign = "OK" if self.ok else "FAIL"
        note = f"; {self.note}" if self.note else ""
        if self.shown:
            return f"{sign} {self.label}: {self.shown}{note}"
        if math.isnan(self.value):
            return f"{sign} {self.label}: n/a{note}"
        if self.unit == SHARE:
            limit = "" if self.limit is None else f" (at most {100 * self.limit:g} %)"
            return f"{sign} {self.label}: {100 * self.value:.0f} % of the limit{limit}{note}"
        unit = f" {self.unit}" if self.unit else ""
        limit = "" if self.limit is None else f" (limit {self.limit:g}{unit})"
        return f"{sign} {self.label}: {self.value:.3g}{unit}{limit}{note}"


def speed(robot: Robot, timed: TimedPath, max_speed: np.ndarray) -> Criterion:
    """The largest joint speed over its limit (1.0: at the limit) of a timed path: each
    segment's joint change over the time the timing gives it, against ``max_speed`` (dof,)
    [pose units/s] (under ``constant`` timing: the largest step against the step the limit
    allows in T/n, as the contract's ``speed_limit_use``)."""
    steps = np.abs(np.diff(timed.poses, axis=0))
    use = steps / np.maximum(timed.segment_s, 1e-12)[:, None] / np.asarray(max_speed, float)
    segment, joint = np.unravel_index(np.argmax(use), use.shape)
    value = float(use[segment, joint])
    if timed.timing == "constant":
        allowed = float(max_speed[joint] * timed.segment_s[segment])
        note = (f"{robot.joint_names[joint]}: {steps[segment, joint]:.3g} {robot.pose_unit} "
                f"in a step, {allowed:.3g} allowed (T = {timed.duration_s:.3g} s)")
    else:
        note = (f"{robot.joint_names[joint]}, the fastest under {timed.timing} "
                f"(T = {timed.duration_s:.3g} s)")
    tolerance = DEFAULT_TOLERANCES["speed_limit_use"]
    return Criterion("speed", value, tolerance, SHARE, value <= tolerance, note)


def limit_margins(robot: Robot, task: Task, poses: np.ndarray) -> tuple[float, str]:
    """(the smallest distance of any pose from a joint limit [pose units] (negative:
    beyond it), which joint and which limit in words)."""
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    poses = wrap_continuous(robot, poses)  # an unwrapped roll: its turn within the bounds
    to_lower, to_upper = poses.min(axis=0) - lower, upper - poses.max(axis=0)
    margins = np.minimum(to_lower, to_upper)
    joint = int(np.argmin(margins))
    side = "lower" if to_lower[joint] <= to_upper[joint] else "upper"
    value = float(margins[joint])
    if not math.isfinite(value):
        return value, "no joint has a finite limit"
    if abs(value) < 1e-3:
        return value, f"{robot.joint_names[joint]} at its {side} limit"
    return value, f"{robot.joint_names[joint]} {value:.3g} {robot.pose_unit} from its {side} limit"


def judge_design(robot: Robot, task: Task, timed: TimedPath) -> list[Criterion]:
    """Every criterion of ``task`` for the timed trajectory (see the module doc)."""
    poses = timed.poses
    if task.goal.has_frames:
        out = _path_criteria(robot, task, poses)
    elif task.goal.curve is not None:
        out = _shape_criteria(robot, task, timed)
    else:
        out = _line_criteria(robot, task, timed)
    if COLLISION_CRITERION not in {c.name for c in out} and collision_model(robot) is not None:
        found = check_trajectory(robot, poses, ())
        out.append(_collisions(found))
    return out


def _contract(robot: Robot, task: Task, timed: TimedPath) -> Contract:
    """The task's contract (a letter's: the robot's) at the timing's duration."""
    base = task.required.contract if task.required.contract is not None else contract_for(robot)
    return replace(base, duration_s=timed.duration_s)


def _line_criteria(robot: Robot, task: Task, timed: TimedPath) -> list[Criterion]:
    contract = _contract(robot, task, timed)
    figures = contract_metrics(robot, task, timed.poses, contract)
    moving = None
    if contract.max_speed is not None:  # the timed motion's (the same figure under constant)
        moving = speed(robot, timed, contract.max_speed)
        figures["speed_limit_use"] = moving.value
    verdict = judge(contract, figures)
    unit = robot.pose_unit
    units = {"start_pose": unit, "end_pose": unit, "line": "mm", "pointing": "deg"}
    out = []
    for name, ok in verdict.items():
        if name == COLLISION_CRITERION:
            out.append(_collisions(figures))
        elif name == "limits":
            out.append(_limits(robot, task, timed.poses))
        elif name == "speed" and moving is not None:
            out.append(replace(moving, limit=float(contract.tolerances["speed_limit_use"]),
                               ok=ok))
        else:
            column, key = CRITERIA[name]
            out.append(Criterion(name, float(figures[column]),
                                 None if key is None else float(contract.tolerances[key]),
                                 units.get(name, ""), ok))
    return out


def _shape_criteria(robot: Robot, task: Task, timed: TimedPath) -> list[Criterion]:
    figures = shape_metrics(robot, task, timed.poses)
    contract = _contract(robot, task, timed)
    tolerance = contract.tolerances
    curve = float(figures["curve_distance_max_mm"])
    pointing = float(figures["pointing_deviation_mean_deg"])
    out = [Criterion("curve", curve, tolerance["line_distance_max_mm"], "mm",
                     curve <= tolerance["line_distance_max_mm"], "the largest, pen down"),
           Criterion("pointing", pointing, tolerance["pointing_judged_mean_deg"], "deg",
                     pointing <= tolerance["pointing_judged_mean_deg"], "the mean, pen down"),
           _limits(robot, task, timed.poses)]
    if contract.max_speed is not None:
        out.append(speed(robot, timed, contract.max_speed))
    return out


def _path_criteria(robot: Robot, task: Task, poses: np.ndarray) -> list[Criterion]:
    figures = frame_metrics(robot, task, poses)
    failed = set(str(figures["failed_criteria"]).split(","))
    out = [Criterion("position", figures["position_error_max_mm"], MAX_POSITION_ERROR_MM,
                     "mm", "position" not in failed, "CppFlow's, every waypoint"),
           Criterion("rotation", figures["rotation_error_max_deg"], MAX_ROTATION_ERROR_DEG,
                     "deg", "rotation" not in failed),
           Criterion("joint_change", figures["max_joint_change_deg"], MAX_JOINT_CHANGE_DEG,
                     "deg", "joint_change" not in failed),
           _limits(robot, task, poses)]
    if task.required.obstacles:
        out.append(_collisions(figures))
    return out


def _limits(robot: Robot, task: Task, poses: np.ndarray) -> Criterion:
    margin, note = limit_margins(robot, task, poses)
    ok = not margin < -1e-6
    return Criterion("limits", margin, None, robot.pose_unit, ok, f"closest: {note}",
                     "every pose within" if ok else "beyond")


def _collisions(figures: dict[str, Any]) -> Criterion:
    """Waypoints in collision (self and with obstacles) from collision figures."""
    self_hits, env_hits = figures.get("self_collisions"), figures.get("env_collisions")
    try:
        count = float(self_hits) + float(env_hits)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        count = math.nan
    pair = figures.get("first_collision_pair") or ""
    if count == 0:
        return Criterion(COLLISION_CRITERION, count, None, "waypoints", True, "", "none")
    note = f"{self_hits} self, {env_hits} with obstacles" + (f"; first: {pair}" if pair else "")
    shown = "not checked" if math.isnan(count) else f"{count:.0f} waypoints"
    return Criterion(COLLISION_CRITERION, count, None, "waypoints", False, note, shown)
