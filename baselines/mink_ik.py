"""mink (PyPI ``mink``, on MuJoCo): pink's differential-IK scheme on a MuJoCo model of the URDF.

Loading: ``mujoco.MjSpec.from_string(urdf)`` on the chain's URDF text. MuJoCo's URDF importer
fuses static bodies (``spec.compiler.fusestatic`` is True after parsing a URDF), which would
merge the fixed end link into its parent: it is set False, so every link stays a body. MuJoCo
refuses massless moving bodies, and URDFs written for kinematics have no ``<inertial>``:
``compiler.boundmass`` / ``boundinertia`` give them a negligible mass (kinematics does not
depend on it). A site on the end body, its z-axis on the pointing axis
(``body.add_site(name, pos, quat)``), is the frame P the tasks act on; ``spec.compile()``.
The chain's limits replace ``model.jnt_range`` (continuous joints stay unlimited); goals are
turned from the base body's frame into MuJoCo's world frame.

Two schemes, as pink's (:mod:`ikbench.baselines.pink_ik`): **track** (``--scheme track``,
the default: from the start pose along the goal points onto the touch pose,
:mod:`ikbench.schemes.track`) and **walk** (``--scheme walk``: back from the touch pose,
the start pose free; also every 6-D pose path). Both call ``mink.Configuration(model, q)``,
``mink.solve_ik(configuration, tasks, dt, qp_solver, damping=..., limits=limits)`` with
``mink.ConfigurationLimit(model, gain)`` among the limits, and ``configuration.integrate(v, dt)`` /
``update(q)``; the pointing is
``mink.FrameTask(site, "site", position_cost, orientation_cost=[w, w, 0])`` with
``set_target(mink.SE3.from_rotation_and_translation(...))`` or, with
``--mink-pointing-task axis-align``, ``mink.AxisAlignTask(site, "site", axis=z)`` (rank 2, roll
free) beside a position-only FrameTask.

Track, per step i (forward from the start pose, warm-started at the step before moved on by
the last segment's motion): the FrameTask at the goal point (``track_position_cost``) and the
scheduled pointing direction (the rotation nearest P's with that z-axis; orientation cost 0
when the task asks no pointing), ``mink.PostureTask(model, cost=posture_cost * weights)`` with
``set_target(posture[i])`` (the start-to-touch interpolation, every pose unit weighted alike:
:func:`ikbench.schemes.diffik.posture_weights`), and a speed box (a ``mink.Limit``
returning a ``mink.Constraint``, :class:`ikbench.schemes.diffik.SpeedBox`: every joint
within ``speed_fraction`` of the contract's largest change per segment from step i-1 and within
(n - i) such changes of the touch pose); QP steps until the position error is below
``tolerance`` and the last step moved no joint more than ``stall``, at most ``max_steps``. A
step is converged when the site's position (MuJoCo's FK) is within ``tolerance``. Defaults
as pink's (position cost 1000 /m, orientation cost 0.1 /rad, posture cost 0.01 /rad, speed
fraction 0.95, stall 1e-4 rad; the reasons are given there).

Walk, per goal point: the scheme of :mod:`ikbench.schemes.diffik` (the FrameTask, all
three orientation costs for 6-D goals, and the ConfigurationLimit only). Defaults as pink's except
the limit gain: mink's own default 0.95 (both schemes). ``iterations`` counts QP solves.

**Obstacles** (a task with ``obstacles``; without them nothing here changes): the model is
compiled again with the collision geometry (:func:`mink_scene_model`): each robot capsule a
``mjGEOM_CAPSULE`` geom on its link's body (``body.add_geom(type, size=[radius], fromto=[a,
b])``), each obstacle a geom on the world body (``mjGEOM_BOX`` / ``SPHERE`` / ``CAPSULE``;
a half-space as a large box), placed from the base frame into MuJoCo's world. Among the
limits, ``mink.CollisionAvoidanceLimit(model, geom_pairs, gain=--mink-collision-gain,
minimum_distance_from_collisions=--mink-clearance, collision_detection_distance=clearance +
--mink-detection)``: per QP step and geom pair within the detection distance, the normal
velocity of the witness points (``mj_geomDistance``) keeps the pair from closing more than
gain (d - clearance). The pairs are given explicitly (each robot capsule that moves with a
joint against each obstacle; the capsules of each of the collision model's self pairs):
mink's own pair filter drops a body's pairs with its parent's weld, which would drop every
obstacle pair of the first link (the obstacles sit on the world body). In the walk, a point
whose warm start overlaps (the home pose a pose path's walk starts from may) is first solved
without the limit and then, if that pose is clear, with it from there
(``started_inside_points``); a QP the limit
makes infeasible (``NoSolutionFound``) leaves the point unsolved.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.options import check_choice, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals
from ikbench.schemes.collision import AvoidsObstacles, Scene
from ikbench.schemes.diffik import (
    SpeedBox,
    WarmStart,
    check_qp_settings,
    converge,
    errors,
    orientation_costs,
    posture_weights,
    qp_option,
    settle,
    target_rotation,
    track_errors,
    track_orientation_costs,
    track_target_rotation,
    walk_clear,
)
from ikbench.schemes.geometry import frame_with_z_on, rotation_angle_rad
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.single_pose import PoseOut, PoseSolver, steps_to_tolerance
from ikbench.schemes.track import SCHEME_HELP, SCHEMES, track
from ikbench.schemes.walk import PointResult

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.schemes.track import TrackPlan

SITE = "ikbench_pointing_site"
POINTING_TASKS = ("frame", "axis-align")
_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class MinkSettings:
    """Settings of mink's track and walk (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    pointing_task: str = option("frame", flag="mink-pointing-task", choices=POINTING_TASKS,
                                help="frame (FrameTask, roll cost 0) or axis-align "
                                "(AxisAlignTask beside a position-only FrameTask)")
    dt: float = qp_option("mink", "dt")
    damping: float = qp_option("mink", "damping", help="Levenberg-Marquardt damping of the QP "
                               "(solve_ik's damping)")
    position_cost: float = qp_option("mink", "position_cost")
    orientation_cost: float = qp_option("mink", "orientation_cost",
                                        help="cost of the pointing axis's tilt (roll free)")
    limit_gain: float = qp_option("mink", "limit_gain", default=0.95)
    qp_solver: str = qp_option("mink", "qp_solver")
    tolerance: float = qp_option("mink", "tolerance")
    max_steps: int = qp_option("mink", "max_steps")
    track_position_cost: float = qp_option("mink", "track_position_cost")
    posture_cost: float = qp_option("mink", "posture_cost")
    speed_fraction: float = qp_option("mink", "speed_fraction")
    stall: float = qp_option("mink", "stall")
    clearance: float = option(5.0, flag="mink-clearance", unit="mm",
                              help="tasks with obstacles: CollisionAvoidanceLimit's "
                              "minimum_distance_from_collisions, kept between the robot's "
                              "capsules and the obstacles and between self pairs")
    detection: float = option(200.0, flag="mink-detection", unit="mm",
                              help="tasks with obstacles: pairs closer than clearance + this "
                              "enter the QP (collision_detection_distance - clearance)")
    collision_gain: float = option(0.5, flag="mink-collision-gain",
                                   help="tasks with obstacles: CollisionAvoidanceLimit's gain "
                                   "in (0, 1]")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_choice(self, "pointing_task", POINTING_TASKS)
        if not (self.clearance >= 0 and self.detection > 0 and 0 < self.collision_gain <= 1):
            raise InputError("--mink-clearance must be >= 0 [mm], --mink-detection > 0 [mm] "
                             "and --mink-collision-gain in (0, 1]")
        check_qp_settings(self)


