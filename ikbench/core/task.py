"""Tasks: the goal points and goal directions a trajectory must follow.

A :class:`Task` holds its :class:`Goal` (n+1 goal points P^g_i [mm] and unit goal directions
v^g_i), its :class:`Requirements` (the start and end poses [pose units] that the start/end loss
terms pin, joint limits, obstacles, contract) and its :class:`Hints` (reference pose, default
weights). The paper's task is the straight line of Eq. 1 from FK(start pose) to FK(touch
pose), pointing along it.

:func:`build_tasks` makes the tasks of any shape (``--shape``):

- ``line``: one line per touch pose of the targets file (the paper's task).
- ``polyline:FILE`` / ``spline:FILE``: control points [mm, torso frame] from a CSV file
  (:func:`ikbench.core.shapes.read_points_csv`), joined by straight lines or a centripetal
  Catmull-Rom spline; one task named after the file's stem. No pose is pinned.
- ``letter:P`` or ``letter:P,A,B``: one task per letter, named after it, drawn on the frontal
  plane through the fingertip at the start pose (:mod:`ikbench.core.letters`). No pose is pinned
  and the task asks for the paper's letter weights (no start/end pose or point terms).

Curves are resampled to n+1 goal points evenly by arc length. Goal directions default to the
path tangent (line, polyline, spline) or the drawing plane's normal (letters).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from ikbench.core import letters
from ikbench.core.contract import Contract, contract_for
from ikbench.core.errors import InputError
from ikbench.core.obstacles import Obstacle
from ikbench.core.robot import Robot
from ikbench.core.shapes import Curve, catmull_rom, read_points_csv
from ikbench.core.targets import Targets, load_targets
from ikbench.core.weights import FRAME_WEIGHTS, PAPER_WEIGHTS

#: Below this distance [mm] start and touch points coincide and a line has no direction.
MIN_LINE_LENGTH_MM = 1e-6
#: ``Task.pen_down`` when none is given: every point is drawn (an (n+1,) array once built).
_EVERY_POINT = np.ones(0, dtype=bool)


@dataclass(frozen=True, eq=False)
class Goal:
    """What a task asks for: the path the end frame must follow.

    Attributes:
        points_mm: (n+1, 3) goal points P^g_i in the robot root frame [mm].
        directions: (n+1, 3) unit goal pointing directions v^g_i.
        rotations: (n+1, 3, 3) goal frames' rotations (end frame in the base frame) of a
            6-D pose path, or None. A goal with frames asks for the full orientation; its
            ``directions`` are then the rotations' pointing axes.
        pen_down: (n+1,) bool, True where the point belongs to the drawn shape (metrics skip
            the others, e.g. pen-up moves between strokes); not given (or None): every point.
        curve: the target curve the goal points were sampled from; None for a line (the
            segment from P^s to P^e).
        shape: the shape's name (``"line"``, ...).
    """

    points_mm: np.ndarray
    directions: np.ndarray
    rotations: np.ndarray | None = None
    pen_down: np.ndarray = field(default_factory=lambda: _EVERY_POINT)
    curve: Curve | None = None
    shape: str = "line"

    def __post_init__(self) -> None:
        pen_down: Any = self.pen_down  # a user may still pass None (every point)
        if pen_down is None or pen_down is _EVERY_POINT:
            object.__setattr__(self, "pen_down", np.ones(len(self.points_mm), dtype=bool))

    @property
    def has_frames(self) -> bool:
        """True for a 6-D pose path (goal rotations given)."""
        return self.rotations is not None

    @property
    def steps(self) -> int:
        """Number of segments n."""
        return len(self.points_mm) - 1

    @property
    def start_point_mm(self) -> np.ndarray:
        """P^s = P^g_0 [mm]."""
        return self.points_mm[0]

    @property
    def end_point_mm(self) -> np.ndarray:
        """P^e = P^g_n [mm]."""
        return self.points_mm[-1]


@dataclass(frozen=True, eq=False)
class Requirements:
    """What a task requires of the poses, besides following the goal.

    Attributes:
        start_pose: (dof,) start pose p^s [pose units: ``Robot.pose_unit``], or None when
            not constrained.
        end_pose: (dof,) end (touch) pose p^e [pose units], or None.
        joint_limits: (lower (dof,), upper (dof,)) [pose units] the poses must respect when
            they differ from the robot's limits (a benchmark's bounds, e.g. CppFlow's
            [-180, 180] deg for continuous joints), or None.
        obstacles: the obstacles the robot must not touch, in the base frame
            (:class:`ikbench.core.obstacles.Obstacle`); empty: none. Judged with the robot's
            collision model (:mod:`ikbench.core.collision`) where the robot has one.
        contract: what the trajectory is judged against
            (:class:`ikbench.core.contract.Contract`: fixed poses, pointing and its judged
            part, speed limits, tolerances), or None (a plain run: the method's own scheme).
            Methods read it to honour the task, e.g. where pointing is asked for.
        initial_pose: (dof,) [pose units] the pose a 6-D pose path must start near (a
            CppFlow problem's ``initial_configuration``), or None.
    """

    start_pose: np.ndarray | None = None
    end_pose: np.ndarray | None = None
    joint_limits: tuple[np.ndarray, np.ndarray] | None = None
    obstacles: tuple[Obstacle, ...] = ()
    contract: Contract | None = None
    initial_pose: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.obstacles, tuple):
            object.__setattr__(self, "obstacles", tuple(self.obstacles))

    def limits(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (dof,) [pose units]: these joint limits, else the robot's."""
        if self.joint_limits is not None:
            return self.joint_limits
        return robot.lower, robot.upper


@dataclass(frozen=True, eq=False)
class Hints:
    """What a task suggests to a method; nothing is judged against it.

    Attributes:
        reference_pose: (dof,) the pose the shape was placed from (a letter's start pose);
            pinned by no loss term, a starting guess for methods that need one.
        default_weights: loss weights c0..c6 (keys L0..L6) this task is meant for, under any
            the user sets; None: the method's own defaults (the paper's).
    """

    reference_pose: np.ndarray | None = None
    default_weights: dict[str, float] | None = None


#: Field names of each part (for the constructors that take them flat).
_GOAL_FIELDS = ("points_mm", "directions", "rotations", "pen_down", "curve", "shape")
_REQUIRED_FIELDS = ("start_pose", "end_pose", "joint_limits", "obstacles", "contract",
                    "initial_pose")
_HINT_FIELDS = ("reference_pose", "default_weights")


@dataclass(frozen=True, eq=False)
class Task:
    """What a method must achieve for one trajectory.

    Attributes:
        name: trajectory id (e.g. ``"1"``).
        goal: what is asked (:class:`Goal`: points, directions, frames, pen, shape).
        required: what is required (:class:`Requirements`: fixed poses, joint limits,
            obstacles, contract, initial pose).
        hints: what is suggested (:class:`Hints`: reference pose, default weights).
    """

    name: str
    goal: Goal
    required: Requirements = field(default_factory=Requirements)
    hints: Hints = field(default_factory=Hints)

    def limits(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (dof,) [pose units]: the task's joint limits, else the robot's."""
        return self.required.limits(robot)


def make_task(name: str, **fields: Any) -> Task:
    """A :class:`Task` from the fields of its parts given flat (``points_mm=``,
    ``start_pose=``, ``reference_pose=``...); an unknown name is a TypeError."""
    unknown = set(fields) - set(_GOAL_FIELDS + _REQUIRED_FIELDS + _HINT_FIELDS)
    if unknown:
        raise TypeError(f"make_task: unknown fields {sorted(unknown)}")
    return Task(name,
                Goal(**{k: v for k, v in fields.items() if k in _GOAL_FIELDS}),
                Requirements(**{k: v for k, v in fields.items() if k in _REQUIRED_FIELDS}),
                Hints(**{k: v for k, v in fields.items() if k in _HINT_FIELDS}))


def line_task(robot: Robot, start_pose: npt.ArrayLike, end_pose: npt.ArrayLike,
              steps: int, name: str = "") -> Task:
    """The paper's straight-line task (Eq. 1) from FK(start pose) to FK(end pose).

    Args:
        robot: the robot.
        start_pose: (dof,) start pose [pose units].
        end_pose: (dof,) touch pose [pose units].
        steps: number of segments n (n+1 goal points).
        name: trajectory id.
    """
    start = np.asarray(start_pose, dtype=float)
    end = np.asarray(end_pose, dtype=float)
    fk = robot.fk(np.stack([start, end]))
    p_start_mm, p_end_mm = fk.point_mm
    length_mm = float(np.linalg.norm(p_end_mm - p_start_mm))
    if length_mm < MIN_LINE_LENGTH_MM:
        raise InputError(
            f"trajectory {name!r}: start and touch points coincide ({length_mm:g} mm apart); "
            "a line task needs two distinct points"
        )
    direction = (p_end_mm - p_start_mm) / length_mm
    t = np.linspace(0.0, 1.0, steps + 1)[:, None]
    points_mm = p_start_mm + t * (p_end_mm - p_start_mm)
    directions = np.repeat(direction[None], steps + 1, axis=0)
    return Task(name, Goal(points_mm, directions, shape="line"), Requirements(start, end))


def frame_task(robot: Robot, name: str, points_mm: npt.ArrayLike, rotations: npt.ArrayLike,
               **fields: Any) -> Task:
    """A 6-D pose path: goal points (n+1, 3) [mm] and goal rotations (n+1, 3, 3) of the end
    frame in the base frame; the goal directions are the rotations' pointing axes.

    Args:
        robot: the robot (its pointing axis).
        name: trajectory id.
        points_mm: (n+1, 3) goal points [mm].
        rotations: (n+1, 3, 3) goal rotations.
        **fields: further fields of the task's parts, flat (``reference_pose``,
            ``joint_limits``...);
            the default weights are the 6-D objective's
            (:data:`ikbench.core.weights.FRAME_WEIGHTS`).
    """
    points = np.asarray(points_mm, dtype=float)
    rotations = np.asarray(rotations, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or rotations.shape != (len(points), 3, 3):
        raise InputError(f"trajectory {name!r}: goal points {points.shape} and rotations "
                         f"{rotations.shape} must be (n+1, 3) and (n+1, 3, 3)")
    if len(points) < 2:
        raise InputError(f"trajectory {name!r}: a path needs at least 2 poses, got "
                         f"{len(points)}")
    fields = {"shape": "path", "default_weights": dict(FRAME_WEIGHTS), **fields}
    return make_task(name, points_mm=points, directions=rotations @ robot.pointing_axis,
                     rotations=rotations, **fields)


def line_tasks(robot: Robot, targets: Targets, contract: Contract | None = None) -> list[Task]:
    """One line task per touch pose of ``targets`` (start pose shared), each with the task
    contract (:class:`ikbench.core.contract.Contract`; default
    :func:`ikbench.core.contract.contract_for` the robot). Where the contract does not ask for
    pointing (a robot whose config names no pointing axis), the tasks' default weights drop
    the pointing term (c1 = 0; ``--weights`` can set it again). Every task carries the
    targets' obstacles (``Targets.obstacles``), and with obstacles the contract judges
    collisions (``Contract.obstacles``)."""

    contract = contract if contract is not None else contract_for(robot)
    if targets.obstacles and not contract.obstacles:
        contract = replace(contract, obstacles=True)
    weights = None if contract.pointing else {**PAPER_WEIGHTS, "L1": 0.0}
    return [
        _with_parts(line_task(robot, targets.start_pose, pose, targets.steps, name),
                    contract, weights, tuple(targets.obstacles))
        for name, pose in targets.touch_poses.items()
    ]


def _with_parts(task: Task, contract: Contract, weights: dict[str, float] | None,
                obstacles: tuple[Obstacle, ...]) -> Task:
    """``task`` with its contract, default weights and obstacles set."""
    return replace(task, required=replace(task.required, contract=contract, obstacles=obstacles),
                   hints=replace(task.hints, default_weights=weights))


# ----- general shapes ------------------------------------------------------------------------
SHAPE_KINDS = ("line", "polyline", "spline", "letter")
DIRECTION_CHOICES = "tangent, normal or x,y,z"


def parse_shape(spec: str) -> tuple[str, str]:
    """``"spline:path.csv"`` -> ``("spline", "path.csv")``; ``"line"`` -> ``("line", "")``."""
    kind, sep, arg = str(spec).partition(":")
    kind = kind.strip().lower()
    if kind not in SHAPE_KINDS or (kind == "line") == bool(sep):
        raise InputError(f"shape: {spec!r} is not one of line, polyline:FILE, spline:FILE, "
                         "letter:X (e.g. letter:P or letter:P,A,B)")
    if kind != "line" and not arg.strip():
        raise InputError(f"shape: {spec!r} names no {'letter' if kind == 'letter' else 'file'}")
    return kind, arg.strip()


def curve_task(curve: Curve, steps: int, name: str, shape: str,
               direction: str | npt.ArrayLike = "tangent", **fields: Any) -> Task:
    """A task following ``curve`` with n+1 = ``steps`` + 1 goal points evenly by arc length.

    Args:
        curve: the target curve [mm].
        steps: number of segments n.
        name: trajectory id.
        shape: the shape's name, e.g. ``"spline"``.
        direction: ``"tangent"`` (along the path), ``"normal"`` (the curve's drawing plane
            normal) or a vector (3,).
        **fields: further fields of the task's parts, flat (:func:`make_task`).
    """
    samples = curve.resample(steps)
    return make_task(name, points_mm=samples.points_mm,
                     directions=goal_directions(curve, samples.tangents, direction),
                     shape=shape, pen_down=samples.pen_down, curve=curve, **fields)


def goal_directions(curve: Curve | None, tangents: np.ndarray,
                    direction: str | npt.ArrayLike) -> np.ndarray:
    """(n+1, 3) unit goal directions: the tangents, the plane normal or a fixed vector."""
    if isinstance(direction, str) and direction == "tangent":
        return tangents
    if isinstance(direction, str) and direction == "normal":
        if curve is None:
            raise InputError("direction: 'normal': a line has no drawing plane; give a vector "
                             "x,y,z")
        vector = curve.drawing_plane().normal
    else:
        vector = parse_direction(direction)
    return np.repeat(vector[None] / np.linalg.norm(vector), len(tangents), axis=0)


def parse_direction(value: str | npt.ArrayLike) -> np.ndarray:
    """A fixed direction from ``"x,y,z"`` or a sequence; non-zero and finite."""
    text = (",".join(map(str, cast(Iterable[Any], value))) if not isinstance(value, str)
            else value)  # a sequence of 3 numbers, or the text
    try:
        vector = np.array([float(v) for v in text.split(",")], dtype=float)
    except ValueError:
        vector = np.array([])
    if vector.shape != (3,) or not np.all(np.isfinite(vector)) or not np.any(vector):
        raise InputError(f"direction: {text!r} is not one of {DIRECTION_CHOICES} (a non-zero "
                         "finite vector)")
    return vector


def letter_plane(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """The robot's letter plane axes (u: the viewer's right, v: up) from its config's
    ``[letters]`` (default NICO's frontal plane: u = -y, v = +z)."""
    section = robot.config.letters
    return (np.asarray(letters.FRONTAL_U if section.plane_u is None else section.plane_u,
                       dtype=float),
            np.asarray(letters.FRONTAL_V if section.plane_v is None else section.plane_v,
                       dtype=float))


def letter_start_pose(robot: Robot, targets: Targets | None = None) -> np.ndarray:
    """The start pose letters are drawn from: the robot config's ``[letters] start_pose``
    (NICO: the paper's), else the targets' start pose."""
    pose = robot.config.letters.start_pose
    if pose is not None:
        return robot.check_pose(pose, f"robot {robot.name}: letters start_pose")
    if targets is None:

        targets = load_targets(None, robot)
    return targets.start_pose


def letter_task(robot: Robot, letter: str, start_pose: npt.ArrayLike,
                steps: int = letters.DEFAULT_STEPS, size_mm: float = letters.DEFAULT_SIZE_MM,
                direction: str | npt.ArrayLike = "normal") -> Task:
    """The paper's letter in the air: ``letter`` on the robot's letter plane through the end
    point at the start pose (NICO: the frontal plane x = FK(start pose).x).

    The letter's box is centred on the fingertip at the start pose, ``size_mm`` high, read
    by a viewer facing the robot (see :mod:`ikbench.core.letters`); goal direction the plane
    normal (NICO: (-1, 0, 0)); no pose pinned, default weights
    :data:`ikbench.core.letters.LETTER_WEIGHTS`.
    """
    start = np.asarray(start_pose, dtype=float)
    tip_mm = robot.fk(start).point_mm[0]
    curve = letters.letter_curve(letter, size_mm, tip_mm, *letter_plane(robot))
    return curve_task(curve, steps, letter, "letter", direction,
                      default_weights=dict(letters.LETTER_WEIGHTS), reference_pose=start)


def file_task(kind: str, path: str | Path, steps: int, direction: str | npt.ArrayLike = "tangent",
              reference_pose: np.ndarray | None = None) -> Task:
    """A polyline or spline task through the control points [mm] of a CSV file."""
    points = read_points_csv(path)
    curve = Curve((points if kind == "polyline" else catmull_rom(points),))
    return curve_task(curve, steps, Path(path).stem, kind, direction,
                      reference_pose=reference_pose)


def build_tasks(robot: Robot, targets: Targets, shape: str = "line", steps: int | None = None,
                size_mm: float | None = None, direction: str | npt.ArrayLike | None = None
                ) -> list[Task]:
    """The tasks of a shape (see the module docstring).

    Args:
        robot: the robot.
        targets: start pose (and, for lines, the touch poses and default n).
        shape: ``line``, ``polyline:FILE``, ``spline:FILE`` or ``letter:X[,Y...]``.
        steps: number of segments n (default: the targets file's for a line,
            :data:`ikbench.core.letters.DEFAULT_STEPS` for other shapes).
        size_mm: letter height [mm] (letters only; default 300).
        direction: ``"tangent"``, ``"normal"`` or a vector; None: the shape's default.

    Every task carries the targets' obstacles (``Targets.obstacles``; none by default).
    """
    tasks = _shape_tasks(robot, targets, shape, steps, size_mm, direction)
    if not targets.obstacles:
        return tasks
    return [replace(t, required=replace(t.required, obstacles=tuple(targets.obstacles)))
            for t in tasks]


def _shape_tasks(robot: Robot, targets: Targets, shape: str, steps: int | None,
                 size_mm: float | None, direction: Any) -> list[Task]:
    """:func:`build_tasks` without the obstacles."""
    kind, arg = parse_shape(shape)
    if size_mm is not None and kind != "letter":
        raise InputError(f"size_mm: only letters are scaled; shape {shape!r} is in mm as given")
    if kind == "line":
        tasks = line_tasks(robot, targets.with_steps(steps))
        if direction is None:
            return tasks
        return [replace(t, goal=replace(t.goal, directions=goal_directions(
                    None, t.goal.directions, direction))) for t in tasks]
    steps = letters.DEFAULT_STEPS if steps is None else targets.with_steps(steps).steps
    if kind == "letter":
        size = letters.DEFAULT_SIZE_MM if size_mm is None else size_mm
        return [letter_task(robot, ch, targets.start_pose, steps, size, direction or "normal")
                for ch in dict.fromkeys(letters.parse_letters(arg))]
    return [file_task(kind, arg, steps, direction or "tangent", targets.start_pose)]
