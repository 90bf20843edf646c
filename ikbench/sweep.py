"""Weight sweep: the paper's objective with other weights, solved by ours-lm, on the targets.

:func:`sweep` takes a grid of loss weights (``{"L0": [1, 10, 100], "L1": [5, 50]}``; terms not
in the grid keep the paper's weights), solves every setting on every target in one batched
``ours-lm`` call and measures each trajectory with :mod:`ikbench.metrics`. The paper's own
weights are always one of the settings. Per setting, the figures are averaged over the
targets (errors: worst target). A setting is *Pareto-optimal* when no other setting has both a
smaller mean line distance and a smaller mean pointing deviation.

Output (:func:`write`): ``sweep.csv`` (one row per setting), ``sweep_trajectories.csv`` (one
row per setting and target), ``pareto.png`` (line distance vs pointing deviation, smoothness as
colour), ``sweep.json`` (settings, provenance) and ``sweep.md`` (findings).
"""

from __future__ import annotations

import itertools
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.errors import InputError
from ikbench.io import atomic_savefig, atomic_write_csv, atomic_write_text
from ikbench.losses import PAPER_WEIGHTS, TERMS, objective
from ikbench.metrics import trajectory_metrics
from ikbench.provenance import provenance
from ikbench.report import markdown_table
from ikbench.robot import load_robot
from ikbench.targets import Targets, load_targets
from ikbench.task import line_tasks

#: Per-trajectory figures averaged (mean) or taken at the worst target (max) per setting.
MEAN_COLUMNS = ("line_distance_mean_mm", "pointing_deviation_mean_deg",
                "mean_sq_joint_step_deg2", "loss", "paper_loss", "iterations")
MAX_COLUMNS = ("line_distance_std_mm", "start_point_error_mm", "end_point_error_mm",
               "end_pose_error_deg", "max_joint_step_deg")


def parse_grid(items: list[str] | str) -> dict[str, list[float]]:
    """``["c0=1,10,100", "c1=5,50"]`` -> ``{"L0": [1, 10, 100], "L1": [5, 50]}``."""
    items = [items] if isinstance(items, str) else list(items or [])
    if not items:
        raise InputError("--weight: give at least one term and its values, e.g. c0=1,10,100")
    grid = {}
    for item in items:
        key, sep, values = str(item).partition("=")
        term = key.strip().upper().replace("C", "L", 1)
        try:
            numbers = [float(v) for v in values.split(",")] if sep else []
        except ValueError:
            numbers = []
        if term not in TERMS or not numbers or not all(np.isfinite(v) and v >= 0
                                                        for v in numbers):
            raise InputError(f"--weight: {item!r} is not term=v1,v2,... with term in c0..c6 "
                             "(or L0..L6) and values finite numbers >= 0, e.g. c0=1,10,100")
        if term in grid:
            raise InputError(f"--weight: term {key.strip()!r} is given twice")
        grid[term] = list(dict.fromkeys(numbers))
    return grid


def setting_label(weights: dict, grid_terms) -> str:
    """``"c0=100,c1=50"`` for the grid's terms of a weights dict."""
    return ",".join(f"c{t[1]}={weights[t]:g}" for t in grid_terms)


def grid_settings(grid: dict[str, list[float]], base: dict | None = None) -> list[dict]:
    """Every combination of the grid on top of ``base`` (the paper's), paper's weights first."""
    base = dict(base or PAPER_WEIGHTS)
    out = [dict(PAPER_WEIGHTS)]
    for values in itertools.product(*grid.values()):
        weights = {**base, **dict(zip(grid, values))}
        if weights not in out:
            out.append(weights)
    return out


@dataclass
class SweepResult:
    """Per-setting summary, per-trajectory rows, and the record (grid, provenance)."""

    settings: pd.DataFrame
    trajectories: pd.DataFrame
    record: dict


