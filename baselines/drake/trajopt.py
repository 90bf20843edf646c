"""Drake ``KinematicTrajectoryOptimization`` (PyPI ``drake``): the whole path at once.

The path is a B-spline r(s), s in [0, 1], in joint space (one control point per goal point
by default, cubic) with a duration T (q(t) = r(t / T)); goal i sits at s_i = i / n. The
program (pydrake.planning.KinematicTrajectoryOptimization and its ``get_mutable_prog()``):

- fixed ends: ``AddPathPositionConstraint(q_start, q_start, 0)`` and
  ``AddPathPositionConstraint(q_touch, q_touch, 1)``;
- goal points 1..n-1: ``AddPathPositionConstraint(PositionConstraint(plant, base, p_i, p_i,
  end, 0, context), s_i)`` (``--drake-position constraint``, default), or a ``PositionCost``;
- pointing at 1..n-1 (with a contract: see below): ``AngleBetweenVectorsCost(plant, base,
  d_i, end, axis, c, context)``, c (1 - cos angle) (``--drake-pointing cost``, default), or
  an ``AngleBetweenVectorsConstraint`` within ``--drake-pointing-tolerance``; 6-D goal
  frames: an ``OrientationCost``. The ends are not pointed: they are fixed poses, and the
  paper's start pose points 44-56 deg away from its line. KinematicTrajectoryOptimization
  has path *constraints* at s but no path *cost*, so each cost is bound to auxiliary
  variables q_i with the linear equality q_i = sum_j M_j(s_i) P_j over the active control
  points (``basis().EvaluateLinearInControlPoints``, ``ComputeActiveBasisFunctionIndices``);
- ``AddPositionBounds(lower, upper)`` (on the control points, so by the convex-hull property
  the whole spline stays within the limits), ``AddVelocityBounds(-v, v)`` (the URDF's velocity
  limits unless ``--drake-velocity-limit``), ``AddDurationConstraint(0.1, 20)`` s, and, with
  positive weights, ``AddDurationCost`` and ``AddPathEnergyCost`` (off by default: measured on
  the paper's tasks they trade the pointing next to the fixed start pose for a shorter path
  and cost SNOPT 10-30x the time).

The task's contract (``task.required.contract``; without one, as described above): pointing costs
only on the steps the contract judges, i >= ``contract.judged_from(n)`` (none when the
contract does not ask for pointing), so the arm may turn from the start pose's own pointing
over the first steps instead of in one segment; and the speed limit as linear constraints on
the control points: |r(s_i+1) - r(s_i)| <= 0.99 max_step per joint and segment, with
r(s_i) = sum_j M_j(s_i) P_j (``basis().EvaluateLinearInControlPoints``), max_step the
contract's largest step per segment at n (``contract.max_step(n)``, pose units) in URDF units
(the motor map is affine: |scale| times it, deg to rad, mm to m). ``AddVelocityBounds`` stays:
it bounds the spline's derivative at its free duration, not the steps between the samples.

Initial guess (``--drake-init``): ``ik`` (default) fits the spline to the Drake IK walk
(:mod:`ikbench.baselines.drake.ik`, ``--scheme walk``: it ends away from the start pose,
so the guess jumps in its first segment) by least squares with the ends fixed; ``linear``
interpolates the control points between the two poses. Solved by SNOPT (``Solve``'s choice) with
feasibility 1e-8, optimality 1e-6 and at most 1000 major iterations; the poses are
``ReconstructTrajectory(result)`` sampled at t_i = s_i T. Rows are returned as solved
(row 0 is the start pose and row n the touch pose to the feasibility tolerance).

Obstacles (a task with ``obstacles``; without them nothing here changes): the plant with
collision geometry (:func:`ikbench.baselines.drake.common.drake_scene_chain`: the robot's
capsules, the obstacles, the collision model's self pairs and the robot-obstacle pairs), and
``AddPathPositionConstraint(MinimumDistanceLowerBoundConstraint(plant, clearance,
plant_context, None, influence), s)`` at every inner goal sample s_i (and, with
``--drake-collision-samples`` k > 1, at k - 1 further samples within each segment): the
clearance ``--drake-clearance`` (default 5 mm) between every such pair where the waypoints
are judged; between samples the spline is not checked. The ``ik`` initial guess is the Drake
IK walk with the same constraint (:mod:`ikbench.baselines.drake.ik`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ikbench.baselines.drake import ik as drake_ik
from ikbench.baselines.drake.common import (
    SOLVERS,
    DrakeMethod,
    drake_chain,
    drake_option,
    drake_scene_chain,
    exit_code,
    make_solver,
    min_distance_constraint,
    set_tolerances,
    solve,
)
from ikbench.baselines.drake.ik import STEP_MARGIN
from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.schemes.chain import Chain, Goals, contract_step
from ikbench.schemes.collision import AvoidsObstacles, Scene
from ikbench.schemes.method import ChainResult

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: Velocity limit [rad/s, m/s] for joints whose URDF gives none.
DEFAULT_VELOCITY_LIMIT = 10.0


@dataclass
class DrakeTrajoptSettings:
    """Settings of the Drake trajectory optimisation (see the module docstring)."""

    control_points: int = option(0, flag="drake-control-points",
                                 help="B-spline control points (0: one per goal point)")
    spline_order: int = option(4, flag="drake-spline-order", help="B-spline order (4: cubic)")
    position: str = option("constraint", flag="drake-position", choices=("constraint", "cost"),
                           help="goal points as path constraints or as costs")
    position_weight: float = option(1e4, flag="drake-position-weight", unit="1/m^2",
                                    help="PositionCost weight (--drake-position cost)")
    pointing: str = option("cost", flag="drake-pointing", choices=("cost", "constraint"),
                           help="pointing as AngleBetweenVectorsCost or as a constraint")
    pointing_weight: float = option(1.0, flag="drake-pointing-weight",
                                    help="weight c of c (1 - cos angle) per goal point (and "
                                    "of the OrientationCost for 6-D goals)")
    pointing_tolerance: float = option(1.0, flag="drake-pointing-tolerance", unit="deg",
                                       help="largest angle (--drake-pointing constraint)")
    velocity_limit: float = option(0.0, flag="drake-velocity-limit", unit="rad/s, m/s",
                                   help="joint speed bound (0: the URDF's velocity limits)")
    duration_weight: float = option(0.0, flag="drake-duration-weight", unit="1/s",
                                     help="AddDurationCost weight (0: none)")
    energy_weight: float = option(0.0, flag="drake-energy-weight",
                                  help="AddPathEnergyCost weight (0: none)")
    init: str = option("ik", flag="drake-init", choices=("ik", "linear"),
                       help="initial guess: the Drake IK walk fitted, or linear in joints")
    max_iterations: int = option(1000, flag="drake-max-iterations",
                                 help="SNOPT major iterations limit")
    solver: str = drake_option("solver")
    feasibility_tolerance: float = drake_option("feasibility_tolerance", default=1e-8)
    optimality_tolerance: float = drake_option("optimality_tolerance")
    clearance: float = drake_option(
        "clearance", help="tasks with obstacles: the least distance kept between the robot's "
        "capsules and the obstacles and between self pairs at the samples "
        "(MinimumDistanceLowerBoundConstraint's bound)")
    influence: float = drake_option("influence")
    collision_samples: int = option(1, flag="drake-collision-samples",
                                    help="tasks with obstacles: distance constraints per "
                                    "segment (1: at the goal samples only)")

    def __post_init__(self):
        for name, allowed in (("position", ("constraint", "cost")),
                              ("pointing", ("cost", "constraint")), ("init", ("ik", "linear")),
                              ("solver", SOLVERS)):
            check_choice(self, name, allowed)
        check_positive(self, "spline_order", "max_iterations", "collision_samples",
                       integer=True)
        check_positive(self, "influence")
        if not self.clearance >= 0:
            raise InputError(f"--drake-clearance: {self.clearance!r} must be >= 0 [mm]")
        check_positive(self, "position_weight", "pointing_tolerance", "feasibility_tolerance",
                       "optimality_tolerance")
        for name in ("control_points", "pointing_weight", "velocity_limit", "duration_weight",
                     "energy_weight"):
            if not getattr(self, name) >= 0:
                raise InputError(f"--drake-{name.replace('_', '-')}: {getattr(self, name)!r} "
                                 "must be >= 0")
        self.control_points, self.spline_order = int(self.control_points), int(self.spline_order)
        self.collision_samples = int(self.collision_samples)


def control_point_count(settings: DrakeTrajoptSettings, n_points: int) -> int:
    """The B-spline's control points for ``n_points`` goal points; InputError if fewer than
    the spline order."""
    count = settings.control_points or n_points
    if count < settings.spline_order:
        raise InputError(f"--drake-control-points: {count} control points are fewer than the "
                         f"spline order {settings.spline_order}; give more, or more --steps")
    return count


def _path_point(trajopt, prog, s: float, cache: dict):
    """Variables q_i (nq,) tied to r(s) by a linear equality (created once per s)."""
    if s not in cache:
        basis, points = trajopt.basis(), trajopt.control_points()  # points: (nq, K)
        active = list(basis.ComputeActiveBasisFunctionIndices(s))
        weights = np.asarray(basis.EvaluateLinearInControlPoints(s))[active]
        nq = points.shape[0]
        q_s = prog.NewContinuousVariables(nq, f"r_{s:.6f}")
        A = np.hstack([np.eye(nq)] + [-w * np.eye(nq) for w in weights])
        prog.AddLinearEqualityConstraint(A, np.zeros(nq),
                                         np.concatenate([q_s, *(points[:, j] for j in active)]))
        cache[s] = q_s
    return cache[s]


def _fitted_control_points(basis, s, samples, first, last) -> np.ndarray:
    """Control points (nq, K) whose spline passes nearest ``samples`` (N, nq) at ``s`` (N,)
    in least squares, the first and last fixed to ``first`` / ``last``."""
    A = np.array([basis.EvaluateLinearInControlPoints(float(v)) for v in s])  # (N, K)
    rhs = samples - np.outer(A[:, 0], first) - np.outer(A[:, -1], last)
    inner = np.linalg.lstsq(A[:, 1:-1], rhs, rcond=None)[0]
    return np.vstack([first, inner, last]).T


def _initial_guess(trajopt, chain, goals, drake, settings, s, scene=None):
    """The B-spline guess (see ``--drake-init``) with duration 2 s."""
    from pydrake.math import BsplineBasis
    from pydrake.trajectories import BsplineTrajectory

    basis = trajopt.basis()
    first, last = drake.positions(goals.q_start), drake.positions(goals.q_touch)
    if settings.init == "ik":

        ik_settings = (drake_ik.DrakeIKSettings(solver=settings.solver) if scene is None else
                       drake_ik.DrakeIKSettings(solver=settings.solver,
                                                clearance=settings.clearance,
                                                influence=settings.influence))
        walk = drake_ik.solve_chain(chain, goals, ik_settings, scene=scene)
        samples = np.array([drake.positions(q) for q in walk.q])
        samples[0] = first  # the walk does not end at the start pose; the spline must
        control = _fitted_control_points(basis, s, samples, first, last)
    else:
        w = np.linspace(0.0, 1.0, trajopt.num_control_points())
        control = (np.outer(1 - w, first) + np.outer(w, last)).T
    control = np.clip(control, drake.positions(chain.lower)[:, None],
                      drake.positions(chain.upper)[:, None])
    duration = DEFAULT_DURATION_S
    scaled = BsplineBasis(basis.order(), np.asarray(basis.knots()) * duration)
    return BsplineTrajectory(scaled, [control[:, [j]] for j in range(control.shape[1])]), duration


def solve_chain(chain: Chain, goals: Goals, settings: DrakeTrajoptSettings,
                pointing_from: int | None = 1, max_step: np.ndarray | None = None,
                scene: Scene | None = None) -> ChainResult:
    """The trajectory optimisation in URDF units (see the module docstring).

    Args:
        chain, goals, settings: the chain, the task's goals and the settings.
        pointing_from: the first goal point with a pointing cost (1: every inner point, as
            without a contract; the contract's ``judged_from(n)``), or None: no pointing.
        max_step: (dof,) the largest joint change per segment [rad, m] between the samples
            s_i and s_i+1 (the contract's speed limit), or None: no such bound.
        scene: the robot's capsules and the task's obstacles
            (:class:`ikbench.schemes.collision.Scene`) kept ``settings.clearance`` apart
            at the samples, or None (no obstacles: the program as without them).
    """
    from pydrake.math import RotationMatrix
    from pydrake.multibody.inverse_kinematics import (
        AngleBetweenVectorsConstraint,
        AngleBetweenVectorsCost,
        OrientationCost,
        PositionConstraint,
        PositionCost,
    )
    from pydrake.planning import KinematicTrajectoryOptimization

    drake = drake_chain(chain) if scene is None else drake_scene_chain(chain, scene)
    plant, context = drake.plant, drake.plant.CreateDefaultContext()
    n_points, nq = len(goals), plant.num_positions()
    count = control_point_count(settings, n_points)
    s = np.linspace(0.0, 1.0, n_points)
    trajopt = KinematicTrajectoryOptimization(nq, count, settings.spline_order, 1.0)
    prog = trajopt.get_mutable_prog()
    assert goals.q_start is not None and goals.q_touch is not None  # pinned (check_tasks)
    for pose, at in ((goals.q_start, 0.0), (goals.q_touch, 1.0)):
        trajopt.AddPathPositionConstraint(drake.positions(pose), drake.positions(pose), at)
    trajopt.AddPositionBounds(drake.positions(chain.lower), drake.positions(chain.upper))
    speed = (plant.GetVelocityUpperLimits() if not settings.velocity_limit
             else np.full(nq, settings.velocity_limit))
    speed = np.where(np.isfinite(speed), speed, DEFAULT_VELOCITY_LIMIT)
    trajopt.AddVelocityBounds(-speed, speed)
    trajopt.AddDurationConstraint(0.1, 20.0)
    if settings.duration_weight > 0:
        trajopt.AddDurationCost(settings.duration_weight)
    if settings.energy_weight > 0:
        trajopt.AddPathEnergyCost(settings.energy_weight)
    if max_step is not None:
        basis = trajopt.basis()
        W = np.array([basis.EvaluateLinearInControlPoints(float(v)) for v in s])  # (N, K)
        D = W[1:] - W[:-1]  # r(s_i+1) - r(s_i) = P D_i^T
        bound = drake.positions(max_step)
        points = trajopt.control_points()  # (nq, K)
        for j in range(nq):
            prog.AddLinearConstraint(D, np.full(len(D), -bound[j]), np.full(len(D), bound[j]),
                                     points[j])
    base, end, axis = drake.base_frame, drake.end_frame, chain.pointing_axis
    path: dict = {}
    for i in range(1, n_points - 1):
        p = goals.points_m[i]
        if settings.position == "constraint":
            trajopt.AddPathPositionConstraint(
                PositionConstraint(plant, base, p, p, end, np.zeros(3), context), s[i])
        else:
            prog.AddCost(PositionCost(plant, base, p, end, np.zeros(3),
                                      settings.position_weight * np.eye(3), context),
                         _path_point(trajopt, prog, s[i], path))
        if goals.rotations is None and (pointing_from is None or i < pointing_from):
            continue
        if goals.rotations is not None:
            prog.AddCost(OrientationCost(plant, base, RotationMatrix(goals.rotations[i]), end,
                                         RotationMatrix(), settings.pointing_weight, context),
                         _path_point(trajopt, prog, s[i], path))
        elif settings.pointing == "cost":
            prog.AddCost(AngleBetweenVectorsCost(plant, base, goals.directions[i], end, axis,
                                                 settings.pointing_weight, context),
                         _path_point(trajopt, prog, s[i], path))
        else:
            trajopt.AddPathPositionConstraint(AngleBetweenVectorsConstraint(
                plant, base, goals.directions[i], end, axis, 0.0,
                np.radians(settings.pointing_tolerance), context), s[i])
    if scene is not None:
        distance = min_distance_constraint(drake, settings.clearance / 1000.0,
                                           settings.influence / 1000.0)
        k = settings.collision_samples
        for at in np.linspace(0.0, 1.0, k * (n_points - 1) + 1)[1:-1]:  # the ends are fixed
            trajopt.AddPathPositionConstraint(distance, float(at))
    guess, duration = _initial_guess(trajopt, chain, goals, drake, settings, s, scene)
    trajopt.SetInitialGuess(guess)
    for at, q_s in path.items():
        prog.SetInitialGuess(q_s, guess.value(at * duration).reshape(-1))
    set_tolerances(prog, settings.feasibility_tolerance, settings.optimality_tolerance,
                   settings.max_iterations)
    result = solve(prog, make_solver(settings.solver))
    trajectory = trajopt.ReconstructTrajectory(result)
    t0, length = trajectory.start_time(), trajectory.end_time() - trajectory.start_time()
    q = np.array([trajectory.value(t0 + v * length).reshape(-1) for v in s])[:, drake.index]
    inside = chain.clip(q)
    return ChainResult(inside, 1, bool(result.is_success()), {
        "solver": result.get_solver_id().name(), "exit_code": exit_code(result),
        "solution_result": str(result.get_solution_result()).split(".")[-1],
        "path_duration_s": float(length), "control_points": count,
        "pointing_from": -1 if pointing_from is None else int(pointing_from),
        "speed_bounded": max_step is not None,
        "clipped_rows": int(np.sum(np.any(inside != q, axis=1))),
        "iterations_are": "program solves (Drake reports no SNOPT iteration count)"})


class DrakeTrajopt(AvoidsObstacles, DrakeMethod):
    """Drake KinematicTrajectoryOptimization of the whole path between start and touch pose."""

    name = "drake-trajopt"
    description = ("library: Drake KinematicTrajectoryOptimization of the whole path (B-spline "
                   "with fixed start and touch poses, goal points as path constraints, "
                   "pointing costs where the contract judges them, velocity bounds, the "
                   "contract's joint steps as linear constraints; SNOPT; with obstacles, "
                   "MinimumDistanceLowerBoundConstraint at the samples)")
    library = "drake"
    Settings = DrakeTrajoptSettings
    whole_path = True

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        """Also: enough control points for the spline order (:func:`control_point_count`)."""
        super().check_tasks(robot, tasks)
        for task in tasks:
            control_point_count(self.settings, len(task.goal.points_mm))

    def solve_scene(self, robot: Robot, chain: Chain, goals: Goals,
                    scene: Scene | None) -> ChainResult:
        contract = goals.contract
        if contract is None:  # no contract: as before it, every inner point pointed
            return solve_chain(chain, goals, self.settings, scene=scene)
        steps = len(goals) - 1
        pointing_from = contract.judged_from(steps) if contract.pointing else None
        return solve_chain(chain, goals, self.settings, pointing_from,
                           contract_step(goals, STEP_MARGIN), scene)
