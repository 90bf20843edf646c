"""Single-pose IK through each library (``ikbench ik``): one goal pose from one initial pose.

Every solver here takes one target in URDF units in the chain's base frame (a point [m] and
a rotation (3, 3) of the end frame; ``kind="position"``: the point only) and an initial pose
(dof,) [rad, m], and returns the library's answer (:class:`PoseOut`). The study
(:mod:`ikbench.studies.ik`) times each call itself, the same way for every library, and
judges every answer by FK through Pinocchio; ``ok`` is only what the library claimed.
Set-up (parsing the URDF, building the library's model, compiling) happens in
:meth:`PoseSolver.prepare`, untimed. The models come from the path-tracking adapters
(``pink_model``, ``mink_model``, ``ikpy_chain``, ``tracik_solver``, ``drake_chain``,
``pyroki_robot``, sequential-ik's ``Residual`` / ``solve_point``), whose behaviour is unchanged.

Each library is called as its documentation shows for one IK, with a stopping tolerance far
below the study's (so the study's tolerance decides success) and no restarts unless the
library makes them itself (TRAC-IK races KDL with random restarts against an SQP within its
timeout; ours-lm restarts from seeded random poses, :mod:`ikbench.methods.ours_lm.single_pose`).
"""

from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt

from ikbench.baselines._common.pose_solver import (
    LIBRARY_TOLERANCE,
    MAX_STEPS,
    PoseOut,
    PoseSolver,
    converge,
)
from ikbench.baselines.libraries.placo_ik import PlacoSolver

__all__ = ["LIBRARY_TOLERANCE", "MAX_STEPS", "PoseOut", "PoseSolver", "SOLVERS",
           "available_solvers"]

#: TRAC-IK's defaults (trac_ik_lib: timeout 5 ms, eps 1e-5, SolveType Speed).
TRACIK_TIMEOUT_S, TRACIK_EPS, TRACIK_SOLVE_TYPE = 0.005, 1e-5, "Speed"
#: Drake: the orientation constraint's bound [rad] (0 would be degenerate) and SNOPT's
#: feasibility tolerance.
DRAKE_ANGLE_RAD, DRAKE_FEASIBILITY = 1e-6, 1e-9


class DLSSolver(PoseSolver):
    """sequential-ik's damped least squares on Pinocchio (``Residual``, ``solve_point``)."""

    name, library, modules = "sequential-ik", "pin", ("pinocchio",)
    iterations_are = "DLS steps"

    def prepare(self) -> None:
        from ikbench.baselines.sequential_ik import DLSSettings

        self.fk = self.robot.pinocchio_fk()
        self.data = self.fk.model.createData()
        self.settings = DLSSettings(tolerance=LIBRARY_TOLERANCE, max_ik_iterations=MAX_STEPS)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        from ikbench.baselines.sequential_ik import Residual, solve_point

        mode = "frame" if self.kind == "pose" else "position"
        residual = Residual(self.fk, self.data, mode, point_m, rotation)
        out = solve_point(residual, q_init, self.settings, self.chain.lower, self.chain.upper)
        return PoseOut(out.q_rad, out.iterations, out.converged)


def _angle(a, b) -> float:
    from ikbench.baselines._common.geometry import rotation_angle_rad

    return rotation_angle_rad(a, b)


class PinkSolver(PoseSolver):
    """pink: FrameTask on the end frame, ConfigurationLimit, daqp; dt 1 s (full steps)."""

    name, library, modules = "pink", "pin-pink", ("pink", "qpsolvers", "daqp")
    iterations_are = "QP solves (pink.solve_ik calls)"

    def prepare(self) -> None:
        from ikbench.baselines.libraries.pink_ik import pink_model

        self.model, self.R_EP = pink_model(self.robot, self.chain)
        self.data = self.model.createData()

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import pink
        import pinocchio as pin
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask

        from ikbench.baselines.libraries.pink_ik import POINTING_FRAME

        pose = self.kind == "pose"
        task = FrameTask(POINTING_FRAME, position_cost=1.0, orientation_cost=1.0 if pose
                         else 0.0)
        goal_R = rotation @ self.R_EP
        task.set_target(pin.SE3(goal_R, np.asarray(point_m, dtype=float)))
        limits = [ConfigurationLimit(self.model, config_limit_gain=0.5)]
        lower, upper = self.model.lowerPositionLimit, self.model.upperPositionLimit
        configuration = pink.Configuration(self.model, self.data, np.clip(q_init, lower, upper))

        def measure():
            T = configuration.get_transform_frame_to_world(POINTING_FRAME)
            return (float(np.linalg.norm(T.translation - point_m)),
                    _angle(T.rotation, goal_R) if pose else 0.0)

        def step():
            v = pink.solve_ik(configuration, [task], 1.0, solver="daqp", damping=1e-6,
                              limits=limits)
            configuration.update(np.clip(configuration.integrate(v, 1.0), lower, upper))

        steps, ok = converge(measure, step)
        return PoseOut(configuration.q.copy(), steps, ok)


