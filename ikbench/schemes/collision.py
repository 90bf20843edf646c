"""What the library adapters share for obstacle avoidance (issue 23).

A task's obstacles (``Task.obstacles``, :mod:`ikbench.core.obstacles`: boxes, spheres, capsules,
half-spaces in the robot's base frame [mm]) reach an adapter's ``solve_chain`` with its goals
(``Goals.obstacles``, :func:`ikbench.schemes.chain.goals_of`); an adapter that keeps
clear of them mixes in :class:`AvoidsObstacles` (before
:class:`ikbench.schemes.method.LibraryMethod`; it declares ``Capabilities(obstacles=True)``
for the adapter), whose ``solve_chain`` hands the
adapter's ``solve_scene`` their :class:`Scene`. The robot's collision geometry is
ikbench's own (:func:`ikbench.core.collision.collision_model`: capsules in link frames [mm] and
the link pairs checked for self-collision); :func:`scene_of` gathers both in the libraries' units
(metres) as a :class:`Scene`, or None when there is nothing to avoid.

**No obstacle, no change**: a task without obstacles gets ``None`` and every adapter runs
exactly as before (no collision geometry is even built). With obstacles, the adapters keep
the robot's capsules clear of every obstacle and of each other (the collision model's
``self_pairs``) by the clearance the method's option gives, using their library's own
avoidance (Drake ``MinimumDistanceLowerBoundConstraint``, pink ``SelfCollisionBarrier`` on a
Pinocchio ``GeometryModel`` holding the obstacles too, mink ``CollisionAvoidanceLimit`` on
MuJoCo geoms).

Half-spaces: Drake's and MuJoCo's distance queries between a half-space and a capsule are
not available everywhere, so a half-space is given to the libraries as a large box
(:data:`HALFSPACE_BOX_M` wide, :data:`HALFSPACE_DEPTH_M` deep, centred on the plane's point
nearest the base) whose top face is the plane: the same solid within reach of the arms
ikbench ships (under 1.5 m); Drake has no signed distance between a capsule and a HalfSpace.
"""

from __future__ import annotations

import abc
import itertools
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from ikbench.core.collision import collision_model
from ikbench.core.obstacles import frame_with_z
from ikbench.methods.base import Capabilities

if TYPE_CHECKING:
    from ikbench.core.collision import Capsule
    from ikbench.core.obstacles import Obstacle
    from ikbench.core.robot import Robot
    from ikbench.schemes.chain import Chain, Goals
    from ikbench.schemes.method import ChainResult

#: A half-space as a box: edge along the plane [m] and depth behind it [m], centred on the
#: plane's point nearest the robot's base (larger boxes cost the libraries' GJK precision:
#: a 20 m box gave 0.5 mm errors at 170 mm distance in Drake).
HALFSPACE_BOX_M = 6.0
HALFSPACE_DEPTH_M = 3.0
MM = 1e-3

class AvoidsObstacles(abc.ABC):
    """Mixin for a library method that keeps the robot clear of the task's obstacles
    (``Capabilities(obstacles=True)``): solves each chain in the :class:`Scene` of its goals'
    obstacles (``Goals.obstacles``): the adapter implements :meth:`solve_scene`, and the
    result's info gets :func:`scene_info` (with the settings' ``clearance`` [mm]).

    Its ``capabilities`` are those of every library method that avoids obstacles: it tracks
    from the start pose onto the touch pose (or walks back from it) and takes 6-D goal frames;
    an adapter that differs declares its own."""

    capabilities: ClassVar[Capabilities] = Capabilities(needs_touch_pose=True, frames=True,
                                                        obstacles=True)

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        """:meth:`solve_scene` in the scene of the goals' obstacles (None without any)."""
        obstacles = goals.obstacles
        scene = scene_of(robot, obstacles)
        result = self.solve_scene(robot, chain, goals, scene)
        result.info.update(scene_info(scene, no_avoidance_reason(robot, obstacles),
                                      self.settings.clearance))  # type: ignore[attr-defined]
        return result

    @abc.abstractmethod
    def solve_scene(self, robot: Robot, chain: Chain, goals: Goals,
                    scene: Scene | None) -> ChainResult:
        """Solve one task in URDF units keeping the robot clear in ``scene`` (None: nothing
        to avoid, solve as without obstacles); implemented by each adapter."""


