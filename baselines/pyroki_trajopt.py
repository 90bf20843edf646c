"""PyRoki (PyPI ``almond-pyroki``, module ``pyroki``; JAX + jaxls): the whole path as one
least-squares problem over the n+1 poses.

``almond-pyroki`` is Almond Bot's fork of PyRoki (chungmin99/pyroki, which has no PyPI
release), pinned to a revision of upstream and depending on ``almond-jaxls`` (their fork of
brentyi/jaxls, module ``jaxls``); same module names and API as upstream.

Robot: ``pyroki.Robot.from_urdf(yourdfpy.URDF.load(chain URDF))`` (the chain's URDF text:
joints off the chain fixed, axes unit). Variables: ``robot.joint_var_cls(arange(n+1))``, one
joint vector per goal point. Costs and constraints (``jaxls.Cost.factory`` residuals, ours
unless named; constraints are solved by jaxls' augmented Lagrangian):

- goal points 1..n-1: ``p_i - p_goal_i`` as equality constraints (``--pyroki-position
  constraint``, default) or as a cost of weight ``--pyroki-position-weight``;
- pointing at 1..n-1: ``w (R_i a - d_i)`` (a: the pointing axis; rank 2, roll free), a cost;
  with a task contract only at i >= ``contract.judged_from(n)`` (weight 0 before; none when
  the contract does not ask for pointing), so the arm may turn from the start pose's own
  pointing over the first steps instead of in one segment;
- smoothness: ``pyroki.costs.smoothness_cost`` between consecutive poses;
- joint limits: ``lower - q <= 0``, ``q - upper <= 0`` with the chain's limits;
- fixed ends: ``q_0 = q_start``, ``q_n = q_touch`` as equality constraints;
- with a task contract that knows the joint speed limits: ``q_i+1 - q_i - m <= 0`` and
  ``q_i - q_i+1 - m <= 0`` per segment, inequality constraints (``constraint_leq_zero``, as
  ``pyroki.costs.limit_velocity_constraint``, whose limit is the URDF's velocity instead), m
  = 0.99 of the contract's largest step per segment at n (``contract.max_step(n)``, pose
  units) in URDF units (the motor map is affine: |scale| times it, deg to rad, mm to m).

Solved by ``LeastSquaresProblem(costs, variables).analyze().solve(initial_vals,
linear_solver="conjugate_gradient", termination=TerminationConfig(max_iterations=300),
return_summary=True)`` (Levenberg-Marquardt inside the augmented Lagrangian), from the
joint-space line between the two poses (PyRoki's trajopt example). ``iterations`` are jaxls'
LM steps.

JAX: float64 is switched on (``jax_enable_x64``, process-wide): in float32 PyRoki's limits
round past the true ones (pi -> 3.1415927). With float64, jaxls' ``dense_cholesky`` fails
(int64 / int32 dtype mix), hence conjugate gradient. The problem is built inside one
``jax.jit``-ed function, compiled once per process, number of points and with or without the
speed constraint: the XLA compile takes 20-40 s on 2 cores and happens in
:meth:`PyrokiTrajopt.prepare` (untimed; the time is in details.csv as ``compile_s``); a solve
then takes tens of ms (with the speed constraint 0.05-2 s: more augmented-Lagrangian rounds).
jaxls' default tolerances leave the goal points ~1e-3 mm off (tighter ones made it worse).
6-D goal frames are not wired in.
"""

from __future__ import annotations

import io
import os
import platform
import signal
import time
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals, chain_of, contract_step
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.single_pose import MAX_STEPS, PoseOut, PoseSolver

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: Stand-in [rad, m] for the infinite limits of continuous joints in the limit constraint.
UNBOUNDED = 1e6
#: The fraction of the contract's joint step a segment may take (room for jaxls' constraint
#: tolerance and round-off).
STEP_MARGIN = 0.99
_ROBOTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_SOLVERS: dict = {}


