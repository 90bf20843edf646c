"""Checking ``robot init``'s default targets under the task contract (issue 64).

:func:`check_targets` solves each touch pose's line task with
:data:`ikbench.core.defaults.TARGET_CHECK_METHOD` (ours-exact: the line and the fixed poses as
hard constraints) and judges the trajectory as ``compare`` does
(:func:`ikbench.core.metrics.contract_metrics`, :func:`ikbench.core.contract.judge`, the
robot's :func:`ikbench.core.contract.contract_for`). A target it does not solve is replaced by
the next pose :func:`ikbench.core.robot_init.touch_pose_draws` gives, at most
:data:`MAX_TRIES` solves in all; the targets file's ``description`` says how many were
replaced and how many are still unsolved. A solve proves a target feasible; a failed one does
not prove it infeasible (the solver may miss), so "unsolved", not "infeasible".
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ikbench.core.contract import judge
from ikbench.core.defaults import TARGET_CHECK_METHOD
from ikbench.core.metrics import contract_metrics
from ikbench.core.robot import Robot
from ikbench.core.robot_init import reach_of, targets_description, touch_pose_draws
from ikbench.core.targets import Targets
from ikbench.core.task import line_tasks
from ikbench.methods.registry import get_method

#: Solves at most, the first targets' and the replacements' together (7 targets: 7 spare).
MAX_TRIES = 14


@dataclass
class TargetCheck:
    """What :func:`check_targets` found.

    Attributes:
        touches: the touch poses kept [pose units], as many as given.
        solved: per kept pose, whether the method's trajectory met every criterion.
        replaced: how many of the first draws were replaced.
        failed: criterion names that failed, per kept pose still unsolved (by index).
        solves: how many solves ran.
        seconds: the check's wall time [s] (the method's first call's compilation included).
    """

    touches: list[np.ndarray]
    solved: list[bool]
    replaced: int = 0
    failed: dict[int, list[str]] = field(default_factory=dict)
    solves: int = 0
    seconds: float = 0.0

    def sentence(self) -> str:
        """What the check found, for the targets file's description."""
        unsolved = self.solved.count(False)
        return (f"checked under the task contract by {TARGET_CHECK_METHOD} ({self.solves} "
                f"solves): {self.replaced} of the first {len(self.touches)} draws replaced, "
                + ("every target solved" if not unsolved else
                   f"{unsolved} still unsolved ({', '.join(str(k + 1) for k in self.failed)})"))


def _solved(robot: Robot, solver: Any, start: np.ndarray, pose: np.ndarray, steps: int
            ) -> tuple[bool, list[str]]:
    """(met every criterion, the failed ones) of ``solver``'s line from start to pose."""
    targets = Targets(joint_names=tuple(robot.joint_names), start_pose=start,
                      touch_poses={"1": pose}, steps=steps, source="robot init")
    task = line_tasks(robot, targets)[0]
    contract = task.required.contract
    assert contract is not None  # line_tasks gives every task one
    poses = np.asarray(solver.solve(robot, task).poses, float)
    verdict = judge(contract, contract_metrics(robot, task, poses, contract))
    return all(verdict.values()), [k for k, ok in verdict.items() if not ok]


def check_targets(made: dict[str, Any], max_tries: int = MAX_TRIES) -> TargetCheck:
    """Check (and replace) the touch poses of :func:`ikbench.core.robot_init.init_robot`'s
    result ``made`` (see the module docstring); ``made["targets"]`` is updated in place."""
    began = time.perf_counter()
    robot, start, seed = made["robot"], made["start"], made["seed"]
    document = made["targets"]
    steps = int(document["steps"])
    touches = [np.array(p, float) for p in document["targets"].values()]
    solver = get_method(TARGET_CHECK_METHOD)()
    spare = itertools.islice(touch_pose_draws(robot, start, seed), len(touches), None)
    check = TargetCheck(touches=[], solved=[])
    for pose in touches:
        ok, failed = _solved(robot, solver, start, pose, steps)
        check.solves += 1
        while not ok and check.solves + len(touches) - len(check.touches) - 1 < max_tries:
            candidate = next(spare, None)
            if candidate is None:
                break
            ok_next, failed_next = _solved(robot, solver, start, candidate, steps)
            check.solves += 1
            if ok_next:
                pose, ok, failed = candidate, True, []
                check.replaced += 1
        if not ok:
            check.failed[len(check.touches)] = failed
        check.touches.append(pose)
        check.solved.append(ok)
    check.seconds = time.perf_counter() - began
    document["targets"] = {str(k + 1): [float(x) for x in pose]
                           for k, pose in enumerate(check.touches)}
    document["description"] = targets_description(made["name"], len(check.touches), seed,
                                                  reach_of(start, check.touches),
                                                  check.sentence())
    return check