@dataclass(frozen=True)
class Shape:
    """One convex solid in metres.

    Attributes:
        kind: ``box``, ``sphere`` or ``capsule`` (half-spaces arrive as boxes).
        name: a unique name.
        rotation: (3, 3) its frame in its parent (a link, or the robot's base frame);
            a capsule's axis is its local z.
        center_m: (3,) its centre in its parent [m].
        size_m: (3,) a box's full edge lengths [m]; None otherwise.
        radius_m: sphere / capsule radius [m].
        length_m: capsule: distance between the end-sphere centres [m].
        link: the robot link it is attached to; None for an obstacle.
    """

    kind: str
    name: str
    rotation: np.ndarray
    center_m: np.ndarray
    size_m: np.ndarray | None = None
    radius_m: float = 0.0
    length_m: float = 0.0
    link: str | None = None

    def transform(self) -> np.ndarray:
        """(4, 4) parent <- shape [m]."""
        T = np.eye(4)
        T[:3, :3] = self.rotation
        T[:3, 3] = self.center_m
        return T

    def ends_m(self) -> tuple[np.ndarray, np.ndarray]:
        """A capsule's two end-sphere centres in its parent [m]."""
        half = 0.5 * self.length_m * self.rotation[:, 2]
        return self.center_m - half, self.center_m + half


@dataclass(frozen=True)
class Scene:
    """What an adapter keeps apart, in metres.

    Attributes:
        links: the robot's capsules (:class:`Shape`, ``link`` set), in link frames.
        obstacles: the task's obstacles in the robot's base frame.
        self_pairs: link pairs checked for self-collision (both links carry capsules).
        key: a hashable description (caches of library models per scene).
    """

    links: tuple[Shape, ...]
    obstacles: tuple[Shape, ...]
    self_pairs: tuple[tuple[str, str], ...]
    key: tuple

    @property
    def link_names(self) -> tuple[str, ...]:
        """The links that carry capsules, in first-seen order."""
        return tuple(dict.fromkeys(s.link for s in self.links))  # type: ignore[misc]

    def pairs(self, moving: Collection[str | None] | None = None) -> list[tuple[Shape, Shape]]:
        """Every pair of shapes to keep apart: each robot capsule with each obstacle, and
        the capsules of each self pair. ``moving``: the links that move with some joint
        (a link that moves with none is welded to the base: its obstacle pairs are left
        out, as no joint could change them)."""
        out = []
        for shape, obstacle in itertools.product(self.links, self.obstacles):
            if moving is None or shape.link in moving:
                out.append((shape, obstacle))
        for a, b in self.self_pairs:
            for sa in self.links:
                if sa.link != a:
                    continue
                out.extend((sa, sb) for sb in self.links if sb.link == b)
        return out


def rotation_with_z(axis: npt.ArrayLike) -> np.ndarray:
    """A rotation whose z column is ``axis`` normalised (identity for a zero axis)."""

    return frame_with_z(axis)


def capsule_shape(capsule: Capsule, index: int) -> Shape:
    """A robot capsule (:class:`ikbench.core.collision.Capsule`, link frame, mm) as a
    :class:`Shape` [m]."""
    a = np.asarray(capsule.a_mm, dtype=float) * MM
    b = np.asarray(capsule.b_mm, dtype=float) * MM
    return Shape("capsule", f"{capsule.link}__capsule{index}", rotation_with_z(b - a),
                 0.5 * (a + b), radius_m=float(capsule.radius_mm) * MM,
                 length_m=float(np.linalg.norm(b - a)), link=str(capsule.link))


