"""Sequential damped-least-squares IK on Pinocchio: the paper's "traditional" baseline.

The walk starts at the touch pose and solves one IK problem per goal point, from P_{n-1} back
to P_0, each initialised with the previous solution; the poses are then reversed so the
trajectory runs start -> touch. Pose n *is* the touch pose (bit for bit). Nothing couples the
points except the initialisation, so the start pose is wherever the walk ends up.

Each point is solved in the URDF's joint space (radians) by damped least squares on the
frame Jacobian, as in Pinocchio's CLIK example::

    dq = J^T (J J^T + damping^2 I)^-1 e,    q <- clamp(q + ik_step * dq, URDF limits)

where e is the task error (goal minus current; metres and radians) and J its Jacobian. A joint
that sits on a limit and would be pushed further out is dropped from J for that step (an
active set), so the other joints keep making progress instead of stalling. A point stops when
||e|| < tolerance, when the applied step is below :data:`STALL_STEP_RAD` (stuck: the target is
out of reach), or at ``max_ik_iterations``; the last two count as "tolerance not reached".

Orientation modes (``orientation``):

- ``"frame"`` (default; the paper's text): the full 6-D frame. Position = goal point; rotation
  with z-axis = goal direction d and x-axis = up x d (normalised), i.e. the roll fixed by a
  constant reference "up" vector. The error is Pinocchio's ``log6`` of the current-to-goal
  transform in the end frame; its Jacobian is ``-Jlog6 . J_local``. The default up vector
  (``"touch"``) is the y-axis of the touch pose's end frame, so the target roll is the touch
  pose's roll; world-fixed up vectors make the target unreachable along most of the line.
- ``"pointing"``: 5-D, position plus pointing axis, roll free. Residual: position (3) and the
  pointing axis z projected on two unit vectors b1, b2 orthogonal to d (zero when z = d),
  with Jacobian rows (z x b_k)^T J_angular.
- ``"position"``: 3-D, position only. This is what the authors' ikpy baseline actually solved:
  their code passed a target frame to ikpy's ``inverse_kinematics_frame`` without an
  ``orientation_mode``, and ikpy then ignores the rotation.

A 6-D pose path (a task with goal frames, e.g. a CppFlow problem) has no touch pose: it is
walked forward instead, waypoint 0 solved from the home pose (at most
:data:`FIRST_POINT_ITERATIONS` iterations), each next one from the previous solution, with the
task's goal rotations in frame mode and the task's joint limits (CppFlow's bounds).

``Solution.loss`` is None (the task errors are not a loss in the paper's units); the largest
position error [mm], the largest orientation error [deg] (frame: rotation angle; pointing and
position: angle between z and d) over the solved points and the number of points that did not
reach the tolerance go to ``Solution.info`` (and so to details.csv). The walk is deterministic.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.base import Method, Solution, check_choice, check_positive, option

ORIENTATIONS = ("frame", "pointing", "position")
#: ``up_vector`` value that takes the roll from the touch pose (y-axis of its end frame).
UP_FROM_TOUCH = "touch"
#: An applied step smaller than this [rad, max over joints] means the solve is stuck.
STALL_STEP_RAD = 1e-10
#: Joints closer than this to a limit [rad] count as sitting on it.
LIMIT_EPS_RAD = 1e-12


@dataclass
class DLSSettings:
    """Settings of the damped-least-squares solve of one point (CLI options from ``option``).

    Attributes:
        orientation: ``"frame"``, ``"pointing"`` or ``"position"`` (see the module doc).
        damping: lambda in dq = J^T (J J^T + lambda^2 I)^-1 e [units of e: m, rad].
        ik_step: fraction of dq applied per iteration (1 = full Gauss-Newton step).
        tolerance: stop when ||e|| < tolerance; e in metres and radians (1e-6: 1 um, 0.06 mdeg).
        max_ik_iterations: iteration cap per point.
        up_vector: ``"touch"`` or a (3,) vector fixing the roll in ``frame`` mode.
    """

    orientation: str = option("frame", choices=ORIENTATIONS,
                              help="frame (6-D, the paper's text), pointing (position + "
                              "pointing axis, roll free) or position (what the authors' ikpy "
                              "call solved)")
    damping: float = option(1e-3, unit="m, rad", help="DLS damping lambda")
    ik_step: float = option(1.0, help="fraction of the DLS step applied, in (0, 1]")
    tolerance: float = option(1e-6, unit="m, rad",
                              help="stop a point when the task error norm is below this")
    max_ik_iterations: int = option(100, help="iteration cap per point")
    up_vector: str | tuple = option(UP_FROM_TOUCH, type=str,
                                    help="frame mode: reference up vector x,y,z fixing the roll "
                                    "(x-axis = up x d); 'touch' takes the touch pose's roll")

    def __post_init__(self):
        check_choice(self, "orientation", ORIENTATIONS)
        check_positive(self, "damping", "ik_step", "tolerance")
        if self.ik_step > 1:
            raise InputError(f"--ik-step: {self.ik_step!r} must be in (0, 1]")
        check_positive(self, "max_ik_iterations", integer=True)
        self.max_ik_iterations = int(self.max_ik_iterations)
        self.up_vector = parse_up_vector(self.up_vector)


class PointResult(NamedTuple):
    """Result of one IK solve: joint angles (nv,) [rad], iterations, final ||e||, converged."""

    q_rad: np.ndarray
    iterations: int
    error_norm: float
    converged: bool


#: |up x d| below this (unit vectors) means the up vector cannot fix the roll.
PARALLEL_EPS = 1e-9


def format_vector(vector) -> str:
    """``(0.1, -0.53, 0.84)``: a vector as plain numbers (6 significant digits)."""
    return "(" + ", ".join(f"{float(v):.6g}" for v in np.ravel(vector)) + ")"


def check_up_vector(up, direction, where: str = "") -> None:
    """InputError if ``up`` (3,) is parallel to ``direction`` (3,): the roll would be undefined.

    Args:
        up: reference up vector (any length but zero).
        direction: goal direction d (any length but zero).
        where: what the direction belongs to, for the message (``"trajectory 1"``).
    """
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    u = np.asarray(up, dtype=float) / np.linalg.norm(up)
    if np.linalg.norm(np.cross(u, z)) < PARALLEL_EPS:
        of = f" of {where}" if where else ""
        raise InputError(f"--up-vector: {format_vector(up)} is parallel to the goal direction"
                         f"{of} {format_vector(z)}, so it cannot fix the roll; give a vector "
                         "at an angle to it, or 'touch'")


def rotation_from_z(direction, up) -> np.ndarray:
    """Rotation (3, 3) with z-axis ``direction`` and x-axis up x z, y = z x x (columns).

    Raises:
        InputError: ``up`` is parallel to ``direction`` (see :func:`check_up_vector`).
    """
    check_up_vector(up, direction)
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    x = np.cross(np.asarray(up, dtype=float), z)
    x = x / np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def axis_frame(axis) -> np.ndarray:
    """A fixed rotation M (3, 3) of the end frame whose z-axis is the pointing ``axis``
    (identity for z): frame mode builds the goal of the frame R M, so R_goal = V M^T."""
    a = np.asarray(axis, dtype=float)
    if np.allclose(a, [0.0, 0.0, 1.0]):
        return np.eye(3)
    helper = np.eye(3)[np.argmin(np.abs(a))]
    return rotation_from_z(a, helper)


def orthonormal_complement(direction) -> np.ndarray:
    """Two unit vectors (2, 3) orthogonal to ``direction`` and to each other."""
    d = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    helper = np.eye(3)[np.argmin(np.abs(d))]
    b1 = np.cross(d, helper)
    b1 /= np.linalg.norm(b1)
    return np.stack([b1, np.cross(d, b1)])


class Residual:
    """Task error e (goal - current) and its Jacobian de/dq for one goal, via Pinocchio.

    Args:
        pin_fk: the robot's :class:`ikbench.core.kinematics.PinocchioFK` (model and frame id).
        data: a ``pinocchio.Data`` of that model (scratch space).
        orientation: ``"frame"``, ``"pointing"`` or ``"position"``.
        point_m: (3,) goal point [m].
        rotation: (3, 3) goal rotation (frame mode) or None.
        direction: (3,) unit goal direction (pointing mode) or None.
    """

    def __init__(self, pin_fk, data, orientation, point_m, rotation=None, direction=None):
        import pinocchio as pin

        self.pin, self.model, self.data = pin, pin_fk.model, data
        self.frame_id = pin_fk.frame_id
        self.orientation = orientation
        self.point_m = np.asarray(point_m, dtype=float)
        self.goal = pin.SE3(rotation, self.point_m) if orientation == "frame" else None
        self.basis = None if direction is None else orthonormal_complement(direction)
        self.direction = direction
        self.axis = pin_fk.robot.pointing_axis

    def error(self, q_rad) -> np.ndarray:
        """e (k,) at ``q_rad``; also leaves the placement in ``self.data``."""
        pin = self.pin
        pin.framesForwardKinematics(self.model, self.data, q_rad)
        T_base_tip = self.data.oMf[self.frame_id]
        if self.orientation == "frame":
            self._tip_M_goal = T_base_tip.actInv(self.goal)
            return pin.log6(self._tip_M_goal).vector  # (6,) in the end frame
        e_pos = self.point_m - T_base_tip.translation
        if self.orientation == "position":
            return e_pos
        z = T_base_tip.rotation @ self.axis                  # the pointing axis
        return np.concatenate([e_pos, -(self.basis @ z)])

    def jacobian(self, q_rad) -> np.ndarray:
        """-de/dq (k, nv): the Jacobian of the current task quantity (call :meth:`error` at
        the same q first)."""
        pin = self.pin
        if self.orientation == "frame":
            J_local = pin.computeFrameJacobian(self.model, self.data, q_rad, self.frame_id,
                                               pin.LOCAL)
            # e = log6(tip^-1 goal) plays "goal - current": de/dq = -Jlog6 J_local (Pinocchio's
            # CLIK example), so the Jacobian of the "current" quantity is +Jlog6 J_local.
            return pin.Jlog6(self._tip_M_goal.inverse()) @ J_local
        J = pin.computeFrameJacobian(self.model, self.data, q_rad, self.frame_id,
                                     pin.LOCAL_WORLD_ALIGNED)  # (6, nv): linear, angular
        if self.orientation == "position":
            return J[:3]
        z = self.data.oMf[self.frame_id].rotation @ self.axis
        # d(b.z) = b.(w x z) = (z x b).w
        rows = np.cross(z, self.basis) @ J[3:]
        return np.vstack([J[:3], rows])


def dls_step(J, e, damping, q_rad, lower, upper) -> np.ndarray:
    """Damped-least-squares step dq (nv,) with joints pushed past a limit left out.

    Args:
        J: (k, nv) Jacobian of the *current* task quantity (e = goal - current).
        e: (k,) task error.
        damping: lambda.
        q_rad, lower, upper: (nv,) joint angles and URDF limits [rad].
    """
    free = np.ones(len(q_rad), dtype=bool)
    regulariser = damping**2 * np.eye(len(e))
    for _ in range(len(q_rad)):
        J_free = J * free
        dq = J_free.T @ np.linalg.solve(J_free @ J_free.T + regulariser, e)
        blocked = free & (((q_rad <= lower + LIMIT_EPS_RAD) & (dq < 0))
                          | ((q_rad >= upper - LIMIT_EPS_RAD) & (dq > 0)))
        if not blocked.any():
            break
        free &= ~blocked
    return dq


def solve_point(residual: Residual, q0_rad, settings: DLSSettings, lower, upper) -> PointResult:
    """Solve one point by DLS from ``q0_rad`` (nv,) [rad]; returns the last iterate."""
    q = np.clip(np.asarray(q0_rad, dtype=float), lower, upper)
    iterations = 0
    while True:
        e = residual.error(q)
        norm = float(np.linalg.norm(e))
        if norm < settings.tolerance:
            return PointResult(q, iterations, norm, True)
        if iterations >= settings.max_ik_iterations:
            return PointResult(q, iterations, norm, False)
        dq = dls_step(residual.jacobian(q), e, settings.damping, q, lower, upper)
        q_next = np.clip(q + settings.ik_step * dq, lower, upper)
        iterations += 1
        if np.max(np.abs(q_next - q)) < STALL_STEP_RAD:
            return PointResult(q_next, iterations, float(np.linalg.norm(residual.error(q_next))),
                               False)
        q = q_next


class Walk(NamedTuple):
    """The raw result of the walk, before the conversion to motor degrees.

    Attributes:
        q_rad: (n+1, nv) joint angles [rad] as the IK left them; row n is the touch pose
            converted to radians (where the walk starts), rows n-1..0 the solved points.
        iterations: total IK iterations over the n points.
        points_not_converged: points whose solve stopped without reaching the tolerance.
        max_position_error_mm: largest fingertip distance from its goal point [mm].
        max_orientation_error_deg: largest orientation error [deg] (see the module doc).
        up: (3,) up vector used in frame mode (root frame), or None in the other modes.
    """

    q_rad: np.ndarray
    iterations: int
    points_not_converged: int
    max_position_error_mm: float
    max_orientation_error_deg: float
    up: np.ndarray | None


def walk_joint_rad(robot, task, settings: DLSSettings) -> Walk:
    """The walk from the touch pose back to P_0 in the URDF's joint space (see the module doc).

    Raises:
        InputError: the task has no touch pose, or the up vector is parallel to the line.
    """
    if task.end_pose_deg is None:
        raise InputError(f"trajectory {task.name!r}: sequential-ik starts at the touch pose; "
                         "the task has no end pose (for letters, polylines and splines use "
                         "--method ours or --method ours-lm)")
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    q = robot.motor_to_joint_rad(np.asarray(task.end_pose_deg, dtype=float))
    up = _up_vector(settings, pin_fk, q)
    n = task.steps
    q_rad = np.empty((n + 1, len(q)))
    q_rad[n] = q
    iterations, missed, worst_pos_mm, worst_angle_deg = 0, 0, 0.0, 0.0
    for i in range(n - 1, -1, -1):
        d = task.goal_directions[i]
        rotation = (rotation_from_z(d, up) @ axis_frame(robot.pointing_axis).T
                    if settings.orientation == "frame" else None)
        residual = Residual(pin_fk, data, settings.orientation, task.goal_points_mm[i] / 1000.0,
                            rotation, d if settings.orientation == "pointing" else None)
        result = solve_point(residual, q_rad[i + 1], settings, lower, upper)
        q_rad[i] = result.q_rad
        iterations += result.iterations
        missed += not result.converged
        pos_mm, angle_deg = _point_errors(pin_fk, data, result.q_rad, task, i, rotation)
        worst_pos_mm, worst_angle_deg = max(worst_pos_mm, pos_mm), max(worst_angle_deg, angle_deg)
    return Walk(q_rad, iterations, missed, worst_pos_mm, worst_angle_deg, up)


#: Iteration cap of the first waypoint of a pose path, solved from the home pose.
FIRST_POINT_ITERATIONS = 1000


def walk_path_rad(robot, task, settings: DLSSettings) -> Walk:
    """A 6-D pose path walked forward: waypoint 0 by IK from the task's start pose (else its
    reference, the robot's home pose), each next waypoint from the previous solution. In frame
    mode the goal rotations are the task's; the joints stay within the task's limits."""
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    low, high = task.limits(robot)
    lower = np.maximum(pin_fk.model.lowerPositionLimit, robot.to_urdf(np.asarray(low, float)))
    upper = np.minimum(pin_fk.model.upperPositionLimit, robot.to_urdf(np.asarray(high, float)))
    home = task.start_pose_deg if task.start_pose_deg is not None else task.reference_pose_deg
    q = robot.to_urdf(np.zeros(robot.dof) if home is None else np.asarray(home, dtype=float))
    q_rad = np.empty((task.steps + 1, len(q)))
    iterations, missed, worst_pos_mm, worst_angle_deg = 0, 0, 0.0, 0.0
    first = replace(settings, max_ik_iterations=max(settings.max_ik_iterations,
                                                    FIRST_POINT_ITERATIONS))
    for i in range(task.steps + 1):
        rotation = task.goal_rotations[i] if settings.orientation == "frame" else None
        residual = Residual(pin_fk, data, settings.orientation, task.goal_points_mm[i] / 1000.0,
                            rotation, task.goal_directions[i]
                            if settings.orientation == "pointing" else None)
        result = solve_point(residual, q, first if i == 0 else settings, lower, upper)
        q = q_rad[i] = result.q_rad
        iterations += result.iterations
        missed += not result.converged
        pos_mm, angle_deg = _point_errors(pin_fk, data, q, task, i, rotation)
        worst_pos_mm, worst_angle_deg = max(worst_pos_mm, pos_mm), max(worst_angle_deg, angle_deg)
    return Walk(q_rad, iterations, missed, worst_pos_mm, worst_angle_deg, None)


def walk(robot, task, settings: DLSSettings) -> Solution:
    """The sequential walk as a :class:`Solution` in motor degrees (see the module doc).

    Poses 0..n-1 are the IK's joint angles converted to motor degrees (and clipped to the
    motor ranges, which the URDF limits the IK respects map onto: the clip only removes
    round-off); pose n is the touch pose as given (the walk's starting point, not solved).
    """
    started = time.perf_counter()
    if task.goal_rotations is not None:
        raw = walk_path_rad(robot, task, settings)
        poses_deg = np.clip(robot.joint_rad_to_motor_deg(raw.q_rad), *task.limits(robot))
    else:
        raw = walk_joint_rad(robot, task, settings)
        poses_deg = np.clip(robot.joint_rad_to_motor_deg(raw.q_rad), robot.lower_motor_deg,
                            robot.upper_motor_deg)
        poses_deg[-1] = task.end_pose_deg  # exactly the touch pose, no round trip
    duration = time.perf_counter() - started
    missed = raw.points_not_converged
    return Solution(
        poses_deg=poses_deg, iterations=raw.iterations, duration_s=duration, loss=None,
        converged=missed == 0,
        info={"points_not_converged": missed, "points_solved": task.steps,
              "max_position_error_mm": raw.max_position_error_mm,
              "max_orientation_error_deg": raw.max_orientation_error_deg,
              "orientation": settings.orientation,
              "up_vector": "" if raw.up is None else ",".join(f"{v:.6f}" for v in raw.up)},
    )


def check_tasks(robot, tasks, settings: DLSSettings) -> None:
    """Fail before any solve: every task needs a touch pose, and in frame mode an up vector
    that is not parallel to its line (InputError naming the trajectory)."""
    pin_fk = robot.pinocchio_fk()
    for task in tasks:
        if task.goal_rotations is not None:  # a pose path: walked forward, its own rotations
            continue
        if task.end_pose_deg is None:
            raise InputError(f"trajectory {task.name!r}: sequential-ik starts at the touch "
                             "pose; the task has no end pose (for letters, polylines and "
                             "splines use --method ours or --method ours-lm)")
        if settings.orientation != "frame":
            continue
        up = _up_vector(settings, pin_fk,
                        robot.motor_to_joint_rad(np.asarray(task.end_pose_deg, dtype=float)))
        for d in np.unique(np.asarray(task.goal_directions, dtype=float), axis=0):
            check_up_vector(up, d, f"trajectory {task.name}")


def _up_vector(settings: DLSSettings, pin_fk, q_touch_rad) -> np.ndarray | None:
    """The (3,) up vector of frame mode (None in the other modes)."""
    if settings.orientation != "frame":
        return None
    setting = settings.up_vector
    if isinstance(setting, str) and setting == UP_FROM_TOUCH:
        rotation = pin_fk.placement(q_touch_rad).rotation @ axis_frame(pin_fk.robot.pointing_axis)
        return rotation[:, 1].copy()
    return np.asarray(setting, dtype=float)


def _point_errors(pin_fk, data, q_rad, task, i, rotation) -> tuple[float, float]:
    """Position error [mm] and orientation error [deg] of the solved point i."""
    import pinocchio as pin

    pin.framesForwardKinematics(pin_fk.model, data, q_rad)
    T_base_tip = data.oMf[pin_fk.frame_id]
    pos_mm = float(np.linalg.norm(T_base_tip.translation * 1000.0 - task.goal_points_mm[i]))
    if rotation is not None:
        angle = np.linalg.norm(pin.log3(T_base_tip.rotation.T @ rotation))
    else:
        z, d = T_base_tip.rotation @ pin_fk.robot.pointing_axis, task.goal_directions[i]
        angle = math.atan2(np.linalg.norm(np.cross(z, d)), float(z @ d))
    return pos_mm, float(np.degrees(angle))


def parse_up_vector(value) -> str | tuple:
    """``"touch"`` or ``"x,y,z"`` (or a sequence of 3 numbers) -> the setting; InputError else."""
    if isinstance(value, str):
        if value.strip() == UP_FROM_TOUCH:
            return UP_FROM_TOUCH
        parts = value.split(",")
    else:
        parts = list(value)
    try:
        vector = tuple(float(p) for p in parts)
    except (TypeError, ValueError):
        vector = ()
    if len(vector) != 3 or not all(map(math.isfinite, vector)) or not any(vector):
        raise InputError(f"--up-vector: {value!r} must be 'touch' or three finite numbers "
                         "x,y,z (not all zero), in the robot's root frame")
    return vector


class SequentialIK(Method):
    """Point-by-point damped-least-squares IK walked back from the touch pose."""

    name = "sequential-ik"
    description = ("baseline: point-by-point damped-least-squares IK on Pinocchio, walked "
                   "back from the touch pose")
    library = "pin"
    Settings = DLSSettings
    requires_touch_pose = True
    supports_frames = True

    def prepare(self, robot) -> None:
        robot.pinocchio_fk()

    def check_tasks(self, robot, tasks) -> None:
        """Every task needs a touch pose or goal frames, and in frame mode an up vector that
        is not parallel to its line (:func:`check_tasks`)."""
        check_tasks(robot, tasks, self.settings)

    def solve(self, robot, task, progress=None) -> Solution:
        return walk(robot, task, self.settings)
