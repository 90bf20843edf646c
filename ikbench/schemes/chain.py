"""The robot's chain and a task's goals in URDF units (m, rad), as the library adapters take them.

Every library method converts once, here: :func:`chain_of` (the chain: its URDF text, joint
names, types and limits) and :func:`goals_of` (goal points [m], unit goal directions, optional
6-D goal rotations, start and touch poses [rad, m]). Back in pose units,
:func:`poses_from_urdf` converts the library's joint values and clips them onto the motor
ranges, a clip that only removes round-off (anything larger is a bug and raises).

Limits: a robot's limits are given in pose units (motor degrees for NICO, whose motor map has
negative scales); in URDF units they are the min / max of the two mapped limits, so lower <=
upper always. Continuous joints keep -inf / +inf.

The URDF text a library parses (:func:`chain_urdf_text`) is written from the robot's URDF model
(``Robot.urdf_model``, :mod:`ikbench.core.urdf_model`) reduced to what kinematics needs: no
``<visual>`` / ``<collision>`` elements (no mesh files to find; yourdfpy writes no
``<transmission>`` / ``<gazebo>`` either), every movable joint that is not one of the chain's
turned ``fixed`` (at 0, as the robot's Pinocchio model locks it, or at the config's locked value,
folded into its origin) and joint axes normalised (URDF axes are unit vectors by the
specification; ikpy and PyRoki use them as written).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.contract import speed_limits
from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError, SolverError

if TYPE_CHECKING:
    from ikbench.core.contract import Contract
    from ikbench.core.obstacles import Obstacle
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.core.urdf_model import UrdfModel

#: Largest clip [pose units] that counts as round-off in :func:`poses_from_urdf`.
ROUND_OFF = 1e-6

_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class Chain:
    """A robot's serial chain in URDF units.

    Attributes:
        urdf_path: the robot's URDF file.
        urdf_text: the URDF a library parses (see the module docstring).
        urdf: the robot's URDF model (its root link, the path to the end frame).
        base_link: the chain's base link; goals are in its frame.
        end_frame: the end link (its origin is the end point).
        joint_names: (dof,) the movable joints, base to end.
        joint_types: (dof,) ``revolute``, ``continuous`` or ``prismatic``.
        lower: (dof,) lower limits [rad, m]; -inf for continuous joints.
        upper: (dof,) upper limits [rad, m]; +inf for continuous joints.
        pointing_axis: (3,) unit axis of the end frame that points.
    """

    urdf_path: Path
    urdf_text: str
    urdf: UrdfModel
    base_link: str
    end_frame: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    pointing_axis: np.ndarray

    @property
    def dof(self) -> int:
        """Number of movable joints."""
        return len(self.joint_names)

    def clip(self, q: npt.ArrayLike) -> np.ndarray:
        """``q`` (..., dof) [rad, m] clipped onto the limits."""
        return np.clip(q, self.lower, self.upper)


@dataclass(frozen=True)
class Goals:
    """What one task asks for, in URDF units and the base frame.

    Attributes:
        points_m: (N, 3) goal points [m].
        directions: (N, 3) unit goal directions (of the pointing axis).
        rotations: (N, 3, 3) goal rotations of the end frame, or None (pointing goals only).
        q_start: (dof,) start pose [rad, m], or None when the task fixes none.
        q_touch: (dof,) touch (end) pose [rad, m], or None.
        q_home: (dof,) where a walk without a touch pose starts (a pose path: the task's
            reference pose, the robot's home), or None.
        track: the per-step targets of the tracking scheme
            (:class:`ikbench.schemes.track.TrackPlan`) when the method tracks from the
            start pose, else None (the walk).
        contract: the task's contract (:class:`ikbench.core.contract.Contract`), or None.
        max_step: (dof,) the largest joint change per segment [rad, m]
            (:func:`max_step_urdf`), or None when no speed limit is known.
        obstacles: the task's obstacles (:class:`ikbench.core.obstacles.Obstacle`, base frame
            [mm], as given), for the adapters that keep clear of them
            (:func:`ikbench.schemes.collision.scene_of`); empty: none.
    """

    points_m: np.ndarray
    directions: np.ndarray
    rotations: np.ndarray | None
    q_start: np.ndarray | None
    q_touch: np.ndarray | None
    q_home: np.ndarray | None = None
    track: Any = None
    contract: Contract | None = None
    max_step: np.ndarray | None = None
    obstacles: tuple[Obstacle, ...] = ()

    def __len__(self) -> int:
        return len(self.points_m)


def urdf_limits(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper), each (dof,), in URDF units [rad, m]: min / max of the mapped pose
    limits (a negative motor scale swaps them); continuous joints stay -inf / +inf."""
    a = robot.to_urdf(np.asarray(robot.lower, dtype=float))
    b = robot.to_urdf(np.asarray(robot.upper, dtype=float))
    return np.minimum(a, b), np.maximum(a, b)