def obstacle_shape(obstacle: Obstacle, index: int) -> Shape:
    """A task obstacle (:class:`ikbench.core.obstacles.Obstacle`, base frame, mm) as a
    :class:`Shape` [m]; a half-space as the box of the module docstring."""
    name = f"obstacle{index}_{obstacle.name}"
    R = np.asarray(obstacle.rotation, dtype=float)
    center = np.asarray(obstacle.center_mm, dtype=float) * MM
    if obstacle.kind == "box":
        return Shape("box", name, R, center, size_m=np.asarray(obstacle.size_mm) * MM)
    if obstacle.kind == "sphere":
        return Shape("sphere", name, np.eye(3), center, radius_m=obstacle.radius_mm * MM)
    if obstacle.kind == "capsule":
        return Shape("capsule", name, R, center, radius_m=obstacle.radius_mm * MM,
                     length_m=obstacle.length_mm * MM)
    if obstacle.kind == "halfspace":
        n = np.asarray(obstacle.normal, dtype=float)
        n = n / np.linalg.norm(n)
        R = rotation_with_z(n)
        surface = (center @ n) * n  # the plane's point nearest the base frame's origin
        return Shape("box", name, R, surface - 0.5 * HALFSPACE_DEPTH_M * n,
                     size_m=np.array([HALFSPACE_BOX_M, HALFSPACE_BOX_M, HALFSPACE_DEPTH_M]))
    raise ValueError(f"obstacle {obstacle.name!r}: unknown kind {obstacle.kind!r}")


def _key(shape: Shape) -> tuple:
    size = () if shape.size_m is None else tuple(np.round(shape.size_m, 12))
    return (shape.kind, shape.name, tuple(np.round(shape.rotation.reshape(-1), 12)),
            tuple(np.round(shape.center_m, 12)), size, round(shape.radius_m, 12),
            round(shape.length_m, 12), shape.link)


def scene_of(robot: Robot, obstacles: Sequence[Obstacle]) -> Scene | None:
    """The :class:`Scene` of ``robot`` among ``obstacles``; None when there are no obstacles
    (nothing changes then) or the robot has no capsule model (nothing to keep apart:
    :func:`no_avoidance_reason` says why)."""
    if not obstacles:
        return None
    model = _model(robot)
    if model is None or not getattr(model, "capsules", ()):
        return None
    links = tuple(capsule_shape(c, k) for k, c in enumerate(model.capsules))
    carried = {s.link for s in links}
    pairs = tuple((str(a), str(b)) for a, b in model.self_pairs
                  if a in carried and b in carried)
    shapes = tuple(obstacle_shape(o, k) for k, o in enumerate(obstacles))
    key = (tuple(map(_key, links)), tuple(map(_key, shapes)), pairs)
    return Scene(links, shapes, pairs, key)


def no_avoidance_reason(robot: Robot, obstacles: Sequence[Obstacle]) -> str:
    """Why :func:`scene_of` is None ('' when it is not)."""
    if not obstacles:
        return "no obstacles"
    model = _model(robot)
    if model is None:
        return f"robot {robot.name} has no collision model"
    if not getattr(model, "capsules", ()):
        return (f"robot {robot.name}'s collision geometry is not made of capsules "
                "(the adapters take capsules only)")
    return ""


def _model(robot):

    return collision_model(robot)


def scene_info(scene: Scene | None, reason: str, clearance_mm: float) -> dict:
    """Flat figures for details.csv about the avoidance of one solve."""
    if scene is None:
        return {} if reason == "no obstacles" else {"collision_avoidance": f"off ({reason})"}
    return {"collision_avoidance": "on", "clearance_mm": float(clearance_mm),
            "avoided_obstacles": len(scene.obstacles), "self_pairs": len(scene.self_pairs)}
