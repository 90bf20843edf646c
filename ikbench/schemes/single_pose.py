"""Single-pose IK (``ikbench ik``): the interface every method implements.

A :class:`PoseSolver` takes one target in the chain's base frame (a point [m] and the end
frame's rotation (3, 3); ``kind="position"``: the point only) and initial configurations, and
returns the method's answer (:class:`PoseOut`). Each method's solver lives beside its method:
the libraries' in their modules of ``baselines/``, sequential-ik's in
``baselines/sequential_ik.py``, ours-lm's in :mod:`ikbench.methods.ours_lm.pose_solver`.
Each module's ``ADAPTER`` lists its solvers, and :mod:`ikbench.methods.registry` finds them
(:func:`~ikbench.methods.registry.available_solvers`; a missing library breaks nothing else).

The protocol (:mod:`ikbench.studies.ik`): each target has a seeded sequence of initial
configurations and a wall-clock budget. A solver that restarts by itself
(``restarts_itself``: TRAC-IK within its timeout, ours-lm) gets the whole sequence and the
budget in one :meth:`PoseSolver.solve_within` call and honours them; any other is called once
per attempt (:meth:`PoseSolver.solve`: one descent from one initial configuration) and the
study restarts it from the next row until the answer holds or the budget is spent. The study
times each call itself, the same way for every method, and judges every answer by FK through
Pinocchio; ``ok`` is only what the method claimed. Set-up (parsing the URDF, building the
library's model, compiling) happens in :meth:`PoseSolver.prepare`, untimed.

Each library is called as its documentation shows for one IK, with a stopping tolerance far
below the study's (:data:`LIBRARY_TOLERANCE`: the study's tolerance decides success).
"""

from __future__ import annotations

import abc
import importlib.util
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np

from ikbench.schemes.chain import chain_of

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: The libraries' own stopping tolerance [m, rad] (far below the study's mm and degrees).
LIBRARY_TOLERANCE = 1e-6
#: Iterations (QP steps, DLS steps, LM steps) of one descent at most.
MAX_STEPS = 100
#: The default wall-clock budget of one target [s] (TRAC-IK's default timeout).
BUDGET_S = 0.005


class PoseOut(NamedTuple):
    """One answer.

    Attributes:
        q: (dof,) the answer [rad, m] (pose units for a solver with ``pose_units``).
        iterations: what the method counts (``iterations_are``), all attempts together.
        ok: the method's own success claim; None when it makes none.
        attempts: initial configurations of the sequence used (1 for one descent).
    """

    q: np.ndarray
    iterations: int
    ok: bool | None
    attempts: int = 1


class BatchOut(NamedTuple):
    """Answers of B targets solved in one call (:meth:`PoseSolver.solve_batch`).

    Attributes:
        q: (B, dof) answers [pose units].
        attempts: (B,) initial configurations used per target.
        threads: threads the call ran on.
    """

    q: np.ndarray
    attempts: np.ndarray
    threads: int