@dataclass(frozen=True)
class MinkModel:
    """The compiled MuJoCo model and how the chain maps onto it.

    Attributes:
        model: ``mujoco.MjModel`` with the site P.
        qpos: (dof,) qpos address of each chain joint.
        R_EP: (3, 3) end frame -> P.
        R_wb, p_wb: (3, 3), (3,) the base body in MuJoCo's world frame [m].
    """

    model: Any
    qpos: np.ndarray
    R_EP: np.ndarray
    R_wb: np.ndarray
    p_wb: np.ndarray


def mink_model(chain: Chain) -> MinkModel:
    """The chain's :class:`MinkModel` (cached per chain)."""
    if chain in _MODELS:
        return _MODELS[chain]
    _MODELS[chain] = _compile(chain)
    return _MODELS[chain]


_SCENE_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def mink_scene_model(chain: Chain, scene: Scene) -> MinkModel:
    """The chain's :class:`MinkModel` with the collision geometry of ``scene``
    (:class:`ikbench.schemes.collision.Scene`; see the module docstring), cached per
    chain and scene."""
    cache = _SCENE_MODELS.setdefault(chain, {})
    if scene.key not in cache:
        cache[scene.key] = _compile(chain, scene, mink_model(chain))
    return cache[scene.key]


def _add_geoms(spec, scene, plain: MinkModel) -> None:
    """The scene's capsules on their links' bodies, its obstacles on the world body."""
    import mujoco

    types = {"capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
             "box": mujoco.mjtGeom.mjGEOM_BOX}
    for shape in scene.links:
        a, b = shape.ends_m()
        spec.body(shape.link).add_geom(name=shape.name, type=types["capsule"],
                                       size=[shape.radius_m, 0.0, 0.0],
                                       fromto=[*map(float, a), *map(float, b)])
    for shape in scene.obstacles:
        R = plain.R_wb @ shape.rotation
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R).reshape(9))
        if shape.kind == "box":
            size = [*map(float, 0.5 * shape.size_m)]
        else:  # sphere: radius; capsule: radius, half length
            size = [shape.radius_m, 0.5 * shape.length_m, 0.0]
        spec.worldbody.add_geom(name=shape.name, type=types[shape.kind], size=size,
                                pos=[*map(float, plain.R_wb @ shape.center_m + plain.p_wb)],
                                quat=list(quat))


