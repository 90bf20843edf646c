"""pink (PyPI ``pin-pink``): QP differential IK on Pinocchio, tracking the goal points from the
start pose onto the touch pose (``--scheme track``, the default) or walked back from the touch
pose (``--scheme walk``, the authors' scheme).

pink works on the robot's own Pinocchio model (:meth:`ikbench.core.robot.Robot.pinocchio_fk`:
the chain only, the base link as world frame), copied once per robot with the chain's limits
and an extra operational frame P on the end frame whose z-axis is the pointing axis
(``model.addFrame(pinocchio.Frame(..., OP_FRAME))``). Both schemes call pink the same way:
``pink.Configuration(model, data, q)``, ``pink.solve_ik(configuration, tasks, dt,
solver=qp_solver, damping=damping, limits=limits)``, ``configuration.integrate(v, dt)`` and
``configuration.update(q)``, with ``pink.limits.ConfigurationLimit(model, config_limit_gain)``
among the limits: the joint limits are QP constraints ``q_min - q <= v dt <= q_max - q``
(scaled by the gain), so no step leaves them. pink's frame error is P's body twist
log(T_P^-1 T_target), so a zero orientation cost on P's z frees the roll.

**Track** (:mod:`ikbench.schemes.track`; tasks with a start and a touch pose and no 6-D
goal frames). Row 0 is the start pose, row n the touch pose; steps 1 .. n-1 are solved forward, each
from the step before moved on by the last segment's motion (a constant-speed warm start).
Per step i, QP steps of

- ``pink.tasks.FrameTask(P, position_cost=track_position_cost, orientation_cost=[w, w, 0])``
  with ``set_target(pinocchio.SE3(R, p_i))``: p_i the goal point, R the rotation nearest P's
  whose z-axis is the scheduled pointing direction (orientation cost 0: position only, when
  the task asks no pointing);
- ``pink.tasks.PostureTask(cost=posture_cost * weights)`` with ``set_target(posture[i])``,
  the start-to-touch interpolation; the weights make every pose unit cost alike (NICO: a motor
  degree; its wrist and finger motors turn their joints only 0.5 and 0.22 URDF degree per
  motor degree), :func:`ikbench.schemes.diffik.posture_weights`;
- a speed box (a ``pink.limits.Limit`` beside the ConfigurationLimit,
  :class:`ikbench.schemes.diffik.SpeedBox`): every joint moves at most ``speed_fraction``
  of the contract's largest change per segment from step i-1, and stays within (n - i) such changes
  of the touch pose, so the arm lands on it without a jump,

until the position error is below ``tolerance`` and the last QP step moved no joint more than
``stall`` (the scheduled pointing may be slightly out of reach: the weighted optimum is
taken), at most ``max_steps``. A step is reported converged when P's position, by pink's FK,
is within ``tolerance``. Defaults and why: position cost 1000 /m against orientation cost
0.1 /rad and posture cost 0.01 /rad (the goal point is the hard goal, kept to ~1e-9 m even
where the pointing or the posture cannot be met; the posture only resolves the arm's
redundancy, strong enough to keep the arm near the path onto the touch pose, weak enough to
leave the pointing a few degrees from its schedule at most), speed fraction 0.95 (a margin
to the contract's limit), stall 1e-4 rad (2-4 QP solves per step, ~40-70 ms per 50-step
trajectory).

**Walk** (:mod:`ikbench.schemes.walk`; also every 6-D pose path). Per goal point the
scheme of
:mod:`ikbench.schemes.diffik`: ``FrameTask(P, position_cost, orientation_cost=[w, w,
0])`` (all three for 6-D goals) and the ConfigurationLimit only. Defaults: dt 1 s with task gain 1
(a full damped Gauss-Newton step per QP), damping 1e-6 (the 7-DoF arm is redundant: a
positive-definite QP Hessian, minimum-norm steps), position cost 1 /m and orientation cost
0.1 /rad (they compete only where a goal is unreachable), limit gain 0.5 (pink's default), QP
solver daqp (qpsolvers backend, deterministic), tolerance 1e-6 m / rad, at most 100 steps per
point. Both schemes share dt, damping, orientation cost, limit gain, QP solver, tolerance and
max steps. ``iterations`` counts QP solves.

**Obstacles** (a task with ``obstacles``; without them nothing here changes): a Pinocchio
``GeometryModel`` on the same model holds the robot's capsules (``coal.Capsule`` on their
links' joints, as :mod:`ikbench.core.collision` places them) and the obstacles (on the
universe joint; a half-space as a large box), with a ``CollisionPair`` for each robot-obstacle
pair whose capsule moves with some joint and for the capsules of each of the collision
model's self pairs; ``pink.Configuration(model, data, q, collision_model=geometry,
collision_data=geometry_data)`` computes their distances on every update (coal), and
``pink.barriers.SelfCollisionBarrier(n_collision_pairs=all pairs, gain=--pink-barrier-gain,
safe_displacement_gain=0, d_min=--pink-clearance)`` goes to ``solve_ik(...,
barriers=[barrier])``: every QP step keeps J_d dq >= -gain (d - d_min) for each pair (pink's
control-barrier condition; its safe-displacement term is off, as it divides by |J|^2, zero
for pairs no joint moves). The barrier only slows the approach; a warm start already inside
an obstacle is not pushed out reliably (pink's gradient of a penetrating pair points along the
witness points, which reverse inside). So, in the walk, a point whose warm start overlaps (the
home pose the walk of a pose path starts from may: CppFlow's panda problems) is first solved
without the barrier and then, if that pose is clear, with it from there
(``started_inside_points`` counts them); a QP
the barrier makes infeasible (pink's ``NoSolutionFound``) leaves the point unsolved.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.kinematics.pinocchio_fk import link_frame_id
from ikbench.methods.options import check_choice, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals, chain_of
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

POINTING_FRAME = "ikbench_pointing_frame"
_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class PinkSettings:
    """Settings of pink's track and walk (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    dt: float = qp_option("pink", "dt")
    damping: float = qp_option("pink", "damping")
    position_cost: float = qp_option("pink", "position_cost")
    orientation_cost: float = qp_option("pink", "orientation_cost")
    limit_gain: float = qp_option("pink", "limit_gain")
    qp_solver: str = qp_option("pink", "qp_solver")
    tolerance: float = qp_option("pink", "tolerance")
    max_steps: int = qp_option("pink", "max_steps")
    track_position_cost: float = qp_option("pink", "track_position_cost")
    posture_cost: float = qp_option("pink", "posture_cost")
    speed_fraction: float = qp_option("pink", "speed_fraction")
    stall: float = qp_option("pink", "stall")
    clearance: float = option(5.0, flag="pink-clearance", unit="mm",
                              help="tasks with obstacles: SelfCollisionBarrier's d_min, the "
                              "least distance kept between the robot's capsules and the "
                              "obstacles and between self pairs")
    barrier_gain: float = option(0.5, flag="pink-barrier-gain",
                                 help="tasks with obstacles: SelfCollisionBarrier's gain (the "
                                 "fraction of the distance above d_min a QP step may close)")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        if not (self.clearance >= 0 and 0 < self.barrier_gain <= 1):
            raise InputError("--pink-clearance must be >= 0 [mm] and --pink-barrier-gain in "
                             "(0, 1]")
        check_qp_settings(self)


