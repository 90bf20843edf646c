"""``ikbench compare``: every method on the same robot and tasks, timed the same way, one table.

:func:`compare` runs each method ``repeat`` times on every task through the study harness
(:mod:`ikbench.studies.harness`: the harness's clock, failures kept as rows), writes each
method's last repetition as a run folder (``DIR/compare/<method>/``, as ``ikbench run`` writes
it, so every report and figure works on it) and measures every trajectory with
:mod:`ikbench.core.metrics` from the CSVs written. A method that is not installed, or whose
solves fail, is a row saying so.

Output ``DIR/compare/``: ``results.csv`` (long form: one row per method, robot, task and
trajectory), ``leaderboard.md`` (the methods ranked, with ratios against the reference
method measured in the same run), ``pareto.png`` (time vs accuracy, one colour per library),
``run.json`` (settings, library versions, machine) and the per-method folders.

Success is judged against stated tolerances (:data:`TOLERANCES`): the solve returned, the
poses stay within the limits, the trajectory ends at the touch pose and starts at the start
point, and the end point follows the line on average.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_savefig, atomic_write_csv, atomic_write_text, staged_folder
from ikbench.core.provenance import library_versions, provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, select_targets
from ikbench.core.task import line_tasks
from ikbench.methods.base import Method
from ikbench.methods.registry import method_status
from ikbench.studies.executors import LocalExecutor, portable_robot
from ikbench.studies.harness import Progress, solve_tasks
from ikbench.studies.report import markdown_table
from ikbench.studies.run import write_run

#: Success tolerances (all must hold): end pose [deg, max abs per joint], start point [mm],
#: mean distance from the line [mm].
TOLERANCES = {"end_pose_error_deg": 0.5, "start_point_error_mm": 1.0,
              "line_distance_mean_mm": 5.0}
#: Metric columns of results.csv, from ikbench.core.metrics.
METRICS = ["line_distance_mean_mm", "line_distance_std_mm", "pointing_deviation_mean_deg",
           "pointing_deviation_std_deg", "start_point_error_mm", "end_point_error_mm",
           "start_pose_error_deg", "end_pose_error_deg", "max_joint_step_deg",
           "mean_sq_jerk_deg2", "mean_sq_joint_step_deg2"]
#: The columns of results.csv, in order.
COLUMNS = ["method", "library", "library_version", "robot", "task", "trajectory", "status",
           "success", "failure", "time_median_s", "time_min_s", "time_max_s", "repetitions",
           "iterations", "within_limits", *METRICS]


@dataclass
class CompareResult:
    """What :func:`compare` measured: ``results`` (results.csv), ``leaderboard`` (one row per
    method) and the ``record`` written as run.json."""

    results: pd.DataFrame
    leaderboard: pd.DataFrame
    record: dict


def parse_methods(text: str | list[str]) -> list[str]:
    """``"ours-lm,ikpy"`` -> names, each registered (available or not); InputError otherwise."""
    names = [n.strip() for n in (text.split(",") if isinstance(text, str) else text)
             if n.strip()]
    if not names:
        raise InputError(f"--methods: {text!r} names no method")
    known = method_status()
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InputError(f"--methods: unknown method(s) {', '.join(map(repr, unknown))}; "
                         f"registered: {', '.join(known)} (ikbench methods lists them)")
    return list(dict.fromkeys(names))


def check_repeat(repeat) -> int:
    """``--repeat``: an integer >= 1."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise InputError(f"--repeat: {repeat!r} must be an integer >= 1")
    return repeat


