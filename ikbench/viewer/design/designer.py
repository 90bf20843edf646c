"""The designer: a trajectory re-solved and judged every time one of its points moves.

:class:`Designer` holds one design (a line, a letter or a 6-D pose path; :mod:`.kinds`), the
method that solves it and the timing that plays it. Every change (a point moved, the size,
the start pose, the timing) builds the task again, solves it with the method warm-started
from the previous solution (:meth:`ikbench.methods.base.Method.solve_from`), times it
(:func:`ikbench.core.timing.retime`) and judges it (:mod:`.criteria`), and returns an
:class:`Update`. A warm-started solution depends on the path the drag took (ours-exact's
SQP settles into a nearby local solution, up to a few degrees away after a long drag);
:meth:`Designer.settle` solves the task from scratch, as ``ikbench run`` does, and the view
calls it when a gizmo is released, so what is shown at rest is what Save writes.

When the method's solution is infeasible (``ours-exact``: a constraint that cannot hold, e.g.
a line that leaves the workspace), the fallback method's (default ``ours-lm``, the paper's
soft objective) is shown instead, and the update says why. A point out of reach is moved as
far as the arm gets, and the update says how far that is.

No viser here: the tests drive it directly, and :mod:`.view` puts it in the browser::

    designer = Designer("nico_right_arm", "ours-lm")
    update = designer.move("touch", designer.handles()["touch"] + [0, 20, 0])
    update.elapsed_s, [c.text() for c in update.criteria]
    designer.save("runs", "designed")     # runs/designed.targets.json, runs/designed/
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ikbench.core.defaults import DEFAULT_DURATION_S, DESIGN_METHOD, REFERENCE_METHOD
from ikbench.core.errors import InputError
from ikbench.core.problems import load_problem
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets
from ikbench.core.task import Task
from ikbench.core.timing import Limits, TimedPath, check_timing, retime
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.hw.limits import timing_limits
from ikbench.methods.base import Method, Solution
from ikbench.methods.registry import get_method
from ikbench.studies.run import DEFAULT_OUTPUT
from ikbench.viewer.design import save as saving
from ikbench.viewer.design.criteria import Criterion, judge_design
from ikbench.viewer.design.kinds import LetterDesign, LineDesign, PathDesign, design_for
from ikbench.viewer.design.reach import REACH_TOLERANCE_MM, Reach


@dataclass(frozen=True)
class DesignSpec:
    """What is designed, and how it is timed (every field optional).

    Attributes:
        shape: ``line`` (default) or ``letter:X``; ignored with ``problem``.
        targets: a targets file or :class:`Targets` (default: the robot's own).
        trajectory: the touch pose a line starts from (default the first); names it when
            saved.
        start_pose: (dof,) [pose units]: the start pose of a line, the pose a letter is
            placed from.
        steps: n (default: the targets' for a line, 100 for a letter).
        size_mm: a letter's height [mm] (default 300).
        problem: a 6-D pose path problem (a shipped name or a YAML file in CppFlow's format).
        duration_s: T [s] of ``constant`` and ``min-jerk``.
        timing: ``constant``, ``min-jerk`` or ``topp``.
        fallback: the method shown where the method's solution is infeasible (None: none).
    """

    shape: str = "line"
    targets: str | Path | Targets | None = None
    trajectory: str | None = None
    start_pose: Any = None
    steps: int | None = None
    size_mm: float | None = None
    problem: str | Path | None = None
    duration_s: float = DEFAULT_DURATION_S
    timing: str = "constant"
    fallback: str | None = REFERENCE_METHOD


@dataclass
class Update:
    """What one change gave.

    Attributes:
        task: the task solved.
        solution: the solution shown (poses (n+1, dof) [pose units]).
        method: the name of the method that solved it (the fallback's where it took over).
        timed: the solution under the chosen timing.
        criteria: each requirement, met or not (:class:`.criteria.Criterion`).
        elapsed_s: wall time from the change to this update: IK, solve, timing and
            judgement [s] (the browser view adds its scene update).
        message: what went differently, in words ("" when nothing did).
        reach: the IK of the moved point (None when no point moved).
        warm: True when the solve started from the previous solution, False when it
            started from scratch (as ``ikbench run`` starts).
    """

    task: Task
    solution: Solution
    method: str
    timed: TimedPath
    criteria: list[Criterion]
    elapsed_s: float
    message: str = ""
    reach: Reach | None = None
    warm: bool = False

    @property
    def poses(self) -> np.ndarray:
        """(n+1, dof) the poses shown [pose units]."""
        return self.solution.poses

    @property
    def failed(self) -> list[str]:
        """The names of the criteria not met."""
        return [c.name for c in self.criteria if not c.ok]

    @property
    def ok(self) -> bool:
        """Every criterion met."""
        return not self.failed


class Designer:
    """One design, re-solved and judged on every change (see the module doc).

    Args:
        robot: a :class:`Robot` or a robot name/config/URDF path (default NICO); with a
            problem, the problem's robot (another one is refused).
        method: the method's name or a configured :class:`Method` (default ``ours-exact``).
        spec: what is designed (:class:`DesignSpec`).
    """

    def __init__(self, robot: Robot | str | Path | None = None,
                 method: str | Method = DESIGN_METHOD, spec: DesignSpec | None = None
                 ) -> None:
        self.spec = spec = spec or DesignSpec()
        check_timing(spec.timing)
        _check_duration(spec.duration_s)
        self.design: LineDesign | LetterDesign | PathDesign
        self.problem = None
        if spec.problem is not None:

            own, task, self.problem = load_problem(spec.problem)
            if robot is not None and as_robot(robot).name != own.name:
                raise InputError(f"--robot {as_robot(robot).name}: the problem "
                                 f"{self.problem.name} is for robot {own.name!r}")
            self.robot = own
            self.design = PathDesign(own, task, self.problem.path_m)
        else:
            self.robot = as_robot(robot)
            self.design = design_for(self.robot, spec.shape, spec.targets, spec.trajectory,
                                     spec.start_pose, spec.steps, spec.size_mm)
        self.timing, self.duration_s = spec.timing, float(spec.duration_s)
        self._limits: Limits | None = None
        self.update = self.set_method(method)

    # ----- what is shown --------------------------------------------------------------------
    @property
    def kind(self) -> str:
        """``line``, ``letter`` or ``path``."""
        return self.design.kind

    def handles(self) -> dict[str, np.ndarray]:
        """The draggable points by name, base frame [mm] (:mod:`.kinds`)."""
        return self.design.handles()

    # ----- changes ----------------------------------------------------------------------------
    def move(self, handle: str, point_mm: npt.ArrayLike) -> Update:
        """Move the point ``handle`` (``touch``, ``start``, ``centre``, ``waypoint``) to
        ``point_mm`` (3,) [mm, base frame] and re-solve."""
        started = time.perf_counter()
        point = np.asarray(point_mm, dtype=float).reshape(3)
        if not np.all(np.isfinite(point)):
            raise InputError(f"{handle}: {point.tolist()} is not a finite point [mm]")
        found = self.design.move(handle, point, self.update.poses)
        return self._solve(self.update.poses, found, started)

    def set_method(self, method: str | Method) -> Update:
        """Solve with ``method`` (a name or a configured :class:`Method`) from now on, and
        solve again from scratch; the fallback stays (none when it is that method)."""
        started = time.perf_counter()
        solver = method if isinstance(method, Method) else get_method(method)()
        name = self.spec.fallback
        fallback = get_method(name)() if name and name != solver.name else None
        task = self.design.task()
        for each in (solver, fallback):
            if each is not None:
                each.check_tasks(self.robot, [task])
                each.prepare(self.robot)
        self.method, self.fallback = solver, fallback
        return self._solve(None, None, started)

    def settle(self) -> Update:
        """Solve the task shown from scratch, as ``ikbench run`` solves it (see the module
        doc); the moved point's reachability is kept."""
        started = time.perf_counter()
        return self._solve(None, self.update.reach, started)

    def move_touch(self, point_mm: npt.ArrayLike) -> Update:
        """Move a line's touch point (:meth:`move` ``"touch"``)."""
        return self.move("touch", point_mm)

    def use_start_pose(self, pose: str | npt.ArrayLike) -> Update:
        """Start a line from ``pose``: a recorded pose's name (``start`` or a touch pose's
        id of the targets) or a pose (dof,) [pose units]."""
        started = time.perf_counter()
        if not isinstance(self.design, LineDesign):
            raise InputError("a start pose is chosen for a line; a letter moves its centre")
        recorded = self.design.recorded_poses
        if isinstance(pose, str):
            if pose not in recorded:
                raise InputError(f"start pose {pose!r}: recorded poses are "
                                 f"{', '.join(recorded)}")
            pose = recorded[pose]
        self.design.use_pose(pose)
        return self._solve(self.update.poses, None, started)

    def set_size(self, size_mm: float) -> Update:
        """A letter's height [mm]."""
        started = time.perf_counter()
        if not isinstance(self.design, LetterDesign):
            raise InputError("--size: only letters are scaled")
        self.design.set_size(size_mm)
        return self._solve(self.update.poses, None, started)

    def select_waypoint(self, waypoint: int) -> None:
        """Drag waypoint ``waypoint`` of a pose path from now on."""
        if not isinstance(self.design, PathDesign):
            raise InputError("waypoints are chosen on a pose path (--problem)")
        self.design.select(waypoint)

    def set_timing(self, timing: str, duration_s: float | None = None) -> Update:
        """Play under ``timing`` (``constant``, ``min-jerk``, ``topp``) over ``duration_s``
        [s] (default: unchanged); the poses are not solved again."""
        started = time.perf_counter()
        self.timing = check_timing(timing)
        if duration_s is not None:
            self.duration_s = _check_duration(duration_s)
        update = self.update
        timed = self._timed(update.poses)
        self.update = replace(update, timed=timed,
                              criteria=self._judge(update.task, timed, update.reach),
                              elapsed_s=time.perf_counter() - started)
        return self.update

    # ----- solving ----------------------------------------------------------------------------
    def _solve(self, previous: np.ndarray | None, found: Reach | None,
               started: float | None = None) -> Update:
        started = time.perf_counter() if started is None else started
        task = self.design.task()
        initial = None
        if previous is not None and len(previous) == task.goal.steps + 1:
            initial = self.design.warm(previous, task)
        solution, method, message = self._solve_task(task, initial)
        if found is not None and not found.reachable:
            message = (f"out of reach: the arm gets within {found.distance_mm:.1f} mm of the "
                       "point; the nearest point is shown" + (f"; {message}" if message else ""))
        timed = self._timed(solution.poses)
        self.update = Update(task, solution, method, timed, self._judge(task, timed, found),
                             time.perf_counter() - started, message, found,
                             initial is not None)
        return self.update

    def _solve_task(self, task: Task, initial: np.ndarray | None
                    ) -> tuple[Solution, str, str]:
        """(solution, the method's name, a message) of the method, else the fallback's."""
        def solve(method: Method) -> Solution:
            return (method.solve(self.robot, task) if initial is None
                    else method.solve_from(self.robot, task, initial))

        solution = solve(self.method)
        if self.fallback is None or solution.info.get("feasible", True):
            return solution, self.method.name, ""
        why = solution.info.get("infeasible", "infeasible")
        return (solve(self.fallback), self.fallback.name,
                f"{self.method.name}: {why}; {self.fallback.name}'s solution is shown")

    def _timed(self, poses: np.ndarray) -> TimedPath:
        if self.timing == "topp" and self._limits is None:

            self._limits = timing_limits(self.robot)
        return retime(self.robot, poses, self.timing, duration_s=self.duration_s,
                      limits=self._limits)

    def _judge(self, task: Task, timed: TimedPath, found: Reach | None) -> list[Criterion]:
        criteria = judge_design(self.robot, task, timed)
        if found is not None:
            criteria.insert(0, Criterion("reach", found.distance_mm, REACH_TOLERANCE_MM, "mm",
                                         found.reachable, "" if found.reachable
                                         else "out of reach"))
        return criteria

    # ----- saving ----------------------------------------------------------------------------
    def save(self, output: str | Path = DEFAULT_OUTPUT, name: str = "design"
             ) -> saving.Saved:
        """Write the design's input file(s) and the run folder ``output/name/`` with
        ``ikbench run``'s own function (:mod:`.save`), with the method whose solution is
        shown; then show the saved trajectory."""
        output = Path(output)
        folder = saving.check_output(output, name)
        method = self.method if self.update.method == self.method.name else self.fallback
        assert method is not None
        design = self.design
        description = (f"designed with ikbench design ({self.kind}, {method.name}, "
                       f"timing {self.timing}, T = {self.duration_s:g} s)")
        if isinstance(design, PathDesign):
            files = saving.write_inputs(output, name, self.robot, problem=self.problem,
                                        path_m=design.moved_path_m())
            arguments = saving.run_arguments(self.robot, files, "path", None, None)
        else:
            files = saving.write_inputs(output, name, self.robot, design.saved_targets(),
                                        description=description)
            if isinstance(design, LetterDesign):
                arguments = saving.run_arguments(self.robot, files, design.shape, design.steps,
                                                 design.size_mm)
            else:
                arguments = saving.run_arguments(self.robot, files, "line",
                                                 design.targets.steps, None)
        table = saving.save_run(method, arguments, output, name, self.duration_s, self.timing)
        tid = name if isinstance(design, PathDesign) else self.update.task.name
        poses = read_trajectory_poses(folder / f"trajectory_{tid}.csv", self.robot)
        change = float(np.abs(poses - self.update.poses).max())
        solution = replace(self.update.solution, poses=poses)
        timed = self._timed(poses)
        self.update = replace(self.update, solution=solution, timed=timed, method=method.name,
                              criteria=self._judge(self.update.task, timed, None), reach=None,
                              message=f"saved to {folder}/", warm=False)
        command = saving.command_line(method, self.robot, arguments, output, name,
                                      self.duration_s, self.timing)
        return saving.Saved(files, folder, table, command, change)


def _check_duration(duration_s: float) -> float:
    if not (isinstance(duration_s, (int, float)) and np.isfinite(duration_s)
            and duration_s > 0):
        raise InputError(f"--duration {duration_s!r}; give a positive number of seconds")
    return float(duration_s)