def pink_model(robot: Robot, chain: Chain) -> tuple[Any, np.ndarray]:
    """A copy of the robot's Pinocchio model with the chain's limits and the frame P."""
    if robot in _MODELS:
        return _MODELS[robot]
    import pinocchio as pin

    model = pin.Model(robot.pinocchio_fk().model)
    model.lowerPositionLimit = np.where(np.isfinite(chain.lower), chain.lower,
                                        model.lowerPositionLimit)
    model.upperPositionLimit = np.where(np.isfinite(chain.upper), chain.upper,
                                        model.upperPositionLimit)
    R_EP = frame_with_z_on(chain.pointing_axis)
    end = model.frames[link_frame_id(model, chain.end_frame)]
    model.addFrame(pin.Frame(POINTING_FRAME, end.parentJoint,
                             end.placement * pin.SE3(R_EP, np.zeros(3)), pin.FrameType.OP_FRAME))
    _MODELS[robot] = (model, R_EP)
    return _MODELS[robot]


class Avoidance:
    """The collision geometry and the barrier of a scene (see the module docstring)."""

    def __init__(self, model: Any, root_link: str, scene: Scene, settings: PinkSettings
                 ) -> None:
        import coal
        import pinocchio as pin
        from pink.barriers import SelfCollisionBarrier

        geometry = pin.GeometryModel()
        root = model.frames[link_frame_id(model, root_link)].placement
        index = {}
        for shape in scene.links:
            fid = model.getFrameId(shape.link)
            frame = model.frames[fid]
            placement = frame.placement if frame.parentJoint else root.actInv(frame.placement)
            index[shape.name] = geometry.addGeometryObject(pin.GeometryObject(
                shape.name, frame.parentJoint, fid,
                placement * pin.SE3(shape.rotation, shape.center_m), _coal(coal, shape)))
        for shape in scene.obstacles:
            index[shape.name] = geometry.addGeometryObject(pin.GeometryObject(
                shape.name, 0, 0, pin.SE3(shape.rotation, shape.center_m),
                _coal(coal, shape)))
        moving = {s.link for s in scene.links
                  if model.frames[model.getFrameId(s.link)].parentJoint}
        for a, b in scene.pairs(moving):
            geometry.addCollisionPair(pin.CollisionPair(index[a.name], index[b.name]))
        self.geometry = geometry
        self.data = pin.GeometryData(geometry)
        self.pairs = len(geometry.collisionPairs)
        self.barriers = [SelfCollisionBarrier(self.pairs, gain=settings.barrier_gain,
                                              safe_displacement_gain=0.0,
                                              d_min=settings.clearance / 1000.0)]

    def configuration(self, model: Any, data: Any, q: np.ndarray) -> Any:
        """``pink.Configuration`` with the collision model (distances on each update)."""
        import pink

        return pink.Configuration(model, data, q, collision_model=self.geometry,
                                  collision_data=self.data)

    def penetrating(self, model: Any, data: Any, q: np.ndarray) -> bool:
        """True when a pair overlaps at ``q`` (coal's distances)."""
        configuration = self.configuration(model, data, q)
        results = configuration.collision_data.distanceResults
        return any(r.min_distance < 0.0 for r in results)


