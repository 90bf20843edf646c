"""Loss-term ablation: a method run with some of the paper's L0..L6 weights set to zero.

``ablate(["L1"], "ours")`` solves the targets with the full loss and with L1 dropped, using the
registered method itself (any method whose constructor takes ``weights``; its optimiser and
stopping rule are untouched). Output under ``output/ablation/``:

- ``<variant>/trajectory_<id>.csv`` for the variants ``full``, ``no-L1``, ``no-L2-L3-L4-L5``...;
- ``table.csv``: one row per (variant, trajectory); every figure is computed from the written
  CSVs by :mod:`ikbench.core.metrics`, plus :func:`joint_interpolation_distance_deg` and the full
  paper loss of the written poses (:func:`ikbench.core.losses.objective`);
- ``summary.csv`` (means per variant), ``run.json`` (settings, weights, versions);
- ``metrics.png``, ``trajectories_3d.png``, ``joints.png`` and ``report.md``, to which the
  paper layer adds its claims about the terms (:mod:`ikbench.paper.ablation_claims`).

The output folder is checked before any solve and written whole or not at all
(:func:`ikbench.core.io.staged_folder`): the trajectory CSVs and top-level files of an earlier
ablation there are replaced; other files in it are kept.
"""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError, SolverError
from ikbench.core.io import check_folder_writable
from ikbench.core.losses import PAPER_WEIGHTS, TERM_DESCRIPTIONS, TERMS, objective, parse_terms
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, select_targets
from ikbench.core.task import line_tasks
from ikbench.methods.base import Method
from ikbench.methods.registry import available_methods, get_method
from ikbench.render.run_report import TABLE_COLUMNS, _matplotlib, markdown_table, report_sections
from ikbench.runtime.harness import Progress, solve_tasks
from ikbench.runtime.progress import message
from ikbench.runtime.record import (
    TRAJECTORY_FILE,
    RunFolder,
    RunRecord,
    jsonable,
    robot_entry,
)
from ikbench.studies.folders import WITHIN
from ikbench.studies.run import DEFAULT_OUTPUT, evaluate, trajectory_files

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.task import Task

EACH = "each"
FOLDER = WITHIN["ablation"]
FULL = "full"
#: The folder names of variants (:attr:`Variant.name`): ``full``, ``no-L1``, ``no-L2-L5``...
VARIANT_FOLDER = re.compile(r"full|no-L[0-9](-L[0-9])*")
#: Columns of table.csv after ``variant, dropped`` and
# :data:`ikbench.render.run_report.TABLE_COLUMNS`.
EXTRA_COLUMNS = ["converged", "hit_cap", "paper_loss", "mean_sq_joint_step_deg2",
                 "max_joint_step_deg", "mean_sq_jerk_deg2", "velocity_sign_changes",
                 "joint_interpolation_distance_deg"]
#: Figures averaged per variant in summary.csv and drawn in metrics.png, with labels.
SUMMARY_METRICS = {
    "line_distance_mean_mm": "line distance [mm]",
    "pointing_deviation_mean_deg": "pointing deviation [deg]",
    "start_point_error_mm": "start point error [mm]",
    "end_point_error_mm": "end point error [mm]",
    "start_pose_error_deg": "start pose error [deg]",
    "end_pose_error_deg": "end pose error [deg]",
    "mean_sq_joint_step_deg2": "mean sq. joint step [deg²]",
    "mean_sq_jerk_deg2": "mean sq. jerk [deg²/step⁶]",
    "velocity_sign_changes": "joint-velocity sign changes",
    "joint_interpolation_distance_deg": "distance from joint interp. [deg]",
    "paper_loss": "full paper loss of the result",
    "iterations": "iterations",
}
@dataclass(frozen=True)
class Variant:
    """One loss configuration: the terms whose weight is set to zero."""

    dropped: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        """``full``, ``no-L1``, ``no-L2-L3-L4-L5``, ... (also its folder's name)."""
        return FULL if not self.dropped else "no-" + "-".join(self.dropped)

    @property
    def label(self) -> str:
        """``full loss`` or ``without L1 (pointing direction)``."""
        if not self.dropped:
            return "full loss"
        return "without " + ", ".join(f"{t} ({TERM_DESCRIPTIONS[t]})" for t in self.dropped)

    def weights(self, base: dict) -> dict:
        """``base`` with the dropped terms' weights set to 0."""
        return {k: (0.0 if k in self.dropped else v) for k, v in base.items()}


