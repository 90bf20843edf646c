"""Sequential damped-least-squares IK on Pinocchio: the paper's "traditional" baseline.

Two schemes (``scheme``):

- ``"track"`` (default, ``sequential-ik``; the paper's task,
:mod:`ikbench.schemes.track`):
  pose 0 *is* the start pose and pose n the touch pose (both exactly as given); points 1..n-1 are
  solved forward, each from the pose before, towards the plan's goal point and scheduled
  pointing direction (position only when the task asks no pointing). Three additions make
  the poses playable:

  * a posture term in the null space of the task, ``dq += (I - J^+ J) k (q_posture - q)``
    per iteration (k = ``posture_gain``, J^+ the exact pseudo-inverse, q_posture on the line
    from the start to the touch pose), which resolves the redundancy without disturbing the
    task;
  * speed bounds: each step's joints stay within ``max_speed_use`` of the joints' speed limit
    per segment around the pose before, and close enough to the touch pose to land on it in
    the steps left (|q_i - q_touch| <= (n - i) max step). The DLS treats these bounds like the
    joint limits (active set); a step they keep from its goals stops short, "not converged";
  * the orientation rows of the task error weighted by ``orientation_weight`` [m/rad], so a
    step that cannot meet both goals within its bounds gives up pointing before position.

- ``"walk"`` (``sequential-ik-walk``, the paper's Table 2 scheme, frame mode): starts at the
  touch pose and solves one IK problem per goal point, from P_{n-1} back to P_0, each
  initialised with the previous solution; the poses are then reversed so the trajectory runs
  start -> touch. Pose n *is* the touch pose (bit for bit). Nothing couples the points except
  the initialisation, so the start pose is wherever the walk ends up.

Each point is solved in the URDF's joint space (radians) by damped least squares on the
frame Jacobian, as in Pinocchio's CLIK example::

    dq = J^T (J J^T + damping^2 I)^-1 e,    q <- clamp(q + ik_step * dq, URDF limits)

where e is the task error (goal minus current; metres and radians) and J its Jacobian. A joint
that sits on a limit and would be pushed further out is dropped from J for that step (an
active set), so the other joints keep making progress instead of stalling. A point stops when
||e|| < tolerance, when the applied step is below :data:`STALL_STEP_RAD` (stuck: the target is
out of reach), or at ``max_ik_iterations``; the last two count as "tolerance not reached".

Orientation modes (``orientation``):

- ``"frame"`` (the paper's text; default of ``sequential-ik-walk``): the full 6-D frame.
  Position = goal point; rotation with z-axis = goal direction d and x-axis = up x d
  (normalised), i.e. the roll fixed by a constant reference "up" vector. The error is
  Pinocchio's ``log6`` of the current-to-goal transform in the end frame; its Jacobian is
  ``-Jlog6 . J_local``. The default up vector (``"touch"``) is the y-axis of the touch pose's
  end frame, so the target roll is the touch pose's roll; world-fixed up vectors make the
  target unreachable along most of the line.
- ``"pointing"`` (default of ``sequential-ik``): 5-D, position plus pointing axis, roll
  free. Residual: position (3) and the pointing axis z projected on two unit vectors b1, b2
  orthogonal to d (zero when z = d), with Jacobian rows (z x b_k)^T J_angular.
- ``"position"``: 3-D, position only. This is what the authors' ikpy baseline actually solved:
  their code passed a target frame to ikpy's ``inverse_kinematics_frame`` without an
  ``orientation_mode``, and ikpy then ignores the rotation.

On the track, frame mode builds its goal rotation from the scheduled direction.

A 6-D pose path (a task with goal frames, e.g. a CppFlow problem) has no touch pose: it is
walked forward instead (in either scheme; in frame mode on the track, whatever
``orientation`` says), waypoint 0 solved from the home pose (at most
:data:`FIRST_POINT_ITERATIONS` iterations), each next one from the previous solution, with the
task's goal rotations in frame mode and the task's joint limits (CppFlow's bounds).

``Solution.loss`` is None (the task errors are not a loss in the paper's units); the largest
position error [mm], the largest orientation error [deg] (frame: rotation angle; pointing and
position: angle between z and d) over the solved points and the number of points that did not
reach the tolerance go to ``Solution.info`` (and so to details.csv). Both schemes are
deterministic.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.methods.base import Capabilities, Method, Solution, report_fraction
from ikbench.methods.options import check_choice, check_fraction, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import goals_of, max_step_urdf
from ikbench.schemes.single_pose import (
    LIBRARY_TOLERANCE,
    MAX_STEPS,
    PoseOut,
    PoseSolver,
)
from ikbench.schemes.track import (
    SCHEME_HELP,
    SCHEMES,
    plan_track,
    require_start_and_touch,
    speed_box,
)

if TYPE_CHECKING:
    from ikbench.core.kinematics.pinocchio_fk import PinocchioFK
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.base import Progress

ORIENTATIONS = ("frame", "pointing", "position")
#: ``up_vector`` value that takes the roll from the touch pose (y-axis of its end frame).
UP_FROM_TOUCH = "touch"
#: An applied step smaller than this [rad, max over joints] means the solve is stuck.
STALL_STEP_RAD = 1e-10
#: Joints closer than this to a limit [rad] count as sitting on it.
LIMIT_EPS_RAD = 1e-12
#: Singular values of J below this times the largest span no task direction (the null-space
#: projector of the posture term).
NULL_SPACE_RCOND = 1e-9


ORIENTATION_HELP = ("frame (6-D, the paper's text), pointing (position + pointing axis, roll "
                    "free) or position (what the authors' ikpy call solved)")


@dataclass
class DLSSettings:
    """Settings of the damped-least-squares solve of one point (CLI options from ``option``).

    Attributes:
        scheme: ``"track"`` (forward from the start pose onto the touch pose, the paper's
            task) or ``"walk"`` (the authors' walk back from the touch pose).
        orientation: ``"frame"``, ``"pointing"`` or ``"position"`` (see the module doc).
        damping: lambda in dq = J^T (J J^T + lambda^2 I)^-1 e [units of e: m, rad].
        ik_step: fraction of dq applied per iteration (1 = full Gauss-Newton step).
        tolerance: stop when ||e|| < tolerance; e in metres and radians (1e-6: 1 um, 0.06 mdeg).
        max_ik_iterations: iteration cap per point.
        up_vector: ``"touch"`` or a (3,) vector fixing the roll in ``frame`` mode.
        posture_gain: scheme track: gain k of the null-space posture term
            dq += (I - J^+ J) k (q_posture - q) per iteration (0: none).
    """

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    orientation: str = option("pointing", choices=ORIENTATIONS, help=ORIENTATION_HELP)
    damping: float = option(1e-3, unit="m, rad", help="DLS damping lambda")
    ik_step: float = option(1.0, help="fraction of the DLS step applied, in (0, 1]")
    tolerance: float = option(1e-6, unit="m, rad",
                              help="stop a point when the task error norm is below this")
    max_ik_iterations: int = option(100, help="iteration cap per point")
    up_vector: str | tuple = option(UP_FROM_TOUCH, type=str,
                                    help="frame mode: reference up vector x,y,z fixing the roll "
                                    "(x-axis = up x d); 'touch' takes the touch pose's roll")
    max_speed_use: float = option(0.95, unit="of the limit",
                                  help="scheme track: every joint's change per step is kept "
                                  "within this fraction of its speed limit per segment, and "
                                  "close enough to the touch pose to land on it in time (0: no "
                                  "bound)")
    orientation_weight: float = option(0.02, unit="m/rad",
                                       help="scheme track: weight of the orientation rows of "
                                       "the task error against the position rows (a step that "
                                       "cannot meet both gives up the orientation first)")
    posture_gain: float = option(0.1, help="scheme track: gain k of the null-space posture "
                                 "term (I - J^+ J) k (q_posture - q) added to every DLS step, "
                                 "q_posture on the line from the start to the touch pose "
                                 "(0: none)")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_choice(self, "orientation", ORIENTATIONS)
        check_positive(self, "damping", "ik_step", "tolerance", "orientation_weight")
        if self.ik_step > 1:
            raise InputError(f"--ik-step: {self.ik_step!r} must be in (0, 1]")
        check_positive(self, "max_ik_iterations", integer=True)
        self.max_ik_iterations = int(self.max_ik_iterations)
        self.up_vector = parse_up_vector(self.up_vector)
        check_fraction(self, "max_speed_use")
        check_fraction(self, "posture_gain")


@dataclass
class WalkDLSSettings(DLSSettings):
    """:class:`DLSSettings` with the paper's Table 2 defaults: the walk back from the touch
    pose, 6-D frame targets (``sequential-ik-walk``)."""

    scheme: str = option("walk", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    orientation: str = option("frame", choices=ORIENTATIONS, help=ORIENTATION_HELP)


class PointResult(NamedTuple):
    """Result of one IK solve: joint angles (nv,) [rad], iterations, final ||e||, converged."""

    q_rad: np.ndarray
    iterations: int
    error_norm: float
    converged: bool


#: |up x d| below this (unit vectors) means the up vector cannot fix the roll.
PARALLEL_EPS = 1e-9


def format_vector(vector: npt.ArrayLike) -> str:
    """``(0.1, -0.53, 0.84)``: a vector as plain numbers (6 significant digits)."""
    return "(" + ", ".join(f"{float(v):.6g}" for v in np.ravel(vector)) + ")"


def check_up_vector(up: npt.ArrayLike, direction: npt.ArrayLike, where: str = "") -> None:
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


def rotation_from_z(direction: npt.ArrayLike, up: npt.ArrayLike) -> np.ndarray:
    """Rotation (3, 3) with z-axis ``direction`` and x-axis up x z, y = z x x (columns).

    Raises:
        InputError: ``up`` is parallel to ``direction`` (see :func:`check_up_vector`).
    """
    check_up_vector(up, direction)
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    x = np.cross(np.asarray(up, dtype=float), z)
    x = x / np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def axis_frame(axis: npt.ArrayLike) -> np.ndarray:
    """A fixed rotation M (3, 3) of the end frame whose z-axis is the pointing ``axis``
    (identity for z): frame mode builds the goal of the frame R M, so R_goal = V M^T."""
    a = np.asarray(axis, dtype=float)
    if np.allclose(a, [0.0, 0.0, 1.0]):
        return np.eye(3)
    helper = np.eye(3)[np.argmin(np.abs(a))]
    return rotation_from_z(a, helper)


def orthonormal_complement(direction: npt.ArrayLike) -> np.ndarray:
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

    def __init__(self, pin_fk: PinocchioFK, data: Any, orientation: str, point_m: npt.ArrayLike,
                 rotation: np.ndarray | None = None, direction: np.ndarray | None = None
                 ) -> None:
        import pinocchio as pin

        self.pin, self.model, self.data = pin, pin_fk.model, data
        self.frame_id = pin_fk.frame_id
        self.orientation = orientation
        self.point_m = np.asarray(point_m, dtype=float)
        self.goal = pin.SE3(rotation, self.point_m) if orientation == "frame" else None
        self.basis = None if direction is None else orthonormal_complement(direction)
        self.direction = direction
        self.axis = pin_fk.robot.pointing_axis

    def error(self, q_rad: np.ndarray) -> np.ndarray:
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

    def jacobian(self, q_rad: np.ndarray) -> np.ndarray:
        """-de/dq (k, nv): the Jacobian of the current task quantity (call :meth:`error` at
        the same q first)."""
        pin = self.pin
        if self.orientation == "frame":
            J_local = pin.computeFrameJacobian(self.model, self.data, q_rad, self.frame_id,
                                               pin.LOCAL)
            # e = log6(tip^-1 goal) plays "goal - current": de/dq = -Jlog6 J_local (Pinocchio's
            # CLIK example), so the Jacobian of the "current" quantity is +Jlog6 J_local.
            return np.einsum("ij,jk->ik", pin.Jlog6(self._tip_M_goal.inverse()), J_local)
        J = pin.computeFrameJacobian(self.model, self.data, q_rad, self.frame_id,
                                     pin.LOCAL_WORLD_ALIGNED)  # (6, nv): linear, angular
        if self.orientation == "position":
            return J[:3]
        z = self.data.oMf[self.frame_id].rotation @ self.axis
        # d(b.z) = b.(w x z) = (z x b).w
        assert self.basis is not None  # pointing mode has a direction
        rows = np.cross(z, self.basis) @ J[3:]
        return np.vstack([J[:3], rows])


class WeightedResidual:
    """A :class:`Residual` with its orientation rows (after the 3 position rows) scaled by
    ``weight`` [m per rad]: when a step cannot meet both goals (the tracking scheme's speed
    bounds), the DLS then gives up orientation before position."""

    def __init__(self, residual: Residual, weight: float) -> None:
        self.residual = residual
        self.scale = None if weight == 1.0 else weight

    def _scaled(self, rows: np.ndarray) -> np.ndarray:
        if self.scale is None or len(rows) <= 3:
            return rows
        rows = rows.copy()
        rows[3:] *= self.scale
        return rows

    def error(self, q_rad: np.ndarray) -> np.ndarray:
        return self._scaled(self.residual.error(q_rad))

    def jacobian(self, q_rad: np.ndarray) -> np.ndarray:
        return self._scaled(self.residual.jacobian(q_rad))


def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x (k,) of A x = b for the small symmetric positive definite A (k, k) of a DLS step,
    by Gaussian elimination in elementwise numpy operations: no BLAS or LAPACK call, whose
    kernels OpenBLAS picks for the CPU (``OPENBLAS_CORETYPE``), so the last bits, and with
    them a chaotic descent's answer, are the same on every machine."""
    k = len(b)
    M = np.concatenate([A, b[:, None]], axis=1)  # (k, k + 1)
    for i in range(k):
        if not M[i, i] > 0.0:
            raise np.linalg.LinAlgError("DLS system not positive definite")
        M[i + 1:] -= np.multiply.outer(M[i + 1:, i] / M[i, i], M[i])
    x = np.zeros(k)
    for i in range(k - 1, -1, -1):
        x[i] = (M[i, k] - (M[i, i + 1:k] * x[i + 1:]).sum()) / M[i, i]
    return x


def dls_step(J: np.ndarray, e: np.ndarray, damping: float, q_rad: np.ndarray,
             lower: np.ndarray, upper: np.ndarray, posture: np.ndarray | None = None
             ) -> np.ndarray:
    """Damped-least-squares step dq (nv,) with joints pushed past a limit left out.

    Args:
        J: (k, nv) Jacobian of the *current* task quantity (e = goal - current).
        e: (k,) task error.
        damping: lambda.
        q_rad, lower, upper: (nv,) joint angles and URDF limits [rad].
        posture: (nv,) a secondary joint step v, projected onto the null space of J,
            (I - J^+ J) v with the exact pseudo-inverse (singular values of J below
            :data:`NULL_SPACE_RCOND` times the largest count as zero): it cannot disturb the
            task; or None (none).
    """
    free = np.ones(len(q_rad), dtype=bool)
    regulariser = damping**2 * np.eye(len(e))
    for _ in range(len(q_rad)):
        J_free = J * free
        # einsum's own loops, not BLAS (see solve_spd)
        dq = np.einsum("ki,k->i", J_free,
                       solve_spd(np.einsum("ik,jk->ij", J_free, J_free) + regulariser, e))
        if posture is not None:
            _, sigma, Vt = np.linalg.svd(J_free, full_matrices=False)
            rows = Vt[sigma > NULL_SPACE_RCOND * max(sigma[0], 1e-300)]
            v = posture * free
            dq = dq + v - rows.T @ (rows @ v)
        blocked = free & (((q_rad <= lower + LIMIT_EPS_RAD) & (dq < 0))
                          | ((q_rad >= upper - LIMIT_EPS_RAD) & (dq > 0)))
        if not blocked.any():
            break
        free &= ~blocked
    return dq


def solve_point(residual: Residual | WeightedResidual, q0_rad: npt.ArrayLike,
                settings: DLSSettings, lower: np.ndarray, upper: np.ndarray,
                posture_rad: np.ndarray | None = None) -> PointResult:
    """Solve one point by DLS from ``q0_rad`` (nv,) [rad]; returns the last iterate.

    ``posture_rad`` (nv,): a pose the redundancy is pulled toward in the task's null space,
    ``settings.posture_gain`` (q_posture - q) per iteration (the tracking scheme), or None.
    """
    q = np.clip(np.asarray(q0_rad, dtype=float), lower, upper)
    use_posture = posture_rad is not None and settings.posture_gain > 0
    iterations = 0
    while True:
        e = residual.error(q)
        norm = float(np.linalg.norm(e))
        if norm < settings.tolerance:
            return PointResult(q, iterations, norm, True)
        if iterations >= settings.max_ik_iterations:
            return PointResult(q, iterations, norm, False)
        posture = (settings.posture_gain * (posture_rad - q)
                   if use_posture and posture_rad is not None else None)
        dq = dls_step(residual.jacobian(q), e, settings.damping, q, lower, upper, posture)
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


def walk_joint_rad(robot: Robot, task: Task, settings: DLSSettings) -> Walk:
    """The walk from the touch pose back to P_0 in the URDF's joint space (see the module doc).

    Raises:
        InputError: the task has no touch pose, or the up vector is parallel to the line.
    """
    if task.required.end_pose is None:
        raise InputError(f"trajectory {task.name!r}: sequential-ik starts at the touch pose; "
                         "the task has no end pose (for letters, polylines and splines use "
                         "--method ours or --method ours-lm)")
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    q = robot.motor_to_joint_rad(np.asarray(task.required.end_pose, dtype=float))
    up = _up_vector(settings, pin_fk, q)
    n = task.goal.steps
    q_rad = np.empty((n + 1, len(q)))
    q_rad[n] = q
    iterations, missed, worst_pos_mm, worst_angle_deg = 0, 0, 0.0, 0.0
    for i in range(n - 1, -1, -1):
        d = task.goal.directions[i]
        rotation = (rotation_from_z(d, cast(np.ndarray, up))  # frame mode has an up vector
                    @ axis_frame(robot.pointing_axis).T
                    if settings.orientation == "frame" else None)
        residual = Residual(pin_fk, data, settings.orientation, task.goal.points_mm[i] / 1000.0,
                            rotation, d if settings.orientation == "pointing" else None)
        result = solve_point(residual, q_rad[i + 1], settings, lower, upper)
        q_rad[i] = result.q_rad
        iterations += result.iterations
        missed += not result.converged
        pos_mm, angle_deg = _point_errors(pin_fk, data, result.q_rad, task, i, rotation)
        worst_pos_mm, worst_angle_deg = max(worst_pos_mm, pos_mm), max(worst_angle_deg, angle_deg)
        report_fraction(n - i, n)
    return Walk(q_rad, iterations, missed, worst_pos_mm, worst_angle_deg, up)


#: Iteration cap of the first waypoint of a pose path, solved from the home pose.
FIRST_POINT_ITERATIONS = 1000


def walk_path_rad(robot: Robot, task: Task, settings: DLSSettings) -> Walk:
    """A 6-D pose path walked forward: waypoint 0 by IK from the task's start pose (else its
    reference, the robot's home pose), each next waypoint from the previous solution. In frame
    mode the goal rotations are the task's; the joints stay within the task's limits."""
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    low, high = (robot.to_urdf(np.asarray(v, dtype=float)) for v in task.limits(robot))
    # a negative motor scale (NICO) swaps the mapped limits: min / max of the two
    lower = np.maximum(pin_fk.model.lowerPositionLimit, np.minimum(low, high))
    upper = np.minimum(pin_fk.model.upperPositionLimit, np.maximum(low, high))
    home = (task.required.start_pose if task.required.start_pose is not None
            else task.hints.reference_pose)
    q = robot.to_urdf(np.zeros(robot.dof) if home is None else np.asarray(home, dtype=float))
    q_rad = np.empty((task.goal.steps + 1, len(q)))
    iterations, missed, worst_pos_mm, worst_angle_deg = 0, 0, 0.0, 0.0
    first = replace(settings, max_ik_iterations=max(settings.max_ik_iterations,
                                                    FIRST_POINT_ITERATIONS))
    for i in range(task.goal.steps + 1):
        rotation = (cast(np.ndarray, task.goal.rotations)[i]  # a pose path has goal frames
                    if settings.orientation == "frame" else None)
        residual = Residual(pin_fk, data, settings.orientation, task.goal.points_mm[i] / 1000.0,
                            rotation, task.goal.directions[i]
                            if settings.orientation == "pointing" else None)
        result = solve_point(residual, q, first if i == 0 else settings, lower, upper)
        q = q_rad[i] = result.q_rad
        iterations += result.iterations
        missed += not result.converged
        pos_mm, angle_deg = _point_errors(pin_fk, data, q, task, i, rotation)
        worst_pos_mm, worst_angle_deg = max(worst_pos_mm, pos_mm), max(worst_angle_deg, angle_deg)
        report_fraction(i + 1, task.goal.steps + 1)
    return Walk(q_rad, iterations, missed, worst_pos_mm, worst_angle_deg, None)


def track_joint_rad(robot: Robot, task: Task, settings: DLSSettings) -> Walk:
    """The tracking scheme in the URDF's joint space (see the module doc): row 0 the start
    pose, rows 1..n-1 solved forward, each from the row before, row n the touch pose.

    Raises:
        InputError: the task lacks the start or the touch pose.
    """

    require_start_and_touch(task, "sequential-ik")
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    plan = plan_track(robot, task, goals_of(robot, task))
    n = task.goal.steps
    q_rad = np.empty((n + 1, len(plan.q_start)))
    q_rad[0], q_rad[n] = plan.q_start, plan.q_touch
    up = None if plan.directions is None else _up_vector(settings, pin_fk, plan.q_touch)
    step = (max_step_urdf(robot, task.required.contract, task.goal.steps)
            if settings.max_speed_use > 0 else None)
    iterations, missed, worst_pos_mm, worst_angle_deg = 0, 0, 0.0, 0.0
    for i in range(1, n):
        direction = None if plan.directions is None else plan.directions[i]
        mode = "position" if direction is None else settings.orientation
        rotation = (rotation_from_z(cast(np.ndarray, direction), cast(np.ndarray, up))
                    @ axis_frame(robot.pointing_axis).T  # frame mode: both are set
                    if mode == "frame" else None)
        residual = WeightedResidual(Residual(pin_fk, data, mode, plan.points_m[i], rotation,
                                             direction if mode == "pointing" else None),
                                    settings.orientation_weight)
        low, high = lower, upper
        if step is not None:  # within the speed limits of the pose before and of the landing
            low, high = speed_box(q_rad[i - 1], plan.q_touch, n - i,
                                  settings.max_speed_use * step, lower, upper)
            low = np.minimum(low, high)  # an empty box (a start too far away): the landing
        result = solve_point(residual, q_rad[i - 1], settings, low, high, plan.posture[i])
        q_rad[i] = result.q_rad
        iterations += result.iterations
        missed += not result.converged
        pos_mm, angle_deg = _point_errors(pin_fk, data, result.q_rad, task, i, rotation,
                                          direction)
        worst_pos_mm, worst_angle_deg = max(worst_pos_mm, pos_mm), max(worst_angle_deg, angle_deg)
        report_fraction(i, n - 1)
    return Walk(q_rad, iterations, missed, worst_pos_mm, worst_angle_deg, up)


def walk(robot: Robot, task: Task, settings: DLSSettings) -> Solution:
    """The sequential walk as a :class:`Solution` in motor degrees (see the module doc),
    whatever ``settings.scheme`` says (:func:`solve_task` picks the scheme).

    Poses 0..n-1 are the IK's joint angles converted to motor degrees (and clipped to the
    motor ranges, which the URDF limits the IK respects map onto: the clip only removes
    round-off); pose n is the touch pose as given (the walk's starting point, not solved).
    """
    started = time.perf_counter()
    if task.goal.rotations is not None:
        raw = walk_path_rad(robot, task, settings)
        poses_deg = np.clip(robot.joint_rad_to_motor_deg(raw.q_rad), *task.limits(robot))
    else:
        raw = walk_joint_rad(robot, task, settings)
        poses_deg = np.clip(robot.joint_rad_to_motor_deg(raw.q_rad), robot.lower,
                            robot.upper)
        poses_deg[-1] = task.required.end_pose  # exactly the touch pose, no round trip
    return _solution(raw, poses_deg, settings, started, "walk")


def track(robot: Robot, task: Task, settings: DLSSettings) -> Solution:
    """The tracking scheme as a :class:`Solution` in motor degrees: pose 0 the start pose and
    pose n the touch pose, exactly as given; poses 1..n-1 the IK's (clipped like
    :func:`walk`'s)."""
    started = time.perf_counter()
    raw = track_joint_rad(robot, task, settings)
    poses_deg = np.clip(robot.joint_rad_to_motor_deg(raw.q_rad), robot.lower,
                        robot.upper)
    poses_deg[0] = task.required.start_pose
    poses_deg[-1] = task.required.end_pose
    return _solution(raw, poses_deg, settings, started, "track")


def solve_task(robot: Robot, task: Task, settings: DLSSettings) -> Solution:
    """One task by ``settings.scheme``: :func:`track` or :func:`walk`. A pose path (goal
    frames) is always walked forward (it has no start and touch pose to track between); in
    the track scheme it follows its goal frames (frame mode), as the walk's default does."""
    if settings.scheme != "track":
        return walk(robot, task, settings)
    if task.goal.rotations is not None:
        return walk(robot, task, replace(settings, orientation="frame"))
    return track(robot, task, settings)


def _solution(raw: Walk, poses_deg, settings: DLSSettings, started: float,
              scheme: str) -> Solution:
    duration = time.perf_counter() - started
    missed = raw.points_not_converged
    info = {"points_not_converged": missed, "points_solved": len(poses_deg) - 1,
            "max_position_error_mm": raw.max_position_error_mm,
            "max_orientation_error_deg": raw.max_orientation_error_deg,
            "orientation": settings.orientation,
            "up_vector": "" if raw.up is None else ",".join(f"{v:.6f}" for v in raw.up)}
    if scheme == "track":
        info = {**info, "points_solved": len(poses_deg) - 2, "scheme": "track",
                "posture_gain": settings.posture_gain}
    return Solution(poses=poses_deg, iterations=raw.iterations, duration_s=duration,
                    loss=None, converged=missed == 0, info=info)


def check_tasks(robot: Robot, tasks: Sequence[Task], settings: DLSSettings,
                method: str = "sequential-ik") -> None:
    """Fail before any solve: the walk needs a touch pose, the track a start and a touch pose
    (a pose path needs neither: it is walked forward), and frame mode an up vector that is not
    parallel to any goal direction asked (InputError naming the trajectory)."""

    pin_fk = robot.pinocchio_fk()
    for task in tasks:
        if task.goal.rotations is not None:  # a pose path: walked forward, its own rotations
            continue
        tracked = settings.scheme == "track"
        if tracked:
            require_start_and_touch(task, method)
        elif task.required.end_pose is None:
            raise InputError(f"trajectory {task.name!r}: {method} starts at the touch "
                             "pose; the task has no end pose (for letters, polylines and "
                             "splines use --method ours or --method ours-lm)")
        if settings.orientation != "frame":
            continue
        directions = task.goal.directions
        if tracked:
            directions = plan_track(robot, task, goals_of(robot, task)).directions
            if directions is None:  # nothing to point: position only
                continue
        up = _up_vector(settings, pin_fk,
                        robot.motor_to_joint_rad(np.asarray(task.required.end_pose, dtype=float)))
        for d in np.unique(np.asarray(directions, dtype=float), axis=0):
            check_up_vector(cast(np.ndarray, up), d, f"trajectory {task.name}")  # frame mode


def _up_vector(settings: DLSSettings, pin_fk, q_touch_rad) -> np.ndarray | None:
    """The (3,) up vector of frame mode (None in the other modes)."""
    if settings.orientation != "frame":
        return None
    setting = settings.up_vector
    if isinstance(setting, str) and setting == UP_FROM_TOUCH:
        rotation = pin_fk.placement(q_touch_rad).rotation @ axis_frame(pin_fk.robot.pointing_axis)
        return rotation[:, 1].copy()
    return np.asarray(setting, dtype=float)


def _point_errors(pin_fk, data, q_rad, task, i, rotation, direction=None) -> tuple[float, float]:
    """Position error [mm] and orientation error [deg] of the solved point i (the angle to
    ``direction`` when given, else to the task's goal direction i)."""
    import pinocchio as pin

    pin.framesForwardKinematics(pin_fk.model, data, q_rad)
    T_base_tip = data.oMf[pin_fk.frame_id]
    pos_mm = float(np.linalg.norm(T_base_tip.translation * 1000.0 - task.goal.points_mm[i]))
    if rotation is not None:
        angle = np.linalg.norm(pin.log3(T_base_tip.rotation.T @ rotation))
    else:
        z = T_base_tip.rotation @ pin_fk.robot.pointing_axis
        d = task.goal.directions[i] if direction is None else direction
        angle = math.atan2(np.linalg.norm(np.cross(z, d)), float(z @ d))
    return pos_mm, float(np.degrees(angle))


def parse_up_vector(value: str | Sequence[float]) -> str | tuple:
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
    """Point-by-point damped-least-squares IK: tracked forward from the start pose onto the
    touch pose (scheme track, the default) or walked back from the touch pose (walk)."""

    name = "sequential-ik"
    description = ("baseline: point-by-point damped-least-squares IK on Pinocchio, tracked "
                   "from the start pose onto the touch pose, pointing mode, null-space posture "
                   "(--scheme walk: back from the touch pose)")
    library = "pin"
    Settings = DLSSettings
    capabilities = Capabilities(needs_touch_pose=True, frames=True)

    def prepare(self, robot: Robot) -> None:
        robot.pinocchio_fk()

    def fixed_poses(self) -> frozenset[str]:
        """Both poses for the track; the walk keeps only the touch pose (its start pose is
        wherever the walk ends up)."""
        if self.settings.scheme == "walk":
            return frozenset({"touch_pose"})
        return frozenset({"start_pose", "touch_pose"})

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        """The walk needs a touch pose, the track a start and a touch pose (pose paths are
        walked forward), frame mode an up vector not parallel to a line
        (:func:`check_tasks`)."""
        check_tasks(robot, tasks, self.settings, self.name)

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        return solve_task(robot, task, self.settings)


class SequentialIKWalk(SequentialIK):
    """The paper's Table 2 scheme: walked back from the touch pose, 6-D frame targets."""

    name = "sequential-ik-walk"
    description = ("baseline: point-by-point damped-least-squares IK on Pinocchio, the "
                   "authors' walk back from the touch pose (the start pose is free), 6-D frame "
                   "targets")
    Settings = WalkDLSSettings


class DLSSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`): the
    damped least squares of :func:`solve_point` on Pinocchio, frame mode (position only for
    points), until the error is below the library tolerance or 100 steps."""

    rank = 50
    name, library, modules = "sequential-ik", "pin", ("pinocchio",)
    iterations_are = "DLS steps"
    attempt_bound = "1e-6, 100 DLS steps"
    #: benchmarks/determinism_check.py: the same answers under OpenBLAS' other kernels and
    #: thread counts since the step stopped calling BLAS (solve_spd).
    stable_across_machines = True

    def prepare(self) -> None:
        self.fk = self.robot.pinocchio_fk()
        self.data = self.fk.model.createData()
        self.settings = DLSSettings(tolerance=LIBRARY_TOLERANCE, max_ik_iterations=MAX_STEPS)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        mode = "frame" if self.kind == "pose" else "position"
        residual = Residual(self.fk, self.data, mode, point_m, rotation)
        out = solve_point(residual, q_init, self.settings, self.chain.lower, self.chain.upper)
        return PoseOut(out.q_rad, out.iterations, out.converged)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="pin", requires=("pinocchio",),
                  methods=(SequentialIK, SequentialIKWalk), solvers=(DLSSolver,), rank=40)
