"""Wall-time benchmark of methods on the same targets, in one process.

:func:`benchmark` solves every selected target with every method: ``warmup`` untimed rounds,
then ``repeat`` timed rounds. A round times each trajectory on its own (``solve``, one task at a
time) and, for methods that batch (override ``solve_many``), also one batched solve of all
targets. Reported per method and trajectory: median, min and max wall time; per method the
total over the trajectories (per round, then median/min/max over rounds); ratios of medians
against the first method; final losses by :func:`ikbench.core.losses.objective` and the metrics of
the last round's poses. Output: ``benchmark.csv`` (summary), ``benchmark_runs.csv`` (every
timed solve), ``benchmark.json`` (settings + provenance) and ``benchmark.md``.

By default each method runs its own number of timed rounds (``Method.bench_rounds``: 5, and 3
for ``ours``, which takes tens of seconds per round for the paper's seven targets).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.losses import objective
from ikbench.core.metrics import trajectory_metrics
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, select_targets
from ikbench.core.task import line_tasks
from ikbench.methods.base import Method
from ikbench.methods.registry import get_method, parse_names
from ikbench.render.run_report import markdown_table
from ikbench.runtime.progress import Reporter
from ikbench.studies.shape import TimedResult

if TYPE_CHECKING:
    from ikbench.core.task import Task

TOTAL = "total"
TOTAL_BATCHED = "total (batched)"
#: At most this many timed rounds per method.
MAX_ROUNDS = 1000


def parse_repeat(text: str | int | None, methods: list[str]) -> dict[str, int]:
    """``"5"`` or ``"5,ours=3"`` -> repetitions per method (each >= 1).

    None, and methods a text does not name, give each method's own ``bench_rounds``.

    Raises:
        InputError: an item that is not N or method=N (N an integer >= 1), or a method name
            that is not one of ``methods`` (the methods being benchmarked).
    """
    if text is None:
        return {m: get_method(m).bench_rounds for m in methods}
    counts, default = {}, None
    for item in str(text).split(","):
        name, sep, value = item.strip().rpartition("=")
        name = name.strip()
        try:
            number = int(value)
        except ValueError:
            number = 0
        if not 1 <= number <= MAX_ROUNDS or (sep and not name):
            raise InputError(f"--repeat: {item.strip()!r} is not N or method=N with N an "
                             f"integer from 1 to {MAX_ROUNDS}, e.g. 5,ours=3")
        if sep and name not in methods:
            raise InputError(f"--repeat: {item.strip()!r} names {name!r}, which is not "
                             f"benchmarked; methods: {', '.join(methods)}")
        if sep:
            counts[name] = number
        else:
            default = number
    return {m: counts.get(m, default or get_method(m).bench_rounds) for m in methods}


def parse_methods(text: str | Sequence[str]) -> list[str]:
    """``"ours,ours-lm"`` -> method names, each available here
    (:func:`~ikbench.methods.registry.parse_names`)."""
    return parse_names(text)


@dataclass
class BenchResult(TimedResult):
    """What :func:`run` measured: the summary, every timed solve, and provenance.
    :meth:`write` writes benchmark.csv, benchmark_runs.csv, benchmark.json and benchmark.md
    (:class:`~ikbench.studies.shape.TimedResult`)."""

    STEM = "benchmark"

    def markdown(self) -> str:
        """The module's :func:`markdown` of this result."""
        return markdown(self)