def parse_drops(specs: str | list[str] | tuple[str, ...]) -> list[Variant]:
    """Variants for ``--drop`` values: the full loss first, then one per spec (no repeats).

    Args:
        specs: one spec or several; each is ``"each"`` (every single-term ablation) or
            comma-separated term names dropped together (``"L1"``, ``"L2,L3,L4,L5"``).

    Raises:
        InputError: unknown term names (the message lists L0..L6), or a spec dropping all.
    """
    specs = [specs] if isinstance(specs, str) else list(specs)
    if not specs:
        raise InputError(f"--drop: give {EACH} or term names among {', '.join(TERMS)}")
    variants = [Variant()]
    for spec in specs:
        if spec.strip().lower() == EACH:
            variants += [Variant((term,)) for term in TERMS]
            continue
        if EACH in [part.strip().lower() for part in spec.split(",")]:
            raise InputError(f"--drop: {spec!r}: {EACH!r} must be its own --drop value (e.g. "
                             f"--drop {EACH} --drop L2,L3); a list names terms among "
                             f"{', '.join(TERMS)}")
        try:
            names = parse_terms(spec)
        except InputError as exc:
            raise InputError(f"--drop: {exc}; or {EACH}") from None
        if len(names) == len(TERMS):
            raise InputError(f"--drop: {spec!r} drops every term; nothing would be optimised")
        variants.append(Variant(tuple(sorted(names, key=TERMS.index))))
    return list(dict.fromkeys(variants))


def weighted_methods() -> dict[str, type]:
    """Available methods with loss weights (those that can be ablated)."""
    return {name: cls for name, cls in available_methods().items() if cls.takes_weights()}


def check_method(name: str) -> type[Method]:
    """The method class ``name`` if it takes loss weights; InputError naming those that do."""
    cls = get_method(name)
    if not cls.takes_weights():
        raise InputError(f"--method: {name!r} has no loss weights to drop; methods that have: "
                         f"{', '.join(weighted_methods())}")
    return cls


def joint_interpolation_distance_deg(poses_motor_deg: npt.ArrayLike, start_pose: npt.ArrayLike,
                                     end_pose: npt.ArrayLike) -> float:
    """How far a trajectory is from linear motion in joint space [motor deg].

    The mean over the n+1 poses of the largest absolute joint difference between pose i and
    pose i of the linear interpolation ``p^s + i/n (p^e - p^s)`` from start to touch pose.

    Args:
        poses_motor_deg: (n+1, dof) trajectory.
        start_pose: (dof,) start pose p^s.
        end_pose: (dof,) touch pose p^e.
    """
    poses = np.asarray(poses_motor_deg, dtype=float)
    line = joint_interpolation(start_pose, end_pose, len(poses))
    return float(np.abs(poses - line).max(axis=1).mean())


def joint_interpolation(start_pose: npt.ArrayLike, end_pose: npt.ArrayLike,
                        count: int) -> np.ndarray:
    """(count, dof) poses linearly interpolated from start to end pose [motor deg]."""
    start = np.asarray(start_pose, dtype=float)
    t = np.linspace(0.0, 1.0, count)[:, None]
    return start + t * (np.asarray(end_pose, dtype=float) - start)


def joint_interpolation_by_joint(robot: Robot, tasks: Sequence[Task],
                                 poses_by_variant: dict[str, dict[str, np.ndarray]]
                                 ) -> pd.DataFrame:
    """Mean absolute difference [motor deg] from the joint-space interpolation, per joint.

    Args:
        robot: the robot (joint names).
        tasks: the tasks (start and touch poses).
        poses_by_variant: variant -> {trajectory id: (n+1, dof) poses}.

    Returns:
        One row per variant, one column per joint: the mean over trajectories and poses.
    """
    rows = {}
    for name, poses in poses_by_variant.items():
        per_task = []
        for task in tasks:
            assert task.required.start_pose is not None and task.required.end_pose is not None, \
                "the ablation's tasks are lines between two poses"
            line = joint_interpolation(task.required.start_pose, task.required.end_pose,
                                       task.goal.steps + 1)
            per_task.append(np.abs(poses[task.name] - line).mean(axis=0))
        rows[name] = np.mean(per_task, axis=0)
    return pd.DataFrame.from_dict(rows, orient="index", columns=list(robot.joint_names))