def _compile(chain: Chain, scene=None, plain: MinkModel | None = None) -> MinkModel:
    """Compile the chain's model (with ``scene``'s geoms when given; ``plain``: the model
    without them, for the base's pose in the world)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(chain.urdf_text)
    spec.compiler.fusestatic = False
    spec.compiler.boundmass = 1e-6
    spec.compiler.boundinertia = 1e-12
    # inertias that break the triangle inequality (PR2's sensor_mount_link) are made valid
    # instead of refusing the robot: mass and inertia play no part in IK
    spec.compiler.balanceinertia = True
    R_EP = frame_with_z_on(chain.pointing_axis)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R_EP).reshape(9))
    spec.body(chain.end_frame).add_site(name=SITE, pos=[0.0, 0.0, 0.0], quat=list(quat))
    if scene is not None:
        assert plain is not None
        _add_geoms(spec, scene, plain)
    model = spec.compile()
    if model.nq != chain.dof:
        raise ValueError(f"MuJoCo's model has {model.nq} coordinates, the chain {chain.dof}")
    for k, name in enumerate(chain.joint_names):
        j = model.joint(name).id
        limited = bool(np.isfinite(chain.lower[k]))
        model.jnt_limited[j] = limited
        model.jnt_range[j] = [chain.lower[k], chain.upper[k]] if limited else [0.0, 0.0]
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    base = model.body(chain.base_link).id
    qpos = np.array([model.joint(name).qposadr[0] for name in chain.joint_names])
    return MinkModel(model, qpos, R_EP, data.xmat[base].reshape(3, 3).copy(),
                     data.xpos[base].copy())


def collision_limit(m: MinkModel, scene: Scene, settings: MinkSettings) -> Any:
    """``mink.CollisionAvoidanceLimit`` on the scene's pairs (see the module docstring)."""
    import mink

    model = m.model
    moving = {s.link for s in scene.links if model.body_weldid[model.body(s.link).id] != 0}
    pairs = sorted({tuple(sorted((model.geom(a.name).id, model.geom(b.name).id)))
                    for a, b in scene.pairs(moving)})

    class Limit(mink.CollisionAvoidanceLimit):
        """mink's limit on exactly these geom pairs (its own filter bypassed)."""

        def _construct_geom_id_pairs(self, geom_pairs):
            return [tuple(p) for p in geom_pairs]

    clearance = settings.clearance / 1000.0
    return Limit(model, pairs, gain=settings.collision_gain,
                 minimum_distance_from_collisions=clearance,
                 collision_detection_distance=clearance + settings.detection / 1000.0)