def sweep(grid: dict[str, list[float]], *, targets: str | Path | Targets | None = None,
          only: str | None = None, steps: int | None = None, lm_settings=None,
          progress: bool = True) -> SweepResult:
    """Solve the targets for every weight setting of ``grid`` (see the module docstring)."""
    from ikbench.methods.ours_lm import LMSettings, solve_batch

    robot = load_robot()
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    targets = targets.select(only).with_steps(steps)
    tasks = line_tasks(robot, targets)
    settings = grid_settings(grid)
    all_tasks = [task for _ in settings for task in tasks]
    all_weights = [w for w in settings for _ in tasks]
    if progress:
        print(f"[sweep] {len(settings)} weight settings x {len(tasks)} targets: one batched "
              f"ours-lm solve of {len(all_tasks)} trajectories", file=sys.stderr, flush=True)
    result = solve_batch(robot, all_tasks, lm_settings or LMSettings(), weights=all_weights)
    if progress:
        print(f"[sweep] solved in {result.duration_s:.2f} s; measuring", file=sys.stderr,
              flush=True)
    rows = []
    for k, (task, weights) in enumerate(zip(all_tasks, all_weights)):
        poses = result.poses_deg[k]
        metrics = trajectory_metrics(robot, task, poses)
        rows.append({"setting": setting_label(weights, grid), "paper_weights":
                     weights == PAPER_WEIGHTS, "trajectory": task.name,
                     **{f"c{t[1]}": weights[t] for t in TERMS},
                     "loss": float(result.loss[k]),
                     "paper_loss": objective(robot, task, poses)[0],
                     "iterations": int(result.iterations[k]),
                     "converged": bool(result.converged[k]),
                     "within_limits": robot.within_limits(poses), **metrics})
    per_traj = pd.DataFrame(rows)
    record = {"grid": {f"c{t[1]}": v for t, v in grid.items()}, "targets": targets.source,
              "trajectories": targets.ids, "steps": targets.steps,
              "solve_wall_time_s": result.duration_s, "trajectories_solved": len(all_tasks),
              **provenance()}
    return SweepResult(summarise(per_traj), per_traj, record)


def summarise(per_traj: pd.DataFrame) -> pd.DataFrame:
    """One row per setting: means / worst values over the targets, and the Pareto flag."""
    weight_cols = [f"c{t[1]}" for t in TERMS]
    agg = {**{c: "first" for c in weight_cols + ["paper_weights"]},
           **{c: "mean" for c in MEAN_COLUMNS}, **{c: "max" for c in MAX_COLUMNS},
           "converged": "all", "within_limits": "all"}
    table = per_traj.groupby("setting", sort=False).agg(agg).reset_index()
    x = table["line_distance_mean_mm"].to_numpy()
    y = table["pointing_deviation_mean_deg"].to_numpy()
    dominated = [bool(np.any((x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i]))))
                 for i in range(len(table))]
    table["pareto"] = ~np.array(dominated)
    return table


def plot_pareto(table: pd.DataFrame, title: str = ""):
    """Line distance vs pointing deviation per setting, smoothness as colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5))
    smooth = table["mean_sq_joint_step_deg2"]
    points = ax.scatter(table["line_distance_mean_mm"], table["pointing_deviation_mean_deg"],
                        c=smooth, cmap="viridis", s=36, zorder=3)
    front = table[table["pareto"]].sort_values("line_distance_mean_mm")
    ax.plot(front["line_distance_mean_mm"], front["pointing_deviation_mean_deg"], "-",
            color="0.5", lw=1, zorder=2, label="Pareto front")
    for _, row in front.iterrows():
        ax.annotate(row["setting"], (row["line_distance_mean_mm"],
                                     row["pointing_deviation_mean_deg"]),
                    fontsize=6, xytext=(4, 3), textcoords="offset points")
    paper = table[table["paper_weights"]]
    ax.scatter(paper["line_distance_mean_mm"], paper["pointing_deviation_mean_deg"],
               marker="*", s=260, facecolors="none", edgecolors="red", zorder=4,
               label="the paper's weights")
    ax.set_xscale("log")
    ax.margins(x=0.25)
    ax.set_xlabel("line distance, mean over poses and targets [mm] (log)")
    ax.set_ylabel("pointing deviation, mean over poses and targets [deg]")
    fig.colorbar(points, ax=ax, label="smoothness: mean squared joint step [deg$^2$]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title or "weight sweep (ours-lm): accuracy on the line vs pointing")
    return fig


def findings(table: pd.DataFrame) -> list[str]:
    """Sentences saying what other weights achieve against the paper's and at what cost."""
    paper = table[table["paper_weights"]].iloc[0]

    def describe(row) -> str:
        return (f"`{row['setting']}`: line distance {row['line_distance_mean_mm']:.3g} mm, "
                f"pointing deviation {row['pointing_deviation_mean_deg']:.2f} deg, "
                f"mean squared joint step {row['mean_sq_joint_step_deg2']:.2f} deg^2, "
                f"worst end point error {row['end_point_error_mm']:.3f} mm")

    best_line = table.loc[table["line_distance_mean_mm"].idxmin()]
    best_point = table.loc[table["pointing_deviation_mean_deg"].idxmin()]
    cost = best_line["pointing_deviation_mean_deg"] - paper["pointing_deviation_mean_deg"]
    closer = paper["line_distance_mean_mm"] / best_line["line_distance_mean_mm"]
    lines = [f"- The paper's weights ({describe(paper)}). This is the optimum of the paper's "
             "objective itself, not an optimiser's shortfall.",
             f"- Smallest line distance: {describe(best_line)}: {closer:.0f}x closer to the "
             f"line, at a cost of {cost:+.2f} deg in pointing.",
             f"- Smallest pointing deviation: {describe(best_point)}."]
    no_worse = table[table["pointing_deviation_mean_deg"]
                     <= paper["pointing_deviation_mean_deg"] + 1e-9]
    if len(no_worse):
        best = no_worse.loc[no_worse["line_distance_mean_mm"].idxmin()]
        lines.append(f"- Best line distance with pointing no worse than the paper's weights: "
                     f"{describe(best)}.")
    within_1 = table[table["pointing_deviation_mean_deg"]
                     <= paper["pointing_deviation_mean_deg"] + 1.0]
    best = within_1.loc[within_1["line_distance_mean_mm"].idxmin()]
    lines.append(f"- Best line distance for at most 1 deg more pointing deviation: "
                 f"{describe(best)}.")
    return lines


