"""Drake ``InverseKinematics`` (PyPI ``drake``): one nonlinear program per goal point, walked
back from the touch pose.

Per goal point i, warm start q_w (the previous solution), on the plant of
:mod:`baselines._drake`::

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baselines._chain import Chain, Goals
from baselines._drake import SOLVERS, DrakeMethod, drake_chain, make_solver, set_tolerances, solve
from baselines._method import ChainResult
from baselines._walk import PointResult, walk_back
from ikbench.core.errors import InputError
from ikbench.methods.base import check_choice, check_positive, option


@dataclass
class DrakeIKSettings:
    """Settings of the Drake IK walk (see the module docstring)."""

    position_tolerance: float = option(0.0, flag="drake-position-tolerance", unit="mm",
                                       help="half-width of the goal point's box (0: equality)")
    pointing_tolerance: float = option(0.01, flag="drake-pointing-tolerance", unit="deg",
                                       help="largest angle between pointing axis and goal "
                                       "direction (or from the goal rotation, 6-D goals)")
    warm_weight: float = option(1.0, flag="drake-warm-weight", unit="1/rad^2",
                                help="weight of the cost |q - q_warm|^2")
    solver: str = option("auto", flag="drake-solver", choices=SOLVERS,
                         help="auto (Drake's choice: SNOPT) or a solver by name")
    feasibility_tolerance: float = option(1e-9, flag="drake-feasibility-tolerance",
                                          help="SNOPT major feasibility / IPOPT constr_viol_tol")
    optimality_tolerance: float = option(1e-6, flag="drake-optimality-tolerance",
                                         help="SNOPT major optimality / IPOPT tol / NLopt "
                                         "xtol_rel")

    def __post_init__(self):
        check_choice(self, "solver", SOLVERS)
        check_positive(self, "pointing_tolerance", "feasibility_tolerance",
                       "optimality_tolerance")
        if not (self.position_tolerance >= 0 and self.warm_weight >= 0):
            raise InputError("--drake-position-tolerance and --drake-warm-weight must be >= 0")


def solve_chain(chain: Chain, goals: Goals, settings: DrakeIKSettings) -> ChainResult:
    """The Drake IK walk in URDF units (see the module docstring)."""
    from pydrake.math import RotationMatrix
    from pydrake.multibody.inverse_kinematics import InverseKinematics

    drake = drake_chain(chain)
    solver = make_solver(settings.solver)
    box = np.full(3, settings.position_tolerance / 1000.0)
    angle = np.radians(settings.pointing_tolerance)
    used = set()

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        ik = InverseKinematics(drake.plant, with_joint_limits=False)
        q, prog = ik.q(), ik.get_mutable_prog()
        ik.AddPositionConstraint(drake.end_frame, np.zeros(3), drake.base_frame,
                                 goals.points_m[i] - box, goals.points_m[i] + box)
        if goals.rotations is not None:
            ik.AddOrientationConstraint(drake.base_frame, RotationMatrix(goals.rotations[i]),
                                        drake.end_frame, RotationMatrix(), angle)
        else:
            ik.AddAngleBetweenVectorsConstraint(drake.base_frame, goals.directions[i],
                                                drake.end_frame, chain.pointing_axis, 0.0,
                                                angle)
        prog.AddBoundingBoxConstraint(drake.positions(chain.lower), drake.positions(chain.upper),
                                      q)
        warm = drake.positions(q_warm)
        prog.AddQuadraticErrorCost(settings.warm_weight * np.eye(len(warm)), warm, q)
        set_tolerances(prog, settings.feasibility_tolerance, settings.optimality_tolerance)
        result = solve(prog, solver, warm)
        used.add(result.get_solver_id().name())
        return PointResult(result.GetSolution(q)[drake.index], 1, bool(result.is_success()))

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, solver=",".join(sorted(used)),
                                 iterations_are="solves (Drake reports no iteration count)")


class DrakeIK(DrakeMethod):
    """Drake InverseKinematics per point, walked back from the touch pose."""

    name = "drake-ik"
    description = ("library: Drake InverseKinematics per point (position constraint, "
                   "angle-between-vectors constraint on the pointing axis; SNOPT), walked "
                   "back from the touch pose")
    library = "drake"
    Settings = DrakeIKSettings
    supports_frames = True

    def solve_chain(self, robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)
