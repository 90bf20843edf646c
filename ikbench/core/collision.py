"""Collision checking: the robot against itself and against a task's obstacles.

The robot's collision geometry comes from

- its config's ``collision`` file (``urdf/<robot>.collision.json``): capsules in link frames
  [mm], the link pairs that never collide (as an SRDF's ``disable_collisions``) and named
  obstacle sets (e.g. NICO's ``touchscreen``); the shipped robots have one (Panda and Fetch:
  jstmn/jrl's capsules; NICO: capsules from its link dimensions), or
- the URDF's ``<collision>`` elements (a user's URDF, a description package's robot), in the
  text written from the robot's URDF model (``Robot.urdf_model``) and read by Pinocchio. Its
  primitives (boxes, cylinders, spheres, capsules) are kept as they are; its meshes are
  replaced by their **convex hulls** (coal's ``BVHModelBase.buildConvexHull``, qhull): a hull
  contains its mesh, so a hull distance is never above the mesh distance (conservative: the
  check may see a collision the meshes would not, never the reverse), and a hull pair is ~100x
  quicker to check than a mesh pair (z1's gripper: 21745 vertices, a hull of 3193).
  :attr:`CollisionModel.geometry` says which geometry a model checks ("capsules", "URDF
  primitives", "convex hulls of the URDF meshes"); :meth:`CollisionModel.mesh_model` gives
  the same pairs on the meshes and :func:`hull_distance_error` the hulls' distance error
  against them.

Pairs never checked: geometry on the same moving body (their distance cannot change), on
adjacent moving bodies (one hangs from the other through a single movable joint, fixed links in
between included: the rule an SRDF's "Adjacent" pairs follow for URDFs whose joints are
separated by fixed frames, as NICO's), and the config's ``never_collide`` pairs. (jstmn/jrl
checks Panda's panda_link6 / panda_hand pair, which this rule skips: the hand is fixed to
panda_link7, the body next to panda_link6.)

Distances are computed by coal through Pinocchio's ``GeometryModel``
(``pinocchio.computeDistances``), one call per waypoint for every checked pair: **self
pairs** (see below) and **environment pairs** (every robot geometry
against every obstacle). A distance is signed: negative inside (the penetration depth for
convex shapes; a penetrating mesh, whose depth coal does not give, reads -0.001 mm from
``pinocchio.computeCollisions``); a waypoint collides when a distance is below 0 (touching is
not a collision, as in CppFlow's capsule check).

:meth:`CollisionModel.check` reports per waypoint; :meth:`CollisionModel.distance_jacobians`
gives the distances of the close pairs with their gradients in pose units, for methods that
keep clear of obstacles (the gradient of a distance is n . (J(p2) - J(p1)) with the witness
points p1, p2 and the unit normal n from the first to the second geometry).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.collision_file import (  # noqa: F401  (re-exported)
    CAPSULE_KEYS,
    CONFIG_KEYS,
    Capsule,
    collision_config,
)
from ikbench.core.errors import InputError
from ikbench.core.kinematics.pinocchio_fk import build_chain_model_with_geometry, link_frame_id
from ikbench.core.obstacles import Obstacle, frame_with_z

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

MM_PER_M = 1000.0
#: The distance [m] reported for a penetrating mesh pair (coal gives a mesh's distance as 0, not
#: its depth): a collision, depth unknown.
MESH_PENETRATION_M = 1e-6


@dataclass
class CollisionReport:
    """Signed distances of every checked pair at every waypoint.

    Attributes:
        distances_mm: (N, P) signed distances [mm] (negative: penetration).
        pairs: (P,) (first, second) names: links, or a link and an obstacle.
        is_env: (P,) True for robot-obstacle pairs.
    """

    distances_mm: np.ndarray
    pairs: list[tuple[str, str]]
    is_env: np.ndarray

    @property
    def colliding(self) -> np.ndarray:
        """(N, P) True where a pair collides."""
        return self.distances_mm < 0.0

    @property
    def self_colliding(self) -> np.ndarray:
        """(N,) True at waypoints where the robot collides with itself."""
        return np.any(self.colliding[:, ~self.is_env], axis=1)

    @property
    def env_colliding(self) -> np.ndarray:
        """(N,) True at waypoints where the robot collides with an obstacle."""
        return np.any(self.colliding[:, self.is_env], axis=1)

    def min_clearance_mm(self, env: bool | None = None) -> float:
        """The smallest signed distance over all waypoints (``env``: obstacle pairs only,
        False: self pairs only); inf when there is no such pair."""
        cols = np.ones(len(self.pairs), dtype=bool) if env is None else self.is_env == env
        values = self.distances_mm[:, cols]
        return float(values.min()) if values.size else math.inf

    def first_collision(self) -> tuple[int, str, str] | None:
        """(waypoint, first name, second name) of the first colliding pair (the deepest at
        that waypoint), or None."""
        rows = np.flatnonzero(np.any(self.colliding, axis=1))
        if not rows.size:
            return None
        i = int(rows[0])
        a, b = self.pairs[int(np.argmin(self.distances_mm[i]))]
        return i, a, b

    def summary(self) -> dict[str, Any]:
        """The table columns: ``self_collisions`` and ``env_collisions`` (waypoints in
        collision), ``min_clearance_mm`` (obstacles; NaN without any),
        ``min_self_clearance_mm``, ``first_collision_waypoint`` (NaN: none) and
        ``first_collision_pair`` (``link / other``, "" when none)."""
        first = self.first_collision()
        env = self.min_clearance_mm(env=True)
        own = self.min_clearance_mm(env=False)
        return {"self_collisions": int(self.self_colliding.sum()),
                "env_collisions": int(self.env_colliding.sum()),
                "min_clearance_mm": env if math.isfinite(env) else math.nan,
                "min_self_clearance_mm": own if math.isfinite(own) else math.nan,
                "first_collision_waypoint": first[0] if first else math.nan,
                "first_collision_pair": f"{first[1]} / {first[2]}" if first else ""}


@dataclass
class _Scene:
    """A GeometryModel with the robot's geometry, some obstacles and the checked pairs."""

    geometry: Any
    data: Any
    pairs: list[tuple[str, str]]
    is_env: np.ndarray
    first_joint: np.ndarray       # (P,) the parent joint of each pair's first geometry
    second_joint: np.ndarray      # (P,) 0 for an obstacle
    obstacles: tuple = ()
    meshes: bool = False


