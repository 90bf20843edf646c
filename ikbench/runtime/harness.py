"""The study harness: every method solved and timed the same way, failures kept as rows.

:func:`solve_tasks` calls ``method.prepare`` (untimed), checks the tasks
(``method.check_tasks``: bad input fails before any solve), then times each solve itself with
``time.perf_counter`` around the method's call - the same clock for every method. A batched
method (``Method.capabilities.batched``) is timed once for the whole batch and each task gets
its share.
An exception in one solve becomes a failed :class:`Outcome` with its message instead of
aborting the study; Ctrl-C stops solving and returns what was solved so far
(:class:`Interrupted`, a ``KeyboardInterrupt``: no ``except Exception`` turns it into a failed
row), so the caller can keep it and say so.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from ikbench.core.task import Task
from ikbench.methods.base import Solution, hearing_fraction
from ikbench.runtime.progress import Reporter, loss_text

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.methods.base import Method


@dataclass
class Outcome:
    """One task's result as the harness saw it.

    Attributes:
        task: the task.
        solution: the method's solution, or None when the solve failed.
        wall_s: wall time of the solve measured by the harness [s] (for a batched method its
            share of the batch).
        failure: ``"ExceptionType: message"`` when the solve raised, else None.
    """

    task: Task
    solution: Solution | None
    wall_s: float
    failure: str | None = None

    @property
    def ok(self) -> bool:
        return self.solution is not None


class Interrupted(KeyboardInterrupt):
    """Ctrl-C while solving; ``outcomes`` holds the tasks solved before it, ``written`` the
    folder they were written to (None: not written)."""

    def __init__(self, outcomes: list[Outcome], written: Path | None = None):
        super().__init__(f"interrupted after {len(outcomes)} solved trajectories")
        self.outcomes = outcomes
        self.written = written


class Progress(Reporter):
    """A method's progress (:class:`ikbench.methods.base.Progress`) as a :class:`Reporter`:
    one unit per trajectory solved, the iterations as its status; a trajectory started moves
    the count by the fraction its method reports
    (:func:`ikbench.methods.base.report_fraction`)."""

    def __init__(self, label: str, stream: TextIO | None = None, enabled: bool = True,
                 unit: str = "trajectory") -> None:
        super().__init__(label, unit=unit, enabled=enabled, stream=stream)

    def start(self, task: Task, index: int, total: int) -> None:
        if self.total != total:
            self.set_total(total)
        self.begin(1)
        self.say(f"trajectory {task.name} ({index + 1}/{total}): solving, n = {task.goal.steps}")

    def update(self, task: Task, iteration: int, loss: float) -> None:
        self.say(f"trajectory {task.name}: iteration {iteration}, loss {loss_text(loss)}")

    def done(self, task: Task, solution: Solution) -> None:
        loss = f", loss {loss_text(solution.loss)}"
        flag = "" if solution.converged else " (did not meet its stopping criterion)"
        if solution.info.get("infeasible"):  # a method's best infeasible result, said so
            flag = f" (INFEASIBLE: {solution.info['infeasible']})"
        self.advance(1, f"trajectory {task.name}: done in {solution.iterations} iterations, "
                     f"{solution.duration_s:.2f} s{loss}{flag}")

    def failed(self, task: Task, failure: str) -> None:
        self.note(f"trajectory {task.name}: FAILED: {failure}")
        self.advance(1)


def describe(exc: BaseException) -> str:
    """``"SolverError: message"`` on one line."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def solve_tasks(method: Method, robot: Robot, tasks: Sequence[Task],
                progress: Progress | None = None) -> list[Outcome]:
    """Solve ``tasks`` with ``method``, timed by the harness (see the module docstring).

    Raises:
        IkbenchError: from ``check_tasks`` (before any solve).
        Interrupted: on Ctrl-C, with the outcomes so far.
    """
    method.check_tasks(robot, tasks)
    method.prepare(robot)
    try:
        if method.capabilities.batched:
            return _solve_batched(method, robot, tasks, progress)
        outcomes: list[Outcome] = []
        for k, task in enumerate(tasks):
            if progress:
                progress.start(task, k, len(tasks))
            outcomes.append(_solve_one(method, robot, task, progress, outcomes))
        return outcomes
    finally:
        if isinstance(progress, Reporter):
            progress.close()  # the bar goes; the next solve of the study opens its own


def _solve_one(method, robot, task, progress, done: list[Outcome]) -> Outcome:
    started = time.perf_counter()
    try:
        with _hearing(progress):
            solution = method.solve(robot, task, progress)
    except KeyboardInterrupt:
        raise Interrupted(done) from None
    except Exception as exc:  # one failed solve is a row, not the end of the study
        outcome = Outcome(task, None, time.perf_counter() - started, describe(exc))
        if progress:
            progress.failed(task, outcome.failure)
        return outcome
    outcome = Outcome(task, solution, time.perf_counter() - started)
    if progress:
        progress.done(task, solution)
    return outcome


def _hearing(progress):
    """The solve's :func:`~ikbench.methods.base.report_fraction` goes to ``progress`` when it
    shows anything, else to nobody (a quiet solve inside a study that counts its own)."""
    shown = isinstance(progress, Reporter) and progress.enabled
    return hearing_fraction(progress.within if shown else None)


def _solve_batched(method, robot, tasks, progress) -> list[Outcome]:
    started = time.perf_counter()
    try:
        with _hearing(progress):
            solutions = method.solve_many(robot, tasks, progress)
    except KeyboardInterrupt:
        raise Interrupted([]) from None
    except Exception:  # find the failing task(s): solve one at a time
        if len(tasks) == 1:
            return [_solve_one(method, robot, tasks[0], progress, [])]
        outcomes: list[Outcome] = []
        for task in tasks:
            outcomes.append(_solve_one(method, robot, task, progress, outcomes))
        return outcomes
    share = (time.perf_counter() - started) / len(tasks)
    return [Outcome(task, solution, share) for task, solution in zip(tasks, solutions)]
