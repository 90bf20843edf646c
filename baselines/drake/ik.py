"""Drake ``InverseKinematics`` (PyPI ``drake``): one nonlinear program per goal point, from the
start pose onto the touch pose (``--scheme track``, default) or walked back from the touch
pose (``--scheme walk``, the authors' scheme).

Walk (and any pose path): per goal point i, warm start q_w (the previous solution), on the
plant of :mod:`ikbench.baselines.drake.common`::

    ik = InverseKinematics(plant, with_joint_limits=False)       # the chain's limits below
    ik.AddPositionConstraint(end_frame, [0, 0, 0], base_frame, p_i - tol, p_i + tol)
    ik.AddAngleBetweenVectorsConstraint(base_frame, d_i, end_frame, axis, 0, pointing_tol)
    prog.AddBoundingBoxConstraint(lower, upper, q)               # joint limits
    prog.AddQuadraticErrorCost(w I, q_w, q)                      # stay near the warm start
    prog.SetInitialGuess(q, q_w); result = Solve(prog)           # SNOPT by default

(pydrake.multibody.inverse_kinematics.InverseKinematics; 6-D goal frames replace the angle
constraint by ``AddOrientationConstraint``.) Defaults: position tolerance 0 mm (an equality),
pointing tolerance 0.01 deg (an upper bound of exactly 0 would be the degenerate constraint
cos >= 1, whose gradient vanishes at the solution), warm-start weight 1 /rad^2, SNOPT
feasibility 1e-9 (its default 1e-6 would be 1 um on the position box) and optimality 1e-6.
The warm-start cost pulls the pointing to the edge of its 0.01 deg cone. ``iterations`` counts
solves (Drake reports no SNOPT iteration count); a point whose result is not a success counts
as not converged.

Track (:mod:`ikbench.schemes.track`): steps 1..n-1 forward from the start pose (row 0),
each warm-started at the step before; row n is the touch pose. Per step i the same program with
the plan's goals: the position constraint at ``plan.points_m[i]``; the pointing constraint on
the scheduled direction ``plan.directions[i]`` (none when the contract does not ask for
pointing); the costs measured in the robot's pose units (weights (pose units per URDF unit)^2,
:func:`pose_metric`: NICO's wrist_x and finger motors turn 4.5 motor deg per joint deg, so a
joint-deg cost would spend their speed first): ``w_warm |q - q_w|^2 + w_posture |q -
posture_i|^2`` (the start-to-touch posture, ``--drake-posture-weight``, default 10, so the
arm keeps near it and lands); and, when the task's contract knows the joint speed limits, the
box of the limits narrowed to what the speed allows: |q - q_w| <= 0.99 max_step (the
contract's step in URDF units: the motor map is affine) and |q - q_touch| <= (n - i) 0.99
max_step (the touch pose stays reachable in the steps left). Where that program is infeasible
(SNOPT reports no success: the pointing cannot follow within the speed), the step is solved
again with the pointing as ``AddAngleBetweenVectorsCost`` c (1 - cos angle)
(``--drake-pointing-cost``, default 3000); ``pointing_relaxed_points`` counts those steps. A
step is solved when Drake reports success and FK puts the end point within 1e-3 mm of its box.

Obstacles (a task with ``obstacles``; without them nothing here changes): the plant is the one with
collision geometry (:func:`ikbench.baselines.drake.common.drake_scene_chain`: the robot's
capsules, the obstacles, only the collision model's self pairs and the robot-obstacle pairs
unfiltered), ``InverseKinematics(plant, plant_context, with_joint_limits=False)`` on its diagram's
plant context, and every program gains ``ik.AddMinimumDistanceLowerBoundConstraint(clearance,
influence)``: every such pair at least ``--drake-clearance`` (default 5 mm) apart, pairs within
clearance + ``--drake-influence`` (default 1 mm: larger values let more pairs into the constraint
and made SNOPT stall more often on the CppFlow panda problems) evaluated. Drake's signed distances
come from its own queries (FCL), its gradients from the witness points' Jacobians. A program that
fails (SNOPT stalls where the warm start overlaps an obstacle: the home pose a pose path's walk
starts from may) is solved again from the pose the same program without the distance constraint
reaches (``collision_retried_points``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ikbench.baselines.drake.common import (
    SOLVERS,
    DrakeMethod,
    drake_chain,
    drake_option,
    drake_scene_chain,
    make_solver,
    set_tolerances,
    solve,
)
from ikbench.core.errors import InputError
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.schemes.chain import Chain, Goals, contract_step, urdf_step
from ikbench.schemes.collision import AvoidsObstacles, Scene
from ikbench.schemes.method import ChainResult
from ikbench.schemes.single_pose import PoseOut, PoseSolver
from ikbench.schemes.track import SCHEME_HELP, SCHEMES, speed_box, track
from ikbench.schemes.walk import PointResult, walk_back

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: A tracked step counts as solved when FK puts the end point within this [m] of its box.
POSITION_CHECK_M = 1e-6
#: The fraction of the contract's joint step a tracked step may take (round-off room).
STEP_MARGIN = 0.99


@dataclass
class DrakeIKSettings:
    """Settings of Drake IK (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    position_tolerance: float = option(0.0, flag="drake-position-tolerance", unit="mm",
                                       help="half-width of the goal point's box (0: equality)")
    pointing_tolerance: float = option(0.01, flag="drake-pointing-tolerance", unit="deg",
                                       help="largest angle between pointing axis and goal "
                                       "direction (or from the goal rotation, 6-D goals)")
    warm_weight: float = option(1.0, flag="drake-warm-weight", unit="1/rad^2",
                                help="weight of the cost |q - q_warm|^2")
    posture_weight: float = option(10.0, flag="drake-posture-weight", unit="1/rad^2",
                                   help="scheme track: weight of the cost |q - posture_i|^2 "
                                   "(the start-to-touch posture; in the robot's pose units)")
    pointing_cost: float = option(3000.0, flag="drake-pointing-cost",
                                  help="scheme track: weight c of c (1 - cos angle) for a "
                                  "step whose pointing constraint is infeasible")
    solver: str = drake_option("solver")
    feasibility_tolerance: float = drake_option("feasibility_tolerance")
    optimality_tolerance: float = drake_option("optimality_tolerance")
    clearance: float = drake_option("clearance")
    influence: float = drake_option("influence")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_choice(self, "solver", SOLVERS)
        check_positive(self, "pointing_tolerance", "pointing_cost", "feasibility_tolerance",
                       "optimality_tolerance", "influence")
        if not self.clearance >= 0:
            raise InputError(f"--drake-clearance: {self.clearance!r} must be >= 0 [mm]")
        if not (self.position_tolerance >= 0 and self.warm_weight >= 0
                and self.posture_weight >= 0):
            raise InputError("--drake-position-tolerance, --drake-warm-weight and "
                             "--drake-posture-weight must be >= 0")


def solve_chain(chain: Chain, goals: Goals, settings: DrakeIKSettings,
                metric: np.ndarray | None = None,
                max_step: np.ndarray | None = None, scene: Scene | None = None) -> ChainResult:
    """Drake IK in URDF units: the tracking scheme when ``goals.track`` is set, else the walk
    (see the module docstring).

    Args:
        chain, goals, settings: the chain, the task's goals (``goals.track``: the plan), the
            settings.
        metric: (dof,) weights of the track's costs (:func:`pose_metric`); None: all 1.
        max_step: (dof,) the largest joint step per segment [rad, m] the track may take, or
            None (no speed limit known; the walk ignores it).
        scene: the robot's capsules and the task's obstacles
            (:class:`ikbench.schemes.collision.Scene`) to keep ``settings.clearance``
            apart, or None (no obstacles: the programs as without them).
    """
    from pydrake.math import RotationMatrix
    from pydrake.multibody.inverse_kinematics import InverseKinematics

    drake = drake_chain(chain) if scene is None else drake_scene_chain(chain, scene)
    solver = make_solver(settings.solver)
    box = np.full(3, settings.position_tolerance / 1000.0)
    angle = np.radians(settings.pointing_tolerance)
    lower, upper = drake.positions(chain.lower), drake.positions(chain.upper)
    plan = goals.track
    tracking = plan is not None
    weights = np.diag(drake.positions(np.ones(chain.dof) if metric is None or not tracking
                                      else metric))
    step = None if max_step is None or not tracking else drake.positions(max_step)
    context = drake.plant.CreateDefaultContext()
    used, relaxed, retried = set(), [], []

    def program(q_warm, point, direction, rotation, bounds, pointing_cost, collide=True):
        """One goal's program: position, pointing (a constraint, or a cost when
        ``pointing_cost``) or frame, limits (``bounds``), the warm-start cost; with a scene
        and ``collide``, the minimum-distance constraint."""
        if scene is None or not collide:
            ik = InverseKinematics(drake.plant, with_joint_limits=False)
        else:
            ik = InverseKinematics(drake.plant, drake.context, with_joint_limits=False)
            ik.AddMinimumDistanceLowerBoundConstraint(settings.clearance / 1000.0,
                                                      settings.influence / 1000.0)
        q, prog = ik.q(), ik.get_mutable_prog()
        ik.AddPositionConstraint(drake.end_frame, np.zeros(3), drake.base_frame,
                                 point - box, point + box)
        if rotation is not None:
            ik.AddOrientationConstraint(drake.base_frame, RotationMatrix(rotation),
                                        drake.end_frame, RotationMatrix(), angle)
        elif direction is not None and pointing_cost:
            ik.AddAngleBetweenVectorsCost(drake.base_frame, direction, drake.end_frame,
                                          chain.pointing_axis, settings.pointing_cost)
        elif direction is not None:
            ik.AddAngleBetweenVectorsConstraint(drake.base_frame, direction, drake.end_frame,
                                                chain.pointing_axis, 0.0, angle)
        prog.AddBoundingBoxConstraint(*bounds, q)
        warm = drake.positions(q_warm)
        prog.AddQuadraticErrorCost(settings.warm_weight * weights, warm, q)
        set_tolerances(prog, settings.feasibility_tolerance, settings.optimality_tolerance)
        return q, prog, warm

    def solve_avoiding(i: int, build):
        """(result, q, solves): ``build(collide) -> (q, prog, warm)`` solved from its warm
        start; with a scene, a failed solve is tried again from the pose the same program
        without the distance constraint reaches (a warm start inside an obstacle stalls
        SNOPT: the distances' gradients there do not lead out)."""
        q, prog, warm = build(True)
        result = solve(prog, solver, warm)
        used.add(result.get_solver_id().name())
        if scene is None or result.is_success():
            return result, q, 1
        retried.append(i)
        q_free, prog_free, _ = build(False)
        free = solve(prog_free, solver, warm)
        if not free.is_success():
            return result, q, 2
        q_again, prog_again, _ = build(True)
        again = solve(prog_again, solver, free.GetSolution(q_free))
        return (again, q_again, 3) if again.is_success() else (result, q, 3)

    def walk_point(i: int, q_warm: np.ndarray) -> PointResult:
        rotation = None if goals.rotations is None else goals.rotations[i]
        result, q, solves = solve_avoiding(i, lambda collide: program(
            q_warm, goals.points_m[i], goals.directions[i], rotation, (lower, upper), False,
            collide))
        return PointResult(result.GetSolution(q)[drake.index], solves,
                           bool(result.is_success()))

    def track_point(i: int, q_warm: np.ndarray) -> PointResult:
        direction = None if plan.directions is None else plan.directions[i]
        bounds = (lower, upper)
        if step is not None:  # within the speed limit, and the touch pose still reachable
            low, high = speed_box(drake.positions(q_warm), drake.positions(plan.q_touch),
                                  len(plan) - 1 - i, step, lower, upper)
            bounds = (low, np.maximum(high, low))
        solves = 0
        for pointing_cost in ((False, True) if direction is not None else (False,)):
            def build(collide, pointing_cost=pointing_cost):
                q, prog, warm = program(q_warm, plan.points_m[i], direction, None, bounds,
                                        pointing_cost, collide)
                if settings.posture_weight > 0:
                    prog.AddQuadraticErrorCost(settings.posture_weight * weights,
                                               drake.positions(plan.posture[i]), q)
                return q, prog, warm

            result, q, count = solve_avoiding(i, build)
            solves += count
            if result.is_success():
                break
        if pointing_cost:
            relaxed.append(i)
        solution = result.GetSolution(q)
        drake.plant.SetPositions(context, solution)
        reached = drake.plant.CalcRelativeTransform(context, drake.base_frame,
                                                    drake.end_frame).translation()
        off = float(np.max(np.abs(reached - plan.points_m[i]) - box, initial=0.0))
        ok = bool(result.is_success()) and off <= POSITION_CHECK_M
        return PointResult(solution[drake.index], solves, ok)

    if not tracking:
        walk = walk_back(walk_point, chain, goals)
        return ChainResult.from_walk(walk, solver=",".join(sorted(used)), scheme="walk",
                                     iterations_are="solves (Drake reports no iteration count)",
                                     **({} if scene is None else
                                        {"collision_retried_points": len(set(retried))}))
    walk = track(track_point, chain, plan)
    return ChainResult.from_walk(walk, solver=",".join(sorted(used)), scheme="track",
                                 pointing_relaxed_points=len(relaxed),
                                 speed_bounded=step is not None,
                                 iterations_are="solves (Drake reports no iteration count)",
                                 **({} if scene is None else
                                    {"collision_retried_points": len(set(retried))}))


def pose_metric(robot: Robot) -> np.ndarray:
    """(dof,) weights that measure a joint change in the robot's pose units: (pose units per
    URDF unit)^2, normalised to 1 for a joint whose pose unit is its URDF unit (deg per rad,
    mm per m). NICO: 1 / scale^2 (its wrist and finger motors turn 4.5 motor deg per joint
    deg)."""
    per_unit = urdf_step(robot, np.ones(robot.dof))
    nominal = np.where(np.asarray(robot.prismatic), 1e-3, np.radians(1.0))
    return (nominal / per_unit) ** 2


class DrakeIK(AvoidsObstacles, DrakeMethod):
    """Drake InverseKinematics per point, tracked from the start pose onto the touch pose
    (``--scheme track``) or walked back from the touch pose (``--scheme walk``)."""

    name = "drake-ik"
    description = ("library: Drake InverseKinematics per point (position constraint, "
                   "angle-between-vectors constraint on the pointing axis; SNOPT), tracked "
                   "from the start pose onto the touch pose within the speed limits (--scheme "
                   "walk: walked back from the touch pose); with obstacles, "
                   "MinimumDistanceLowerBoundConstraint on the robot's capsules")
    library = "drake"
    Settings = DrakeIKSettings

    def solve_scene(self, robot: Robot, chain: Chain, goals: Goals,
                    scene: Scene | None) -> ChainResult:
        step = None
        if goals.track is not None:
            step = contract_step(goals, STEP_MARGIN)
        return solve_chain(chain, goals, self.settings, pose_metric(robot), step, scene)


#: Single-pose IK: the orientation constraint's bound [rad] (0 would be degenerate) and
#: SNOPT's feasibility tolerance.
POSE_ANGLE_RAD, POSE_FEASIBILITY = 1e-6, 1e-9


class DrakeSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`):
    ``InverseKinematics`` with position and orientation constraints (position only for
    points), the limits as a bounding box, a quadratic cost to the initial pose; SNOPT."""

    rank = 80
    name, library, modules = "drake-ik", "drake", ("pydrake",)
    iterations_are = "solves (Drake reports no iteration count)"
    attempt_bound = "SNOPT's own limits (feasibility 1e-9)"

    def prepare(self) -> None:
        self.drake = drake_chain(self.chain)
        self.lower = self.drake.positions(self.chain.lower)
        self.upper = self.drake.positions(self.chain.upper)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        from pydrake.math import RotationMatrix
        from pydrake.multibody.inverse_kinematics import InverseKinematics

        d = self.drake
        ik = InverseKinematics(d.plant, with_joint_limits=False)
        q, prog = ik.q(), ik.get_mutable_prog()
        point = np.asarray(point_m, dtype=float)
        ik.AddPositionConstraint(d.end_frame, np.zeros(3), d.base_frame, point, point)
        if self.kind == "pose":
            ik.AddOrientationConstraint(d.base_frame, RotationMatrix(rotation), d.end_frame,
                                        RotationMatrix(), POSE_ANGLE_RAD)
        prog.AddBoundingBoxConstraint(self.lower, self.upper, q)
        warm = np.clip(d.positions(q_init), self.lower, self.upper)
        prog.AddQuadraticErrorCost(np.eye(len(warm)), warm, q)
        set_tolerances(prog, POSE_FEASIBILITY, 1e-6)
        result = solve(prog, None, warm)
        return PoseOut(result.GetSolution(q)[d.index], 1, bool(result.is_success()))