@dataclass(eq=False)
class CollisionModel:
    """The robot's collision geometry and its checked pairs (see the module docstring).

    Attributes:
        robot: the robot.
        source: where the geometry comes from (one sentence).
        geometry: what is checked: ``"capsules"`` (a collision file), ``"URDF primitives"``,
            ``"convex hulls of the URDF meshes"`` (primitives kept, meshes as their convex
            hulls) or ``"URDF meshes"`` (:meth:`mesh_model`).
        capsules: the capsules (empty when the geometry comes from the URDF).
        links: (G,) the link of each robot geometry.
        self_pairs: the link pairs checked for self-collision.
    """

    robot: Any
    source: str
    capsules: tuple[Capsule, ...]
    links: tuple[str, ...]
    self_pairs: tuple[tuple[str, str], ...]
    geometry: str = "capsules"
    _model: Any = field(repr=False, default=None)
    _geometry: Any = field(repr=False, default=None)
    _mesh_geometry: Any = field(repr=False, default=None)
    _self_index: list[tuple[int, int]] = field(repr=False, default_factory=list)
    _scenes: dict = field(repr=False, default_factory=dict)

    # ----- building -----------------------------------------------------------------------------
    def scene(self, obstacles: Sequence[Obstacle] = ()) -> _Scene:
        """The geometry with ``obstacles`` added and every checked pair (cached per set)."""
        import coal
        import pinocchio as pin

        key = tuple(id(o) for o in obstacles)
        if key in self._scenes:
            return self._scenes[key]
        geometry = self._geometry.clone()
        n_robot = geometry.ngeoms
        for obstacle in obstacles:
            shape, placement = coal_shape(obstacle)
            geometry.addGeometryObject(pin.GeometryObject(f"obstacle:{obstacle.name}", 0, 0,
                                                          placement, shape))
        pairs, is_env, index = [], [], []
        for a, b in self._self_index:
            index.append((a, b))
            pairs.append((self.links[a], self.links[b]))
            is_env.append(False)
        for k, obstacle in enumerate(obstacles):
            for a in range(n_robot):
                index.append((a, n_robot + k))
                pairs.append((self.links[a], obstacle.name))
                is_env.append(True)
        for a, b in index:
            geometry.addCollisionPair(pin.CollisionPair(a, b))
        data = geometry.createData()
        joints = [g.parentJoint for g in geometry.geometryObjects]
        meshes = any(isinstance(g.geometry, coal.BVHModelBase) for g in geometry.geometryObjects)
        scene = _Scene(geometry, data, pairs, np.array(is_env, dtype=bool),
                       np.array([joints[a] for a, _ in index], dtype=int),
                       np.array([joints[b] for _, b in index], dtype=int), tuple(obstacles),
                       meshes)
        if len(self._scenes) > 8:
            self._scenes.clear()
        self._scenes[key] = scene
        return scene

    def mesh_model(self) -> CollisionModel | None:
        """The same robot and pairs with the URDF's meshes instead of their hulls (None when
        the geometry has no meshes): the reference :func:`hull_distance_error` measures
        against."""
        if self._mesh_geometry is None:
            return None
        return CollisionModel(self.robot, self.source, self.capsules, self.links,
                              self.self_pairs, "URDF meshes", self._model, self._mesh_geometry,
                              None, list(self._self_index))

    # ----- checking -----------------------------------------------------------------------------
    def check(self, poses: npt.ArrayLike, obstacles: Sequence[Obstacle] = ()) -> CollisionReport:
        """Signed distances of every checked pair at every pose (N, dof) [pose units]."""
        import pinocchio as pin

        scene = self.scene(obstacles)
        q_urdf = np.atleast_2d(self.robot.to_urdf(np.asarray(poses, dtype=float)))
        data = self._model.createData()
        out = np.empty((len(q_urdf), len(scene.pairs)))
        for i, q in enumerate(q_urdf):
            pin.computeDistances(self._model, data, scene.geometry, scene.data, q)
            out[i] = [r.min_distance for r in scene.data.distanceResults]
            if scene.meshes:  # a mesh's distance is 0, not negative, when it penetrates
                pin.computeCollisions(self._model, data, scene.geometry, scene.data, q, False)
                hit = np.array([r.isCollision() for r in scene.data.collisionResults])
                out[i, hit] = np.minimum(out[i, hit], -MESH_PENETRATION_M)
        return CollisionReport(out * MM_PER_M, list(scene.pairs), scene.is_env.copy())

    def distance_jacobians(self, poses: npt.ArrayLike, obstacles: Sequence[Obstacle] = (),
                           below_mm: float = 50.0, self_pairs: bool = True
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      list[tuple[str, str]]]:
        """Distances below ``below_mm`` and their gradients, for poses (N, dof) [pose units].

        Returns:
            (waypoint (K,), pair (K,), distance_mm (K,), gradient (K, dof) [mm per pose
            unit], pair names (P,)): one row per (waypoint, pair) closer than ``below_mm``.
        """
        import pinocchio as pin

        scene = self.scene(obstacles)
        robot = self.robot
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        q_urdf = robot.to_urdf(poses)
        per_unit = robot.to_urdf(np.ones(robot.dof)) - robot.to_urdf(np.zeros(robot.dof))
        data = self._model.createData()
        use = np.ones(len(scene.pairs), dtype=bool) if self_pairs else scene.is_env
        rows_i, rows_p, rows_d, rows_g = [], [], [], []
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for i, q in enumerate(q_urdf):
            pin.computeDistances(self._model, data, scene.geometry, scene.data, q)
            results = scene.data.distanceResults
            d = np.array([r.min_distance for r in results]) * MM_PER_M
            close = np.flatnonzero((d < below_mm) & use)
            if not close.size:
                continue
            pin.computeJointJacobians(self._model, data, q)
            for p in close:
                r = results[int(p)]
                n = np.asarray(r.normal)
                g = (_point_jacobian(self._model, data, scene.second_joint[p],
                                     r.getNearestPoint2(), world)
                     - _point_jacobian(self._model, data, scene.first_joint[p],
                                       r.getNearestPoint1(), world))
                rows_i.append(i)
                rows_p.append(p)
                rows_d.append(d[p])
                rows_g.append(n @ g * MM_PER_M * per_unit)
        dof = robot.dof
        return (np.array(rows_i, dtype=int), np.array(rows_p, dtype=int),
                np.array(rows_d, dtype=float), np.array(rows_g, dtype=float).reshape(-1, dof),
                list(scene.pairs))

    def placements(self, poses: npt.ArrayLike) -> np.ndarray:
        """(N, G, 4, 4) [mm] base <- geometry of every robot geometry at each pose."""
        import pinocchio as pin

        q_urdf = np.atleast_2d(self.robot.to_urdf(np.asarray(poses, dtype=float)))
        data = self._model.createData()
        gdata = self._geometry.createData()
        out = np.empty((len(q_urdf), self._geometry.ngeoms, 4, 4))
        for i, q in enumerate(q_urdf):
            pin.updateGeometryPlacements(self._model, data, self._geometry, gdata, q)
            for k in range(self._geometry.ngeoms):
                out[i, k] = gdata.oMg[k].homogeneous
        out[..., :3, 3] *= MM_PER_M
        return out

    def capsule_segments(self, poses: npt.ArrayLike) -> np.ndarray:
        """(N, C, 2, 3) [mm] both end-sphere centres of every capsule in the base frame (for
        drawing; empty when the geometry is not capsules)."""
        if not self.capsules:
            return np.zeros((len(np.atleast_2d(poses)), 0, 2, 3))
        T = self.placements(poses)
        half = np.array([0.5 * float(np.linalg.norm(c.b_mm - c.a_mm)) for c in self.capsules])
        axis = T[..., :3, 2]
        centre = T[..., :3, 3]
        return np.stack([centre - half[None, :, None] * axis,
                         centre + half[None, :, None] * axis], axis=2)