def penetrating(m: MinkModel, limit: Any, q_chain: np.ndarray) -> bool:
    """True when a pair of ``limit`` overlaps at ``q_chain`` (``mj_geomDistance``)."""
    import mujoco

    data = mujoco.MjData(m.model)
    data.qpos[m.qpos] = q_chain
    mujoco.mj_kinematics(m.model, data)
    fromto = np.zeros(6)
    return any(mujoco.mj_geomDistance(m.model, data, a, b, 0.0, fromto) < 0.0
               for a, b in limit.geom_id_pairs)


def solve_chain(chain: Chain, goals: Goals, settings: MinkSettings,
                scene: Scene | None = None) -> ChainResult:
    """The mink walk in URDF units (see the module docstring; ``scene``: the obstacles and
    capsules to keep apart, or None)."""
    import mink
    from mink.exceptions import NoSolutionFound

    m = mink_model(chain) if scene is None else mink_scene_model(chain, scene)
    model, site = m.model, m.model.site(SITE).id
    # the goals in MuJoCo's world frame
    world = Goals(goals.points_m @ m.R_wb.T + m.p_wb, goals.directions @ m.R_wb.T,
                  None if goals.rotations is None else m.R_wb @ goals.rotations, None, None)
    axis_align = settings.pointing_task == "axis-align" and goals.rotations is None
    frame_task = mink.FrameTask(SITE, "site", position_cost=settings.position_cost,
                                orientation_cost=0.0 if axis_align else
                                orientation_costs(goals, settings.orientation_cost))
    tasks: list[Any] = [frame_task]
    if axis_align:
        align = mink.AxisAlignTask(SITE, "site", axis=(0.0, 0.0, 1.0),
                                   cost=settings.orientation_cost)
        tasks.append(align)
    plain_limits = [mink.ConfigurationLimit(model, gain=settings.limit_gain)]
    limits = plain_limits
    avoid = None if scene is None else collision_limit(m, scene, settings)
    if avoid is not None:
        limits = [*plain_limits, avoid]

    def run(i: int, q_warm: np.ndarray, avoiding: bool) -> PointResult:
        q0 = np.zeros(model.nq)
        q0[m.qpos] = q_warm
        configuration = mink.Configuration(model, q0)
        if axis_align:
            align.set_target(world.directions[i])

        def frame():
            data = configuration.data
            return data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()

        def step():
            p_P, R_P = frame()
            R = R_P if axis_align else target_rotation(world, i, R_P, m.R_EP)
            frame_task.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.from_matrix(R), world.points_m[i]))
            v = mink.solve_ik(configuration, tasks, settings.dt, settings.qp_solver,
                              damping=settings.damping,
                              limits=limits if avoiding else plain_limits)
            q = configuration.integrate(v, settings.dt)
            q[m.qpos] = chain.clip(q[m.qpos])
            configuration.update(q)

        def measure():
            p_P, R_P = frame()
            return errors(world, i, p_P, R_P, m.R_EP)

        steps, ok = converge(measure, step, settings.tolerance, settings.max_steps)
        return PointResult(configuration.q[m.qpos].copy(), steps, ok)

    return walk_clear(run, None if avoid is None else lambda q: penetrating(m, avoid, q),
                      NoSolutionFound, chain, goals, qp_solver=settings.qp_solver,
                      pointing_task=settings.pointing_task,
                      iterations_are="QP solves (mink.solve_ik calls)")