def chain_urdf_text(robot: Robot) -> str:
    """The robot's URDF as the libraries parse it (see the module docstring), written from the
    robot's URDF model."""
    urdf = robot.urdf_model
    keep = set(robot.joint_names)
    fixed = {j.name: float(robot.locked_urdf.get(j.name, 0.0)) for j in urdf.joints
             if j.movable and j.name not in keep}
    return urdf.to_xml(collisions=False, fixed=fixed, unit_axes=True)


def chain_of(robot: Robot) -> Chain:
    """The robot's :class:`Chain` (cached per robot object)."""
    if robot not in _CHAINS:
        lower, upper = urdf_limits(robot)
        axis = np.asarray(robot.pointing_axis, dtype=float)
        _CHAINS[robot] = Chain(Path(robot.urdf_path), chain_urdf_text(robot), robot.urdf_model,
                               robot.root_link, robot.end_frame, tuple(robot.joint_names),
                               tuple(robot.joint_types), lower, upper,
                               axis / np.linalg.norm(axis))
    return _CHAINS[robot]


def goals_of(robot: Robot, task: Task) -> Goals:
    """The task's goals in URDF units (6-D rotations from ``task.goal.rotations`` if any),
    with its contract and obstacles."""
    directions = np.asarray(task.goal.directions, dtype=float)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    rotations = task.goal.rotations

    def pose(value):
        return None if value is None else robot.to_urdf(np.asarray(value, dtype=float))

    contract = task.required.contract
    return Goals(np.asarray(task.goal.points_mm, dtype=float) / 1000.0, directions,
                 None if rotations is None else np.asarray(rotations, dtype=float),
                 pose(task.required.start_pose), pose(task.required.end_pose),
                 pose(task.hints.reference_pose), contract=contract,
                 max_step=max_step_urdf(robot, contract, len(task.goal.points_mm) - 1),
                 obstacles=task.required.obstacles)


def urdf_step(robot: Robot, pose_step: npt.ArrayLike) -> np.ndarray:
    """(dof,) a joint change [pose units] in URDF units [rad, m] (the pose map is affine:
    |scale| times the change, deg to rad, mm to m)."""
    return np.abs(robot.to_urdf(np.asarray(pose_step, dtype=float))
                  - robot.to_urdf(np.zeros(robot.dof)))


def contract_step(goals: Goals, margin: float = 1.0) -> np.ndarray | None:
    """(dof,) ``margin`` times the contract's largest joint change per segment [rad, m]
    (``goals.max_step``); None when the task has no contract or no speed limit is known."""
    if goals.contract is None or goals.max_step is None:
        return None
    return margin * goals.max_step


def max_step_urdf(robot: Robot, contract: Contract | None, steps: int) -> np.ndarray | None:
    """(dof,) the largest joint change per segment [rad, m]: the contract's speed limits at
    its duration (:meth:`~ikbench.core.contract.Contract.max_step`); without a contract the
    robot's own limits at the default duration; None when no speed limit is known."""

    if contract is not None:
        step = contract.max_step(steps)
    else:
        speed, _ = speed_limits(robot)
        step = None if speed is None else np.asarray(speed) * DEFAULT_DURATION_S / steps
    return None if step is None else urdf_step(robot, step)


def poses_from_urdf(robot: Robot, q_urdf: npt.ArrayLike) -> np.ndarray:
    """Joint values (N, dof) [rad, m] -> poses [pose units], clipped onto the motor ranges.

    The clip only removes round-off of the unit conversion: the adapters keep their joint
    values within the URDF limits, which map onto the motor ranges.

    Raises:
        SolverError: a pose lies more than :data:`ROUND_OFF` outside the ranges (a bug).
    """
    poses = robot.from_urdf(np.asarray(q_urdf, dtype=float))
    clipped = np.clip(poses, robot.lower, robot.upper)
    excess = float(np.max(np.abs(clipped - poses), initial=0.0))
    if excess > ROUND_OFF:
        raise SolverError(f"a pose leaves the motor ranges by {excess:.3g} (pose units) after "
                          "the conversion from URDF units; the adapter should have kept it "
                          "within the limits")
    return clipped


def element_path(chain: Chain) -> list[tuple[str, str, str]]:
    """The joints from the chain's base link down to its end frame as (joint, type, child
    link), with the types of :func:`chain_urdf_text` (a joint off the chain is fixed)."""
    path = chain.urdf.path_between(chain.base_link, chain.end_frame)
    return [(j.name, j.type if j.name in chain.joint_names else "fixed", j.child)
            for j in path]


def require_touch_and_start(task: Task, method: str) -> None:
    """InputError unless the task fixes both the start and the touch pose (whole-path
    methods pin both ends)."""
    if task.required.start_pose is None or task.required.end_pose is None:
        missing = "start" if task.required.start_pose is None else "touch"
        raise InputError(f"trajectory {task.name!r}: {method} optimises the path between the "
                         "fixed start and touch poses; the task fixes "
                         f"no {missing} pose"
                         " (for letters, polylines and splines use --method ours or "
                         "--method ours-lm)")