def _point_jacobian(model, data, joint: int, point_m, frame) -> np.ndarray:
    """(3, nv) [m per rad] velocity Jacobian of a point rigidly attached to ``joint``."""
    import pinocchio as pin

    if joint == 0:
        return np.zeros((3, model.nv))
    J = pin.getJointJacobian(model, data, int(joint), frame)
    r = np.asarray(point_m) - data.oMi[int(joint)].translation
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return J[:3] - skew @ J[3:]


def coal_shape(obstacle: Obstacle) -> tuple[Any, Any]:
    """(coal geometry, pinocchio.SE3 placement) of an obstacle, in metres."""
    import coal
    import pinocchio as pin

    centre_m = obstacle.center_mm / MM_PER_M
    if obstacle.kind == "box":
        assert obstacle.size_mm is not None
        shape = coal.Box(*(obstacle.size_mm / MM_PER_M))
    elif obstacle.kind == "sphere":
        shape = coal.Sphere(obstacle.radius_mm / MM_PER_M)
    elif obstacle.kind == "capsule":
        shape = coal.Capsule(obstacle.radius_mm / MM_PER_M, obstacle.length_mm / MM_PER_M)
    else:
        assert obstacle.normal is not None
        n = np.asarray(obstacle.normal, dtype=float)
        return coal.Halfspace(n, float(n @ centre_m)), pin.SE3.Identity()
    return shape, pin.SE3(np.asarray(obstacle.rotation, dtype=float), centre_m)