def _coal(coal, shape):
    if shape.kind == "capsule":
        return coal.Capsule(shape.radius_m, shape.length_m)
    if shape.kind == "sphere":
        return coal.Sphere(shape.radius_m)
    return coal.Box(*map(float, shape.size_m))


def solve_chain(robot: Robot, chain: Chain, goals: Goals, settings: PinkSettings,
                scene: Scene | None = None) -> ChainResult:
    """The pink walk in URDF units (see the module docstring)."""
    import pink
    import pinocchio as pin
    from pink.exceptions import NoSolutionFound
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    model, R_EP = pink_model(robot, chain)
    data = model.createData()
    avoid = None if scene is None else Avoidance(model, robot.root_link, scene, settings)
    task = FrameTask(POINTING_FRAME, position_cost=settings.position_cost,
                     orientation_cost=orientation_costs(goals, settings.orientation_cost))
    limits = [ConfigurationLimit(model, config_limit_gain=settings.limit_gain)]
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    barriers = {} if avoid is None else {"barriers": avoid.barriers}

    def run(i: int, q_warm: np.ndarray, avoiding: bool) -> PointResult:
        configuration = (avoid.configuration(model, data, q_warm) if avoid and avoiding
                         else pink.Configuration(model, data, q_warm))

        def frame():
            T = configuration.get_transform_frame_to_world(POINTING_FRAME)
            return T.translation, T.rotation

        def step():
            p_P, R_P = frame()
            task.set_target(pin.SE3(target_rotation(goals, i, R_P, R_EP), goals.points_m[i]))
            v = pink.solve_ik(configuration, [task], settings.dt, solver=settings.qp_solver,
                              damping=settings.damping, limits=limits,
                              **(barriers if avoiding else {}))
            configuration.update(np.clip(configuration.integrate(v, settings.dt), lower, upper))

        def measure():
            p_P, R_P = frame()
            return errors(goals, i, p_P, R_P, R_EP)

        steps, ok = converge(measure, step, settings.tolerance, settings.max_steps)
        return PointResult(configuration.q.copy(), steps, ok)

    penetrating = None if avoid is None else lambda q: avoid.penetrating(model, data, q)
    return walk_clear(run, penetrating, NoSolutionFound, chain, goals,
                      qp_solver=settings.qp_solver,
                      iterations_are="QP solves (pink.solve_ik calls)")