def _say(text: str, enabled: bool) -> None:
    message("ablation", text, enabled)


@dataclass(frozen=True)
class AblationSpec:
    """An ablation: the variants (:func:`parse_drops`), the method's name, the robot and the
    selected targets, the method's other settings, the full loss's weights keyed L0..L6, the
    trajectory drawn per variant (None: the first selected), the movement duration T [s] and
    the progress lines. :meth:`validate` checks the rest; :func:`run` runs it
    (:mod:`ikbench.studies.shape`)."""

    variants: tuple[Variant, ...]
    method: str
    robot: Robot
    targets: Targets
    options: dict[str, Any] = field(default_factory=dict)
    base_weights: dict[str, float] = field(default_factory=lambda: dict(PAPER_WEIGHTS))
    figure_trajectory: str | None = None
    duration_s: float = DEFAULT_DURATION_S
    progress: bool = True

    @property
    def figure_id(self) -> str:
        """The trajectory drawn per variant: the one named, else the first selected."""
        return str(self.figure_trajectory or self.targets.ids[0])

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a method without loss weights, a
        figure trajectory not selected or settings the method refuses, before any solve."""
        check_method(self.method)
        if self.figure_id not in self.targets.ids:
            raise InputError(f"--figure-trajectory: {self.figure_id!r} is not among the "
                             f"selected trajectories ({', '.join(self.targets.ids)})")
        self.solvers()

    def solvers(self) -> list[Method]:
        """The method once per variant, with the variant's weights."""
        cls = get_method(self.method)
        return [cls(**{**self.options, "weights": v.weights(self.base_weights)})
                for v in self.variants]