def solve_track(robot: Robot, chain: Chain, plan: TrackPlan, settings: MinkSettings,
                step: np.ndarray | None = None, scene: Scene | None = None) -> ChainResult:
    """mink's track from the start pose onto the touch pose (``plan``: a
    :class:`ikbench.schemes.track.TrackPlan`; ``step``: (dof,) the contract's largest
    joint change per segment [rad, m], or None: no speed box). See the module docstring."""
    import mink
    from mink.exceptions import NoSolutionFound

    m = mink_model(chain) if scene is None else mink_scene_model(chain, scene)
    model, site = m.model, m.model.site(SITE).id
    # the plan in MuJoCo's world frame
    world = replace(plan, points_m=plan.points_m @ m.R_wb.T + m.p_wb,
                    directions=None if plan.directions is None else plan.directions @ m.R_wb.T)
    axis_align = settings.pointing_task == "axis-align" and world.directions is not None
    frame_task = mink.FrameTask(SITE, "site", position_cost=settings.track_position_cost,
                                orientation_cost=0.0 if axis_align else
                                track_orientation_costs(world, settings.orientation_cost))
    weights = np.zeros(model.nv)
    weights[m.qpos] = posture_weights(robot)  # hinge / slide joints: dof address = qpos
    posture_task = mink.PostureTask(model, cost=settings.posture_cost * weights)
    tasks: list[Any] = [frame_task, posture_task]
    if axis_align:
        align = mink.AxisAlignTask(SITE, "site", axis=(0.0, 0.0, 1.0),
                                   cost=settings.orientation_cost)
        tasks.append(align)
    limits: list[Any] = [mink.ConfigurationLimit(model, gain=settings.limit_gain)]
    if scene is not None:
        limits.append(collision_limit(m, scene, settings))
    box = SpeedBox.of(plan, step, settings.speed_fraction, chain.lower, chain.upper,
                      settings.limit_gain)
    if box is not None:
        speed_box = box  # the box, not None, inside the limit's method

        class SpeedLimit(mink.Limit):
            """The speed box (:class:`ikbench.schemes.diffik.SpeedBox`) as a mink
            limit."""

            def compute_qp_inequalities(self, configuration, dt):
                G, h = speed_box.inequalities(configuration.q[m.qpos])
                if not len(h):
                    return mink.Constraint()
                G_full = np.zeros((len(h), model.nv))
                G_full[:, m.qpos] = G
                return mink.Constraint(G=G_full, h=h)

        limits.append(SpeedLimit())
    warm_start = WarmStart(box, chain.clip, moving_on=scene is None)
    q_full = np.zeros(model.nq)
    configuration = mink.Configuration(model)

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        q_full[m.qpos] = warm_start(i, q_warm)
        configuration.update(q_full)
        q_full[m.qpos] = plan.posture[i]
        posture_task.set_target(q_full)
        if axis_align:
            assert world.directions is not None  # axis_align needs them
            align.set_target(world.directions[i])

        def frame():
            data = configuration.data
            return data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()

        def step_once() -> float:
            _, R_P = frame()
            R = R_P if axis_align else track_target_rotation(world, i, R_P)
            frame_task.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.from_matrix(R), world.points_m[i]))
            v = mink.solve_ik(configuration, tasks, settings.dt, settings.qp_solver,
                              damping=settings.damping, limits=limits)
            q_before = configuration.q[m.qpos].copy()
            q = configuration.integrate(v, settings.dt)
            q[m.qpos] = chain.clip(q[m.qpos])
            configuration.update(q)
            return float(np.max(np.abs(q[m.qpos] - q_before)))

        def measure():
            p_P, R_P = frame()
            return track_errors(world, i, p_P, R_P)

        steps, ok = settle(measure, step_once, settings.tolerance, settings.stall,
                           settings.max_steps, NoSolutionFound)
        return PointResult(configuration.q[m.qpos].copy(), steps, ok)

    walk = track(solve_point, chain, plan)
    return ChainResult.from_walk(walk, qp_solver=settings.qp_solver, scheme="track",
                                 pointing_task=settings.pointing_task,
                                 speed_box=box is not None,
                                 iterations_are="QP solves (mink.solve_ik calls)")