def solve_track(robot: Robot, chain: Chain, plan: TrackPlan, settings: PinkSettings,
                step: np.ndarray | None = None, scene: Scene | None = None) -> ChainResult:
    """pink's track from the start pose onto the touch pose (``plan``: a
    :class:`ikbench.schemes.track.TrackPlan`; ``step``: (dof,) the contract's largest
    joint change per segment [rad, m], or None: no speed box). See the module docstring."""
    import pink
    import pinocchio as pin
    from pink.exceptions import NoSolutionFound
    from pink.limits import ConfigurationLimit, Limit
    from pink.tasks import FrameTask, PostureTask

    model, _ = pink_model(robot, chain)
    data = model.createData()
    avoid = None if scene is None else Avoidance(model, robot.root_link, scene, settings)
    barriers = {} if avoid is None else {"barriers": avoid.barriers}
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    frame_task = FrameTask(POINTING_FRAME, position_cost=settings.track_position_cost,
                           orientation_cost=track_orientation_costs(plan,
                                                                    settings.orientation_cost))
    posture_task = PostureTask(cost=settings.posture_cost * posture_weights(robot))
    tasks = [frame_task, posture_task]
    limits: list = [ConfigurationLimit(model, config_limit_gain=settings.limit_gain)]
    box = SpeedBox.of(plan, step, settings.speed_fraction, lower, upper, settings.limit_gain)
    if box is not None:
        speed_box = box  # the box, not None, inside the limit's method

        class SpeedLimit(Limit):
            """The speed box (:class:`ikbench.schemes.diffik.SpeedBox`) as a pink
            limit."""

            def compute_qp_inequalities(self, configuration, dt):
                G, h = speed_box.inequalities(configuration.q)
                return (G, h) if len(h) else None

        limits.append(SpeedLimit())
    warm_start = WarmStart(box, lambda q: np.clip(q, lower, upper), moving_on=scene is None)

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        q0 = warm_start(i, q_warm)
        configuration = (pink.Configuration(model, data, q0) if avoid is None
                         else avoid.configuration(model, data, q0))
        posture_task.set_target(plan.posture[i])

        def frame():
            T = configuration.get_transform_frame_to_world(POINTING_FRAME)
            return T.translation, T.rotation

        def step_once() -> float:
            _, R_P = frame()
            frame_task.set_target(pin.SE3(track_target_rotation(plan, i, R_P),
                                          plan.points_m[i]))
            v = pink.solve_ik(configuration, tasks, settings.dt, solver=settings.qp_solver,
                              damping=settings.damping, limits=limits, **barriers)
            q_before = configuration.q.copy()
            configuration.update(np.clip(configuration.integrate(v, settings.dt), lower, upper))
            return float(np.max(np.abs(configuration.q - q_before)))

        def measure():
            p_P, R_P = frame()
            return track_errors(plan, i, p_P, R_P)

        steps, ok = settle(measure, step_once, settings.tolerance, settings.stall,
                           settings.max_steps, NoSolutionFound)
        return PointResult(configuration.q.copy(), steps, ok)

    walk = track(solve_point, chain, plan)
    return ChainResult.from_walk(walk, qp_solver=settings.qp_solver, scheme="track",
                                 speed_box=box is not None,
                                 iterations_are="QP solves (pink.solve_ik calls)")


