"""What every backend of ours-lm's batched LM shares: its settings, the stopping constants,
the batch's result and its initial poses. The numpy solver (:mod:`.solver`), the numba loop
(:mod:`.compiled`) and the torch backend (:mod:`.torch_backend`) import them from here, so
none of them imports another.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.losses import PAPER_WEIGHTS_TEXT, check_weights
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.methods.ours_lm.devices import (
    BACKENDS,
    DTYPES,
    check_backend,
    check_device,
)

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task


#: ``progress(iteration, n_active, losses)``: called every iteration of a batched solve.
LMProgress = Callable[[int, int, np.ndarray], object]


KINEMATICS = ("numpy", "pinocchio")


LINEAR_SOLVERS = ("banded", "thomas")


#: A variable within this distance [motor deg] of a bound counts as on the bound.
BOUND_EPS_DEG = 1e-9


#: Steps whose gain ratio (actual / predicted reduction) is below this are rejected.
MIN_GAIN_RATIO = 1e-4


#: Give up on a trajectory when the damping exceeds this (no descent step exists).
MAX_DAMPING = 1e12


@dataclass
class LMSettings:
    """Settings of the Levenberg-Marquardt solver (CLI options from the ``option`` fields).

    Attributes:
        weights: loss weights: a complete dict keyed L0..L6, or changes such as ``"c0=100"``
            on top of each task's (else the paper's) weights; None: none.
        max_iterations: iteration cap per trajectory.
        tolerance: stop when an accepted step lowers the loss by less than
            ``tolerance * loss`` (relative), or moves no pose by more than ``tolerance`` deg.
        damping: initial Marquardt damping factor lambda (times diag(J^T J)).
        kinematics: ``"numpy"`` (vectorised chain FK from the Pinocchio model) or
            ``"pinocchio"`` (``computeFrameJacobian`` per pose; the reference, slower).
        linear_solver: ``"banded"`` (LAPACK banded Cholesky) or ``"thomas"`` (numpy).
        device: None for the CPU solvers (numpy or numba, ``backend``); ``"cpu"``,
            ``"cuda"`` or ``"cuda:N"`` for the torch backend on that device
            (:mod:`.torch_backend`).
        dtype: the torch backend's precision, ``"float64"`` or ``"float32"``.
        backend: without ``device``: ``"numpy"`` (this module, the reference), ``"numba"``
            (the same loop compiled, :mod:`.compiled`; needs the ``[fast]`` extra) or
            ``"auto"``: numba when installed (and kinematics numpy, linear solver banded).
        threads: threads of the numba backend (None: all cores numba sees).
    """

    weights: dict | str | None = option(
        None, type=str, show_default=PAPER_WEIGHTS_TEXT,
        help="loss weights to change, e.g. c1=20,c6=5 (letters start from their own)")
    max_iterations: int = option(200, flag="lm-max-iterations",
                                 help="iteration cap per trajectory")
    tolerance: float = option(1e-9, flag="lm-tolerance",
                              help="stop when a step lowers the loss by less than this "
                              "fraction or moves no joint by more than this many degrees")
    damping: float = option(1e-3, flag="lm-damping", help="initial Marquardt damping")
    kinematics: str = option("numpy", flag="lm-kinematics", choices=KINEMATICS,
                             help="vectorised numpy chain, or Pinocchio "
                             "computeFrameJacobian per pose (reference, slower)")
    linear_solver: str = option("banded", flag="lm-linear-solver", choices=LINEAR_SOLVERS,
                                help="banded Cholesky via LAPACK, or numpy block Thomas "
                                "(the torch backend: thomas forces its block Thomas; else it "
                                "picks cyclic reduction or block Thomas by batch size)")
    device: str | None = option(None, type=str, show_default="none: the numpy solver",
                                help="cpu, cuda or cuda:N: the torch backend on that device")
    dtype: str = option("float64", choices=DTYPES,
                        help="precision of the torch backend (--device)")
    backend: str = option("auto", flag="lm-backend", choices=BACKENDS,
                          help="CPU solver without --device: numpy (the reference), numba "
                          "(the same loop compiled; pip extra [fast]) or auto (numba when "
                          "installed)")
    threads: int | None = option(None, flag="lm-threads", type=int,
                                 show_default="all cores",
                                 help="threads of the numba backend (trajectories are shared "
                                 "out among them)")

    def __post_init__(self):
        check_positive(self, "max_iterations", integer=True)
        check_positive(self, "tolerance", "damping")
        check_choice(self, "kinematics", KINEMATICS)
        check_choice(self, "linear_solver", LINEAR_SOLVERS)
        check_weights(self.weights)
        self.max_iterations = int(self.max_iterations)
        self.device = check_device(self.device)
        check_backend(self)


@dataclass
class BatchResult:
    """Result of :func:`solve_batch`: arrays over the B trajectories."""

    poses: np.ndarray        # (B, N, dof)
    loss: np.ndarray             # (B,)
    terms: np.ndarray            # (B, 7) L0..L6
    iterations: np.ndarray       # (B,) LM iterations (accepted + rejected steps)
    converged: np.ndarray        # (B,) bool: the tolerance was met before the cap
    duration_s: float            # wall time of the whole batch [s]


def initial_poses(robot: Robot, tasks: Sequence[Task]) -> np.ndarray:
    """Initial poses (B, N, dof) [motor deg], clipped to the motor ranges.

    The joint interpolation from start to touch pose; a task that pins neither (a letter,
    polyline or spline) starts with every pose at its reference pose.

    Raises:
        InputError: a task has neither a start and an end pose nor a reference pose.
    """
    out = []
    for task in tasks:
        t = np.linspace(0.0, 1.0, task.goal.steps + 1)[:, None]
        if task.required.start_pose is not None and task.required.end_pose is not None:
            start, end = task.required.start_pose, task.required.end_pose
            out.append(start + t * (end - start))
        elif task.hints.reference_pose is not None:
            out.append(np.asarray(task.hints.reference_pose, dtype=float) + 0.0 * t)
        else:
            raise InputError(f"trajectory {task.name!r}: ours-lm needs a start and an end pose "
                             "or a reference pose to start from")
    return np.clip(np.stack(out), robot.lower, robot.upper)


def initial_poses_batched(robot: Robot, tasks: Sequence[Task]) -> np.ndarray:
    """:func:`~.solver.initial_poses` without a loop over tasks when every task pins a start
    and a touch pose (the same operations, so the same numbers)."""
    if not all(t.required.start_pose is not None and t.required.end_pose is not None
               for t in tasks) \
            or len({t.goal.steps for t in tasks}) != 1:
        return initial_poses(robot, tasks)
    # every task pins both (checked above)
    start = np.stack([cast(np.ndarray, t.required.start_pose) for t in tasks])[:, None, :]
    end = np.stack([cast(np.ndarray, t.required.end_pose) for t in tasks])[:, None, :]
    t = np.linspace(0.0, 1.0, tasks[0].goal.steps + 1)[None, :, None]
    return np.clip(start + t * (end - start), robot.lower, robot.upper)
