"""The figure of the methods page: ours-lm against ours-exact on one paper target.

Three panels per step of the trajectory: the fingertip's distance from the line [mm], the
pointing deviation from the line's direction [deg] (the judged part shaded), and the largest
joint step per segment [motor deg] against the contract's speed limit. Regenerate with::

    python -m ikbench.render.exact_figure docs/ours_exact.png [--target 7]
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.io import atomic_savefig
from ikbench.core.metrics import line_distances_mm, pointing_deviations_deg
from ikbench.core.robot import load_robot
from ikbench.core.targets import load_targets
from ikbench.core.task import line_tasks
from ikbench.methods.ours_exact import OursExact
from ikbench.methods.ours_lm import OursLM
from ikbench.render.arm_plots import matplotlib_pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: Distances below this [mm] are drawn at it (the log axis cannot show 0).
FLOOR_MM = 1e-9


def exact_figure(robot: Robot, task: Task, poses_by_method: dict[str, np.ndarray]) -> Figure:
    """The three-panel figure for ``task`` and {method name: poses (n+1, dof)}."""

    plt = matplotlib_pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    steps = np.arange(task.goal.steps + 1)
    contract = task.required.contract
    for name, poses in poses_by_method.items():
        fk = robot.fk(poses)
        distance = line_distances_mm(fk.point_mm, task.goal.start_point_mm, task.goal.end_point_mm)
        axes[0].semilogy(steps, np.maximum(distance, FLOOR_MM), label=name)
        axes[1].plot(steps, pointing_deviations_deg(fk.direction, task.goal.directions),
                     label=name)
        axes[2].plot(steps[1:], np.max(np.abs(np.diff(poses, axis=0)), axis=1), label=name)
    axes[0].set_title("fingertip distance from the line")
    axes[0].set_ylabel(f"[mm] (log; below {FLOOR_MM:g} drawn at it)")
    axes[1].set_title("pointing deviation from the line")
    axes[1].set_ylabel("[deg]")
    if contract is not None:
        axes[1].axvspan(contract.judged_from(task.goal.steps), task.goal.steps, color="0.9",
                        label="judged part", zorder=0)
        limit = contract.max_step(task.goal.steps)
        if limit is not None:
            axes[2].axhline(float(np.min(limit)), color="red", lw=1, ls="--",
                            label=f"speed limit (T = {contract.duration_s:g} s)")
    axes[2].set_title("largest joint step per segment")
    axes[2].set_ylabel(f"[{robot.pose_unit}]")
    for ax in axes:
        ax.set_xlabel("step i")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"trajectory {task.name}: the paper's weighted objective (ours-lm) against "
                 "hard constraints (ours-exact)", fontsize=10)
    fig.tight_layout()
    return fig


def main(argv: list[str] | None = None) -> int:
    """Write the figure for one of NICO's paper targets."""

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", help="PNG file to write")
    parser.add_argument("--target", default="7", help="paper target id (default 7)")
    args = parser.parse_args(argv)
    robot = load_robot()
    tasks = {t.name: t for t in line_tasks(robot, load_targets(None, robot))}
    task = tasks[args.target]
    poses = {cls.name: cls().solve(robot, task).poses for cls in (OursLM, OursExact)}
    atomic_savefig(args.output, exact_figure(robot, task, poses))
    print(f"written to {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