def write(result: SweepResult, output: str | Path) -> Path:
    """Write sweep.csv, sweep_trajectories.csv, pareto.png, sweep.json and sweep.md."""
    out = Path(output)
    atomic_write_csv(out / "sweep.csv", result.settings, float_format="%.6g")
    atomic_write_csv(out / "sweep_trajectories.csv", result.trajectories, float_format="%.6g")
    atomic_write_text(out / "sweep.json", json.dumps(result.record, indent=2) + "\n")
    atomic_savefig(out / "pareto.png", plot_pareto(result.settings))
    atomic_write_text(out / "sweep.md", markdown(result))
    return out / "sweep.csv"


def markdown(result: SweepResult) -> str:
    """sweep.md: the findings, the Pareto-optimal settings, and every setting."""
    rec, table = result.record, result.settings
    cols = ["setting", "line_distance_mean_mm", "pointing_deviation_mean_deg",
            "mean_sq_joint_step_deg2", "max_joint_step_deg", "end_point_error_mm",
            "end_pose_error_deg", "loss", "paper_loss", "converged", "pareto"]
    digits = {"loss": 3, "paper_loss": 3, "end_point_error_mm": 3, "end_pose_error_deg": 3,
              "line_distance_mean_mm": 3}
    grid = "; ".join(f"{k} = {', '.join(f'{v:g}' for v in vals)}"
                     for k, vals in rec["grid"].items())
    ordered = table.sort_values("line_distance_mean_mm")
    return "\n".join([
        "# Weight sweep", "",
        f"The paper's objective (L0..L6, cm and motor degrees) minimised by `ours-lm` for every "
        f"combination of {grid} (other weights the paper's: c0=1, c1=50, c2=5, c3=100, c4=10, "
        f"c5=200, c6=1), on targets {rec['targets']} (trajectories "
        f"{', '.join(rec['trajectories'])}, n = {rec['steps']}). {rec['trajectories_solved']} "
        f"trajectories in one batched solve of {rec['solve_wall_time_s']:.2f} s. Figures are "
        "means over the targets (errors and max joint step: the worst target); `loss` is the "
        "setting's own objective, `paper_loss` the paper's objective of the same poses.", "",
        "## Findings", "", *findings(table), "",
        "![Pareto](pareto.png)", "",
        "## Pareto-optimal settings (line distance vs pointing deviation)", "",
        markdown_table(ordered[ordered["pareto"]][cols], digits), "",
        "## Every setting", "", markdown_table(ordered[cols], digits), "",
        f"Produced by ikbench (git {rec['git_revision']}) on {rec['cpu']}, "
        f"{rec['created_utc']}.", ""])
