"""``ikbench report DIR``: methods side by side, and the paper's claims about its baseline
checked with numbers, as report.md and a figure.

:func:`write_comparison_report` loads and measures every run folder of ``DIR``
(:func:`ikbench.paper.baseline_runs.load_comparison`), judges the paper's claims about its
traditional baseline for every baseline run against ``ours``
(:func:`ikbench.paper.baseline_claims.check_claims`) and writes ``DIR/report.md`` and
``DIR/pointing_deviation_per_step.png``. This module renders: the tables and sentences of the
report (also used by ``ikbench reproduce``'s results/README.md), the notes on the paper's
Table 2, the figure.

The paper's claim that the baseline's start pose varies is a property of the walk; the report
checks it on every run and says what it shows for each scheme
(:data:`ikbench.paper.baseline_claims.SCHEME_TASKS`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.io import atomic_savefig, atomic_write_text
from ikbench.paper.baseline_claims import (
    BASELINE,
    BASELINE_WALK,
    DEFAULT_SCHEME,
    IKPY,
    IKPY_MODES,
    IKPY_WALK,
    METHOD_FAMILIES,
    ORIENTATION_MODES,
    OURS,
    SCHEME_ORDER,
    SCHEME_TASKS,
    check_claims,
    pointing_tradeoff_note,
    task_text,
)
from ikbench.paper.baseline_runs import (
    MethodRun,
    baseline_names,
    ikpy_table2_run,
    load_comparison,
    pointing_per_step,
    table2_run,
)
from ikbench.paper.values import PAPER_STEPS, accuracy_beside_paper, paper_values
from ikbench.render.run_report import _matplotlib, markdown_table

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.task import Task

REPORT_NAME = "report.md"
FIGURE_NAME = "pointing_deviation_per_step.png"
PAPER_BASELINE_NOTE = (
    "The paper's baseline is not this one: the authors solved it with ikpy on a *different* "
    "NICO URDF (other joint conventions; ikbench/paper/data/reference/README.md), so only its "
    "qualitative claims are expected to carry over, not its numbers. Their script "
    "(andylucny/nico2, `generate-ikpy/generate-ikpy.py`) passes a target frame to ikpy's "
    "`inverse_kinematics_frame` without `orientation_mode`, and ikpy then fits the position "
    "only, walking back from the touch pose (the start pose is free: a touch-pose-only task). "
    f"`ikbench run --method {IKPY_WALK}` makes their call on the paper's robot (Table 2 as "
    f"they ran it); `ikbench run --method {BASELINE_WALK} --orientation position` solves the "
    f"same problem by damped least squares. `{BASELINE}` and `{IKPY}` (scheme track) solve "
    "the paper's own task instead: from the recorded start pose onto the touch pose.")
IKPY_TABLE2_NOTE = (
    "This is the paper's baseline as the authors ran it: their library (ikpy) and their call "
    "(`inverse_kinematics_frame` with a target frame and no `orientation_mode`, so the position "
    "only), walked back from the touch pose, here on ikbench's URDF of the paper's robot rather "
    "than theirs (other joint conventions; ikbench/paper/data/reference/README.md). Their "
    "script also re-solved the touch point itself; here pose n is the touch pose as given.")
TABLE2_UNITS_NOTE = (
    "Columns named *paper* are copied from the paper's Table 2. Its \"distance from the line "
    "[mm]\" and \"start point variation [mm]\" values are in centimetres (the unit label is off "
    "by a factor of ten, see ikbench/paper/data/reference/README.md), so they are shown here "
    "x 10, in mm. *Start point variation* is |P_0 - P_s|, the distance of the trajectory's "
    "first point from the recorded start point.")


def claims_lines(summary: pd.DataFrame, runs: dict, frame: pd.DataFrame | None = None,
                 level: int = 3) -> list[str]:
    """Markdown lines: one claims table per baseline run against ``ours``, each headed by the
    run and its orientation mode, with the trade-off note and the missed points per trajectory.

    Self-contained (no references to other sections), so the same lines serve report.md and
    results/README.md.

    Args:
        summary: :func:`summarise` output.
        runs: the runs (:func:`load_runs`).
        frame: :func:`evaluate_runs` output, for the missed points per trajectory.
        level: heading level of each baseline's subsection.
    """
    names = baseline_names(runs)
    lines = ["The paper's baseline is compared with `ours` once per baseline run; the run's "
             "scheme and mode (from its run.json) say which task it solved and decide the "
             "pointing claim. Scheme: "
             + "; ".join(f"`{scheme}`: {task_text(scheme)}" for scheme in SCHEME_ORDER)
             + f". The paper's baseline walked (`{BASELINE_WALK}`, `{IKPY_WALK}`; runs written "
             "before the schemes existed are walks too); "
             f"`{BASELINE}` and `{IKPY}` track by default. Per point the "
             f"`{BASELINE}` family solves, in mode (`--orientation`) "
             + "; ".join(f"`{mode}`: {text}" for mode, text in ORIENTATION_MODES.items())
             + "."]
    if any(runs[n].family == IKPY for n in names):
        lines[-1] += (f" `{IKPY}`, the authors' own library, solves, in mode "
                      "(`--ikpy-orientation`) "
                      + "; ".join(f"`{mode}`: {text}" for mode, text in IKPY_MODES.items())
                      + ".")
    lines.append("")
    for name in names:
        run = runs[name]
        description = (run.description if run.orientation
                       else f"{run.mode_flag} unknown; {run.description}")
        lines += [f"{'#' * level} `{name}` ({description}) against `{OURS}`", "",
                  f"Task solved: {run.task}.", "",
                  escaped_table(check_claims(summary, name, scheme=run.scheme)), ""]
        note = pointing_tradeoff_note(summary, name)
        if note:
            lines += [note, ""]
        if frame is not None:
            sub = frame[frame["method"] == name]
            if "points_not_converged" in sub and sub["points_not_converged"].notna().all():
                parts = [f"{r['trajectory']}: {r['points_not_converged']:.0f}/"
                         f"{r['points_solved']:.0f}" for _, r in sub.iterrows()]
                lines += ["Points that did not reach the IK tolerance, per trajectory: "
                          + ", ".join(parts) + ".", ""]
    note = start_pose_note(summary, runs)
    return lines + ([note, ""] if note else [])


def start_pose_note(summary: pd.DataFrame, runs: dict) -> str:
    """A sentence on the start-pose claim over every baseline run: how far the walks' start
    poses are from p^s, against the track runs' (medians of |p_0 - p^s|, motor deg), and
    what that means; "" without baseline runs."""
    rows = summary.set_index("method")
    names = [n for n in baseline_names(runs) if n in rows.index]
    by_scheme = {scheme: [n for n in names if runs[n].scheme == scheme]
                 for scheme in SCHEME_ORDER}
    if not names:
        return ""

    def figures(group):
        return ", ".join(f"`{n}` {rows.loc[n, 'median |p_0 - p^s| [deg]']:.2f}" for n in group)

    parts = []
    if by_scheme["walk"]:
        parts.append(f"the walks from the touch pose ({SCHEME_TASKS['walk'][1]}) start "
                     f"{figures(by_scheme['walk'])} motor deg from p^s (median |p_0 - p^s|)")
    if by_scheme["track"]:
        parts.append(f"the tracks from the start pose ({SCHEME_TASKS['track'][1]}) start "
                     f"{figures(by_scheme['track'])} motor deg from it")
    text = "The start-pose claim is about the walk the paper's baseline made: " + \
        "; ".join(parts) + "."
    if by_scheme["walk"] and by_scheme["track"]:
        text += (" The start pose varies because the walk leaves it free, not because the "
                 "IK is solved point by point: tracked from the start pose, the same "
                 "point-by-point IK starts at the recorded start pose, by construction.")
    elif by_scheme["walk"]:
        text += (" A track run (`sequential-ik` or `ikpy`, scheme track: the paper's task) "
                 "starts at the recorded start pose by construction.")
    else:
        text += (" No walk is in this folder: the paper's baseline walked back from the "
                 "touch pose (`sequential-ik-walk`, `ikpy-walk`), where the start pose is "
                 "free.")
    return text


def _range(values, digits: int = 2) -> str:
    """``0.14-0.38 (mean 0.26)``, or the value alone when all are equal at ``digits``."""
    values = np.asarray(values, dtype=float)
    lo, hi = f"{values.min():.{digits}f}", f"{values.max():.{digits}f}"
    return lo if lo == hi else f"{lo}-{hi} (mean {values.mean():.{digits}f})"


def modes_table(frame: pd.DataFrame, runs: dict, steps: int, paper: bool = False) -> pd.DataFrame:
    """The baseline runs (one per orientation mode) beside ``ours`` and, with ``paper``, the
    paper's Table 2 values: the method, its mode, the task it solved (:data:`TASK_CELLS`),
    time per trajectory, points that missed the IK tolerance, line distance, pointing
    deviation and start point variation (ranges over the trajectories).

    Args:
        frame: :func:`evaluate_runs` output.
        runs: the runs (:func:`load_runs`).
        steps: n, the number of points each trajectory solves.
        paper: add the paper's row (its cm-valued distances shown x 10, in mm).
    """
    missing_column = f"points missing the IK tolerance (of {steps}, per trajectory)"
    rows = []
    for name in [OURS, *baseline_names(runs)]:
        sub = frame[frame["method"] == name]
        ms = sub["duration_s"].to_numpy(dtype=float) * 1000.0
        missed = sub["points_not_converged"]
        missing = ("-" if missed.isna().any() else "none" if (missed == 0).all()
                   else ", ".join(f"{v:.0f}" for v in missed))
        run = runs[name]
        rows.append({
            "run": name, "method": run.method, "orientation": run.orientation or "",
            "task solved": TASK_CELLS.get(run.scheme, task_text(run.scheme)) if run.is_baseline
            else TASK_CELLS[OURS] if run.method == OURS else task_text(run.scheme),
            "time per trajectory [ms]": f"{ms[0]:.1f}" if len(ms) == 1 else
            f"median {np.median(ms):.1f} ({ms.min():.1f}-{ms.max():.1f})",
            missing_column: missing,
            "line distance, mean [mm]": _range(sub["line_distance_mean_mm"]),
            "pointing deviation, mean [deg]": _range(sub["pointing_deviation_mean_deg"]),
            "start point variation [mm]": _range(sub["start_point_error_mm"]),
        })
    values = paper_values()
    ids = [t for t in dict.fromkeys(frame["trajectory"]) if t in values["table2"]]
    if paper and ids:
        scale = values["table1_cm_to_mm"]
        p = [values["table2"][t] for t in ids]
        rows.append({
            "run": "paper (ikpy, other URDF)", "method": "", "orientation": "",
            "task solved": TASK_CELLS["paper"],
            "time per trajectory [ms]": "", missing_column: "",
            "line distance, mean [mm]": _range([r["line_distance_mean_printed"] * scale
                                                for r in p], 1),
            "pointing deviation, mean [deg]": _range([r["pointing_deviation_mean_deg"]
                                                      for r in p], 0),
            "start point variation [mm]": _range([r["start_point_variation_printed"] * scale
                                                  for r in p], 0)})
    return pd.DataFrame(rows)
#: The modes table's "task solved" cells: per scheme, for ``ours`` and the paper's row.
TASK_CELLS = {
    "walk": "touch-pose-only (walk from the touch pose; the start pose is free)",
    "track": "the paper's task (track from the start pose; start and touch poses fixed)",
    OURS: "the paper's task (whole trajectory; start and touch poses in its loss)",
    "paper": "touch-pose-only (the authors' walk from the touch pose)",
}
MODES_NOTE = (
    "Task solved: the paper's task fixes both the recorded start pose and the touch pose "
    "(its Sec. 3); the touch-pose-only task fixes the touch pose only, as the authors' walk "
    "back from it did for their Table 2 (its start pose is wherever the walk ends, so its "
    "start point variation is part of its result, not an error against the same task). "
    "Ranges are min-max over the trajectories, with the mean; time per trajectory is each "
    "run's own solver wall time (one run, not a benchmark; compare only runs made on the same "
    "machine under similar load). Points missing the IK tolerance: points whose solve ended "
    "above its tolerance (damped least squares: stalled or at --max-ik-iterations above "
    "--tolerance; ikpy: its answer checked by FK against --ikpy-position-tolerance and, where "
    "pointing is asked, --ikpy-pointing-tolerance), from details.csv (- where a run records "
    "none, as ikpy runs written before that check). Start point variation: |P_0 - P_s|.")


def table2_comparison(table: pd.DataFrame) -> pd.DataFrame:
    """Measured Table 2 columns beside the paper's (its cm values shown x 10, in mm).

    Args:
        table: one row per trajectory with ``trajectory``, ``line_distance_mean_mm``,
            ``line_distance_std_mm``, ``pointing_deviation_mean_deg``,
            ``pointing_deviation_std_deg`` and ``start_point_error_mm``.
    """
    paper = paper_values()["table2"]
    scale = paper_values()["table1_cm_to_mm"]  # the same cm -> mm slip in both tables
    rows = []
    for _, row in table.iterrows():
        p = paper.get(str(row["trajectory"]))
        rows.append({
            "trajectory": str(row["trajectory"]),
            **accuracy_beside_paper(row, p, scale),
            "start point variation [mm]": f"{row['start_point_error_mm']:.2f}",
            "paper start point variation [mm]": p and
            f"{p['start_point_variation_printed'] * scale:.0f}",
        })
    return pd.DataFrame(rows)


def table2_section(table: pd.DataFrame, steps: int | None = None,
                   run: str | None = None, method: str = BASELINE,
                   scheme: str | None = DEFAULT_SCHEME,
                   orientation: str | None = None) -> list[str]:
    """Markdown lines: the measured Table 2 beside the paper's, with the unit and ikpy notes
    and the task the run solved.

    Args:
        table: the baseline run's rows (see :func:`table2_comparison`).
        steps: the run's n (a note when it is not the paper's).
        run: the run's label for the heading (:attr:`MethodRun.label`).
        method: the run's method (a walk of the ``ikpy`` family in position mode: the note
            on the authors' own call).
        scheme: the run's scheme (``walk``, the paper's baseline's, or ``track``).
        orientation: the run's mode (None: its method's default).
    """
    heading = "## Beside the paper's Table 2" + (f": {run}" if run else "")
    authors = (METHOD_FAMILIES.get(method) == IKPY and scheme == "walk"
               and orientation in (None, "position"))
    note = IKPY_TABLE2_NOTE if authors else PAPER_BASELINE_NOTE
    lines = [heading, "", TABLE2_UNITS_NOTE, "", note, "", table2_task_line(scheme), ""]
    if steps is not None and steps != PAPER_STEPS:
        lines += [f"The paper used n = {PAPER_STEPS} segments; this run used n = {steps}.", ""]
    return lines + [markdown_table(table2_comparison(table)), ""]


def table2_task_line(scheme: str | None) -> str:
    """The sentence under a Table 2 section saying which task the run solved."""
    if scheme == "walk":
        return (f"Task solved: {task_text('walk')}, the task the paper's baseline solved for "
                "its Table 2; its start point variation measures where the walk ended.")
    if scheme == "track":
        return (f"Task solved: {task_text('track')}, not the paper's baseline's touch-pose-only "
                "walk: this run starts at the recorded start pose by construction, so its start "
                "point variation is not comparable with the paper's column.")
    return f"Task solved: {task_text(scheme) or 'not recorded'}."


def plot_pointing_per_step(deviations: dict[tuple[str, str], np.ndarray], tasks: Sequence[Task],
                           methods: list[str]) -> Figure:
    """Pointing deviation [deg] per step, one panel per trajectory, one line per method."""

    plt = _matplotlib()
    cols = min(4, len(tasks))
    rows = -(-len(tasks) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.8 * rows), squeeze=False,
                             sharey=True)
    styles = ["-", "--", ":", "-."]
    for ax, task in zip(axes.flat, tasks):
        for k, name in enumerate(methods):
            values = deviations[(name, task.name)]
            ax.plot(np.arange(len(values)), values, styles[k % 4], lw=1.4, label=name)
        ax.set_title(f"trajectory {task.name}", fontsize=9)
        ax.set_xlabel("step")
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("pointing deviation [deg]")
    for ax in list(axes.flat)[len(tasks):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle("angle between the finger's pointing direction and the line direction d, "
                 "per pose (step 0 = start, n = touch)", fontsize=10)
    fig.tight_layout()
    return fig


def _settings_line(run: MethodRun) -> str:
    text = ", ".join(f"{k}={v}" for k, v in run.record.method_settings().items()
                     if not isinstance(v, dict))
    machine = run.record.provenance
    return (f"| {run.name} | {run.method} | {text} | {machine.get('created_utc', '')} | "
            f"{machine.get('cpu', '')} | {machine.get('git_revision', '')} |")


def _side_by_side(frame: pd.DataFrame) -> pd.DataFrame:
    def pm(mean, std, digits=2):
        return f"{mean:.{digits}f} ± {std:.{digits}f}"

    return pd.DataFrame([{
        "trajectory": r["trajectory"], "method": r["method"],
        "duration [s]": r["duration_s"], "iterations": r["iterations"],
        "line distance [mm]": pm(r["line_distance_mean_mm"], r["line_distance_std_mm"]),
        "pointing deviation [deg]": pm(r["pointing_deviation_mean_deg"],
                                       r["pointing_deviation_std_deg"]),
        "|P_0 - P_s| [mm]": r["start_point_error_mm"],
        "|p_0 - p^s| [deg]": r["start_pose_error_deg"],
        "|P_n - P_e| [mm]": r["end_point_error_mm"],
        "|p_n - p^e| [deg]": r["end_pose_error_deg"],
        "mean sq. step [deg^2]": r["mean_sq_joint_step_deg2"],
        "max step [deg]": r["max_joint_step_deg"],
        "mean sq. jerk [deg^2]": r["mean_sq_jerk_deg2"],
        "sign changes": int(r["velocity_sign_changes"]),
    } for _, r in frame.iterrows()])


def escaped_table(frame: pd.DataFrame, digits: dict | None = None) -> str:
    """:func:`markdown_table` with "|" inside headers and cells escaped (|P_0 - P_s| ...)."""
    def escape(text):
        return text.replace("|", "\\|")

    safe = frame.rename(columns=escape).apply(
        lambda column: column.map(lambda v: escape(v) if isinstance(v, str) else v))
    return markdown_table(safe, {escape(k): v for k, v in (digits or {}).items()})


def _run_table2(frame: pd.DataFrame, runs: dict, name: str, steps: int,
                suffix: str = "") -> list[str]:
    """:func:`table2_section` of the run ``name``."""
    run = runs[name]
    return table2_section(frame[frame["method"] == name], steps, run.label + suffix,
                          run.method, run.scheme, run.orientation)


def write_comparison_report(output_dir: str | Path) -> Path:
    """Write ``output_dir/report.md`` and its figure comparing every run folder there.

    Args:
        output_dir: the ``--output`` directory of ``ikbench run`` runs; it must hold at least
            ``ours/`` and one baseline run (``sequential-ik``, ``sequential-ik-walk``,
            ``ikpy`` or ``ikpy-walk``; any folder name, e.g. one per orientation mode) on
            the same targets and n.

    Returns:
        The path of report.md.

    Raises:
        InputError: the directory is missing, lacks one of the two methods, or its runs do
            not match (targets, n, trajectory ids).
    """
    output_dir = Path(output_dir)
    result = load_comparison(output_dir)
    runs, tasks, targets, frame = result.runs, result.tasks, result.targets, result.frame
    atomic_savefig(output_dir / FIGURE_NAME,
                   plot_pointing_per_step(pointing_per_step(runs, tasks), tasks, list(runs)))
    table2 = table2_run(runs)
    lines = [
        f"# Comparison: {', '.join(runs)}", "",
        f"Produced by `ikbench report {output_dir}` from the trajectory CSVs in "
        "`<run>/trajectory_<id>.csv`; every figure is recomputed by `ikbench.core.metrics` "
        "(only duration and iterations come from each run's table.csv, the points that "
        "missed the IK tolerance from its details.csv). Targets: "
        f"{targets.source}; trajectories {', '.join(targets.ids)}; n = {targets.steps} "
        "segments. Distances in mm, angles in degrees (poses: motor degrees).", "",
        "| run | method | settings | run (UTC) | CPU | git |", "|---|---|---|---|---|---|",
        *[_settings_line(run) for run in runs.values()], "",
        "Durations are each solver's own wall time as recorded by its run; compare them only "
        "between runs on the same machine under similar load.", "",
        "## The paper's claims about its traditional baseline, checked", "",
        *claims_lines(result.summary, runs, frame, level=3),
        "## The baseline's orientation modes", "",
        "Each baseline run with the task it solved (its scheme), beside `ours`:", "",
        escaped_table(modes_table(frame, runs, targets.steps, targets.is_paper)), "",
        MODES_NOTE, "",
        "## Summary over the trajectories", "",
        escaped_table(result.summary, {"median duration [s]": 4, "median iterations": 0,
                                "max |p_0 - p^s| [deg]": 3, "median |p_0 - p^s| [deg]": 3,
                                "start pose spread [deg]": 3,
                                "median mean sq. jerk [deg^2]": 3,
                                "median velocity sign changes": 1,
                                "points missing the IK tolerance": 0,
                                "points solved": 0}), "",
        "Start pose spread: max over joints of (max - min over trajectories) of the first pose; "
        "start point spread: largest distance between two trajectories' first points. Mean "
        "squared joint step and jerk (third difference) are per step, from "
        "`ikbench.core.metrics.smoothness`. Points missing the IK tolerance: summed over the "
        "trajectories (empty for methods without an IK tolerance).", "",
        "## Per trajectory, side by side", "",
        escaped_table(_side_by_side(frame), {"duration [s]": 4, "iterations": 0,
                                      "|p_0 - p^s| [deg]": 3,
                                      "mean sq. jerk [deg^2]": 3}), "",
        "## Pointing deviation per step", "", f"![pointing deviation per step]({FIGURE_NAME})",
        "",
    ]
    if targets.is_paper:
        lines += _run_table2(frame, runs, table2, targets.steps)
        authors = ikpy_table2_run(runs)
        if authors is not None and authors != table2:
            lines += _run_table2(frame, runs, authors, targets.steps, ", the authors' call")
    else:
        lines += ["## The paper's baseline", "", PAPER_BASELINE_NOTE, ""]
    path = output_dir / REPORT_NAME
    atomic_write_text(path, "\n".join(lines))
    return path