@dataclass
class PyrokiSettings:
    """Settings of the PyRoki trajectory optimisation (see the module docstring)."""

    position: str = option("constraint", flag="pyroki-position",
                           choices=("constraint", "cost"),
                           help="goal points as equality constraints or as costs")
    position_weight: float = option(1e3, flag="pyroki-position-weight", unit="1/m",
                                    help="goal point cost weight (--pyroki-position cost)")
    pointing_weight: float = option(10.0, flag="pyroki-pointing-weight",
                                    help="weight of the pointing residual R a - d")
    smoothness_weight: float = option(0.1, flag="pyroki-smoothness-weight", unit="1/rad",
                                      help="weight of pyroki's smoothness cost q_i+1 - q_i")
    max_iterations: int = option(300, flag="pyroki-max-iterations",
                                 help="jaxls termination: LM iterations at most")

    def __post_init__(self):
        check_choice(self, "position", ("constraint", "cost"))
        check_positive(self, "position_weight", "pointing_weight")
        check_positive(self, "max_iterations", integer=True)
        if not self.smoothness_weight >= 0:
            raise InputError(f"--pyroki-smoothness-weight: {self.smoothness_weight!r} must be "
                             ">= 0")
        self.max_iterations = int(self.max_iterations)


#: XLA settings for the same answers on every x86 machine: one thread per computation (no
#: split of a reduction by core count), code for AVX2 at most (an AVX-512 machine runs what
#: an AVX2 one runs), no fast math. Added to XLA_FLAGS before the first JAX computation of
#: the process; a flag the user set stays theirs.
XLA_DETERMINISTIC = ("--xla_cpu_multi_thread_eigen=false", "intra_op_parallelism_threads=1",
                     "--xla_cpu_enable_fast_math=false",
                     *(("--xla_cpu_max_isa=AVX2",) if platform.machine().lower()
                       in ("x86_64", "amd64") else ()))
#: Set by :func:`_on_sigint` (Ctrl-C while a jitted call runs: JAX may drop the
#: KeyboardInterrupt raised inside it); :func:`_honour_ctrl_c` raises it after the call.
_CTRL_C = [False]
_PREVIOUS_SIGINT: list = []


def _xla_flags(current: str) -> str:
    """``current`` (XLA_FLAGS) with :data:`XLA_DETERMINISTIC`'s flags it does not set."""
    given = {flag.split("=")[0].lstrip("-") for flag in current.split()}
    extra = [f for f in XLA_DETERMINISTIC if f.split("=")[0].lstrip("-") not in given]
    return " ".join([current.strip(), *extra]).strip()


def _xla_pinned() -> bool:
    """Whether XLA_FLAGS holds every flag of :data:`XLA_DETERMINISTIC` (as the JAX backend
    started with them only if they were there before its first computation)."""
    flags = os.environ.get("XLA_FLAGS", "")
    return _xla_flags(flags) == flags.strip()


def _on_sigint(signum, frame):  # type: ignore[no-untyped-def]
    """SIGINT: remembered for :func:`_honour_ctrl_c`, then the handler before it (Python's
    raises KeyboardInterrupt; one that ignored SIGINT, as a script's background job
    inherits, is not called: Ctrl-C still stops the solves)."""
    _CTRL_C[0] = True
    previous = _PREVIOUS_SIGINT[0] if _PREVIOUS_SIGINT else None
    if callable(previous):
        previous(signum, frame)


def _guard_ctrl_c() -> None:
    """Install :func:`_on_sigint` (once; the main thread only, elsewhere Python's own stays)."""
    if signal.getsignal(signal.SIGINT) is _on_sigint:
        return
    try:
        previous = signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread
        return
    _PREVIOUS_SIGINT[:] = [previous]


def _honour_ctrl_c() -> None:
    """Raise the KeyboardInterrupt of a Ctrl-C that came during the last jitted call."""
    if _CTRL_C[0]:
        _CTRL_C[0] = False
        raise KeyboardInterrupt


def _setup_jax():
    """XLA's deterministic settings (:data:`XLA_DETERMINISTIC`, before the first
    computation), float64 on (process-wide), jaxls / pyroki logging off, the Ctrl-C guard
    (:func:`_guard_ctrl_c`); returns jax."""
    os.environ["XLA_FLAGS"] = _xla_flags(os.environ.get("XLA_FLAGS", ""))
    _guard_ctrl_c()
    import jax

    jax.config.update("jax_enable_x64", True)
    try:
        from loguru import logger

        logger.disable("jaxls")
        logger.disable("pyroki")
    except ImportError:  # pragma: no cover - loguru comes with jaxls
        pass
    return jax


def with_velocity_limits(urdf: Any) -> Any:
    """``urdf`` (a ``yourdfpy.URDF``) with a ``<limit>`` (velocity only) on continuous joints
    that have none: PyRoki's parser refuses joints without a velocity limit. The velocity is
    not used here, and the position limits of continuous joints stay open (-pi..pi is PyRoki's
    default guess)."""
    import yourdfpy

    for joint in urdf.robot.joints:
        if joint.type == "continuous" and joint.limit is None:
            joint.limit = yourdfpy.Limit(effort=0.0, velocity=UNBOUNDED)
    return urdf


