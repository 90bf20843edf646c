"""What every method is: a settings dataclass, ``solve(robot, task) -> Solution``.

A method's options live in its settings dataclass, each field declared with
:func:`ikbench.methods.options.option` (the option machinery and its checks:
:mod:`ikbench.methods.options`).

A method class sets ``name``, ``description``, ``Settings`` and ``solve`` (the one abstract
method of :class:`Method`, an :class:`abc.ABC`), and says what it can do beyond goal points and
directions in one :class:`Capabilities` value (``capabilities = Capabilities(frames=True)``);
optionally ``solve_many`` (batched methods), ``check_tasks`` (refuse before any solve),
``prepare`` (untimed set-up, e.g. building kinematics) and ``solve_from`` (a warm start from
given poses, ``Capabilities(warm_starts=True)``; the designer re-solves that way while a point
is dragged). Methods that come from another library say so in ``library`` (its PyPI
distribution, whose version is recorded with results).
"""

from __future__ import annotations

import abc
import dataclasses
import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.options import MethodOption, method_options

if TYPE_CHECKING:  # the robot module imports pinocchio: for type checkers only
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: name -> class of every method available here, for :meth:`Method.check_tasks` to name the
#: able ones. The registry installs its ``available_methods`` (:func:`use_catalogue`) when it is
#: imported, which ``ikbench/methods/__init__.py`` does before any method module runs, so this
#: module, below the registry, never imports it.
_catalogue: Callable[[], dict[str, type[Method]]] = dict


def use_catalogue(available: Callable[[], dict[str, type[Method]]]) -> None:
    """Make ``available()`` (name -> method class) the catalogue that
    :meth:`Method.check_tasks` lists alternatives from (the registry's)."""
    global _catalogue
    _catalogue = available


@dataclass(frozen=True)
class Capabilities:
    """What a method can do beyond following goal points and directions (the class attribute
    :attr:`Method.capabilities`; the studies, the CLI and :meth:`Method.check_tasks` read it).

    Attributes:
        needs_touch_pose: the method starts at, or walks back from, the task's touch pose, so it
            cannot draw letters or curves (they pin no pose).
        frames: follows goal frames (6-D pose paths, e.g. the CppFlow problems);
            :meth:`Method.check_tasks` refuses such tasks for the others.
        obstacles: keeps the robot clear of a task's obstacles (``Task.obstacles``) and of
            itself; the others still solve such tasks, and the studies name "does not avoid
            obstacles" beside a collision.
        batched: ``solve_many`` solves all tasks in one call (timed as one).
        warm_starts: :meth:`Method.solve_from` starts from the poses it is given (else it
            solves from scratch).
    """

    needs_touch_pose: bool = False
    frames: bool = False
    obstacles: bool = False
    batched: bool = False
    warm_starts: bool = False


@dataclass
class Solution:
    """A method's result for one task.

    Attributes:
        poses: (n+1, dof) poses [pose units: ``Robot.pose_unit``, motor deg for NICO].
        iterations: optimiser iterations (total IK iterations for sequential methods).
        duration_s: wall time of the solve as the method measured it [s] (the study harness
            measures its own, the same way for every method).
        loss: final loss in the paper's units (cm, motor deg), or None if the method has none.
        converged: whether the method's own stopping criterion was met (not the cap).
        info: extra method-specific figures (written to details.csv).
    """

    poses: np.ndarray
    iterations: int
    duration_s: float
    loss: float | None
    converged: bool = True
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class NoSettings:
    """Settings of a method without options."""


class Progress(Protocol):
    """Where a method reports its progress (the studies pass ``harness.Progress``)."""

    def start(self, task: Task, index: int, total: int) -> None:
        """Task ``index`` of ``total`` (from 0) starts."""

    def update(self, task: Task, iteration: int, loss: float) -> None:
        """An iteration of the task's solve."""

    def done(self, task: Task, solution: Solution) -> None:
        """The task's solve finished."""


#: Who hears how far the running solve is (:func:`report_fraction`): set by the harness around
#: each solve (:func:`hearing_fraction`), None where nobody listens (a worker, a bare call).
_fraction_listener: ContextVar[Callable[[float], None] | None] = ContextVar(
    "ikbench_fraction_listener", default=None)


def report_fraction(done: float, total: float) -> None:
    """How far the running solve is within its task (or batch): ``done`` of ``total``, in the
    method's own units of its cap (iterations done of the iteration cap, waypoints solved of
    the waypoints). The study's progress bar moves by that fraction of the item; a method
    that never calls it moves the bar once per item. A non-finite or non-positive total says
    nothing; the fraction is clipped to [0, 1]. Cheap where nobody listens."""
    listener = _fraction_listener.get()
    if listener is None or not total > 0:
        return
    fraction = done / total
    if math.isfinite(fraction):
        listener(min(max(fraction, 0.0), 1.0))


@contextmanager
def hearing_fraction(listener: Callable[[float], None] | None) -> Iterator[None]:
    """Within the block, :func:`report_fraction` goes to ``listener(fraction)`` (None: to
    nobody)."""
    token = _fraction_listener.set(listener)
    try:
        yield
    finally:
        _fraction_listener.reset(token)


