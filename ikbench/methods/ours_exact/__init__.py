"""``ours-exact``: the whole trajectory with hard constraints, smoothness and pointing optimised.

The paper's objective (and ours-lm, which minimises it) trades every requirement against the
others by weights: the fingertip leaves the line by millimetres so that the motion stays smooth
and the finger points. ``ours-exact`` makes the requirements that must hold exactly hard
constraints and optimises only what is a matter of degree:

- **constraints**: every fingertip point at its goal point (3-D tasks: lines, polylines,
  splines, letters) or every end frame at its goal frame (6-D pose paths), the start and touch
  poses exactly where the task fixes them, the joint limits as bounds;
- **objective**: the paper's smoothness L6 (mean squared joint step), the paper's pointing L1
  over the part of the path where pointing is judged (the task contract's, the last 80 % of a
  line; the whole of a letter, along the drawing plane's normal), optionally the mean squared
  jerk, and a penalty that keeps every joint step within ``--exact-max-step``.

Solved by SQP (:mod:`.sqp`: Gauss-Newton model, banded KKT solve :mod:`.kkt`, l1 merit,
bound active set), batched over trajectories, from the joint interpolation between the fixed
poses, or (tasks without them) from ours-lm's solution. A trajectory whose constraints cannot
all hold is returned as solved-but-infeasible (``converged=False``) with the constraint and
place that failed in its ``info``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.validity import MAX_JOINT_CHANGE_DEG, MAX_JOINT_CHANGE_MM
from ikbench.methods.base import Capabilities, Method, Solution
from ikbench.methods.options import check_choice, check_positive, check_seed, flag_of, option
from ikbench.methods.ours_exact.problem import TERMS, ExactProblem, evaluate
from ikbench.methods.ours_exact.sqp import RESTORATIONS, SQPResult, solve
from ikbench.methods.ours_lm import OursLM, initial_poses
from ikbench.methods.ours_lm.avoidance import collision_checker
from ikbench.methods.ours_lm.search_common import lm_seed_option
from ikbench.methods.registry import Adapter

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.base import Progress

__all__ = ["ExactProblem", "ExactSettings", "OursExact", "SQPResult", "build_problem", "solve"]

INITS = ("auto", "interpolation", "ours-lm")
#: Steps of a 6-D pose path are kept below this share of CppFlow's joint-change limits.
PATH_STEP_SHARE = 0.95
#: The poses keep this far inside the joint limits [pose units]: a joint held at its bound
#: stays within it after the trajectory CSV's rounding (10 significant digits).
BOUND_MARGIN = 1e-5
#: A step this far above its limit [pose units] still counts as within it (the penalty
#: leaves a residue of this order).
STEP_SLACK = 0.01
#: A solution from the joint interpolation pointing worse than this (RMS over the judged part
#: [deg]) is solved again from ours-lm's solution, and the better of the two kept.
RETRY_POINTING_DEG = 3.0
#: Below the task contract's speed limit by this share (a margin for the penalty's residue).
CONTRACT_STEP_SHARE = 0.98


@dataclass
class ExactSettings:
    """Settings of ``ours-exact`` (CLI options from the ``option`` fields).

    Attributes:
        pointing_weight: c1, the weight of the paper's pointing term L1 over the judged part.
        smoothness_weight: c6, the weight of the paper's smoothness term L6.
        jerk_weight: weight of the mean squared jerk (third differences) [1/deg^2].
        max_step: largest joint step per segment the penalty allows [pose units]; the task
            contract's speed limit lowers it where that is stricter.
        step_penalty: weight of the squared step excess above ``max_step``.
        max_iterations: SQP iteration cap.
        tolerance: stop when a step changes the merit by less than this fraction or moves no
            joint by more than this [pose units] (and the constraints hold).
        feasibility_tolerance: the constraints hold when no point is further than this from
            its goal [mm] (and no frame rotated further [deg]).
        init: the initial trajectory: ``interpolation`` (joint interpolation between the
            fixed poses), ``ours-lm`` (ours-lm's solution) or ``auto`` (the first where the
            task fixes both poses, else the second).
        seed: 6-D pose paths: the seed of ours-lm's start search (the initial trajectory).
        legibility_weight: W of ikbench's legibility term (not the paper's method; 0: off,
            the paper's objective unchanged): W sum_i f_i (1 - P_i(G*))^2 / sum f, the
            pointing observer's P(true goal), early poses weighted most
            (:func:`ikbench.core.legibility.legibility_term`). Needs ``legibility_goals_mm``.
        legibility_goals_mm: the goal set (K, 3) [mm] of the legibility term (a task's touch
            point not in it is added as its true goal); set from Python or by
            ``ikbench legibility``, not a CLI option.
    """

    pointing_weight: float = option(2000.0, flag="exact-pointing-weight",
                                    help="c1: weight of pointing over the judged part")
    smoothness_weight: float = option(1.0, flag="exact-smoothness-weight",
                                      help="c6: weight of the mean squared joint step")
    jerk_weight: float = option(0.0, flag="exact-jerk-weight",
                                help="weight of the mean squared jerk (third differences)")
    max_step: float = option(9.5, flag="exact-max-step", unit="pose units per segment",
                             help="largest joint step the step penalty allows")
    step_penalty: float = option(1e4, flag="exact-step-penalty",
                                 help="weight of the squared step excess above the max step")
    max_iterations: int = option(100, flag="exact-max-iterations", help="SQP iteration cap")
    tolerance: float = option(1e-4, flag="exact-tolerance",
                              help="stop when a step changes the merit by less than this "
                              "fraction or moves no joint more than this")
    feasibility_tolerance: float = option(1e-6, flag="exact-feasibility-tolerance",
                                          unit="mm, deg",
                                          help="largest constraint violation that counts as "
                                          "holding")
    init: str = option("auto", flag="exact-init", choices=INITS,
                       help="initial trajectory: interpolation between the fixed poses, "
                       "ours-lm's solution, or auto (the first when both poses are fixed)")
    seed: int = lm_seed_option()
    legibility_weight: float = option(0.0, flag="exact-legibility-weight",
                                      help="W of ikbench's legibility term (not the paper's "
                                      "method; 0: off): W * weighted mean of (1 - the "
                                      "pointing observer's P(true goal))^2, early poses "
                                      "weighted most; needs a goal set (ikbench "
                                      "legibility)")
    legibility_goals_mm: Any = None

    def __post_init__(self):
        check_positive(self, "smoothness_weight", "max_step", "step_penalty", "tolerance",
                       "feasibility_tolerance")
        check_positive(self, "max_iterations", integer=True)
        for name in ("pointing_weight", "jerk_weight", "legibility_weight"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise InputError(f"{flag_of(self, name)}: {value!r} must be a number >= 0")
        if self.legibility_weight and self.legibility_goals_mm is None:
            raise InputError(f"{flag_of(self, 'legibility_weight')} needs a goal set (the "
                             "task's other goals): use ikbench legibility, or set "
                             "legibility_goals_mm from Python")
        check_choice(self, "init", INITS)
        self.max_iterations = int(self.max_iterations)
        check_seed(self)


class OursExact(Method):
    """Hard path and pose constraints, smoothness and pointing optimised (SQP, batched)."""

    name = "ours-exact"
    description = ("hard constraints (every point on the path, the start and touch poses, "
                   "joint limits), the paper's smoothness and pointing optimised: batched SQP "
                   "with a banded KKT solve")
    Settings = ExactSettings
    capabilities = Capabilities(frames=True, batched=True, warm_starts=True)

    def scheme_label(self) -> str:
        s = self.settings
        jerk = f", jerk {s.jerk_weight:g}" if s.jerk_weight else ""
        legible = f", legibility {s.legibility_weight:g}" if s.legibility_weight else ""
        return (f"whole path, exact constraints, c1 {s.pointing_weight:g}, "
                f"c6 {s.smoothness_weight:g}{jerk}{legible}")

    def _sqp(self, kinematics, problem, initial, init_info) -> SQPResult:
        s = self.settings
        from_lm = all(how == "ours-lm" for how in init_info)
        return solve(kinematics, problem, initial,
                     restorations=0 if from_lm else RESTORATIONS,
                     max_iterations=s.max_iterations, tolerance=s.tolerance,
                     feasibility_tolerance=s.feasibility_tolerance)

    def runtime(self) -> dict[str, Any]:
        """The SQP runs on numpy (LAPACK's banded solver); 6-D pose paths without fixed poses
        start from ours-lm's solution, whose backend is named too."""
        return {"backend": "numpy", "threads": 1,
                "initial_solution": OursLM().runtime()["backend"]}

    #: The tasks checked last hold a pose path (ours-lm's search is then warmed up too).
    _pose_paths_ahead = False

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        super().check_tasks(robot, tasks)
        self._pose_paths_ahead = any(t.goal.has_frames for t in tasks)

    def prepare(self, robot: Robot) -> None:
        robot.chain_kinematics().frames(np.zeros((1, robot.dof)))
        import scipy.linalg.lapack  # noqa: F401  the banded solver's import is not timed

        if self._pose_paths_ahead:  # its initial trajectories come from ours-lm's search
            lm = OursLM(seed=self.settings.seed)
            lm._pose_paths_ahead = True
            lm.prepare(robot)

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        return self.solve_many(robot, [task])[0]

    def solve_many(self, robot: Robot, tasks: Sequence[Task],
                   progress: Progress | None = None) -> list[Solution]:
        """Solve tasks in batches of one length and kind; each Solution's duration_s is its
        share of its batch's wall time (the initial solve included)."""
        groups: dict[tuple, list[int]] = {}
        for k, task in enumerate(tasks):
            groups.setdefault((task.goal.steps, task.goal.has_frames, _limits_key(robot, task)),
                              []).append(k)
        out: dict[int, Solution] = {}
        for members in groups.values():
            batch = [tasks[k] for k in members]
            if progress:
                for k in members:
                    progress.start(tasks[k], k, len(tasks))
            for k, solution in zip(members, self._solve_batch(robot, batch)):
                out[k] = solution
                if progress:
                    progress.done(tasks[k], solution)
        return [out[k] for k in range(len(tasks))]

    def _solve_batch(self, robot, tasks) -> list[Solution]:
        started = time.perf_counter()
        s = self.settings
        kinematics = robot.chain_kinematics()
        problem = build_problem(robot, tasks, s)
        initial, init_info = initial_trajectories(robot, tasks, s)
        result = self._sqp(kinematics, problem, initial, init_info)
        # a start from the joint interpolation that ends in a poor local solution (a step
        # above the limit, poor pointing, infeasible, not converged) is solved again from
        # ours-lm's
        tol = s.feasibility_tolerance
        retry = [k for k, how in enumerate(init_info) if how == "interpolation"
                 and s.init == "auto" and not _good(problem, result, k, tol)]
        if retry:
            again = [tasks[k] for k in retry]
            second_initial, _ = initial_trajectories(robot, again, replace(s, init="ours-lm"))
            part = problem.take(retry)
            second = self._sqp(kinematics, part, second_initial, ["ours-lm"] * len(retry))
            for j, k in enumerate(retry):
                result.iterations[k] += second.iterations[j]
                if _rank(part, second, j, tol) > _rank(problem, result, k, tol):
                    for name in ("poses", "objective", "terms", "violation", "worst",
                                 "converged"):
                        getattr(result, name)[k] = getattr(second, name)[j]
                    init_info[k] = "ours-lm (after the interpolation's)"
        fallback = self._avoid_collisions(robot, tasks, problem, result, initial, init_info)
        return self._solutions(problem, result, init_info, time.perf_counter() - started,
                               fallback)

    def solve_from(self, robot: Robot, task: Task, initial_poses: np.ndarray) -> Solution:
        """The task's SQP from ``initial_poses`` (n+1, dof) [pose units], moved onto the
        constraints first (the fixed poses put in place): no initial solve, no retry."""
        started = time.perf_counter()
        s = self.settings
        problem = build_problem(robot, [task], s)
        initial = np.clip(np.array(initial_poses, dtype=float)[None], problem.lower,
                          problem.upper)
        for fixed, pose in ((0, task.required.start_pose), (-1, task.required.end_pose)):
            if pose is not None:
                initial[0, fixed] = pose
        result = solve(robot.chain_kinematics(), problem, initial,
                       max_iterations=s.max_iterations, tolerance=s.tolerance,
                       feasibility_tolerance=s.feasibility_tolerance)
        return self._solutions(problem, result, ["given (warm start)"],
                               time.perf_counter() - started)[0]

    def _solutions(self, problem: ExactProblem, result: SQPResult, init_info: list[str],
                   wall_s: float, fallback: dict[int, str] | None = None) -> list[Solution]:
        """One Solution per trajectory of ``result``; ``wall_s``: the batch's time [s];
        ``fallback``: the trajectories replaced by ours-lm's path, with why
        (:meth:`_avoid_collisions`)."""
        fallback = fallback or {}
        tolerance = self.settings.feasibility_tolerance
        size, solutions = len(result.poses), []
        for k in range(size):
            feasible = bool(result.violation[k] <= tolerance)
            info = {"batch_size": size, "batch_wall_time_s": wall_s,
                    "constraint_violation_max": float(result.violation[k]),
                    "feasible": feasible, "sqp_converged": bool(result.converged[k]),
                    "initial": init_info[k],
                    **{f"objective_{t}": float(v) for t, v in zip(TERMS, result.terms[k])}}
            if not feasible:
                info["infeasible"] = describe_violation(problem, result, k)
            if k in fallback:
                info["collision"] = fallback[k]
            solutions.append(Solution(
                poses=result.poses[k], iterations=int(result.iterations[k]),
                duration_s=wall_s / size, loss=float(result.objective[k]),
                converged=bool(result.converged[k]) and feasible, info=info))
        return solutions


    def _avoid_collisions(self, robot: Robot, tasks: Sequence[Task], problem: ExactProblem,
                          result: SQPResult, initial: np.ndarray, init_info: list[str]
                          ) -> dict[int, str]:
        """Self-collision (and, on pose paths, the task's obstacles) judged on every result:
        the SQP has no collision term, so a result that collides where ours-lm's path (its
        initial trajectory, or solved now for a task that started from the interpolation) does
        not, or less, is replaced by that path (``result`` updated in place). Returns the
        replaced trajectories' notes."""

        checker = collision_checker(robot)
        if checker is None:
            return {}
        notes: dict[int, str] = {}
        for k, task in enumerate(tasks):
            obstacles = tuple(task.required.obstacles) if task.goal.has_frames else ()
            colliding = int(checker.check(result.poses[k], obstacles).colliding.any(axis=1)
                            .sum())
            if not colliding:
                continue
            if init_info[k].startswith("ours-lm"):
                other = initial[k]
            else:
                other, _ = initial_trajectories(robot, [task], replace(self.settings,
                                                                      init="ours-lm"))
                other = other[0]
            theirs = int(checker.check(other, obstacles).colliding.any(axis=1).sum())
            if theirs >= colliding:
                continue
            model = evaluate(robot.chain_kinematics(), problem.take([k]), other[None], False)
            result.poses[k] = other
            result.objective[k], result.terms[k] = model.objective[0], model.terms[0]
            result.violation[k] = model.violation()[0]
            result.converged[k] = False
            notes[k] = (f"the SQP's result collides at {colliding} waypoints; ours-lm's path "
                        f"returned instead ({theirs})")
        return notes


def _step_excess(problem: ExactProblem, result: SQPResult, k: int) -> float:
    """The largest joint step above its limit in trajectory ``k`` [pose units] (0: none)."""
    steps = np.abs(np.diff(result.poses[k], axis=0))
    return float(np.max(steps - problem.step_limit[k], initial=0.0))


def _pointing_rms_deg(problem: ExactProblem, result: SQPResult, k: int) -> float:
    """Root mean square pointing deviation over the judged poses [deg], from the pointing
    term (c1 mean(1 - cos) and 1 - cos t ~ t^2 / 2); 0 where pointing is not optimised."""
    weights = problem.pointing[k]
    if not np.any(weights > 0):
        return 0.0
    c1 = 2.0 * np.sum(weights > 0) * float(np.max(weights))    # weights = c1 / (2 N_judged)
    mean_one_minus_cos = result.terms[k, TERMS.index("pointing")] / c1
    return float(np.degrees(np.sqrt(2.0 * max(mean_one_minus_cos, 0.0))))


def _good(problem: ExactProblem, result: SQPResult, k: int, tolerance: float) -> bool:
    """Converged, feasible, every step within its limit (to STEP_SLACK) and pointing within
    RETRY_POINTING_DEG."""
    return bool(result.converged[k] and result.violation[k] <= tolerance
                and _step_excess(problem, result, k) <= STEP_SLACK
                and _pointing_rms_deg(problem, result, k) <= RETRY_POINTING_DEG)


def _rank(problem: ExactProblem, result: SQPResult, k: int, tolerance: float) -> tuple:
    """Sort key of a result: feasible, then within the step limits, then lower objective."""
    return (bool(result.violation[k] <= tolerance),
            _step_excess(problem, result, k) <= STEP_SLACK, -float(result.objective[k]))


def _limits_key(robot, task) -> tuple:
    lower, upper = task.limits(robot)
    return tuple(np.round(np.concatenate([lower, upper]), 9))


def describe_violation(problem: ExactProblem, result: SQPResult, k: int) -> str:
    """Which constraint fails where, in words: ``point 23: 3.2 mm from its goal``."""
    pose, row = (int(v) for v in result.worst[k])
    what, unit = ("point", "mm") if row < 3 else ("frame rotation", "deg")
    return (f"{what} {pose}: {result.violation[k]:.3g} {unit} from its goal (the largest "
            "violation; the constraints cannot all hold from this start, e.g. a point out of "
            "reach or a path that needs a jump)")


def step_limits(robot: Robot, task: Task, settings: ExactSettings) -> np.ndarray:
    """(k,) the largest joint step per segment the penalty allows [pose units]: for a task
    with a contract, ``--exact-max-step`` or the contract's speed limit (the stricter); for a
    6-D pose path, CppFlow's joint-change limits; none (inf) for other tasks (a letter asks
    for its points, not for a speed)."""
    limit = np.full(robot.dof, np.inf)
    if task.goal.has_frames:  # CppFlow's joint-change criteria, with a margin
        prismatic = robot.chain_kinematics().prismatic
        limit = PATH_STEP_SHARE * np.where(prismatic, MAX_JOINT_CHANGE_MM, MAX_JOINT_CHANGE_DEG)
    contract = task.required.contract
    if contract is not None:
        limit = np.minimum(limit, float(settings.max_step))
        contract_step = contract.max_step(task.goal.steps)
        if contract_step is not None:
            limit = np.minimum(limit, CONTRACT_STEP_SHARE * contract_step)
    return limit


def pointing_scales(task: Task, settings: ExactSettings) -> np.ndarray:
    """(N,) squared residual scale of the pointing residual per pose: c1 / (2 N_judged) on
    the judged poses (the contract's judged part, pen-down points; the whole path without a
    contract), 0 elsewhere and for 6-D pose paths (their frames are constraints)."""
    n_poses = task.goal.steps + 1
    judged = np.asarray(task.goal.pen_down, dtype=bool).copy()
    contract = task.required.contract
    if task.goal.has_frames or (contract is not None and not contract.pointing):
        judged[:] = False
    elif contract is not None:
        judged[:contract.judged_from(task.goal.steps)] = False
    out = np.zeros(n_poses)
    if judged.any():
        out[judged] = settings.pointing_weight / (2.0 * judged.sum())
    return out


def build_problem(robot: Robot, tasks: Sequence[Task], settings: ExactSettings) -> ExactProblem:
    """The :class:`ExactProblem` of tasks of one length, kind and joint limits."""
    n = tasks[0].goal.steps
    dof = robot.dof
    fixed = np.zeros((len(tasks), n + 1), dtype=bool)
    fixed[:, 0] = [t.required.start_pose is not None for t in tasks]
    fixed[:, -1] = [t.required.end_pose is not None for t in tasks]
    frames = tasks[0].goal.has_frames
    lower, upper = (np.asarray(v, dtype=float) for v in tasks[0].limits(robot))
    lower, upper = lower + BOUND_MARGIN, upper - BOUND_MARGIN
    jerk = settings.jerk_weight / (max(n - 2, 1) * dof)
    legibility = _legibility_fields(tasks, settings)
    return ExactProblem(
        goal_points_mm=np.stack([t.goal.points_mm for t in tasks]),
        goal_directions=np.stack([t.goal.directions for t in tasks]),
        # a batch is of one kind: every task has frames when the first has
        goal_rotations=(np.stack([cast(np.ndarray, t.goal.rotations) for t in tasks])
                        if frames else None),
        pointing=np.stack([pointing_scales(t, settings) for t in tasks]),
        smooth=np.full(len(tasks), settings.smoothness_weight / (n * dof)),
        jerk=np.full(len(tasks), jerk if n >= 3 else 0.0),
        step_limit=np.stack([step_limits(robot, t, settings) for t in tasks]),
        step_penalty=np.full(len(tasks), float(settings.step_penalty)),
        fixed=fixed, constrained=~fixed, lower=lower, upper=upper, **legibility)


def _legibility_fields(tasks: Sequence[Task], settings: ExactSettings) -> dict[str, Any]:
    """The :class:`ExactProblem` fields of the legibility term (none when its weight is 0):
    weights (B, N), goal sets (B, K, 3) padded with NaN, true goals (B,)."""
    if not settings.legibility_weight:
        return {}
    from ikbench.core.legibility import POINTING_SIGMA_DEG, legibility_term_weights, true_goal_index

    flag = flag_of(settings, "legibility_weight")
    if settings.legibility_goals_mm is None:
        raise InputError(f"{flag} needs a goal set (the task's other goals): use ikbench "
                         "legibility, or set legibility_goals_mm from Python")
    if tasks[0].goal.has_frames:
        raise InputError(f"{flag} applies to point paths (lines), not to 6-D pose paths")
    sets, trues = [], []
    for task in tasks:
        goals, true = true_goal_index(np.asarray(settings.legibility_goals_mm, dtype=float),
                                      task.goal.points_mm[-1])
        if len(goals) < 2:
            raise InputError(f"{flag} needs a goal set with a goal other than the task's "
                             f"touch point ({task.name!r} has none)")
        sets.append(goals)
        trues.append(true)
    k = max(len(g) for g in sets)
    padded = np.full((len(tasks), k, 3), np.nan)
    for b, goals in enumerate(sets):
        padded[b, :len(goals)] = goals
    n_poses = tasks[0].goal.steps + 1
    weights = legibility_term_weights(n_poses, settings.legibility_weight)
    return {"legibility": np.tile(weights, (len(tasks), 1)), "legibility_goals_mm": padded,
            "true_goal": np.asarray(trues, dtype=int), "sigma_deg": POINTING_SIGMA_DEG}


def initial_trajectories(robot: Robot, tasks: Sequence[Task], settings: ExactSettings
                         ) -> tuple[np.ndarray, list[str]]:
    """(poses (B, N, k) to start from, a word per task saying which)."""
    both = [t.required.start_pose is not None and t.required.end_pose is not None for t in tasks]
    use_lm = [settings.init == "ours-lm" or (settings.init == "auto" and not ok)
              for ok in both]
    for task, ok, lm in zip(tasks, both, use_lm):
        if not lm and not ok:
            raise InputError(f"trajectory {task.name!r}: --exact-init interpolation needs a "
                             "start and a touch pose; use --exact-init ours-lm or auto")

    out: Any = (initial_poses(robot, tasks) if not tasks[0].goal.has_frames or not any(use_lm)
                else None)
    if any(use_lm):
        chosen = [t for t, lm in zip(tasks, use_lm) if lm]
        solved = OursLM(seed=settings.seed).solve_many(robot, chosen)
        poses = iter(s.poses for s in solved)
        stacked = [next(poses) if lm else out[k] for k, lm in enumerate(use_lm)]
        out = np.stack(stacked)
    for k, task in enumerate(tasks):  # the fixed poses exactly, whatever the start
        if task.required.start_pose is not None:
            out[k, 0] = task.required.start_pose
        if task.required.end_pose is not None:
            out[k, -1] = task.required.end_pose
    return out, ["ours-lm" if lm else "interpolation" for lm in use_lm]


#: What ikbench brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="ikbench", requires=("scipy", "pinocchio"),
                  methods=(OursExact,), solvers=(), rank=30)