def compare(methods: list[str] | str, *, robot: Robot | str | None = None,
            targets: str | Path | Targets | None = None, only: str | None = None,
            steps: int | None = None, repeat: int = 5, warmup: int = 1,
            output: str | Path | None = "runs",
            reference: str | None = None, progress: bool = True,
            solvers: dict[str, Method] | None = None, executor=None) -> CompareResult:
    """Run every method on every task ``repeat`` times; write ``output/compare/``.

    Args:
        methods: registered method names (list or comma-separated); unavailable ones become
            rows saying why.
        robot: the robot or its name/config/URDF (default NICO's right arm).
        targets: a targets file, :class:`Targets`, or None for the robot's own.
        only: trajectory ids to keep (``"1,3"``).
        steps: number of segments n (default the targets file's).
        repeat: timed solves per method and task; times are the median, min and max over them.
        warmup: untimed solves of every task before (caches, lazy imports, JIT).
        output: the results directory (``output/compare/`` is replaced whole); None writes
            nothing.
        reference: the method the leaderboard's ratios are against (default ``ours-lm`` if
            compared, else the first method).
        progress: progress lines on stderr.
        solvers: configured methods by name, replacing the defaults.
        executor: where the methods run (:mod:`ikbench.studies.executors`; default this
            process). On Ray each method is one task; the numbers are those of the local
            executor, but methods that run at the same time share the machine, so compare
            times only from runs with one method per machine at a time (local).

    Returns:
        A :class:`CompareResult`.
    """
    names = parse_methods(methods)
    repeat = check_repeat(repeat)
    robot = as_robot(robot)
    targets = select_targets(targets, robot, only, steps)
    tasks = line_tasks(robot, targets)
    reference = reference or ("ours-lm" if "ours-lm" in names else names[0])
    if reference not in names:
        raise InputError(f"--reference: {reference!r} is not among --methods "
                         f"{', '.join(names)}")
    log = Progress("compare", enabled=progress)
    started = time.perf_counter()
    status = method_status()
    rows, outcomes_by_method, built = [], {}, {}
    for k, name in enumerate(names):
        cls = status[name].cls
        if cls is None:
            log.say(f"{name} ({k + 1}/{len(names)}): unavailable: {status[name].reason}")
            rows += [_row(name, "", robot, targets, task, "unavailable", status[name].reason)
                     for task in tasks]
            continue
        try:
            solver = (solvers or {}).get(name) or cls()
            solver.check_tasks(robot, tasks)
        except Exception as exc:  # a method that cannot take these tasks is a row too
            rows += [_row(name, cls.library, robot, targets, task, "refused", str(exc))
                     for task in tasks]
            continue
        built[name] = solver
    executor = executor or LocalExecutor()
    portable = robot if executor.workers == 1 else portable_robot(robot)
    work = [(name, solver, portable, tasks, warmup, repeat) for name, solver in built.items()]
    for (name, solver), runs in zip(built.items(), executor.map(solve_method, work)):
        outcomes_by_method[name] = runs[-1]
        for j, task in enumerate(tasks):
            times = [run[j].wall_s for run in runs]
            last = runs[-1][j]
            row = _row(name, solver.library, robot, targets, task,
                       "solved" if last.ok else "failed", last.failure or "")
            row.update(time_median_s=float(np.median(times)), time_min_s=float(min(times)),
                       time_max_s=float(max(times)), repetitions=repeat,
                       iterations=last.solution.iterations if last.ok else np.nan)
            rows.append(row)
        median_s = np.median([r["time_median_s"] for r in rows[-len(tasks):]])
        log.say(f"{name}: {repeat} x {len(tasks)} trajectories, median {median_s:.4f} s "
                "per trajectory")
    results = pd.DataFrame(rows)
    record = {"methods": names, "reference": reference, "repeat": repeat, "warmup": warmup,
              "robot": robot.describe(), "targets": targets.source,
              "trajectories": targets.ids, "steps": targets.steps, "tolerances": TOLERANCES,
              "libraries": library_versions(sorted({r["library"] for r in rows if r["library"]})),
              **provenance()}
    if output is None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            results = _measure(results, built, robot, targets, outcomes_by_method, Path(tmp),
                               animation=False)
        board = leaderboard(results, reference)
    else:
        root = Path(output) / "compare"
        with staged_folder(root) as tmp:
            results = _measure(results, built, robot, targets, outcomes_by_method, tmp)
            board = leaderboard(results, reference)
            record["total_wall_time_s"] = time.perf_counter() - started
            atomic_write_csv(tmp / "results.csv", results, float_format="%.10g")
            atomic_write_text(tmp / "leaderboard.md", leaderboard_markdown(board, record))
            atomic_savefig(tmp / "pareto.png", plot_pareto(results))
            atomic_write_text(tmp / "run.json", json.dumps(record, indent=2) + "\n")
        log.say(f"written to {root}/ in {time.perf_counter() - started:.1f} s")
    return CompareResult(results, board, record)


