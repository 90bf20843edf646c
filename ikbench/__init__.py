"""ikbench: generate robot-arm trajectories of a required shape and compare kinematics methods.

The public API, in a few names::

    import ikbench
    robot = ikbench.load_robot("nico_right_arm")        # or a config .toml / URDF + end frame
    targets = ikbench.load_targets(robot=robot)         # the robot's start and touch poses
    tasks = ikbench.build_tasks(robot, targets)         # goal points [mm] and directions
    solution = ikbench.get_method("ours-lm")().solve(robot, tasks[0])
    metrics = ikbench.trajectory_metrics(robot, tasks[0], solution.poses)
    table = ikbench.run("ours-lm", robot=robot, output=None)   # a pandas DataFrame
    advice = ikbench.recommend(robot, budget_ms=1.0, minutes=2)  # which IK solver, and why
    q, ok = ikbench.solve_pose(robot, T, q0)    # ours-lm's IK of a frame T (4, 4) [m] from q0

Poses are in the robot's units (motor degrees for NICO; joint degrees, mm for prismatic
joints, otherwise), reports in millimetres and degrees. Names are imported on first use, so
``import ikbench`` is quick. The layout (``core``, ``methods``, ``baselines``, ``runtime``,
``render``, ``studies``, ``hw``, ``paper``, ``viewer``, ``cli``) and its rules:
docs/contributing.md.
"""

from __future__ import annotations

import importlib
import os as _os
from typing import TYPE_CHECKING, Any

from ikbench.render.sections import name_report_section as _name_report_section

__version__ = "0.4.0"

# The paper's sections beside the studies' reports (its Table 1 or 2 beside a run on its task,
# its claims beside an ablation): named here, where the package is put together, so that render
# and the studies, below the paper, never name it; imported when such a report is written.
_name_report_section("run", "ikbench.paper.report_tables:run_section")
_name_report_section("ablation", "ikbench.paper.ablation_claims:ablation_section")

if _os.environ.get("IKBENCH_MODULES_LOG"):  # ``reproduce --all`` records the code a study ran
    from ikbench.core import module_log as _module_log

    _module_log.install()

#: public name -> module that defines it
_EXPORTS = {
    "IkbenchError": "ikbench.core.errors", "InputError": "ikbench.core.errors",
    "SolverError": "ikbench.core.errors",
    "Robot": "ikbench.core.robot", "load_robot": "ikbench.core.robot",
    "Targets": "ikbench.core.targets", "load_targets": "ikbench.core.targets",
    "Task": "ikbench.core.task", "build_tasks": "ikbench.core.task",
    "line_task": "ikbench.core.task", "line_tasks": "ikbench.core.task",
    "trajectory_metrics": "ikbench.core.metrics", "shape_metrics": "ikbench.core.metrics",
    "Method": "ikbench.methods.base", "Solution": "ikbench.methods.base",
    "option": "ikbench.methods.options",
    "get_method": "ikbench.methods.registry", "available_methods": "ikbench.methods.registry",
    "method_status": "ikbench.methods.registry",
    "run": "ikbench.studies.run",
    "solve_pose": "ikbench.methods.ours_lm.api",
    "recommend": "ikbench.studies.recommend", "Recommendation": "ikbench.studies.recommend",
}
__all__ = ["IkbenchError", "InputError", "Method", "Recommendation", "Robot", "Solution",
           "SolverError", "Targets", "Task", "available_methods", "build_tasks", "get_method",
           "line_task", "line_tasks", "load_robot", "load_targets", "method_status", "option",
           "recommend", "run", "shape_metrics", "solve_pose", "trajectory_metrics"]

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from ikbench.core.errors import IkbenchError, InputError, SolverError
    from ikbench.core.metrics import shape_metrics, trajectory_metrics
    from ikbench.core.robot import Robot, load_robot
    from ikbench.core.targets import Targets, load_targets
    from ikbench.core.task import Task, build_tasks, line_task, line_tasks
    from ikbench.methods.base import Method, Solution
    from ikbench.methods.options import option
    from ikbench.methods.ours_lm.api import solve_pose
    from ikbench.methods.registry import available_methods, get_method, method_status
    from ikbench.studies.recommend import Recommendation, recommend
    from ikbench.studies.run import run


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ikbench' has no attribute {name!r}")