@dataclass
class AblationResult:
    """What :func:`run` measured: table.csv and summary.csv as DataFrames, the trajectory files
    per variant (as written), the poses read back from them, the solvers and the run record.
    :meth:`write` writes ``folder/ablation/``."""

    spec: AblationSpec
    tasks: list
    solvers: list[Method]
    files: dict[str, dict]
    poses: dict[str, dict[str, np.ndarray]]
    table: pd.DataFrame
    summary: pd.DataFrame
    started: float

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/ablation/`` whole (files of an earlier ablation there that this one
        does not write are removed; other files are kept); return it."""
        spec, table, poses = self.spec, self.table, self.poses
        robot, targets, variants = spec.robot, spec.targets, spec.variants
        cls = get_method(spec.method)
        root = Path(folder) / FOLDER
        with RunFolder(root).staged(keep=_not_ablation_output) as stage:
            for variant in variants:
                for file in self.files[variant.name].values():
                    stage.trajectory(file, variant.name)
            stage.csv("table.csv", table)
            stage.csv("summary.csv", self.summary)
            record = RunRecord(
                kind="ablation", method=cls.name, robot=robot_entry(robot),
                targets=targets.source, trajectories=targets.ids, steps=targets.steps,
                total_wall_time_s=time.perf_counter() - self.started,
                provenance=provenance(extra=(cls.library,)),
                study={"figure_trajectory": spec.figure_id,
                       "variants": {v.name: {"dropped": list(v.dropped),
                                             "settings": jsonable({"settings": s.settings})}
                                    for v, s in zip(variants, self.solvers)}})
            stage.record(record)
            task = self.tasks[targets.ids.index(spec.figure_id)]
            shown = {v.name: poses[v.name][task.name] for v in variants}
            title = f"{cls.name}, trajectory {spec.figure_id}"
            stage.figure("metrics.png", plot_metrics(table))
            stage.figure("trajectories_3d.png", plot_variants_3d(robot, task, shown, title))
            stage.figure("joints.png", plot_joints(robot, task, shown, title))
            by_joint = joint_interpolation_by_joint(robot, self.tasks, poses)
            stage.text("report.md", ablation_report(table, self.summary, variants,
                                                    record.to_dict(), by_joint))
        _say(f"written to {root}/ in {time.perf_counter() - self.started:.1f} s", spec.progress)
        return root


def ablate(drops: str | list[str], method: str, *,
           targets: str | Path | Targets | None = None, only: str | None = None,
           steps: int | None = None, output: str | Path = DEFAULT_OUTPUT,
           options: dict | None = None, base_weights: dict | None = None,
           figure_trajectory: str | None = None, robot: Robot | str | None = None,
           duration_s: float = DEFAULT_DURATION_S, progress: bool = True) -> pd.DataFrame:
    """Run the full loss and each ablation on the same targets; write ``output/ablation/``.

    Builds an :class:`AblationSpec`, validates it, checks the output folder, then
    :func:`run` and :meth:`AblationResult.write`.

    Args:
        drops: ``--drop`` specs, see :func:`parse_drops`.
        method: a registered method with loss weights (``"ours"``, ``"ours-lm"``).
        targets, only, steps: as in :func:`ikbench.studies.run.run`.
        output: the results directory; the ablation goes to ``output/ablation/``, replaced
            whole (files of an earlier ablation there that this one does not write are gone).
        options: other settings of the method (e.g. ``max_iterations``).
        base_weights: weights of the full loss keyed L0..L6 (default the paper's).
        figure_trajectory: trajectory id drawn per variant (default the first selected).
        robot: the robot or its name/config/URDF (default NICO's right arm).
        duration_s: movement duration T [s] for the trajectories' ``time_s`` column.
        progress: print progress to stderr.

    Returns:
        table.csv as a DataFrame: one row per (variant, trajectory).
    """
    variants = parse_drops(drops)
    check_method(method)
    robot = as_robot(robot)
    spec = AblationSpec(tuple(variants), method, robot,
                        select_targets(targets, robot, only, steps), dict(options or {}),
                        dict(PAPER_WEIGHTS if base_weights is None else base_weights),
                        figure_trajectory, duration_s, progress)
    spec.validate()
    check_folder_writable(Path(output) / FOLDER)  # before any solve, not after minutes of it
    result = run(spec)
    result.write(output)
    return result.table


def run(spec: AblationSpec) -> AblationResult:
    """Solve every variant of ``spec`` (validated: :meth:`AblationSpec.validate`) and measure
    the trajectories as they will be written; nothing is written
    (:meth:`AblationResult.write` writes it)."""
    robot, variants, progress = spec.robot, spec.variants, spec.progress
    solvers = spec.solvers()
    tasks = line_tasks(robot, spec.targets)
    started = time.perf_counter()
    outcomes = {}
    for k, (variant, solver) in enumerate(zip(variants, solvers)):
        _say(f"variant {k + 1}/{len(variants)}: {variant.name} ({variant.label}), "
             f"{len(tasks)} trajectories, {time.perf_counter() - started:.0f} s so far", progress)
        outcomes[variant.name] = solve_tasks(
            solver, robot, tasks, Progress(f"ablation {variant.name}", enabled=progress))
        failed = [o for o in outcomes[variant.name] if not o.ok]
        if failed:
            raise SolverError(f"ablation {variant.name}: trajectory {failed[0].task.name} "
                              f"failed: {failed[0].failure}")
    tables, poses, files = [], {}, {}
    for variant, solver in zip(variants, solvers):
        files[variant.name] = trajectory_files(robot, outcomes[variant.name], spec.duration_s)
        table, poses[variant.name] = _measure_variant(robot, solver, variant,
                                                      outcomes[variant.name],
                                                      files[variant.name])
        tables.append(table)
        _say(f"variant {variant.name}: {int(table['iterations'].sum())} iterations, "
             f"{int(table['hit_cap'].sum())} of {len(table)} hit the cap, "
             f"{table['duration_s'].sum():.1f} s", progress)
    table = pd.concat(tables, ignore_index=True)
    return AblationResult(spec, tasks, solvers, files, poses, table, summarize(table), started)


#: The files an ablation writes at its top level.
ABLATION_FILES = ("table.csv", "summary.csv", "run.json", "metrics.png", "trajectories_3d.png",
                  "joints.png", "report.md")


def _not_ablation_output(rel: Path) -> bool:
    """True for files of an old ablation folder that no ablation writes (kept on rewrite):
    not its top-level files, not the trajectory CSVs of variant folders."""
    if len(rel.parts) == 1:
        return rel.name not in ABLATION_FILES
    return not (len(rel.parts) == 2 and VARIANT_FOLDER.fullmatch(rel.parts[0])
                and TRAJECTORY_FILE.fullmatch(rel.name))


def _measure_variant(robot: Robot, solver: Method, variant: Variant, outcomes: list,
                     files: dict) -> tuple[pd.DataFrame, dict]:
    """Measure the variant's trajectory files as they will be written; returns (table rows,
    {id: poses as written})."""
    table, details, _ = evaluate(robot, outcomes, files, solver.name)
    poses, extra = {}, []
    for outcome in outcomes:
        task, solution = outcome.task, outcome.solution
        poses[task.name] = files[task.name].poses
        extra.append({
            "hit_cap": bool(solution.info.get("hit_cap", not solution.converged)),
            "paper_loss": objective(robot, task, poses[task.name])[0],
            "joint_interpolation_distance_deg": joint_interpolation_distance_deg(
                poses[task.name], task.required.start_pose, task.required.end_pose),
        })
    extra = pd.DataFrame(extra)
    rows = table.assign(variant=variant.name, dropped=",".join(variant.dropped),
                        **{c: details[c] for c in EXTRA_COLUMNS if c not in extra},
                        **{c: extra[c] for c in extra})
    return rows[["variant", "dropped", *TABLE_COLUMNS, *EXTRA_COLUMNS]], poses


def summarize(table: pd.DataFrame) -> pd.DataFrame:
    """summary.csv: per variant (in table order) the mean of :data:`SUMMARY_METRICS` over the
    trajectories, the number of trajectories and of capped runs, and the total solve time."""
    groups = table.groupby("variant", sort=False)
    summary = groups[list(SUMMARY_METRICS)].mean()
    summary.insert(0, "hit_cap", groups["hit_cap"].sum().astype(int))
    summary.insert(0, "trajectories", groups.size())
    summary.insert(0, "dropped", groups["dropped"].first().fillna(""))
    summary["duration_s_total"] = groups["duration_s"].sum()
    return summary.reset_index()


# ----- per-variant means -------------------------------------------------------------------
def _fmt(value: float) -> str:
    return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"


class VariantMeans:
    """Per-variant means and per-trajectory values (for claims and trade-offs)."""

    def __init__(self, table: pd.DataFrame):
        self.table = table
        self.mean = table.groupby("variant", sort=False)[list(SUMMARY_METRICS)].mean()

    def has(self, *names: str) -> bool:
        return all(n in self.mean.index for n in names)

    def __call__(self, variant: str, column: str) -> float:
        return float(self.mean.loc[variant, column])

    def ratio(self, variant: str, column: str, floor: float = 1e-12) -> float:
        return self(variant, column) / max(self(FULL, column), floor)

    def pair(self, variant: str, column: str) -> str:
        """``line distance [mm]: full 3.1 mm -> no-L0 45 mm (x14.5)``."""
        unit = " mm" if column.endswith("_mm") else "°" if column.endswith("_deg") else ""
        return (f"{SUMMARY_METRICS[column]}: full {_fmt(self(FULL, column))}{unit} → "
                f"{variant} {_fmt(self(variant, column))}{unit} "
                f"(×{_fmt(self.ratio(variant, column))})")

    def rises(self, variant: str, column: str, lower: bool = False) -> str:
        """``higher on 5 of 7 trajectories`` (or ``lower on``)."""
        full = self.table[self.table.variant == FULL].set_index("trajectory")[column]
        other = self.table[self.table.variant == variant].set_index("trajectory")[column]
        count = int(((other < full) if lower else (other > full)).sum())
        return f"{'lower' if lower else 'higher'} on {count} of {len(full)} trajectories"


# ----- report and figures ------------------------------------------------------------------
PER_TRAJECTORY_COLUMNS = {
    "variant": "variant", "trajectory": "trajectory", "iterations": "iterations",
    "hit_cap": "hit cap", "loss": "loss", "paper_loss": "full paper loss",
    "line_distance_mean_mm": "line dist. [mm]", "pointing_deviation_mean_deg": "pointing [deg]",
    "start_point_error_mm": "start pt err [mm]", "end_point_error_mm": "end pt err [mm]",
    "start_pose_error_deg": "start pose err [deg]", "end_pose_error_deg": "end pose err [deg]",
    "mean_sq_joint_step_deg2": "mean sq. step [deg²]", "mean_sq_jerk_deg2": "mean sq. jerk",
    "velocity_sign_changes": "sign changes",
    "joint_interpolation_distance_deg": "from joint interp. [deg]",
}


#: Figures named as the cost of a trade-off when at least twice the full loss's.
COST_FIGURES = ["start_point_error_mm", "end_point_error_mm", "start_pose_error_deg",
                "end_pose_error_deg", "mean_sq_joint_step_deg2", "mean_sq_jerk_deg2",
                "velocity_sign_changes"]


def _tradeoffs(m: VariantMeans) -> list[str]:
    """Variants that beat the full loss on both line distance and pointing deviation, with
    the figures that are at least twice the full loss's."""
    shape = ["line_distance_mean_mm", "pointing_deviation_mean_deg"]
    lines = []
    for name in m.mean.index:
        if name == FULL or not all(m.ratio(name, c) < 1.0 for c in shape):
            continue
        costs = [m.pair(name, c) for c in COST_FIGURES if m.ratio(name, c) >= 2.0]
        lines.append(f"- `{name}` follows the line and points better than the full loss "
                     f"({m.pair(name, shape[0])}; {m.pair(name, shape[1])}), at "
                     f"the cost of: {'; '.join(costs) or 'nothing measured here'}.")
    return lines


def ablation_report(table: pd.DataFrame, summary: pd.DataFrame, variants: Sequence[Variant],
                    record: dict[str, Any],
                    by_joint: pd.DataFrame | None = None) -> str:
    """report.md of an ablation run (``by_joint``: :func:`joint_interpolation_by_joint`)."""
    tradeoffs = _tradeoffs(VariantMeans(table))
    settings = record["variants"][FULL]["settings"]
    cap = (settings.get("settings") or settings).get("max_iterations")
    shown = summary.rename(columns={"hit_cap": "runs at cap", **SUMMARY_METRICS})
    lines = [
        f"# Ablation of the loss terms ({record['method']})", "",
        f"Targets: {record['targets']}; trajectories {', '.join(record['trajectories'])}; "
        f"n = {record['steps']} segments; iteration cap {cap}. Produced by ikbench "
        f"(git {record['git_revision']}) on {record['cpu']} ({record['cpu_count']} cores), "
        f"torch {record['packages']['torch']}, in {record['total_wall_time_s']:.0f} s.", "",
        "Each variant runs the same method with the dropped terms' weights set to 0 "
        "(everything else, including the stopping rule, as in the paper). Every figure is "
        "computed by `ikbench.core.metrics` from the trajectory CSVs in this folder; *full paper "
        "loss* is the paper's loss with all seven terms evaluated on the written poses; "
        "*distance from joint interpolation* is the mean over poses of the largest absolute "
        "joint difference [motor deg] from the linear interpolation start pose → touch pose. "
        "Dropping a term lowers the loss, so the paper's stopping rule (loss < 10) fires "
        "earlier and the remaining terms are optimised less than with the full loss.", "",
        "Variants: " + "; ".join(f"`{v.name}`: {v.label}" for v in variants) + ".", "",
        *report_sections("ablation", table=table),
        *(["Mean absolute difference from the joint-space interpolation per joint [motor deg] "
           "(mean over trajectories and poses; the claim's figure takes the largest joint per "
           "pose):", "", markdown_table(by_joint.rename_axis("variant").reset_index(), {}), ""]
          if by_joint is not None else []),
        *(["Trade-offs:", "", *tradeoffs, ""] if tradeoffs else []),
        "## Summary per variant (mean over the trajectories)", "",
        markdown_table(shown.drop(columns=["dropped"]),
                       {"iterations": 0, "duration_s_total": 1}), "",
        "## Figures", "",
        "![metrics per variant](metrics.png)", "",
        f"Trajectory {record['figure_trajectory']} per variant (fingertip and goal line; "
        "joint angles and the joint-space interpolation):", "",
        "![trajectories per variant](trajectories_3d.png)", "", "![joints](joints.png)", "",
        "## Per trajectory", "",
        markdown_table(table[list(PER_TRAJECTORY_COLUMNS)].rename(columns=PER_TRAJECTORY_COLUMNS),
                       {"loss": 3, "full paper loss": 3, "mean sq. jerk": 3}), ""]
    return "\n".join(lines)


def plot_metrics(table: pd.DataFrame) -> Figure:
    """Bars per metric: the mean per variant, dots for the single trajectories."""
    plt = _matplotlib()
    names = list(dict.fromkeys(table["variant"]))
    columns = list(SUMMARY_METRICS)
    ncols = 3
    nrows = -(-len(columns) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 2.9 * nrows))
    x = np.arange(len(names))
    colors = plt.cm.tab10(np.linspace(0, 1, 10))[: len(names)]
    for ax, column in zip(axes.flat, columns):
        groups = [table.loc[table.variant == n, column].to_numpy(dtype=float) for n in names]
        ax.bar(x, [np.nanmean(g) for g in groups], color=colors, alpha=0.8)
        for k, values in enumerate(groups):
            ax.plot(np.full(len(values), x[k]), values, "k.", ms=3)
        positive = np.concatenate(groups)
        positive = positive[np.isfinite(positive) & (positive > 0)]
        if len(positive) and positive.max() / positive.min() > 100:
            ax.set_yscale("log")
        ax.set_title(SUMMARY_METRICS[column], fontsize=9)
        ax.set_xticks(x, names, rotation=45, ha="right", fontsize=7)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(columns):]:
        ax.axis("off")
    fig.suptitle("Loss-term ablation: mean over trajectories (bars), single trajectories (dots)")
    fig.tight_layout()
    return fig