class Method(abc.ABC):
    """Base class of every method (see the module docstring).

    Class attributes:
        name: the registry name (``ours-lm``).
        description: one line, shown by ``ikbench methods`` and in ``--help``.
        Settings: the settings dataclass (fields made with :func:`option` are CLI options).
        library: the PyPI distribution the method is built on (its version is recorded).
        capabilities: what the method can do (:class:`Capabilities`).
        bench_rounds: timed rounds ``ikbench bench`` gives the method by default.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Settings: ClassVar[type] = NoSettings
    library: ClassVar[str] = "ikbench"
    capabilities: ClassVar[Capabilities] = Capabilities()
    bench_rounds: ClassVar[int] = 5

    def __init__(self, settings: Any = None, **options: Any) -> None:
        """Build from a settings object or from its fields as keywords."""
        if settings is not None and options:
            raise TypeError("give settings or keyword options, not both")
        try:
            self.settings = settings if settings is not None else self.Settings(**options)
        except TypeError as exc:
            known = ", ".join(f.name for f in dataclasses.fields(self.Settings))
            raise InputError(f"method {self.name}: {exc}; its settings are: {known}") from None

    @classmethod
    def options(cls) -> list[MethodOption]:
        """The method's CLI options (from its settings dataclass)."""
        return method_options(cls.Settings)

    @classmethod
    def takes_weights(cls) -> bool:
        """True when the method minimises the paper's loss with settable weights."""
        return any(f.name == "weights" for f in dataclasses.fields(cls.Settings))

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> Method:
        """Build from CLI values keyed by flag (``{"lm-max-iterations": 50}``); None = unset."""
        kwargs = {}
        for opt in cls.options():
            value = values.get(opt.flag)
            if value is not None:
                kwargs[opt.field] = value
        return cls(**kwargs)

    def settings_for(self, task: Task) -> Any:
        """The settings used for one task (default: the method's own)."""
        return self.settings

    def prepare(self, robot: Robot) -> None:  # noqa: B027  (an optional hook, empty by default)
        """Untimed set-up before the first solve (e.g. build the kinematics)."""

    def runtime(self) -> dict[str, Any]:
        """What actually runs the solves, recorded beside every result and shown in the
        leaderboards' headers: ``backend`` (the library, or for ikbench's own methods the
        solver that the settings choose on this machine: ``numba``, ``numpy``, ``torch
        (cpu, float32)``) and ``threads`` where the backend uses several. Default: the
        method's library."""
        return {"backend": self.library}

    def fixed_poses(self) -> frozenset[str]:
        """The poses this method's scheme keeps fixed (``start_pose``, ``touch_pose``): a
        task contract that fixes a pose the method does not keep is not honoured, and its rows
        say so instead of counting as success. Default: both (ikbench's own methods pin them
        in their objective; the study judges how close they come)."""
        return frozenset({"start_pose", "touch_pose"})

    def scheme_label(self) -> str:
        """The method's scheme and mode in a few words (leaderboard rows): ``track``,
        ``walk`` or ``whole path``, then the settings that choose its mode (orientation,
        solve type, pointing task, weights)."""
        settings = self.settings
        parts = [str(getattr(self, "scheme", None) or getattr(settings, "scheme", None)
                     or "whole path")]
        for key in ("orientation", "solve_type", "pointing_task"):
            if hasattr(settings, key):
                parts.append(f"{key.replace('_', ' ')} {getattr(settings, key)}")
        if self.takes_weights():
            weights = getattr(settings, "weights", None)
            parts.append(f"weights {weights}" if weights else "the paper's weights")
        return ", ".join(parts)

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        """Raise InputError before any solve if a task cannot be solved by this method."""
        for task in tasks:
            if task.goal.has_frames and not self.capabilities.frames:
                able = [name for name, cls in _catalogue().items()
                        if cls.capabilities.frames]
                raise InputError(
                    f"trajectory {task.name!r}: --method {self.name} cannot follow goal frames "
                    f"(a 6-D pose path); methods that can: {', '.join(able) or 'none'}")
        if self.capabilities.needs_touch_pose:
            for task in tasks:
                if task.required.end_pose is None and not task.goal.has_frames:
                    planners = [f"--method {name}" for name, cls in _catalogue().items()
                                if not cls.capabilities.needs_touch_pose]
                    raise InputError(
                        f"trajectory {task.name!r}: {self.name} starts at the touch pose; the "
                        "task has no end pose (for letters, polylines and splines use "
                        f"{' or '.join(planners) or 'a method that plans the whole path'})")

    @abc.abstractmethod
    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        """Solve one task: the poses and the method's own figures."""

    def solve_from(self, robot: Robot, task: Task, initial_poses: np.ndarray) -> Solution:
        """Solve ``task`` starting from ``initial_poses`` (n+1, dof) [pose units], e.g. the
        solution of a slightly different task (a warm start). Methods that cannot start from
        given poses (``capabilities.warm_starts`` False) solve from scratch: this default."""
        return self.solve(robot, task)

    def solve_many(self, robot: Robot, tasks: Sequence[Task],
                   progress: Progress | None = None) -> list[Solution]:
        """Solve every task; batched methods override this."""
        solutions = []
        for k, task in enumerate(tasks):
            if progress:
                progress.start(task, k, len(tasks))
            solutions.append(self.solve(robot, task, progress))
            if progress:
                progress.done(task, solutions[-1])
        return solutions