def _capsule_placement(capsule: Capsule):
    """(coal.Capsule, SE3 link <- capsule) of a robot capsule."""
    import coal
    import pinocchio as pin


    a, b = capsule.a_mm / MM_PER_M, capsule.b_mm / MM_PER_M
    length = float(np.linalg.norm(b - a))
    shape = coal.Capsule(capsule.radius_mm / MM_PER_M, length)
    return shape, pin.SE3(frame_with_z(b - a), 0.5 * (a + b))


def build_collision_model(robot: Robot) -> CollisionModel | None:
    """The robot's :class:`CollisionModel` (see the module docstring), or None when it has no
    collision geometry.

    Raises:
        InputError: a collision file naming a link the robot does not have.
    """
    import pinocchio as pin


    config = collision_config(robot)
    if config is None and not robot.urdf_model.collisions:
        return None
    meshes = None
    kind = "capsules"
    if config is None:
        model, geometry = build_chain_model_with_geometry(robot, with_collision=True)
        if geometry is None or geometry.ngeoms == 0:
            return None
        links = tuple(model.frames[g.parentFrame].name for g in geometry.geometryObjects)
        source = f"the <collision> elements of {robot.urdf_path.name}"
        meshes, geometry = geometry, convex_hulls(geometry)
        kind = "URDF primitives"
        if meshes is geometry:
            meshes = None
        else:
            kind = "convex hulls of the URDF meshes"
        capsules: tuple[Capsule, ...] = ()
        srdf, never = srdf_never_collide(robot.urdf_path)
        if srdf is not None:
            source += f"; the pairs its SRDF ({srdf.name}) disables not checked"
    else:
        model = robot.pinocchio_fk().model
        geometry = pin.GeometryModel()
        root = model.frames[link_frame_id(model, robot.root_link)].placement
        names = []
        for k, capsule in enumerate(config["capsules"]):
            if not model.existFrame(capsule.link):
                raise InputError(f"collision file {config['path']!r}: capsule {k}: link "
                                 f"{capsule.link!r} is not a link of {robot.name}'s model")
            fid = link_frame_id(model, capsule.link)
            frame = model.frames[fid]
            placement = frame.placement if frame.parentJoint else root.actInv(frame.placement)
            shape, local = _capsule_placement(capsule)
            geometry.addGeometryObject(pin.GeometryObject(
                f"{capsule.link}:{k}", frame.parentJoint, fid, placement * local, shape))
            names.append(capsule.link)
        links = tuple(names)
        capsules = tuple(config["capsules"])
        never = {frozenset(p) for p in config["never_collide"]}
        source = str(config.get("source") or config["path"])
    joints = [g.parentJoint for g in geometry.geometryObjects]
    index, pairs = [], []
    for a in range(len(joints)):
        for b in range(a + 1, len(joints)):
            la, lb, ja, jb = links[a], links[b], joints[a], joints[b]
            adjacent = ja == jb or model.parents[ja] == jb or model.parents[jb] == ja
            if adjacent or frozenset((la, lb)) in never:
                continue
            index.append((a, b))
            pairs.append((links[a], links[b]))
    built = CollisionModel(robot, source, capsules, links, tuple(dict.fromkeys(pairs)), kind,
                           _model=model, _geometry=geometry, _mesh_geometry=meshes,
                           _self_index=index)
    if config is not None or not index:
        return built
    always = always_colliding(built)
    if not always.any():
        return built
    keep = [k for k in range(len(index)) if not always[k]]
    dropped = sorted({pairs[k] for k in np.flatnonzero(always)})
    source += (f"; {len(dropped)} link pair(s) in collision in every one of "
               f"{ALWAYS_SAMPLES} sampled poses not checked (always touching, as MoveIt's "
               f"setup assistant disables them): "
               + ", ".join(f"{a} / {b}" for a, b in dropped))
    return CollisionModel(robot, source, capsules, links,
                          tuple(dict.fromkeys(pairs[k] for k in keep)), kind, _model=model,
                          _geometry=geometry, _mesh_geometry=meshes,
                          _self_index=[index[k] for k in keep])