def _grid(plt, count: int, projection=None, size=(3.6, 3.2)):
    ncols = min(count, 3)
    nrows = -(-count // ncols)
    fig = plt.figure(figsize=(size[0] * ncols, size[1] * nrows))
    return fig, [fig.add_subplot(nrows, ncols, k + 1, projection=projection)
                 for k in range(count)]


def plot_variants_3d(robot: Robot, task: Task, poses_by_variant: dict[str, np.ndarray],
                     title: str) -> Figure:
    """One 3-D panel per variant: the fingertip path of one trajectory over its goal line
    (the full loss's path in grey for reference), same axes and front view everywhere."""
    plt = _matplotlib()
    points = {name: robot.fk(poses).point_mm for name, poses in poses_by_variant.items()}
    fig, axes = _grid(plt, len(points), projection="3d")
    goal = task.goal.points_mm
    everything = np.concatenate([goal, *points.values()])
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    for ax, (name, path) in zip(axes, points.items()):
        ax.plot(*goal.T, "--", color="tab:blue", lw=1, label="goal line")
        if name != FULL and FULL in points:
            ax.plot(*points[FULL].T, "-", color="0.6", lw=1, label="full loss")
        ax.plot(*path.T, "-o", color="tab:red", ms=1.5, lw=1.2, label=name)
        ax.scatter(*goal[-1], color="k", marker="x", s=30)
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]))
        ax.view_init(elev=12, azim=180)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=6)
        ax.legend(fontsize=6, loc="upper left")
    fig.suptitle(f"{title}: fingertip [mm] (front view; x: touch point)")
    return fig


