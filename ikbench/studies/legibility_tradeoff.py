"""The legibility trade-off of ours-exact (ikbench's extension, not the paper's method).

:func:`run` (a :class:`LegibilitySpec`; :func:`legibility_tradeoff` builds one) solves one
line target with ``ours-exact`` for a sweep of
``--exact-legibility-weight`` W (W = 0 is the paper's objective) and measures, for each W,
the pointing observer's legibility, the predictability, the largest line distance, the
pointing deviation over the judged part and the solve time. ours-exact holds every fingertip
point on the line as a constraint, so the line distance stays within its feasibility
tolerance (``--exact-feasibility-tolerance``, 1e-6 mm) for every W: what the term trades is
the pointing (mostly early in the motion, where the paper does not judge it) and, for large W,
smoothness. :func:`plot_tradeoff` draws legibility against the pointing deviation and the line
distance, each point labelled by its weight; :meth:`LegibilityResult.write` writes the curve
and the figure.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.legibility import (
    constant_times_s,
    goal_points_mm,
    legibility_metrics,
    true_goal_index,
)
from ikbench.core.task import Task, line_tasks
from ikbench.methods.ours_exact import OursExact
from ikbench.render.arm_plots import matplotlib_pyplot

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.targets import Targets

#: The default sweep of W (c1, the pointing weight, is 2000: W of its order moves pointing).
WEIGHTS = (0.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0)
#: The line distance every W keeps within [mm]: ours-exact's feasibility tolerance (1e-6 mm,
#: the largest coordinate of a point's error) times sqrt 3 (the distance it allows).
LINE_BOUND_MM = 1e-6 * 3 ** 0.5
#: The files :meth:`LegibilityResult.write` writes into its folder.
CSV, PNG = "legibility_tradeoff.csv", "legibility_tradeoff.png"
#: The curve's columns, in order.
COLUMNS = ["weight", "pointing_legibility", "position_legibility", "predictability",
           "line_distance_max_mm", "pointing_deviation_max_deg", "pointing_deviation_rms_deg",
           "early_pointing_deviation_max_deg", "converged", "iterations", "time_s"]


def check_weights(weights: Sequence[float | str]) -> list[float]:
    """The weights as floats; InputError for an empty list, a negative or non-finite one."""
    out = []
    for w in weights:
        try:
            value = float(w)
        except (TypeError, ValueError):
            raise InputError(f"--weights: {w!r} is not a number") from None
        if not np.isfinite(value) or value < 0:
            raise InputError(f"--weights: {w!r} must be a number >= 0")
        out.append(value)
    if not out:
        raise InputError("--weights: give at least one weight")
    return out


@dataclass(frozen=True)
class LegibilitySpec:
    """A legibility trade-off: the robot, its targets, the target's id (None: the first),
    the weights W, the goal set's targets (None: ``targets``, every id) and the motion's
    duration [s] (legibility is independent of it: times only scale). :meth:`validate`
    checks it; :func:`run` runs it (:mod:`ikbench.studies.shape`)."""

    robot: Robot
    targets: Targets
    target_id: str | None = None
    weights: tuple[float, ...] = WEIGHTS
    goals: Targets | None = None
    duration_s: float = 1.0

    @property
    def target(self) -> str:
        """The target's id: ``target_id``, else the first of the targets file."""
        return self.target_id if self.target_id is not None else self.targets.ids[0]

    @cached_property
    def problem(self) -> tuple[Task, np.ndarray, int, np.ndarray]:
        """The target's line task, the goals with the true one, its index and the goal set's
        points [mm] (built once: :meth:`validate` checks them, :func:`run` solves them)."""
        task = {t.name: t for t in line_tasks(self.robot, self.targets)}[self.target]
        _, goals_mm = goal_points_mm(self.robot, self.goals if self.goals is not None
                                     else self.targets)
        all_goals, true = true_goal_index(goals_mm, task.goal.end_point_mm)
        return task, all_goals, true, goals_mm

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a bad weight, a target not in the
        targets file, or a goal set without a goal other than the target's touch point."""
        check_weights(self.weights)
        if self.target_id is not None and self.target_id not in self.targets.touch_poses:
            raise InputError(f"--target: {self.target_id!r} is not a target of the targets "
                             f"file ({', '.join(self.targets.ids)})")
        if len(self.problem[1]) < 2:
            raise InputError("the legibility term needs a goal set with a goal other than the "
                             "target's touch point (--goals)")