class MinkIK(AvoidsObstacles, LibraryMethod):
    """mink's QP differential IK on MuJoCo, tracking from the start pose onto the touch pose
    (or walked back from the touch pose: ``--scheme walk``)."""

    name = "mink"
    description = ("library: mink QP differential IK on MuJoCo (the URDF loaded by MuJoCo) "
                   "tracking the goal points from the start pose (frame task + posture task, "
                   "joint limits and speed limits as QP constraints), landing on the touch "
                   "pose (--scheme walk: walked back from the touch pose); with obstacles, "
                   "CollisionAvoidanceLimit on capsule geoms and the obstacles")
    library = "mink"
    Settings = MinkSettings
    chain_model = staticmethod(mink_model)  # untimed: MuJoCo parses and compiles the URDF

    def solve_scene(self, robot: Robot, chain: Chain, goals: Goals,
                    scene: Scene | None) -> ChainResult:
        if goals.track is not None:
            return solve_track(robot, chain, goals.track, self.settings, goals.max_step, scene)
        return solve_chain(chain, goals, self.settings, scene)


class MinkSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`): a
    FrameTask on the end site, ConfigurationLimit, daqp; dt 1 s (full steps) until both
    errors are below the library tolerance or 100 QP steps."""

    rank = 70
    name, library, modules = "mink", "mink", ("mink", "mujoco", "qpsolvers", "daqp")
    iterations_are = "QP solves (mink.solve_ik calls)"
    attempt_bound = "LIBRARY_TOLERANCE (1e-6, m and rad), 100 QP steps"
    #: benchmarks/determinism_check.py: answers move under OpenBLAS' other kernels (mink
    #: builds its QP with numpy matrix products inside the library, which BLAS computes).
    stable_across_machines = False

    def prepare(self) -> None:
        self.m = mink_model(self.chain)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import mink

        m, pose = self.m, self.kind == "pose"
        site = m.model.site(SITE).id
        goal_p = m.R_wb @ np.asarray(point_m, dtype=float) + m.p_wb  # MuJoCo's world frame
        goal_R = m.R_wb @ rotation @ m.R_EP
        task = mink.FrameTask(SITE, "site", position_cost=1.0,
                              orientation_cost=1.0 if pose else 0.0)
        task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(goal_R),
                                                               goal_p))
        limits = [mink.ConfigurationLimit(m.model, gain=0.95)]
        q0 = np.zeros(m.model.nq)
        q0[m.qpos] = self.chain.clip(q_init)
        configuration = mink.Configuration(m.model, q0)

        def measure() -> tuple[float, float]:
            data = configuration.data
            R = data.site_xmat[site].reshape(3, 3)
            return (float(np.linalg.norm(data.site_xpos[site] - goal_p)),
                    rotation_angle_rad(R, goal_R) if pose else 0.0)

        def step() -> None:
            v = mink.solve_ik(configuration, [task], 1.0, "daqp", damping=1e-6, limits=limits)
            q = configuration.integrate(v, 1.0)
            q[m.qpos] = self.chain.clip(q[m.qpos])
            configuration.update(q)

        steps, ok = steps_to_tolerance(measure, step)
        return PoseOut(configuration.q[m.qpos].copy(), steps, ok)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="mink", requires=("mink", "mujoco", "qpsolvers", "daqp"),
                  methods=(MinkIK,), solvers=(MinkSolver,), rank=90)