class PoseSolver(abc.ABC):
    """One method's single-pose IK (see the module docstring).

    Class attributes:
        name: the method's name (as in ``ikbench methods``).
        library: PyPI distribution whose version is recorded.
        modules: modules that must be importable.
        kinds: the target kinds it takes (``pose``, ``position``).
        deterministic: same input, same answer.
        restarts_itself: takes the sequence of initial configurations and the budget in one
            call (:meth:`solve_within`) instead of being restarted by the study.
        one_descent: given a single initial configuration, it makes one descent (False for
            TRAC-IK, which restarts from its own random poses within its timeout whatever it
            is given).
        batched: also solves many targets in one call (:meth:`solve_batch`; throughput).
        pose_units: takes initial configurations and returns answers in the robot's pose
            units (deg, mm) instead of URDF units (rad, m).
        iterations_are: what ``iterations`` counts.
        rank: the solver's place in listings and leaderboards (lower first).
        analytic: gives every solution of a target in closed form (``branches(point_m,
            rotation, near)``: (S, dof) [rad, m]); the study's ground truth where one applies.

    Args:
        robot: the robot.
        kind: ``"pose"`` or ``"position"``.
        tolerance: the study's (position [mm], rotation [deg]) (for methods that scale their
            residual by it; the others stop at :data:`LIBRARY_TOLERANCE`).
        budget_s: the wall-clock budget of one target [s] (for methods that take one).
    """

    name: ClassVar[str] = ""
    library: ClassVar[str] = ""
    modules: ClassVar[tuple[str, ...]] = ()
    kinds: ClassVar[tuple[str, ...]] = ("pose", "position")
    deterministic: ClassVar[bool] = True
    restarts_itself: ClassVar[bool] = False
    one_descent: ClassVar[bool] = True
    batched: ClassVar[bool] = False
    pose_units: ClassVar[bool] = False
    iterations_are: ClassVar[str] = "iterations"
    #: What bounds one attempt (a fixed-count rule has no wall-clock cut: this does).
    attempt_bound: ClassVar[str] = f"its own stopping rule, at most {MAX_STEPS} steps"
    rank: ClassVar[int] = 1000
    analytic: ClassVar[bool] = False
    #: Same answers on another CPU under the deterministic protocol, as measured by
    #: benchmarks/determinism_check.py (None: not measured).
    stable_across_machines: ClassVar[bool | None] = None

    def __init__(self, robot: Robot, kind: str = "pose",
                 tolerance: tuple[float, float] = (1.0, 0.5), budget_s: float = BUDGET_S
                 ) -> None:
        self.robot = robot
        self.kind = kind
        self.tolerance = tolerance
        self.budget_s = budget_s
        self.chain = chain_of(robot)

    @classmethod
    def available(cls) -> bool:
        """True when every module it needs can be imported (nothing is imported here)."""
        return all(importlib.util.find_spec(m) is not None for m in cls.modules)

    def runtime(self) -> dict[str, Any]:
        """What runs the solves (recorded in run.json, shown in the leaderboard): the
        library by default; ikbench's own solver names its backend."""
        return {"backend": self.library}

    def prepare(self) -> None:  # noqa: B027  (an optional hook, empty by default)
        """Untimed set-up (models, compilation)."""

    @abc.abstractmethod
    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        """One descent from ``q_init`` (dof,) toward the point [m] and rotation (3, 3)."""

    def bare_call(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray
                  ) -> Callable[[], object] | None:
        """The library's own call alone, for measuring the glue an adapter adds: a
        zero-argument function that makes ONLY the library's call :meth:`solve` makes for
        ``q_init`` (dof,), the point [m] and the rotation (3, 3), on inputs converted in
        advance (no conversion, branch choice or answer building inside it); what it returns
        is the library's, unused. None (the default): the call cannot be isolated, not
        measured (:func:`ikbench.studies.ik.bare_call_times`)."""
        return None

    def prepared_call(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                      budget_s: float) -> Callable[[], PoseOut] | None:
        """``restarts_itself`` only, optional: :meth:`solve_within` of these inputs as a
        zero-argument function, its inputs converted to the library's form in advance, as
        :meth:`bare_call`'s are (``ikbench ik`` makes it before the clock and times the call
        alone: what a conversion costs is then outside the adapter's time, so an adapter that
        has one says what it prepares). None (the default): the study times
        :meth:`solve_within` itself, conversions included."""
        return None

    def solve_within(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                     budget_s: float) -> PoseOut:  # pragma: no cover - interface
        """``restarts_itself`` only: from ``initials`` (A, dof), in order, until the answer
        holds, the rows are used up or ``budget_s`` [s] is spent."""
        raise TypeError(f"{self.name} does not restart itself (restarts_itself is False)")

    def solve_batch(self, initials: np.ndarray, points_m: np.ndarray, rotations: np.ndarray,
                    budget_s: float, threads: int | None = None
                    ) -> BatchOut:  # pragma: no cover - interface
        """``batched`` only: B targets, points (B, 3) [m], rotations (B, 3, 3), each from its
        own rows ``initials`` (B, A, dof) [pose units] within ``budget_s`` [s] per target."""
        raise TypeError(f"{self.name} solves one target per call (batched is False)")


def steps_to_tolerance(measure: Callable[[], tuple[float, float]], step: Callable[[], None]
             ) -> tuple[int, bool]:
    """Steps (``step()``, at most :data:`MAX_STEPS`) until both errors of ``measure()``
    (position [m], rotation [rad]) are below :data:`LIBRARY_TOLERANCE`; (steps, reached)."""
    for steps in range(MAX_STEPS + 1):
        position, angle = measure()
        if position < LIBRARY_TOLERANCE and angle < LIBRARY_TOLERANCE:
            return steps, True
        if steps < MAX_STEPS:
            step()
    return MAX_STEPS, False
