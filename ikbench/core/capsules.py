"""Capsule collision models compiled with numba: signed distances, witness points, Jacobians.

The shipped robots' collision geometry is capsules (:mod:`ikbench.core.collision`: jstmn/jrl's
for Panda and Fetch, NICO's estimated ones); a task's obstacles are boxes, spheres, capsules
and half-spaces. For these, a pair's signed distance [m] has a closed form or a 1-D convex
minimisation, cheap enough to evaluate for every pair at every carried pose of a search,
where coal through Pinocchio (one call per pose from Python) is the slow part:

- capsule - capsule (self pairs, capsule obstacles): the closest points of two segments
  (:func:`segment_segment`, Ericson's clamped solution), minus both radii;
- capsule - sphere: the closest point of the segment to the centre, minus both radii;
- capsule - half-space: the lower end of the segment's height above the plane, minus the radius;
- capsule - box: the box's signed distance function (outside: the distance to the box;
  inside: minus the distance to the nearest face) is convex, so along the segment it has one
  minimum, found by golden-section search (:data:`GOLDEN_ITERATIONS`); minus the radius.
  Inside a box this is the deepest point of the segment, not coal's penetration depth (the
  smallest translation that separates them): both are negative exactly when the shapes
  overlap, and equal when they do not.

Every pair also gets its witness point on the robot's capsule axis (``p1``; on the second
capsule's axis ``p2`` for a self pair) and the unit normal ``n`` from the first geometry
towards the second, so that the distance's gradient in pose units is
``n . (J(p2) - J(p1))`` (self pairs) or ``-n . J(p1)`` (obstacles), J the point Jacobian of
the witness on its link (:func:`distance_gradient`): a witness on the axis rather than on the
surface gives the same product (the difference is along n and rotates with the link).

Pairs far apart are not resolved: a pair whose lower bound (its bounding spheres' distance,
or the box's distance function at the segment's midpoint less half its length) exceeds
``below`` reports that bound and a zero normal (:func:`pair_distances`). Agreement with coal
is tested to 0.1 mm (``tests/test_capsules.py``).

:class:`CapsuleModel` is the robot side (each capsule's joint and its end points in that
joint's frame), built from the :class:`ikbench.core.collision.CollisionModel` when all its
geometry is capsules or spheres; :class:`CapsuleScene` adds a task's obstacles and offers
:meth:`CapsuleScene.check` and :meth:`CapsuleScene.distance_jacobians` with the signatures
and pair order of the coal checker's, so the numpy search runs on either. numba is the
``[fast]`` extra: import this module only where it may fail.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from numba import njit

from ikbench.core.collision import CollisionModel, CollisionReport, collision_model

if TYPE_CHECKING:
    from ikbench.core.obstacles import Obstacle
    from ikbench.core.robot import Robot

MM_PER_M = 1000.0
#: Obstacle kinds in the compiled arrays.
BOX, SPHERE, CAPSULE, HALFSPACE = 0, 1, 2, 3
KIND_CODES = {"box": BOX, "sphere": SPHERE, "capsule": CAPSULE, "halfspace": HALFSPACE}
#: Golden-section iterations of a capsule-box distance: the bracket shrinks to 0.618^60 ~
#: 3e-13 of the segment.
GOLDEN_ITERATIONS = 60
INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(eq=False)
class CapsuleModel:
    """A robot's capsules for the compiled distances.

    Attributes:
        joint: (C,) the chain index of the joint each capsule moves with (-1: fixed to the base).
        a_m, b_m: (C, 3) the end-sphere centres in that joint's frame (the base frame for -1)
            [m].
        radius_m: (C,) [m].
        self_pairs: (P, 2) capsule indices of the checked self pairs (the coal checker's
            order).
        model: the coal :class:`ikbench.core.collision.CollisionModel` it was built from.
    """

    joint: np.ndarray
    a_m: np.ndarray
    b_m: np.ndarray
    radius_m: np.ndarray
    self_pairs: np.ndarray
    model: CollisionModel
    _scenes: dict = field(default_factory=dict, repr=False)

    @property
    def robot(self) -> Any:
        return self.model.robot

    def scene(self, obstacles: Sequence[Obstacle] = ()) -> CapsuleScene:
        """The model with ``obstacles`` (cached per set, as the coal checker's scenes)."""
        key = tuple(id(o) for o in obstacles)
        if key not in self._scenes:
            if len(self._scenes) > 8:
                self._scenes.clear()
            self._scenes[key] = CapsuleScene(self, tuple(obstacles))
        return self._scenes[key]

    def world_segments(self, poses: npt.ArrayLike) -> np.ndarray:
        """(N, C, 2, 3) [m] both end centres of every capsule in the base frame at poses
        (N, dof) [pose units] (the numpy chain's joint frames)."""
        rotations, origins, _ = joint_frames(self.robot, poses)
        n, c = len(rotations), len(self.joint)
        out = np.empty((n, c, 2, 3))
        for k in range(c):
            j = int(self.joint[k])
            for end, local in enumerate((self.a_m[k], self.b_m[k])):
                out[:, k, end] = (local if j < 0 else
                                  origins[:, j] + rotations[:, j] @ local)
        return out

    # the coal checker's interface (a scene per obstacle set)
    def check(self, poses: npt.ArrayLike, obstacles: Sequence[Obstacle] = ()
              ) -> CollisionReport:
        return self.scene(obstacles).check(poses)

    def distance_jacobians(self, poses: npt.ArrayLike, obstacles: Sequence[Obstacle] = (),
                           below_mm: float = 50.0, self_pairs: bool = True
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      list[tuple[str, str]]]:
        return self.scene(obstacles).distance_jacobians(poses, below_mm, self_pairs)


def joint_frames(robot: Robot, poses: npt.ArrayLike
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rotations (N, dof, 3, 3), origins (N, dof, 3) [m], world axes (N, dof, 3)) of every
    joint frame at poses (N, dof) [pose units], by the numpy chain."""
    kin = robot.chain_kinematics()
    return kin.joint_frames(np.atleast_2d(np.asarray(poses, dtype=float)))


def capsule_model(robot: Robot) -> CapsuleModel | None:
    """The robot's :class:`CapsuleModel` (cached on the robot), or None when it has no
    collision geometry or geometry other than capsules and spheres (meshes: coal only)."""
    key = "capsule_model"
    if key not in robot._cache:
        robot._cache[key] = _build(collision_model(robot))
    return robot._cache[key]


def _build(model: CollisionModel | None) -> CapsuleModel | None:
    import coal

    if model is None:
        return None
    joints, a, b, radius = [], [], [], []
    for g in model._geometry.geometryObjects:
        shape, placement = g.geometry, g.placement
        if isinstance(shape, coal.Capsule):
            half, r = float(shape.halfLength), float(shape.radius)
        elif isinstance(shape, coal.Sphere):
            half, r = 0.0, float(shape.radius)
        else:
            return None
        axis = np.asarray(placement.rotation)[:, 2]
        centre = np.asarray(placement.translation, dtype=float)
        joints.append(int(g.parentJoint) - 1)
        a.append(centre - half * axis)
        b.append(centre + half * axis)
        radius.append(r)
    pairs = np.array(model._self_index, dtype=np.int64).reshape(-1, 2)
    return CapsuleModel(np.array(joints, dtype=np.int64), np.array(a), np.array(b),
                        np.array(radius), pairs, model)


def obstacle_arrays(obstacles: Sequence[Obstacle]) -> tuple[np.ndarray, ...]:
    """The obstacles as arrays [m]: (kind (O,), centre (O, 3), rotation (O, 3, 3), half size
    (O, 3) (a box's half edges; a capsule's half length in [0]), radius (O,), normal (O, 3))."""
    o = len(obstacles)
    kind = np.zeros(o, dtype=np.int64)
    centre, half, normal = np.zeros((o, 3)), np.zeros((o, 3)), np.zeros((o, 3))
    rotation = np.tile(np.eye(3), (o, 1, 1))
    radius = np.zeros(o)
    for k, ob in enumerate(obstacles):
        kind[k] = KIND_CODES[ob.kind]
        centre[k] = ob.center_mm / MM_PER_M
        rotation[k] = ob.rotation
        radius[k] = ob.radius_mm / MM_PER_M
        if ob.kind == "box":
            assert ob.size_mm is not None
            half[k] = ob.size_mm / (2.0 * MM_PER_M)
        elif ob.kind == "capsule":
            half[k, 0] = ob.length_mm / (2.0 * MM_PER_M)
        elif ob.kind == "halfspace":
            assert ob.normal is not None
            normal[k] = ob.normal
    return kind, centre, rotation, half, radius, normal


class CapsuleScene:
    """A :class:`CapsuleModel` with a task's obstacles: every checked pair as arrays.

    Attributes:
        first: (P,) the first capsule of each pair.  second: (P,) the second capsule (self
            pairs) or the obstacle's index (robot-obstacle pairs).
        is_env: (P,) True for robot-obstacle pairs.  pairs: (P,) names, as the coal checker's.
        obstacles: the obstacles; ``arrays``: :func:`obstacle_arrays`.
    """

    def __init__(self, capsules: CapsuleModel, obstacles: tuple) -> None:
        self.capsules = capsules
        self.obstacles = obstacles
        model = capsules.model
        links = model.links
        first = [int(a) for a, _ in capsules.self_pairs]
        second = [int(b) for _, b in capsules.self_pairs]
        names = [(links[a], links[b]) for a, b in zip(first, second)]
        is_env = [False] * len(first)
        for k, ob in enumerate(obstacles):
            for a in range(len(capsules.joint)):
                first.append(a)
                second.append(k)
                names.append((links[a], ob.name))
                is_env.append(True)
        self.first = np.array(first, dtype=np.int64)
        self.second = np.array(second, dtype=np.int64)
        self.is_env = np.array(is_env, dtype=bool)
        self.pairs = names
        self.arrays = obstacle_arrays(obstacles)

    def distances(self, poses: npt.ArrayLike, below_mm: float = math.inf
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(distance (N, P) [m], p1 (N, P, 3), p2 (N, P, 3), n (N, P, 3)) at poses (N, dof):
        :func:`pair_distances` per pose (pairs above ``below_mm`` hold a lower bound)."""
        segments = self.capsules.world_segments(poses)
        n, p = len(segments), len(self.first)
        d, p1, p2, normal = (np.empty((n, p)), np.empty((n, p, 3)), np.empty((n, p, 3)),
                             np.empty((n, p, 3)))
        _distances_many(np.ascontiguousarray(segments), self.capsules.radius_m,  # type: ignore[call-arg]
                        self.first, self.second, self.is_env, *self.arrays,
                        below_mm / MM_PER_M, d, p1, p2, normal)
        return d, p1, p2, normal

    def check(self, poses: npt.ArrayLike) -> CollisionReport:
        """Every pair's signed distance [mm] at poses (N, dof), as the coal checker's."""
        d, _, _, _ = self.distances(poses)
        return CollisionReport(d * MM_PER_M, list(self.pairs), self.is_env.copy())

    def distance_jacobians(self, poses: npt.ArrayLike, below_mm: float = 50.0,
                           self_pairs: bool = True
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      list[tuple[str, str]]]:
        """As :meth:`ikbench.core.collision.CollisionModel.distance_jacobians`: (waypoint (K,),
        pair (K,), distance_mm (K,), gradient (K, dof) [mm per pose unit], names (P,)) of
        every (waypoint, pair) closer than ``below_mm``."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        robot = self.capsules.robot
        d, p1, p2, normal = self.distances(poses, below_mm)
        use = np.ones(len(self.first), dtype=bool) if self_pairs else self.is_env
        rows, pairs = np.nonzero((d * MM_PER_M < below_mm) & use[None])
        _, origins, axes = joint_frames(robot, poses)
        kin = robot.chain_kinematics()
        gradient = np.empty((len(rows), robot.dof))
        _gradients_many(rows, pairs, p1, p2, normal, self.first, self.second, self.is_env,
                        self.capsules.joint, np.ascontiguousarray(axes),
                        np.ascontiguousarray(origins), np.asarray(kin.prismatic, dtype=np.bool_),
                        np.asarray(kin.urdf_per_unit, dtype=float), gradient)
        return (rows.astype(int), pairs.astype(int), d[rows, pairs] * MM_PER_M,
                gradient * MM_PER_M, list(self.pairs))


# ----- the compiled geometry ---------------------------------------------------------------------
@njit(cache=True, inline="always")
def _clamp01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


@njit(cache=True)
def segment_segment(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray
                    ) -> tuple[float, float]:
    """Parameters (s, t) in [0, 1] of the closest points p1 + s (q1 - p1) and
    p2 + t (q2 - p2) of two segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d10, d11, d12 = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d20, d21, d22 = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    r0, r1, r2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    eps = 1e-18
    if a <= eps and e <= eps:
        return 0.0, 0.0
    if a <= eps:
        return 0.0, _clamp01(f / e)
    c = d10 * r0 + d11 * r1 + d12 * r2
    if e <= eps:
        return _clamp01(-c / a), 0.0
    b = d10 * d20 + d11 * d21 + d12 * d22
    denom = a * e - b * b
    s = _clamp01((b * f - c * e) / denom) if denom > eps * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = _clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = _clamp01((b - c) / a)
    return s, t


@njit(cache=True, inline="always")
def _box_sdf(x0: float, x1: float, x2: float, h: np.ndarray) -> float:
    """Signed distance of a point (box frame) to the box of half edges h."""
    q0, q1, q2 = abs(x0) - h[0], abs(x1) - h[1], abs(x2) - h[2]
    outside = math.sqrt(max(q0, 0.0) ** 2 + max(q1, 0.0) ** 2 + max(q2, 0.0) ** 2)
    return outside + min(max(q0, max(q1, q2)), 0.0)


@njit(cache=True)
def segment_box(a: np.ndarray, b: np.ndarray, centre: np.ndarray, rotation: np.ndarray,
                half: np.ndarray, witness: np.ndarray, normal: np.ndarray) -> float:
    """Smallest signed distance of the box (centre, rotation's columns = its axes, half edges)
    over the segment a-b [m]; writes the segment's witness point and the unit normal from it
    towards the box (world)."""
    la = np.empty(3)
    lb = np.empty(3)
    for r in range(3):  # the end points in the box frame: R^T (x - c)
        la[r] = ((a[0] - centre[0]) * rotation[0, r] + (a[1] - centre[1]) * rotation[1, r]
                 + (a[2] - centre[2]) * rotation[2, r])
        lb[r] = ((b[0] - centre[0]) * rotation[0, r] + (b[1] - centre[1]) * rotation[1, r]
                 + (b[2] - centre[2]) * rotation[2, r])
    lo, hi = 0.0, 1.0
    t1 = hi - INV_PHI * (hi - lo)
    t2 = lo + INV_PHI * (hi - lo)
    f1 = _box_sdf(la[0] + t1 * (lb[0] - la[0]), la[1] + t1 * (lb[1] - la[1]),
                  la[2] + t1 * (lb[2] - la[2]), half)
    f2 = _box_sdf(la[0] + t2 * (lb[0] - la[0]), la[1] + t2 * (lb[1] - la[1]),
                  la[2] + t2 * (lb[2] - la[2]), half)
    for _ in range(GOLDEN_ITERATIONS):
        if f1 <= f2:
            hi, t2, f2 = t2, t1, f1
            t1 = hi - INV_PHI * (hi - lo)
            f1 = _box_sdf(la[0] + t1 * (lb[0] - la[0]), la[1] + t1 * (lb[1] - la[1]),
                          la[2] + t1 * (lb[2] - la[2]), half)
        else:
            lo, t1, f1 = t1, t2, f2
            t2 = lo + INV_PHI * (hi - lo)
            f2 = _box_sdf(la[0] + t2 * (lb[0] - la[0]), la[1] + t2 * (lb[1] - la[1]),
                          la[2] + t2 * (lb[2] - la[2]), half)
    t = 0.5 * (lo + hi)
    # the ends: a flat minimum at an end is found there exactly
    best_t = t
    best = _box_sdf(la[0] + t * (lb[0] - la[0]), la[1] + t * (lb[1] - la[1]),
                    la[2] + t * (lb[2] - la[2]), half)
    for end in (0.0, 1.0):
        value = _box_sdf(la[0] + end * (lb[0] - la[0]), la[1] + end * (lb[1] - la[1]),
                         la[2] + end * (lb[2] - la[2]), half)
        if value < best:
            best, best_t = value, end
    x = np.empty(3)
    for r in range(3):
        x[r] = la[r] + best_t * (lb[r] - la[r])
        witness[r] = a[r] + best_t * (b[r] - a[r])
    # the gradient of the distance function at x (box frame), pointing out of the box
    g = np.zeros(3)
    if best > 0.0:
        for r in range(3):
            over = abs(x[r]) - half[r]
            if over > 0.0:
                g[r] = math.copysign(over, x[r]) / best
    else:
        axis = 0
        for r in range(1, 3):
            if abs(x[r]) - half[r] > abs(x[axis]) - half[axis]:
                axis = r
        g[axis] = 1.0 if x[axis] >= 0.0 else -1.0
    for r in range(3):  # towards the box: minus the outward gradient, in the world frame
        normal[r] = -(rotation[r, 0] * g[0] + rotation[r, 1] * g[1] + rotation[r, 2] * g[2])
    return best


@njit(cache=True, inline="always")
def _towards(p: np.ndarray, q: np.ndarray, normal: np.ndarray) -> float:
    """|q - p|, and the unit vector from p towards q in ``normal`` (zero when p = q)."""
    d0, d1, d2 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    inv = 1.0 / length if length > 1e-300 else 0.0
    normal[0], normal[1], normal[2] = d0 * inv, d1 * inv, d2 * inv
    return length


@njit(cache=True)
def pair_distance(a1: np.ndarray, b1: np.ndarray, r1: float, a2: np.ndarray, b2: np.ndarray,
                  r2: float, env: bool, kind: int, centre: np.ndarray, rotation: np.ndarray,
                  half: np.ndarray, radius: float, plane_normal: np.ndarray, below: float,
                  p1: np.ndarray, p2: np.ndarray, normal: np.ndarray) -> float:
    """Signed distance [m] of the capsule a1-b1 (radius r1) to the capsule a2-b2 (r2; a self
    pair, ``env`` False) or to an obstacle (``env``: its kind and arrays); witnesses p1, p2
    and the normal from the first towards the second written in place. A pair whose lower
    bound exceeds ``below`` gets the bound and a zero normal."""
    m0, m1, m2 = 0.5 * (a1[0] + b1[0]), 0.5 * (a1[1] + b1[1]), 0.5 * (a1[2] + b1[2])
    h1 = 0.5 * math.sqrt((b1[0] - a1[0]) ** 2 + (b1[1] - a1[1]) ** 2 + (b1[2] - a1[2]) ** 2)
    normal[0] = normal[1] = normal[2] = 0.0
    p1[0], p1[1], p1[2] = m0, m1, m2
    if not env or kind == CAPSULE:
        if env:  # a capsule obstacle: its segment from the arrays
            for r in range(3):
                a2[r] = centre[r] - half[0] * rotation[r, 2]
                b2[r] = centre[r] + half[0] * rotation[r, 2]
            r2 = radius
        n0, n1, n2 = 0.5 * (a2[0] + b2[0]), 0.5 * (a2[1] + b2[1]), 0.5 * (a2[2] + b2[2])
        h2 = 0.5 * math.sqrt((b2[0] - a2[0]) ** 2 + (b2[1] - a2[1]) ** 2
                             + (b2[2] - a2[2]) ** 2)
        bound = math.sqrt((m0 - n0) ** 2 + (m1 - n1) ** 2 + (m2 - n2) ** 2) - h1 - h2 - r1 - r2
        p2[0], p2[1], p2[2] = n0, n1, n2
        if bound > below:
            return bound
        s, t = segment_segment(a1, b1, a2, b2)
        for r in range(3):
            p1[r] = a1[r] + s * (b1[r] - a1[r])
            p2[r] = a2[r] + t * (b2[r] - a2[r])
        return _towards(p1, p2, normal) - r1 - r2
    if kind == SPHERE:
        bound = math.sqrt((m0 - centre[0]) ** 2 + (m1 - centre[1]) ** 2
                          + (m2 - centre[2]) ** 2) - h1 - r1 - radius
        p2[0], p2[1], p2[2] = centre[0], centre[1], centre[2]
        if bound > below:
            return bound
        s, _ = segment_segment(a1, b1, centre, centre)
        for r in range(3):
            p1[r] = a1[r] + s * (b1[r] - a1[r])
        return _towards(p1, centre, normal) - r1 - radius
    if kind == HALFSPACE:
        ha = ((a1[0] - centre[0]) * plane_normal[0] + (a1[1] - centre[1]) * plane_normal[1]
              + (a1[2] - centre[2]) * plane_normal[2])
        hb = ((b1[0] - centre[0]) * plane_normal[0] + (b1[1] - centre[1]) * plane_normal[1]
              + (b1[2] - centre[2]) * plane_normal[2])
        low = min(ha, hb)
        for r in range(3):
            p1[r] = a1[r] if ha <= hb else b1[r]
            p2[r] = p1[r] - low * plane_normal[r]
            normal[r] = -plane_normal[r]
        return low - r1
    # a box
    m = np.empty(3)
    m[0], m[1], m[2] = m0, m1, m2
    local = np.empty(3)
    for r in range(3):
        local[r] = ((m[0] - centre[0]) * rotation[0, r] + (m[1] - centre[1]) * rotation[1, r]
                    + (m[2] - centre[2]) * rotation[2, r])
    bound = _box_sdf(local[0], local[1], local[2], half) - h1 - r1
    p2[0], p2[1], p2[2] = centre[0], centre[1], centre[2]
    if bound > below:
        return bound
    d = segment_box(a1, b1, centre, rotation, half, p1, normal)
    for r in range(3):
        p2[r] = p1[r] + d * normal[r]
    return d - r1


@njit(cache=True)
def pair_distances(segments: np.ndarray, radius: np.ndarray, first: np.ndarray,
                   second: np.ndarray, is_env: np.ndarray, kind: np.ndarray, centre: np.ndarray,
                   rotation: np.ndarray, half: np.ndarray, obstacle_radius: np.ndarray,
                   plane_normal: np.ndarray, below: float, d: np.ndarray, p1: np.ndarray,
                   p2: np.ndarray, normal: np.ndarray) -> None:
    """Every pair's :func:`pair_distance` at one pose: ``segments`` (C, 2, 3) [m] world end
    centres; results into d (P,), p1, p2, normal (P, 3)."""
    a2 = np.empty(3)
    b2 = np.empty(3)
    none3, none33 = np.zeros(3), np.eye(3)
    for p in range(len(first)):
        i = first[p]
        o = second[p]
        if is_env[p]:
            d[p] = pair_distance(segments[i, 0], segments[i, 1], radius[i], a2, b2, 0.0, True,
                                 kind[o], centre[o], rotation[o], half[o], obstacle_radius[o],
                                 plane_normal[o], below, p1[p], p2[p], normal[p])
        else:
            d[p] = pair_distance(segments[i, 0], segments[i, 1], radius[i], segments[o, 0],
                                 segments[o, 1], radius[o], False, 0, none3, none33, none3,
                                 0.0, none3, below, p1[p], p2[p], normal[p])


@njit(cache=True)
def _distances_many(segments, radius, first, second, is_env, kind, centre, rotation, half,
                    obstacle_radius, plane_normal, below, d, p1, p2, normal):
    for i in range(segments.shape[0]):
        pair_distances(segments[i], radius, first, second, is_env, kind, centre, rotation,
                       half, obstacle_radius, plane_normal, below, d[i], p1[i], p2[i],
                       normal[i])


@njit(cache=True, inline="always")
def _point_jacobian_dot(sign: float, normal: np.ndarray, point: np.ndarray, joint: int,
                        axes: np.ndarray, origins: np.ndarray, prismatic: np.ndarray,
                        per_unit: np.ndarray, out: np.ndarray) -> None:
    """out += sign n . J(point) for a point moving with joints 0..joint (per pose unit)."""
    for j in range(joint + 1):
        w0, w1, w2 = axes[j, 0], axes[j, 1], axes[j, 2]
        if prismatic[j]:
            v0, v1, v2 = w0, w1, w2
        else:
            r0 = point[0] - origins[j, 0]
            r1 = point[1] - origins[j, 1]
            r2 = point[2] - origins[j, 2]
            v0, v1, v2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0
        out[j] += sign * (normal[0] * v0 + normal[1] * v1 + normal[2] * v2) * per_unit[j]


@njit(cache=True)
def distance_gradient(p: int, p1: np.ndarray, p2: np.ndarray, normal: np.ndarray,
                      first: np.ndarray, second: np.ndarray, is_env: np.ndarray,
                      joint: np.ndarray, axes: np.ndarray, origins: np.ndarray,
                      prismatic: np.ndarray, per_unit: np.ndarray, out: np.ndarray) -> None:
    """The gradient (dof,) [m per pose unit] of pair p's distance, into ``out`` (zeroed):
    n . (J(p2) - J(p1)), the second term only for a self pair; ``axes``, ``origins`` (dof, 3)
    the joints' world axes and origins [m]."""
    out[:] = 0.0
    _point_jacobian_dot(-1.0, normal[p], p1[p], joint[first[p]], axes, origins, prismatic,
                        per_unit, out)
    if not is_env[p]:
        _point_jacobian_dot(1.0, normal[p], p2[p], joint[second[p]], axes, origins, prismatic,
                            per_unit, out)


@njit(cache=True)
def _gradients_many(rows, pairs, p1, p2, normal, first, second, is_env, joint, axes, origins,
                    prismatic, per_unit, out):
    for k in range(len(rows)):
        i, p = rows[k], pairs[k]
        distance_gradient(p, p1[i], p2[i], normal[i], first, second, is_env, joint, axes[i],
                          origins[i], prismatic, per_unit, out[k])