@dataclass
class LegibilityResult:
    """What :func:`run` measured: ``curve`` (the :data:`COLUMNS`, one row per weight), the
    robot's name and the target's id."""

    curve: pd.DataFrame
    robot_name: str
    target: str

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/legibility_tradeoff.csv`` and ``.png`` (:func:`plot_tradeoff`);
        return ``folder``."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        self.curve.to_csv(out / CSV, index=False)
        plot_tradeoff(self.curve, out / PNG,
                      f"{self.robot_name}, target {self.target}: ours-exact + ikbench's "
                      "legibility term (not the paper's method)")
        return out


def legibility_tradeoff(robot: Robot, targets: Targets, target_id: str | None = None,
                        weights: Sequence[float | str] = WEIGHTS,
                        goals: Targets | None = None, duration_s: float = 1.0) -> pd.DataFrame:
    """The :data:`COLUMNS` of one target (``target_id``, default the first touch pose of
    ``targets``) solved by ours-exact for each weight; ``goals``: the goal set's targets
    (default ``targets``, every id). Legibility is independent of ``duration_s`` (times
    only scale). Builds a :class:`LegibilitySpec`, validates it and returns
    ``run(spec).curve``."""
    spec = LegibilitySpec(robot, targets, target_id, tuple(check_weights(weights)), goals,
                          duration_s)
    spec.validate()
    return run(spec).curve


def run(spec: LegibilitySpec) -> LegibilityResult:
    """Run the trade-off ``spec`` (validated: :meth:`LegibilitySpec.validate`); nothing is
    written (:meth:`LegibilityResult.write` writes it)."""
    robot = spec.robot
    task, all_goals, true, goals_mm = spec.problem
    judged = (task.required.contract.judged_from(task.goal.steps)
              if task.required.contract is not None else 0)
    rows = []
    for w in spec.weights:
        method = OursExact(legibility_weight=w, legibility_goals_mm=goals_mm)
        started = time.perf_counter()
        solution = method.solve(robot, task)
        elapsed = time.perf_counter() - started
        fk = robot.fk(solution.poses)
        metrics = legibility_metrics(fk.point_mm, fk.direction, solution.poses, all_goals,
                                     true, constant_times_s(len(solution.poses),
                                                            spec.duration_s))
        cos = np.clip(np.sum(fk.direction * task.goal.directions, axis=1), -1.0, 1.0)
        deviation = np.degrees(np.arccos(cos))
        rows.append({
            "weight": w, "pointing_legibility": metrics["pointing_legibility"],
            "position_legibility": metrics["position_legibility"],
            "predictability": metrics["predictability"],
            "line_distance_max_mm": float(np.linalg.norm(
                fk.point_mm - task.goal.points_mm, axis=1).max()),
            "pointing_deviation_max_deg": float(deviation[judged:].max()),
            "pointing_deviation_rms_deg": float(np.sqrt(np.mean(deviation[judged:] ** 2))),
            "early_pointing_deviation_max_deg": float(deviation[1:max(judged, 2)].max()),
            "converged": bool(solution.converged), "iterations": int(solution.iterations),
            "time_s": elapsed})
    return LegibilityResult(pd.DataFrame(rows, columns=COLUMNS), robot.name, spec.target)


def plot_tradeoff(curve: pd.DataFrame, path: str | Path, title: str = "") -> Path:
    """Two panels: pointing legibility against the pointing deviation over the judged part
    (the trade ours-exact makes) and against the largest line distance (held by the
    constraints), each point labelled by its weight W; written to ``path`` (PNG)."""
    plt = matplotlib_pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    panels = (("pointing_deviation_rms_deg",
               "pointing deviation over the judged part, RMS [deg]"),
              ("line_distance_max_mm", "largest line distance [mm]"))
    for ax, (column, label) in zip(axes, panels):
        # the line distances are rounding residues: points, not a curve
        style = "-o" if column != "line_distance_max_mm" else "o"
        ax.plot(curve[column], curve["pointing_legibility"], style, color="tab:blue")
        for _, row in curve.iterrows():
            ax.annotate(f"W={row['weight']:g}", (row[column], row["pointing_legibility"]),
                        textcoords="offset points", xytext=(6, 4), fontsize=9)
        ax.set_xlabel(label)
        ax.set_ylabel("pointing legibility (Dragan, f = T - t)")
        ax.grid(alpha=0.3)
    axes[1].axvline(LINE_BOUND_MM, color="tab:red", linestyle="--",
                    label=f"bound {LINE_BOUND_MM:.2g} mm (feasibility tolerance x sqrt 3)")
    axes[1].set_xlim(0.0, 1.25 * LINE_BOUND_MM)
    axes[1].legend(loc="lower right", fontsize=9)
    axes[1].ticklabel_format(axis="x", style="sci", scilimits=(-3, 3))
    axes[0].set_title("what the term trades: pointing")
    axes[1].set_title("line distance: held by ours-exact's constraints")
    fig.suptitle(title or "ours-exact with ikbench's legibility term (not the paper's method)")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