#: Poses (seeded, uniform within the limits) on which a URDF's link pairs are tried: a pair in
#: collision in every one touches by construction (a shoulder mounted into the torso's mesh)
#: and is not checked, as MoveIt's setup assistant marks "always in collision" pairs.
ALWAYS_SAMPLES = 100
#: Seed of those poses.
ALWAYS_SEED = 0


def always_colliding(model: CollisionModel) -> np.ndarray:
    """(P,) True for the self pairs of ``model`` in collision at every one of
    :data:`ALWAYS_SAMPLES` poses drawn uniformly within the limits (seeded)."""
    robot = model.robot
    rng = np.random.default_rng(ALWAYS_SEED)
    poses = rng.uniform(robot.sample_lower, robot.sample_upper, (ALWAYS_SAMPLES, robot.dof))
    return np.all(model.check(poses).colliding, axis=0)


def srdf_never_collide(urdf_path: Any) -> tuple[Any, set[frozenset[str]]]:
    """(path, pairs) of the ``<disable_collisions link1= link2=>`` of the SRDF a description
    package ships with the URDF (``<stem>.srdf`` beside it, or ``../srdf/<stem>.srdf``, as
    example-robot-data's robots); (None, empty) when there is none."""
    import xml.etree.ElementTree as ET
    from pathlib import Path

    path = Path(urdf_path)
    for candidate in (path.with_suffix(".srdf"), path.parent.parent / "srdf" / f"{path.stem}.srdf"):
        if candidate.is_file():
            try:
                root = ET.parse(candidate).getroot()
            except ET.ParseError:
                return None, set()
            return candidate, {frozenset((str(e.get("link1")), str(e.get("link2"))))
                               for e in root.iter("disable_collisions")
                               if e.get("link1") and e.get("link2")}
    return None, set()