def solve_method(job) -> list:
    """``warmup + repeat`` harness runs of one method on every task (in a worker); returns
    the ``repeat`` timed runs (each a list of outcomes)."""
    name, solver, robot, tasks, warmup, repeat = job
    runs = [solve_tasks(solver, robot, tasks, Progress(name, enabled=False))
            for _ in range(warmup + repeat)]
    return runs[warmup:]


def _row(method, library, robot, targets, task, status, failure) -> dict:
    version = library_versions([library]).get(library) if library else None
    return {"method": method, "library": library, "library_version": version,
            "robot": robot.name, "task": targets.source, "trajectory": task.name,
            "status": status, "failure": failure, "repetitions": 0}


def _measure(results, built, robot, targets, outcomes_by_method, folder: Path,
             animation: bool = True) -> pd.DataFrame:
    """Write each method's run folder (with its animation unless ``animation`` is False)
    and add its metrics and success to ``results``."""
    results = results.copy()
    for name, outcomes in outcomes_by_method.items():
        solver = built[name]
        table = write_run(solver, robot, targets, outcomes, folder / name,
                          {"shape": "line", "name": name}, animation)
        details = pd.read_csv(folder / name / "details.csv", dtype={"trajectory": str})
        merged = table.merge(details, on=["trajectory", "method"], how="left",
                             suffixes=("", "_details"))
        for _, row in merged.iterrows():
            mask = (results["method"] == name) & (results["trajectory"] == row["trajectory"])
            for column in METRICS:
                if column in row:
                    results.loc[mask, column] = row[column]
            results.loc[mask, "within_limits"] = row.get("within_limits")
    results = results.reindex(columns=COLUMNS)
    ok = (results["status"] == "solved") & (results["within_limits"] == True)  # noqa: E712
    for column, limit in TOLERANCES.items():
        ok &= results[column].astype(float) <= limit
    results["success"] = ok
    return results


def leaderboard(results: pd.DataFrame, reference: str) -> pd.DataFrame:
    """One row per method: success share, median time per trajectory and its ratio against
    ``reference``, median accuracy and smoothness figures."""
    rows = []
    ref = results[results["method"] == reference]["time_median_s"].median()
    for name, group in results.groupby("method", sort=False):
        solved = group[group["status"] == "solved"]
        row = {"method": name, "library": group["library"].iloc[0],
               "version": group["library_version"].iloc[0],
               "status": "; ".join(sorted(set(group["status"]))),
               "success": float(group["success"].mean()) if len(group) else 0.0,
               "time_median_s": solved["time_median_s"].median() if len(solved) else np.nan}
        row["time_vs_reference"] = row["time_median_s"] / ref if ref and ref > 0 else np.nan
        for column in ("line_distance_mean_mm", "pointing_deviation_mean_deg",
                       "end_pose_error_deg", "max_joint_step_deg", "mean_sq_jerk_deg2"):
            row[column] = solved[column].median() if len(solved) else np.nan
        row["note"] = "" if len(solved) else str(group["failure"].iloc[0])
        rows.append(row)
    return pd.DataFrame(rows)