def pyroki_robot(chain: Chain) -> tuple[Any, np.ndarray, int, int]:
    """(pyroki.Robot, order, end link index, base link index) of the chain (cached):
    ``order`` maps PyRoki's actuated joints to the chain's (q_pyroki = q_chain[order])."""
    if chain in _ROBOTS:
        return _ROBOTS[chain]
    _setup_jax()
    import pyroki
    import yourdfpy

    urdf = yourdfpy.URDF.load(io.BytesIO(chain.urdf_text.encode()), load_meshes=False,
                              build_collision_scene_graph=False)
    robot = pyroki.Robot.from_urdf(with_velocity_limits(urdf))
    names = list(robot.joints.actuated_names)
    if sorted(names) != sorted(chain.joint_names):
        raise ValueError(f"PyRoki's actuated joints {names} differ from {chain.joint_names}")
    order = np.array([chain.joint_names.index(n) for n in names])
    _ROBOTS[chain] = (robot, order, robot.links.names.index(chain.end_frame),
                      robot.links.names.index(chain.base_link))
    return _ROBOTS[chain]


def _cost_factories():
    """The residuals (created once per process: jaxls keys compiled code on them)."""
    if "costs" in _SOLVERS:
        return _SOLVERS["costs"]
    import jaxlie
    import jaxls

    def end_pose(vals, robot, var, link, T_base_root):
        return T_base_root @ jaxlie.SE3(robot.forward_kinematics(vals[var])[link])

    @jaxls.Cost.factory(kind="constraint_eq_zero", name="ikbench_goal_point")
    def goal_point(vals, robot, var, link, T_base_root, p_goal):
        return end_pose(vals, robot, var, link, T_base_root).translation() - p_goal

    @jaxls.Cost.factory(name="ikbench_goal_point_cost")
    def goal_point_cost(vals, robot, var, link, T_base_root, p_goal, weight):
        return (end_pose(vals, robot, var, link, T_base_root).translation() - p_goal) * weight

    @jaxls.Cost.factory(name="ikbench_pointing")
    def pointing(vals, robot, var, link, T_base_root, axis, d_goal, weight):
        rotation = end_pose(vals, robot, var, link, T_base_root).rotation()
        return (rotation @ axis - d_goal) * weight

    @jaxls.Cost.factory(kind="constraint_eq_zero", name="ikbench_fixed_pose")
    def fixed_pose(vals, var, q):
        return vals[var] - q

    @jaxls.Cost.factory(kind="constraint_leq_zero", name="ikbench_limits")
    def limits(vals, var, lower, upper):
        import jax.numpy as jnp

        q = vals[var]
        return jnp.concatenate([lower - q, q - upper])

    @jaxls.Cost.factory(kind="constraint_leq_zero", name="ikbench_step_limit")
    def step_limit(vals, var, previous, max_step):
        import jax.numpy as jnp

        step = vals[var] - vals[previous]
        return jnp.concatenate([step - max_step, -step - max_step])

    _SOLVERS["costs"] = (goal_point, goal_point_cost, pointing, fixed_pose, limits, step_limit)
    return _SOLVERS["costs"]