class MinkSolver(PoseSolver):
    """mink: FrameTask on the end site, ConfigurationLimit, daqp; dt 1 s (full steps)."""

    name, library, modules = "mink", "mink", ("mink", "mujoco", "qpsolvers", "daqp")
    iterations_are = "QP solves (mink.solve_ik calls)"

    def prepare(self) -> None:
        from ikbench.baselines.libraries.mink_ik import mink_model

        self.m = mink_model(self.chain)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import mink

        from ikbench.baselines.libraries.mink_ik import SITE

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

        def measure():
            data = configuration.data
            R = data.site_xmat[site].reshape(3, 3)
            return (float(np.linalg.norm(data.site_xpos[site] - goal_p)),
                    _angle(R, goal_R) if pose else 0.0)

        def step():
            v = mink.solve_ik(configuration, [task], 1.0, "daqp", damping=1e-6, limits=limits)
            q = configuration.integrate(v, 1.0)
            q[m.qpos] = self.chain.clip(q[m.qpos])
            configuration.update(q)

        steps, ok = converge(measure, step)
        return PoseOut(configuration.q[m.qpos].copy(), steps, ok)


class IkpySolver(PoseSolver):
    """ikpy: ``Chain.inverse_kinematics_frame`` (scipy least squares within the bounds),
    ``orientation_mode="all"`` for poses, None (position only) for points."""

    name, library, modules = "ikpy", "ikpy", ("ikpy",)
    iterations_are = "ikpy calls (ikpy reports no iteration count)"
    #: A start on a bound is moved this far inside (scipy's trf wants strictly feasible).
    INSIDE = 1e-3

    def prepare(self) -> None:
        from ikbench.baselines.libraries.ikpy_ik import ikpy_chain

        self.ik_chain, self.active = ikpy_chain(self.chain)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = rotation, point_m
        start = np.zeros(len(self.ik_chain.links))
        start[self.active] = np.clip(q_init, self.chain.lower + self.INSIDE,
                                     self.chain.upper - self.INSIDE)
        kwargs = {"orientation_mode": "all"} if self.kind == "pose" else {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = np.asarray(self.ik_chain.inverse_kinematics_frame(
                target=frame, initial_position=start, **kwargs), dtype=float)
        return PoseOut(full[self.active], 1, None)


class TracIKSolver(PoseSolver):
    """TRAC-IK (pytracik): ``ik(solver, seed, x, y, z, qx, qy, qz, qw)`` with TRAC-IK's
    defaults (5 ms timeout, eps 1e-5, Speed). Poses only: the binding cannot free the
    rotation (no tolerance twist)."""

    name, library, modules = "trac-ik", "pytracik", ("pytracik",)
    kinds = ("pose",)
    deterministic = False
    iterations_are = "pytracik.ik calls (TRAC-IK reports no iteration count)"

    def prepare(self) -> None:
        from ikbench.baselines.libraries.trac_ik import TracIKSettings, tracik_solver

        self.solver = tracik_solver(self.chain, TracIKSettings(
            timeout=TRACIK_TIMEOUT_S, eps=TRACIK_EPS, solve_type=TRACIK_SOLVE_TYPE))

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import pytracik

        from ikbench.baselines._common.geometry import quaternion_xyzw

        x, y, z = (float(v) for v in point_m)
        out = pytracik.ik(self.solver, np.ascontiguousarray(q_init, dtype=float), x, y, z,
                          *quaternion_xyzw(rotation))
        ok = out[0] >= 0
        return PoseOut(np.asarray(out[1:], dtype=float) if ok else np.asarray(q_init), 1, ok)


class DrakeSolver(PoseSolver):
    """Drake ``InverseKinematics``: position and orientation constraints (position only for
    points), the limits as a bounding box, a quadratic cost to the initial pose; SNOPT."""

    name, library, modules = "drake-ik", "drake", ("pydrake",)
    iterations_are = "solves (Drake reports no iteration count)"

    def prepare(self) -> None:
        from ikbench.baselines._common.drake import drake_chain

        self.drake = drake_chain(self.chain)
        self.lower = self.drake.positions(self.chain.lower)
        self.upper = self.drake.positions(self.chain.upper)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        from pydrake.math import RotationMatrix
        from pydrake.multibody.inverse_kinematics import InverseKinematics

        from ikbench.baselines._common.drake import set_tolerances, solve

        d = self.drake
        ik = InverseKinematics(d.plant, with_joint_limits=False)
        q, prog = ik.q(), ik.get_mutable_prog()
        point = np.asarray(point_m, dtype=float)
        ik.AddPositionConstraint(d.end_frame, np.zeros(3), d.base_frame, point, point)
        if self.kind == "pose":
            ik.AddOrientationConstraint(d.base_frame, RotationMatrix(rotation), d.end_frame,
                                        RotationMatrix(), DRAKE_ANGLE_RAD)
        prog.AddBoundingBoxConstraint(self.lower, self.upper, q)
        warm = np.clip(d.positions(q_init), self.lower, self.upper)
        prog.AddQuadraticErrorCost(np.eye(len(warm)), warm, q)
        set_tolerances(prog, DRAKE_FEASIBILITY, 1e-6)
        result = solve(prog, None, warm)
        return PoseOut(result.GetSolution(q)[d.index], 1, bool(result.is_success()))


class PyrokiSolver(PoseSolver):
    """PyRoki: ``pyroki.costs.pose_cost_analytic_jac`` (orientation weight 0 for points) and
    the limits as jaxls inequality constraints, one jitted jaxls least-squares solve per
    target (compiled in ``prepare``)."""

    name, library, modules = "pyroki", "almond-pyroki", ("pyroki", "jaxls", "jax")
    iterations_are = "jaxls Levenberg-Marquardt steps"

    def prepare(self) -> None:
        import jax.numpy as jnp
        import jaxlie

        from ikbench.baselines.libraries.pyroki_trajopt import UNBOUNDED, _setup_jax, pyroki_robot

        jax = _setup_jax()
        robot, order, link, base = pyroki_robot(self.chain)
        self.order, self.pk = order, robot
        T_root_base = jaxlie.SE3(robot.forward_kinematics(jnp.zeros(self.chain.dof))[base])
        self.T_root_base = T_root_base
        lower = np.where(np.isfinite(self.chain.lower), self.chain.lower, -UNBOUNDED)[order]
        upper = np.where(np.isfinite(self.chain.upper), self.chain.upper, UNBOUNDED)[order]
        self.bounds = (jnp.asarray(lower), jnp.asarray(upper))
        self.run = jax.jit(self._program(link, 1.0 if self.kind == "pose" else 0.0))
        self.solve(np.clip(np.zeros(self.chain.dof), self.chain.lower, self.chain.upper),
                   np.zeros(3), np.eye(3))  # compile (untimed)

    @staticmethod
    def _program(link: int, ori_weight: float):
        import jax.numpy as jnp
        import jaxls
        import pyroki

        from ikbench.baselines.libraries.pyroki_trajopt import _cost_factories

        limits = _cost_factories()[4]

        def run(robot, target, init, lower, upper):
            var = robot.joint_var_cls(0)
            costs = [pyroki.costs.pose_cost_analytic_jac(robot, var, target,
                                                         jnp.int32(link), 1.0, ori_weight),
                     limits(var, lower, upper)]
            problem = jaxls.LeastSquaresProblem(costs=costs, variables=[var]).analyze()
            solution, summary = problem.solve(
                initial_vals=jaxls.VarValues.make([var.with_value(init)]),
                linear_solver="conjugate_gradient", verbose=False, return_summary=True,
                termination=jaxls.TerminationConfig(max_iterations=MAX_STEPS))
            return solution[var], summary.iterations

        return run

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import jax.numpy as jnp
        import jaxlie

        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rotation, point_m
        target = self.T_root_base @ jaxlie.SE3.from_matrix(jnp.asarray(T))
        q, iterations = self.run(self.pk, target, jnp.asarray(np.asarray(q_init)[self.order]),
                                 *self.bounds)
        out = np.empty(self.chain.dof)
        out[self.order] = np.asarray(q, dtype=float)
        return PoseOut(out, int(iterations), bool(int(iterations) < MAX_STEPS))


class OursLMSolver(PoseSolver):
    """ours-lm's machinery: every target in one batch (:mod:`ikbench.methods.ours_lm.
    single_pose`), restarts from seeded random poses."""

    name, library, modules = "ours-lm", "ikbench", ()
    batched = True
    iterations_are = "LM iterations (restarts included)"
    #: Restarts per target at most, iterations since a (re)start before the next, in all.
    RESTARTS, RESTART_AFTER, MAX_ITERATIONS = 100, 15, 1500

    def solve_batch(self, initial_deg: npt.ArrayLike, goal_points_mm: npt.ArrayLike,
                    goal_rotations: npt.ArrayLike, tolerance: tuple[float, float], seed: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(poses (B, dof) [pose units], iterations (B,), converged (B,))."""
        from ikbench.methods.ours_lm.single_pose import solve_poses

        out = solve_poses(self.robot, goal_points_mm, goal_rotations, initial_deg, tolerance,
                          position_only=self.kind == "position",
                          max_iterations=self.MAX_ITERATIONS, restarts=self.RESTARTS,
                          restart_after=self.RESTART_AFTER, seed=seed)
        return out.poses, out.iterations, out.converged


#: Every single-pose solver, in the leaderboard's order.
SOLVERS: dict[str, type[PoseSolver]] = {cls.name: cls for cls in (
    OursLMSolver, TracIKSolver, DLSSolver, PinkSolver, MinkSolver, DrakeSolver, PyrokiSolver,
    IkpySolver, PlacoSolver)}


def available_solvers() -> dict[str, type[PoseSolver]]:
    """The solvers whose libraries are installed (registry order)."""
    return {name: cls for name, cls in SOLVERS.items() if cls.available()}