def convex_hulls(geometry: Any) -> Any:
    """``geometry`` (a pinocchio GeometryModel) with every mesh replaced by its convex hull
    (coal, qhull; the hull keeps its triangles, so GJK walks its vertex neighbours); the same
    object when it has no mesh."""
    import coal

    if not any(isinstance(g.geometry, coal.BVHModelBase) for g in geometry.geometryObjects):
        return geometry
    hulls = geometry.clone()
    for item in hulls.geometryObjects:
        mesh = item.geometry
        if isinstance(mesh, coal.BVHModelBase):
            mesh.buildConvexHull(True, "Qt")
            item.geometry = mesh.convex
    return hulls


def hull_distance_error(model: CollisionModel, samples: int = 300, seed: int = 0
                        ) -> dict[str, Any] | None:
    """The convex hulls' distance error against the meshes (None without meshes): on
    ``samples`` uniformly random poses within the limits, each self pair with a mesh in it,
    ``mesh distance - hull distance`` [mm] (>= 0: a hull contains its mesh).

    Returns:
        ``pairs`` (the pairs with a mesh), ``samples``, ``median_mm`` and ``max_mm`` of the
        error, ``min_mm`` (negative only if a hull distance exceeded its mesh distance: coal's
        GJK tolerance) and ``geometry``.
    """
    import coal

    meshes = model.mesh_model()
    if meshes is None:
        return None
    robot = model.robot
    rng = np.random.default_rng(seed)
    poses = rng.uniform(robot.sample_lower, robot.sample_upper, size=(samples, robot.dof))
    is_mesh = [isinstance(g.geometry, coal.BVHModelBase)
               for g in model._mesh_geometry.geometryObjects]
    use = np.array([is_mesh[a] or is_mesh[b] for a, b in model._self_index], dtype=bool)
    hull_mm = model.check(poses).distances_mm[:, use]
    mesh_mm = meshes.check(poses).distances_mm[:, use]
    error = (mesh_mm - hull_mm).ravel()
    return {"geometry": model.geometry, "pairs": int(use.sum()), "samples": samples,
            "median_mm": float(np.median(error)) if error.size else math.nan,
            "max_mm": float(error.max()) if error.size else math.nan,
            "min_mm": float(error.min()) if error.size else math.nan}


def collision_model(robot: Robot) -> CollisionModel | None:
    """The robot's :class:`CollisionModel` (cached on the robot), or None without geometry."""
    if "collision_model" not in robot._cache:
        robot._cache["collision_model"] = build_collision_model(robot)
    return robot._cache["collision_model"]


def check_trajectory(robot: Robot, poses: npt.ArrayLike,
                     obstacles: Sequence[Obstacle] = ()) -> dict[str, Any]:
    """:meth:`CollisionReport.summary` of poses (N, dof) [pose units], plus
    ``collision_model`` (its source; "none" when the robot has no collision geometry: then the
    counts are 0 and the clearances NaN, nothing was checked), ``collision_geometry``
    (:attr:`CollisionModel.geometry`, "none") and ``collision_check_ms`` (the check's wall
    time [ms], the model built before the clock starts; NaN when nothing was checked)."""
    model = collision_model(robot)
    if model is None:
        return {"self_collisions": 0, "env_collisions": 0, "min_clearance_mm": math.nan,
                "min_self_clearance_mm": math.nan, "first_collision_waypoint": math.nan,
                "first_collision_pair": "", "collision_model": "none",
                "collision_geometry": "none", "collision_check_ms": math.nan}
    model.scene(obstacles)  # built (and cached) outside the clock
    started = time.perf_counter()
    summary = model.check(poses, obstacles).summary()
    check_ms = (time.perf_counter() - started) * 1000.0
    return {**summary, "collision_model": model.source, "collision_geometry": model.geometry,
            "collision_check_ms": check_ms}