def _solver(position: str, max_iterations: int, speed: bool = False):
    """The jitted solve for a position mode, iteration cap and whether the joint steps are
    bounded (see the module docstring)."""
    key = (position, max_iterations, speed)
    if key in _SOLVERS:
        return _SOLVERS[key]
    jax = _setup_jax()
    import jax.numpy as jnp
    import jaxlie
    import jaxls
    import pyroki

    goal_point, goal_point_cost, pointing, fixed_pose, limits, step_limit = _cost_factories()

    @jax.jit
    def run(robot, link, T_base_root, axis, points, directions, ends, init, lower, upper,
            position_weight, pointing_weights, smoothness_weight, max_step):
        n_points = points.shape[0]
        inner = jnp.arange(1, n_points - 1)
        k = n_points - 2
        var = robot.joint_var_cls
        batched = jax.tree.map(lambda x: x[None], robot)
        links = jnp.full((k,), link, dtype=jnp.int32)
        T = jaxlie.SE3(jnp.broadcast_to(T_base_root, (k, 7)))
        costs = [
            goal_point(batched, var(inner), links, T, points[1:-1]) if position == "constraint"
            else goal_point_cost(batched, var(inner), links, T, points[1:-1],
                                 jnp.full((k, 1), position_weight)),
            pointing(batched, var(inner), links, T, jnp.broadcast_to(axis, (k, 3)),
                     directions[1:-1], pointing_weights[1:-1, None]),
            pyroki.costs.smoothness_cost(var(jnp.arange(1, n_points)),
                                         var(jnp.arange(n_points - 1)),
                                         jnp.reshape(smoothness_weight, (1, 1))),
            limits(var(jnp.arange(n_points)), lower[None], upper[None]),
            fixed_pose(var(jnp.array([0, n_points - 1])), ends),
        ]
        if speed:
            costs.append(step_limit(var(jnp.arange(1, n_points)), var(jnp.arange(n_points - 1)),
                                    max_step[None]))
        path = var(jnp.arange(n_points))
        problem = jaxls.LeastSquaresProblem(costs=costs, variables=[path]).analyze()
        solution, summary = problem.solve(
            initial_vals=jaxls.VarValues.make([path.with_value(init)]),
            linear_solver="conjugate_gradient",
            termination=jaxls.TerminationConfig(max_iterations=max_iterations),
            verbose=False, return_summary=True)
        return solution[path], summary.iterations

    _SOLVERS[key] = run
    return run


def _inputs(chain: Chain, goals: Goals, settings: PyrokiSettings, pointing_from: int | None,
            max_step: np.ndarray | None):
    """The jitted function's arguments for ``goals`` (PyRoki's joint order)."""
    import jax.numpy as jnp
    import jaxlie

    robot, order, link, base = pyroki_robot(chain)
    q_start, q_touch = goals.q_start[order], goals.q_touch[order]  # type: ignore[index]
    T_root_base = jaxlie.SE3(robot.forward_kinematics(jnp.asarray(q_start))[base])
    w = np.linspace(0.0, 1.0, len(goals))[:, None]
    lower = np.where(np.isfinite(chain.lower), chain.lower, -UNBOUNDED)[order]
    upper = np.where(np.isfinite(chain.upper), chain.upper, UNBOUNDED)[order]
    return (robot, jnp.int32(link), T_root_base.inverse().wxyz_xyz,
            jnp.asarray(chain.pointing_axis), jnp.asarray(goals.points_m),
            jnp.asarray(goals.directions), jnp.asarray(np.stack([q_start, q_touch])),
            jnp.asarray((1 - w) * q_start + w * q_touch), jnp.asarray(lower),
            jnp.asarray(upper), jnp.asarray(settings.position_weight),
            jnp.asarray(pointing_weights(len(goals), settings.pointing_weight, pointing_from)),
            jnp.asarray(settings.smoothness_weight),
            jnp.asarray(np.zeros(chain.dof) if max_step is None else max_step[order]))


def pointing_weights(n_points: int, weight: float, pointing_from: int | None) -> np.ndarray:
    """(N,) the pointing residual's weight per goal point: ``weight`` from ``pointing_from``
    on (1: every inner point), 0 before it; all 0 when ``pointing_from`` is None."""
    out = np.zeros(n_points)
    if pointing_from is not None:
        out[max(1, int(pointing_from)):] = weight
    return out


def solve_chain(chain: Chain, goals: Goals, settings: PyrokiSettings,
                pointing_from: int | None = 1,
                max_step: np.ndarray | None = None) -> ChainResult:
    """The PyRoki trajectory optimisation in URDF units (see the module docstring).

    Args:
        chain, goals, settings: the chain, the task's goals and the settings.
        pointing_from: the first goal point with a pointing residual (1: every inner point,
            as without a contract; the contract's ``judged_from(n)``), or None: no pointing.
        max_step: (dof,) the largest joint change per segment [rad, m] (the contract's speed
            limit, chain order), or None: no such constraint.
    """
    _, order, _, _ = pyroki_robot(chain)
    run = _solver(settings.position, settings.max_iterations, max_step is not None)
    q_pyroki, iterations = run(*_inputs(chain, goals, settings, pointing_from, max_step))
    _honour_ctrl_c()
    q = np.empty((len(goals), chain.dof))
    q[:, order] = np.asarray(q_pyroki, dtype=float)
    inside = chain.clip(q)
    return ChainResult(inside, int(iterations), int(iterations) < settings.max_iterations, {
        "clipped_rows": int(np.sum(np.any(inside != q, axis=1))),
        "max_limit_violation": float(np.max(np.abs(inside - q), initial=0.0)),
        "pointing_from": -1 if pointing_from is None else int(pointing_from),
        "speed_bounded": max_step is not None,
        "iterations_are": "jaxls Levenberg-Marquardt steps"})


