"""What the library methods share: checks before any solve, the conversion of a library's
result to a :class:`~ikbench.methods.base.Solution` in pose units, the method's own timer.

A library method implements :meth:`LibraryMethod.solve_chain` on the chain and goals in URDF
units (:mod:`ikbench.schemes.chain`) and returns a :class:`ChainResult`; everything else
is here.
"""

from __future__ import annotations

import abc
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.base import Capabilities, Method, Solution
from ikbench.methods.options import option
from ikbench.schemes.chain import Chain, Goals, chain_of, goals_of, poses_from_urdf
from ikbench.schemes.chain import require_touch_and_start as _require_both
from ikbench.schemes.track import plan_track, require_start_and_touch
from ikbench.schemes.walk import Walk

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.base import Progress


def shared_option(options: Mapping[str, Mapping[str, Any]], prefix: str, name: str,
                  **changes: Any) -> Any:
    """A settings field that several methods declare alike: ``options[name]`` (the
    arguments of :func:`ikbench.methods.options.option`, ``default`` among them) as the flag
    ``--<prefix>-<name with dashes>``; ``changes`` replace some of them (another default or
    help) for one method."""
    spec = {**options[name], **changes}
    return option(spec.pop("default"), flag=f"{prefix}-{name.replace('_', '-')}", **spec)


@dataclass
class ChainResult:
    """A library's trajectory in URDF units.

    Attributes:
        q: (N, dof) joint values [rad, m], within the chain's limits.
        iterations: the library's iterations (what they count: ``info["iterations_are"]``).
        converged: the library's own success criterion held (every point, or the whole path).
        info: flat figures for details.csv (numbers and strings).
    """

    q: np.ndarray
    iterations: int
    converged: bool
    info: dict = field(default_factory=dict)

    @classmethod
    def from_walk(cls, walk: Walk, **info: object) -> ChainResult:
        """The result of a sequential walk (:func:`ikbench.schemes.walk.walk_back`)."""
        return cls(walk.q, walk.iterations, not walk.failed, {**walk.info(), **info})


class LibraryMethod(Method):
    """Base class of the methods in ``baselines/`` that call another kinematics library.

    Class attributes (besides :class:`~ikbench.methods.base.Method`'s):
        capabilities: ``needs_touch_pose`` (the walks start at the touch pose, the trajectory
            optimisers fix it); ``frames`` when the library takes full 6-D goal frames
            (``task.goal.rotations``), otherwise such tasks are refused before any solve.
        whole_path: True for trajectory optimisers (the start and touch poses are both
            fixed; the result's rows are returned as solved, row n included); False for the
            sequential walks (row n is the touch pose exactly).
        loads_urdf: True when the library parses the URDF itself (the chain's URDF text
            from :func:`ikbench.schemes.chain.chain_urdf_text`, locked joints folded into
            fixed ones).
        chain_check: ``staticmethod(f)``, ``f(chain)`` raising InputError for a chain the
            library cannot model (run by :meth:`check_robot`), or None.
        chain_model: ``staticmethod(f)``, ``f(chain)`` building (and caching) the library's
            model of the chain, untimed (run by :meth:`prepare`), or None.
    """

    library: ClassVar[str] = ""
    capabilities: ClassVar[Capabilities] = Capabilities(needs_touch_pose=True)
    whole_path: ClassVar[bool] = False
    loads_urdf: ClassVar[bool] = True
    chain_check: ClassVar[Callable[..., object] | None] = None
    chain_model: ClassVar[Callable[..., object] | None] = None

    @property
    def scheme(self) -> str:
        """``track`` (from the start pose onto the touch pose,
        :mod:`ikbench.schemes.track`), ``walk`` (back from the touch pose,
        :mod:`ikbench.schemes.walk`) or ``whole-path`` (trajectory optimisers)."""
        if self.whole_path:
            return "whole-path"
        return str(getattr(self.settings, "scheme", "walk"))

    def tracks(self, task: Task) -> bool:
        """True when ``task`` is solved by the tracking scheme (a pose path is always
        walked forward from the home pose: it has no start pose to track from)."""
        return self.scheme == "track" and not task.goal.has_frames

    def fixed_poses(self) -> frozenset[str]:
        """Both poses for trajectory optimisers and the tracking scheme; the walk keeps only
        the touch pose (its start pose is wherever the walk ends up)."""
        if self.scheme == "walk":
            return frozenset({"touch_pose"})
        return frozenset({"start_pose", "touch_pose"})

    def check_tasks(self, robot: Robot, tasks: Sequence[Task]) -> None:
        """Refuse, before any solve: tasks without the poses the method fixes, 6-D goal frames
        the library cannot take, locked joints, robots the library cannot model
        (:meth:`check_robot`)."""
        for task in tasks:
            if self.whole_path:
                _require_both(task, self.name)
            elif self.tracks(task):
                require_start_and_touch(task, self.name)
            if task.goal.has_frames and not self.capabilities.frames:
                raise InputError(f"trajectory {task.name!r}: --method {self.name} takes goal "
                                 "points and pointing directions, not 6-D goal frames")
        super().check_tasks(robot, tasks)
        self.check_robot(robot)

    def check_robot(self, robot: Robot) -> None:
        """InputError when the library cannot model this robot (:attr:`chain_check`; without
        one it can)."""
        if self.chain_check is not None:
            self.chain_check(chain_of(robot))

    def prepare(self, robot: Robot) -> None:
        """Untimed: build the chain in URDF units (parses the URDF once) and the library's
        model of it (:attr:`chain_model`)."""
        chain = chain_of(robot)
        if self.chain_model is not None:
            self.chain_model(chain)

    @abc.abstractmethod
    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        """Solve one task in URDF units (implemented by each library method); ``robot`` for
        methods that work on the robot's own model (pink: its Pinocchio model)."""

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        """Solve ``task`` with the library; poses in the robot's pose units."""
        started = time.perf_counter()
        goals = goals_of(robot, task)
        if self.tracks(task):
            goals = replace(goals, track=plan_track(robot, task, goals))
        result = self.solve_chain(robot, chain_of(robot), goals)
        poses = poses_from_urdf(robot, result.q)
        if not self.whole_path and task.required.end_pose is not None:
            poses[-1] = task.required.end_pose  # the walk's start / the track's end, as given
        if self.tracks(task):
            poses[0] = task.required.start_pose  # the track's start, exactly as given
        return Solution(poses=poses, iterations=int(result.iterations),
                        duration_s=time.perf_counter() - started, loss=None,
                        converged=bool(result.converged), info=dict(result.info))