@dataclass(frozen=True)
class BenchSpec:
    """A benchmark: the method names (:func:`parse_methods`; the first is the ratios'
    baseline), the timed rounds per method (:func:`parse_repeat`), the untimed warm-up rounds,
    the robot and the selected targets, optional configured methods per name and the progress
    lines. :meth:`validate` checks the rest; :func:`run` runs it (:mod:`ikbench.studies.shape`).
    """

    methods: tuple[str, ...]
    repeat: dict[str, int]
    robot: Robot
    targets: Targets
    warmup: int = 1
    solvers: dict[str, Method] = field(default_factory=dict)
    progress: bool = True

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a warm-up count that is not an integer
        >= 0."""
        warmup = self.warmup
        if isinstance(warmup, bool) or not isinstance(warmup, int) or warmup < 0:
            raise InputError(f"--warmup: {warmup!r} must be an integer >= 0")


def benchmark(methods: list[str] | str, *, repeat: str | int | None = None,
              warmup: int = 1, targets: str | Path | Targets | None = None,
              only: str | None = None, steps: int | None = None, solvers: dict | None = None,
              progress: bool = True, robot: Robot | str | None = None) -> BenchResult:
    """Time methods on the same targets (see the module docstring); builds a
    :class:`BenchSpec`, validates it and runs it (:func:`run`); nothing is written.

    Args:
        methods: method names (list or comma-separated); the first is the ratios' baseline.
        repeat: timed rounds, ``N`` or ``"N,method=M"`` (each method named must be in
            ``methods``); None: each method's ``bench_rounds``.
        warmup: untimed rounds before timing (>= 0).
        targets: a targets file, :class:`Targets`, or None for the paper's.
        only: trajectory ids to keep (``"1,3"``).
        steps: number of segments n (default the targets file's).
        solvers: optional configured :class:`Method` per name (default: default settings).
        progress: progress lines on stderr.
        robot: the robot or its name/config/URDF (default NICO's right arm).
    """
    names = parse_methods(",".join(methods) if isinstance(methods, list) else methods)
    counts = parse_repeat(repeat, names)
    robot = as_robot(robot)
    spec = BenchSpec(tuple(names), counts, robot, select_targets(targets, robot, only, steps),
                     warmup, dict(solvers or {}), progress)
    spec.validate()
    return run(spec)


def run(spec: BenchSpec) -> BenchResult:
    """Time the methods of ``spec`` (validated: :meth:`BenchSpec.validate`); nothing is
    written (:meth:`BenchResult.write` writes it)."""
    names, counts, warmup, robot, targets = (list(spec.methods), spec.repeat, spec.warmup,
                                             spec.robot, spec.targets)
    solvers, progress = spec.solvers, spec.progress
    tasks = line_tasks(robot, targets)
    solves = sum((warmup + counts[n]) * (len(tasks) + get_method(n).capabilities.batched)
                 for n in names)
    log = Reporter("bench", total=solves, unit="solve", enabled=progress)
    runs, last = [], {}
    for name in names:
        solver = solvers.get(name) or get_method(name)()
        for r in range(warmup + counts[name]):
            timed = r >= warmup
            label = (f"round {r - warmup + 1}/{counts[name]}" if timed
                     else f"warm-up {r + 1}/{warmup}")
            for k, task in enumerate(tasks):
                t0 = time.perf_counter()
                solution = solver.solve(robot, task)
                wall = time.perf_counter() - t0
                log.advance(1, f"{name} {label}: trajectory {task.name} ({k + 1}/{len(tasks)}) "
                            f"{wall:.4f} s")
                if timed:
                    runs.append({"method": name, "round": r - warmup + 1, "mode": "single",
                                 "trajectory": task.name, "wall_s": wall,
                                 "iterations": solution.iterations})
                    last[name, task.name] = solution
            if solver.capabilities.batched:
                t0 = time.perf_counter()
                solver.solve_many(robot, tasks)
                wall = time.perf_counter() - t0
                log.advance(1, f"{name} {label}: batched solve of {len(tasks)} trajectories "
                            f"{wall:.4f} s")
                if timed:
                    runs.append({"method": name, "round": r - warmup + 1, "mode": "batched",
                                 "trajectory": TOTAL_BATCHED, "wall_s": wall,
                                 "iterations": np.nan})
    log.close()
    runs = pd.DataFrame(runs)
    summary = summarise(robot, tasks, names, runs, last)
    record = {"methods": names, "repeat": counts, "warmup": warmup, "robot": robot.describe(),
              "targets": targets.source, "trajectories": targets.ids, "steps": targets.steps,
              **provenance(extra=[get_method(n).library for n in names])}
    return BenchResult(summary, runs, record)


def _stats(values) -> dict:
    values = np.asarray(values, dtype=float)
    return {"rounds": len(values), "wall_median_s": float(np.median(values)),
            "wall_min_s": float(values.min()), "wall_max_s": float(values.max())}


def summarise(robot: Robot, tasks: Sequence[Task], names: Sequence[str], runs: pd.DataFrame,
              last: dict[tuple[str, str], Any]) -> pd.DataFrame:
    """One row per method and trajectory, plus the totals, with ratios to the first method."""
    rows = []
    for name in names:
        mine = runs[runs["method"] == name]
        single = mine[mine["mode"] == "single"]
        for task in tasks:
            solution = last[name, task.name]
            loss, _ = objective(robot, task, solution.poses)
            metrics = trajectory_metrics(robot, task, solution.poses)
            rows.append({"method": name, "trajectory": task.name,
                         **_stats(single[single["trajectory"] == task.name]["wall_s"]),
                         "iterations": solution.iterations, "loss": loss,
                         "line_distance_mean_mm": metrics["line_distance_mean_mm"],
                         "pointing_deviation_mean_deg": metrics["pointing_deviation_mean_deg"],
                         "end_point_error_mm": metrics["end_point_error_mm"],
                         "within_limits": robot.within_limits(solution.poses)})
        per_round = single.groupby("round")["wall_s"].sum()
        rows.append({"method": name, "trajectory": TOTAL, **_stats(per_round),
                     "loss": sum(r["loss"] for r in rows[-len(tasks):])})
        batched = mine[mine["mode"] == "batched"]
        if len(batched):
            rows.append({"method": name, "trajectory": TOTAL_BATCHED,
                         **_stats(batched["wall_s"]), "loss": rows[-1]["loss"]})
    summary = pd.DataFrame(rows)
    base = summary[summary["method"] == names[0]].set_index("trajectory")
    baseline_total = base.loc[TOTAL]
    ratios, loss_change = [], []
    for _, row in summary.iterrows():
        ref = base.loc[row["trajectory"]] if row["trajectory"] in base.index else baseline_total
        ratios.append(ref["wall_median_s"] / row["wall_median_s"])
        loss_change.append(100.0 * (row["loss"] - ref["loss"]) / ref["loss"])
    summary[f"speedup_vs_{names[0]}"] = ratios
    summary[f"loss_change_vs_{names[0]}_pct"] = loss_change
    return summary


def write(result: BenchResult, output: str | Path) -> Path:
    """Write benchmark.csv, benchmark_runs.csv, benchmark.json and benchmark.md
    (:meth:`BenchResult.write`); return benchmark.csv's path."""
    return result.write(output)


def speedup_ranges(summary: pd.DataFrame, base: str) -> dict[str, tuple]:
    """Per method other than ``base``: the smallest and largest per-trajectory speed-up.

    Returns:
        ``{method: (min ratio, trajectory, max ratio, trajectory)}``, ratios of median wall
        times against ``base`` on the same trajectory, each solved on its own.
    """
    speed = f"speedup_vs_{base}"
    per_traj = summary[~summary["trajectory"].isin([TOTAL, TOTAL_BATCHED])]
    out = {}
    for method, rows in per_traj.groupby("method", sort=False):
        if method == base or rows.empty:
            continue
        low, high = rows.loc[rows[speed].idxmin()], rows.loc[rows[speed].idxmax()]
        out[method] = (float(low[speed]), str(low["trajectory"]), float(high[speed]),
                       str(high["trajectory"]))
    return out


def _range_lines(summary: pd.DataFrame, base: str) -> list[str]:
    """benchmark.md's paragraph on the per-trajectory speed-ups (none for one method)."""
    ranges = speedup_ranges(summary, base)
    if not ranges:
        return []
    return [f"Per-trajectory speed-ups (ratio of median wall times against {base} on the same "
            "trajectory, each solved on its own; the total hides how much the slowest one "
            "gains):", "",
            *[f"- {method}: {low:.1f}x (trajectory {t_low}) to {high:.1f}x (trajectory "
              f"{t_high})" for method, (low, t_low, high, t_high) in ranges.items()], ""]


def headline(result: BenchResult) -> pd.DataFrame:
    """The totals: median/min/max wall time and speed-up per method (and batched)."""
    s = result.summary
    return s[s["trajectory"].isin([TOTAL, TOTAL_BATCHED])].reset_index(drop=True)


def markdown(result: BenchResult) -> str:
    """benchmark.md: totals, per-trajectory table, machine and versions."""
    rec, s = result.record, result.summary
    base = rec["methods"][0]
    speed, change = f"speedup_vs_{base}", f"loss_change_vs_{base}_pct"
    cols = ["method", "trajectory", "rounds", "wall_median_s", "wall_min_s", "wall_max_s",
            speed, "loss", change]
    per_traj = s[~s["trajectory"].isin([TOTAL, TOTAL_BATCHED])]
    digits = {"wall_median_s": 4, "wall_min_s": 4, "wall_max_s": 4, speed: 1, "loss": 4,
              change: 2, "rounds": 0}
    packages = ", ".join(f"{k} {v}" for k, v in rec["packages"].items() if v)
    lines = [
        "# Benchmark", "",
        f"Methods {', '.join(rec['methods'])} on targets {rec['targets']} (trajectories "
        f"{', '.join(rec['trajectories'])}, n = {rec['steps']}), in one process: "
        f"{rec['warmup']} untimed warm-up round(s), then timed rounds "
        f"({', '.join(f'{m}: {n}' for m, n in rec['repeat'].items())}). Wall times in "
        f"seconds; *total* is the sum over trajectories solved one at a time, per round; "
        f"*total (batched)* is one call solving all of them at once. Speed-ups are ratios of "
        f"medians against {base} measured in this run; losses are "
        "`ikbench.core.losses.objective` (cm, motor degrees) of the last round's poses.", "",
        "## Totals", "", markdown_table(headline(result)[cols], digits), "",
        *_range_lines(s, base),
        "## Per trajectory", "",
        markdown_table(per_traj[cols + ["line_distance_mean_mm", "pointing_deviation_mean_deg",
                                        "end_point_error_mm", "within_limits"]], digits), "",
        "## Machine", "",
        f"{rec['cpu']} ({rec['cpu_count']} cores, torch threads {rec['torch_threads']}), "
        f"Python {rec['python']}, {rec['platform']}; git {rec['git_revision']}; "
        f"{packages}; {rec['created_utc']}.", "",
        "Timings on a shared machine vary from run to run; compare the ratios measured "
        "within one run.", ""]
    return "\n".join(lines)