class PyrokiTrajopt(LibraryMethod):
    """PyRoki's least-squares trajectory optimisation between start and touch pose."""

    name = "pyroki"
    description = ("library: PyRoki (almond-pyroki) trajectory optimisation of the whole path "
                   "(jaxls least squares: goal-point constraints, pointing costs where the "
                   "contract judges them, smoothness cost, fixed start and touch poses, the "
                   "contract's joint steps as constraints); JAX compiles once per n (untimed)")
    library = "almond-pyroki"
    Settings = PyrokiSettings
    whole_path = True

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        super().check_tasks(robot, tasks)
        self._sizes = sorted({(len(task.goal.points_mm), _speed_limited(task))
                              for task in tasks})

    def prepare(self, robot: Robot) -> None:
        """Untimed: parse the URDF, and JIT-compile the solve for every task size (and with or
        without the speed constraint) seen by :meth:`check_tasks` (one solve of a placeholder
        task each)."""

        _CTRL_C[0] = False  # a Ctrl-C an earlier study stopped for is forgotten
        _setup_jax()
        chain = chain_of(robot)
        pyroki_robot(chain)
        _honour_ctrl_c()
        started = time.perf_counter()
        for size, speed in getattr(self, "_sizes", []):
            q = np.clip(np.zeros(chain.dof), np.nan_to_num(chain.lower),
                        np.nan_to_num(chain.upper))
            line = np.linspace([0.0, 0.0, 0.0], [0.1, 0.0, 0.0], size)
            placeholder = Goals(line, np.tile([0.0, 0.0, 1.0], (size, 1)), None, q, q)
            solve_chain(chain, placeholder, self.settings,
                        max_step=np.ones(chain.dof) if speed else None)
        self._compile_s = time.perf_counter() - started

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        contract = goals.contract
        if contract is None:  # no contract: as before it, every inner point pointed
            result = solve_chain(chain, goals, self.settings)
        else:
            steps = len(goals) - 1
            result = solve_chain(chain, goals, self.settings,
                                 contract.judged_from(steps) if contract.pointing else None,
                                 contract_step(goals, STEP_MARGIN))
        result.info["compile_s"] = getattr(self, "_compile_s", float("nan"))
        return result


def _speed_limited(task: Task) -> bool:
    """True when the task's contract bounds the joint steps (a speed limit is known)."""
    contract = task.required.contract
    return contract is not None and contract.max_step(len(task.goal.points_mm) - 1) is not None


class PyrokiSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`):
    ``pyroki.costs.pose_cost_analytic_jac`` (orientation weight 0 for points) and the limits
    as jaxls inequality constraints, one jitted jaxls least-squares solve per target (compiled
    in ``prepare``), 100 steps at most."""

    rank = 90
    name, library, modules = "pyroki", "almond-pyroki", ("pyroki", "jaxls", "jax")
    iterations_are = "jaxls Levenberg-Marquardt steps"
    attempt_bound = "jaxls, 100 LM steps"
    #: benchmarks/determinism_check.py: with XLA_DETERMINISTIC the same answers under XLA's
    #: AVX-512 code and OpenBLAS' other settings; without the one-thread pin, 16 threads moved
    #: answers (by ~1e-3 deg). An x86 CPU without AVX2 still gets other answers.
    stable_across_machines = True

    def prepare(self) -> None:
        _CTRL_C[0] = False  # a Ctrl-C an earlier study stopped for is forgotten
        jax = _setup_jax()
        import jax.numpy as jnp
        import jaxlie

        robot, order, link, base = pyroki_robot(self.chain)
        _honour_ctrl_c()
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
    def _program(link: int, ori_weight: float) -> Any:
        import jax.numpy as jnp
        import jaxls
        import pyroki

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
        _honour_ctrl_c()
        out = np.empty(self.chain.dof)
        out[self.order] = np.asarray(q, dtype=float)
        return PoseOut(out, int(iterations), bool(int(iterations) < MAX_STEPS))


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="almond-pyroki", requires=("pyroki", "jax", "jaxls"),
                  methods=(PyrokiTrajopt,), solvers=(PyrokiSolver,), rank=110)