def leaderboard_markdown(board: pd.DataFrame, record: dict) -> str:
    """leaderboard.md: the table, and who is fastest, most accurate, smoothest."""
    solved = board.dropna(subset=["time_median_s"])
    lines = [f"# Leaderboard: {record['robot']['name']}, targets {record['targets']}", "",
             f"{len(record['trajectories'])} trajectories (n = {record['steps']}), each solved "
             f"{record['repeat']} times per method; time = the harness's wall time of one "
             "trajectory's solve (median over repetitions, then over trajectories; a batched "
             "method's share of its batch); ratios against "
             f"`{record['reference']}` measured in the same run. Figures are medians over the "
             "trajectories, computed by `ikbench.core.metrics` from the CSVs written. Success: "
             "the solve returned, within the limits, end pose within "
             f"{TOLERANCES['end_pose_error_deg']} deg of the touch pose, start point within "
             f"{TOLERANCES['start_point_error_mm']} mm, mean line distance at most "
             f"{TOLERANCES['line_distance_mean_mm']} mm.", ""]
    if len(solved):
        def best(column, what):
            row = solved.loc[solved[column].idxmin()]
            return f"- {what}: **{row['method']}** ({_fmt(row[column])})"

        lines += [best("time_median_s", "fastest [s per trajectory]"),
                  best("line_distance_mean_mm", "closest to the line [mm]"),
                  best("pointing_deviation_mean_deg", "best pointing [deg]"),
                  best("mean_sq_jerk_deg2", "smoothest [mean squared jerk, deg^2]"), ""]
    shown = board.rename(columns={
        "time_median_s": "time/traj [s]", "time_vs_reference": f"x {record['reference']}",
        "success": "success", "line_distance_mean_mm": "line dist. [mm]",
        "pointing_deviation_mean_deg": "pointing [deg]", "end_pose_error_deg": "end pose [deg]",
        "max_joint_step_deg": "max step [deg]", "mean_sq_jerk_deg2": "jerk [deg^2]"})
    shown["success"] = [f"{100 * v:.0f} %" for v in board["success"]]
    lines += [markdown_table(shown, {"time/traj [s]": 4, f"x {record['reference']}": 1,
                                     "line dist. [mm]": 3, "jerk [deg^2]": 3}), "",
              f"Machine: {record['cpu']} ({record['cpu_count']} cores); libraries: "
              + ", ".join(f"{k} {v}" for k, v in record["libraries"].items())
              + f"; ikbench git {record['git_revision']}.", ""]
    return "\n".join(lines)


def _fmt(value) -> str:
    return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"


def plot_pareto(results: pd.DataFrame):
    """Time per trajectory vs mean line distance, one colour per library (log-log)."""
    from ikbench.studies.report import _matplotlib

    plt = _matplotlib()
    fig, ax = plt.subplots(figsize=(7.5, 5))
    solved = results[results["status"] == "solved"]
    libraries = list(dict.fromkeys(solved["library"]))
    colors = plt.cm.tab10(np.linspace(0, 1, 10))
    markers = "osD^v<>pPX*h"
    for k, (name, group) in enumerate(solved.groupby("method", sort=False)):
        color = colors[libraries.index(group["library"].iloc[0]) % 10]
        ax.scatter(group["time_median_s"], group["line_distance_mean_mm"].clip(lower=1e-6),
                   color=color, marker=markers[k % len(markers)], s=25, alpha=0.5)
        ax.scatter(group["time_median_s"].median(),
                   max(group["line_distance_mean_mm"].median(), 1e-6), color=color,
                   marker=markers[k % len(markers)], s=120, edgecolor="k",
                   label=f"{name} ({group['library'].iloc[0]})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("solve time per trajectory [s] (median over repetitions)")
    ax.set_ylabel("mean distance from the line [mm]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("Time vs accuracy: small dots per trajectory, large the method's median\n"
                 "(lower left is better; colour: library)")
    return fig