class PinkIK(AvoidsObstacles, LibraryMethod):
    """pink's QP differential IK, tracking from the start pose onto the touch pose (or walked
    back from the touch pose: ``--scheme walk``)."""

    name = "pink"
    description = ("library: pink QP differential IK on Pinocchio tracking the goal points "
                   "from the start pose (frame task + posture task, joint limits and speed "
                   "limits as QP constraints), landing on the touch pose (--scheme walk: "
                   "walked back from the touch pose); with obstacles, SelfCollisionBarrier "
                   "on the robot's capsules and the obstacles")
    library = "pin-pink"
    Settings = PinkSettings
    loads_urdf = False  # the robot's own Pinocchio model

    def prepare(self, robot: Robot) -> None:
        """Untimed: the model copy with the pointing frame."""

        pink_model(robot, chain_of(robot))

    def solve_scene(self, robot: Robot, chain: Chain, goals: Goals,
                    scene: Scene | None) -> ChainResult:
        if goals.track is not None:
            return solve_track(robot, chain, goals.track, self.settings, goals.max_step, scene)
        return solve_chain(robot, chain, goals, self.settings, scene)


class PinkSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`): a
    FrameTask on the end frame, ConfigurationLimit, daqp; dt 1 s (full steps) until both
    errors are below the library tolerance or 100 QP steps."""

    rank = 60
    name, library, modules = "pink", "pin-pink", ("pink", "qpsolvers", "daqp")
    iterations_are = "QP solves (pink.solve_ik calls)"
    attempt_bound = "LIBRARY_TOLERANCE (1e-6, m and rad), 100 QP steps"

    def prepare(self) -> None:
        self.model, self.R_EP = pink_model(self.robot, self.chain)
        self.data = self.model.createData()

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import pink
        import pinocchio as pin
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask

        pose = self.kind == "pose"
        task = FrameTask(POINTING_FRAME, position_cost=1.0, orientation_cost=1.0 if pose
                         else 0.0)
        goal_R = rotation @ self.R_EP
        task.set_target(pin.SE3(goal_R, np.asarray(point_m, dtype=float)))
        limits = [ConfigurationLimit(self.model, config_limit_gain=0.5)]
        lower, upper = self.model.lowerPositionLimit, self.model.upperPositionLimit
        configuration = pink.Configuration(self.model, self.data, np.clip(q_init, lower, upper))

        def measure() -> tuple[float, float]:
            T = configuration.get_transform_frame_to_world(POINTING_FRAME)
            return (float(np.linalg.norm(T.translation - point_m)),
                    rotation_angle_rad(T.rotation, goal_R) if pose else 0.0)

        def step() -> None:
            v = pink.solve_ik(configuration, [task], 1.0, solver="daqp", damping=1e-6,
                              limits=limits)
            configuration.update(np.clip(configuration.integrate(v, 1.0), lower, upper))

        steps, ok = steps_to_tolerance(measure, step)
        return PoseOut(configuration.q.copy(), steps, ok)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="pin-pink", requires=("pink", "qpsolvers", "daqp"),
                  methods=(PinkIK,), solvers=(PinkSolver,), rank=60)