def plot_joints(robot: Robot, task: Task, poses_by_variant: dict[str, np.ndarray], title: str
                ) -> Figure:
    """One panel per variant: joint angles [motor deg] per step (solid) and the linear
    interpolation from start to touch pose (dashed)."""
    plt = _matplotlib()
    fig, axes = _grid(plt, len(poses_by_variant), size=(3.8, 2.8))
    steps = np.arange(task.goal.steps + 1)
    assert task.required.start_pose is not None and task.required.end_pose is not None, \
        "the ablation's tasks are lines between two poses"
    line = joint_interpolation(task.required.start_pose, task.required.end_pose,
                               task.goal.steps + 1)
    colors = plt.cm.tab10(np.linspace(0, 1, 10))
    for ax, (name, poses) in zip(axes, poses_by_variant.items()):
        for j in range(poses.shape[1]):
            ax.plot(steps, poses[:, j], "-", color=colors[j], lw=1.2,
                    label=robot.joint_names[j])
            ax.plot(steps, line[:, j], "--", color=colors[j], lw=0.8, alpha=0.7)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("step", fontsize=7)
        ax.set_ylabel("motor deg", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=5, loc="best")
    fig.suptitle(f"{title}: joint angles (solid) and joint-space interpolation (dashed)")
    fig.tight_layout()
    return fig
