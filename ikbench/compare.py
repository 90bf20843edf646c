"""Methods side by side, and the paper's claims about its baseline checked with numbers.

``ikbench report DIR`` (:func:`write_comparison_report`) reads every method folder that
``ikbench run --output DIR`` wrote (``DIR/<method>/run.json`` + ``trajectory_<id>.csv``),
recomputes every figure with :mod:`ikbench.metrics` from the trajectory CSVs (only the solver's
own duration and iteration count come from ``table.csv``), and writes ``DIR/report.md`` and
``DIR/pointing_deviation_per_step.png``.

The paper (Section "Results") says of its traditional baseline: generation is much faster,
the pointing vector is much worse, the start pose varies significantly (constant with ours),
and the fluency is comparable. :func:`check_claims` turns each into a measured ratio and a
stated threshold (:data:`FASTER_FACTOR`, ...), with a verdict *holds* / *does not hold*.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.errors import InputError
from ikbench.io import atomic_savefig, atomic_write_text
from ikbench.metrics import pointing_deviations_deg, trajectory_metrics
from ikbench.report import PAPER_STEPS, accuracy_beside_paper, markdown_table, paper_values

OURS, BASELINE = "ours", "sequential-ik"
REPORT_NAME = "report.md"
FIGURE_NAME = "pointing_deviation_per_step.png"
#: "much faster": the median duration of ours is at least this many times the baseline's.
FASTER_FACTOR = 10.0
#: "much worse": the baseline's mean pointing deviation is at least this many times ours.
WORSE_FACTOR = 2.0
#: "constant" start pose: within this many motor degrees of the recorded start pose p^s.
CONSTANT_START_DEG = 1.0
#: "varies": the baseline's median start-pose error is at least this many times ours' largest.
VARIES_FACTOR = 10.0
#: "comparable" fluency: the baseline's median figure is within this factor of ours (either way).
COMPARABLE_FACTOR = 2.0
PAPER_BASELINE_NOTE = (
    "The paper's baseline is not this one: the authors solved it with ikpy on a *different* "
    "NICO URDF (other joint conventions; shared/reference/README.md), so only its qualitative "
    "claims are expected to carry over, not its numbers. Their script (andylucny/nico2, "
    "`generate-ikpy/generate-ikpy.py`) passes a target frame to ikpy's "
    "`inverse_kinematics_frame` without `orientation_mode`, and ikpy then fits the position "
    "only; `ikbench run --method sequential-ik --orientation position` solves that problem.")
TABLE2_UNITS_NOTE = (
    "Columns named *paper* are copied from the paper's Table 2. Its \"distance from the line "
    "[mm]\" and \"start point variation [mm]\" values are in centimetres (the unit label is off "
    "by a factor of ten, see shared/reference/README.md), so they are shown here x 10, in mm. "
    "*Start point variation* is |P_0 - P_s|, the distance of the trajectory's first point from "
    "the recorded start point.")


@dataclass
class MethodRun:
    """One method folder read back from disk.

    Attributes:
        name: method name (folder name).
        record: its run.json.
        poses: trajectory id -> (n+1, dof) poses [motor deg] read from the CSVs.
        solver: trajectory id -> {"duration_s", "iterations"} from table.csv.
    """

    name: str
    record: dict
    poses: dict
    solver: dict


def _method_folders(output_dir: Path) -> list[Path]:
    return sorted(p.parent for p in output_dir.glob("*/run.json")
                  if any(p.parent.glob("trajectory_*.csv")))


def load_method_run(folder: Path, robot) -> MethodRun:
    """Read run.json, the trajectory CSVs and the solver columns of table.csv in ``folder``."""
    from ikbench.trajectory import read_trajectory_poses

    try:
        record = json.loads((folder / "run.json").read_text())
        table = pd.read_csv(folder / "table.csv", dtype={"trajectory": str})
    except (OSError, ValueError) as exc:
        raise InputError(f"report: cannot read {folder}: {exc}") from None
    ids = [str(i) for i in record.get("trajectories", [])]
    poses, solver = {}, {}
    for tid in ids:
        poses[tid] = read_trajectory_poses(folder / f"trajectory_{tid}.csv", robot)
        row = table[table["trajectory"] == tid]
        solver[tid] = {"duration_s": float(row["duration_s"].iloc[0]) if len(row) else np.nan,
                       "iterations": float(row["iterations"].iloc[0]) if len(row) else np.nan}
    return MethodRun(folder.name, record, poses, solver)


def load_runs(output_dir) -> tuple[dict, list, object]:
    """Every method run in ``output_dir`` and the shared tasks; InputError if unusable.

    Returns:
        (runs: name -> MethodRun, tasks: the tasks of the trajectories all runs share, targets)
    """
    from ikbench.robot import load_robot
    from ikbench.targets import load_targets
    from ikbench.task import line_tasks

    output_dir = Path(output_dir)
    if not output_dir.is_dir():
        raise InputError(f"report: {str(output_dir)!r} is not a directory; give the --output "
                         "directory of `ikbench run`")
    folders = _method_folders(output_dir)
    names = [f.name for f in folders]
    missing = [m for m in (OURS, BASELINE) if m not in names]
    if missing:
        raise InputError(
            f"report: {str(output_dir)!r} has no {' or '.join(missing)} results (method folders "
            f"found: {', '.join(names) or 'none'}); run `ikbench run --method "
            f"{missing[0]} --output {output_dir}` first")
    robot = load_robot()
    runs = {f.name: load_method_run(f, robot) for f in folders}
    shaped = [n for n, r in runs.items() if r.record.get("shape", "line") != "line"]
    if shaped:
        raise InputError(f"report: compares line runs (touch poses) only; {', '.join(shaped)} "
                         f"in {str(output_dir)!r} drew another shape")
    turned = [n for n, r in runs.items() if r.record.get("direction") is not None]
    if turned:
        raise InputError(f"report: compares runs pointing along the line only; "
                         f"{', '.join(turned)} in {str(output_dir)!r} used --direction")
    keys = {name: (str(r.record.get("targets")), r.record.get("steps"),
                   tuple(r.record.get("start_pose_deg") or ())) for name, r in runs.items()}
    if len(set(keys.values())) > 1:
        raise InputError("report: the method folders were run on different targets, steps or "
                         "start poses: " + "; ".join(f"{n}: targets {t}, n = {s}, start {p}"
                                                     for n, (t, s, p) in keys.items()))
    source, steps, start = keys[OURS]
    shared = [t for t in runs[OURS].poses if all(t in r.poses for r in runs.values())]
    if not shared:
        raise InputError("report: the method folders share no trajectory id")
    targets = load_targets(source, robot).select(shared).with_steps(int(steps))
    if start:  # the run's own start pose (--start-pose may have replaced the file's)
        targets = replace(targets, start_pose_deg=np.asarray(start, dtype=float))
    return runs, line_tasks(robot, targets), targets


def evaluate_runs(runs: dict, tasks) -> pd.DataFrame:
    """One row per (trajectory, method): solver figures + :func:`trajectory_metrics`."""
    from ikbench.robot import load_robot

    robot = load_robot()
    rows = []
    for task in tasks:
        for name, run in runs.items():
            poses = run.poses[task.name]
            if len(poses) != task.steps + 1:
                raise InputError(f"report: {name}/trajectory_{task.name}.csv has {len(poses)} "
                                 f"poses; run.json says n = {task.steps}")
            metrics = trajectory_metrics(robot, task, poses)
            rows.append({"trajectory": task.name, "method": name, **run.solver[task.name],
                         **metrics, "start_point_mm": robot.fk(poses[0]).point_mm[0]})
    return pd.DataFrame(rows)


def pointing_per_step(runs: dict, tasks) -> dict:
    """(method, trajectory id) -> (n+1,) pointing deviation [deg] of each pose."""
    from ikbench.robot import load_robot

    robot = load_robot()
    return {(name, task.name): pointing_deviations_deg(robot.fk(run.poses[task.name]).direction,
                                                       task.goal_directions)
            for name, run in runs.items() for task in tasks}


def summarise(frame: pd.DataFrame, runs: dict) -> pd.DataFrame:
    """Per-method summary over the trajectories (medians unless the column says otherwise)."""
    rows = []
    for name, run in runs.items():
        sub = frame[frame["method"] == name]
        start_poses = np.stack([run.poses[t][0] for t in sub["trajectory"]])
        start_points = np.stack(sub["start_point_mm"].to_numpy())
        rows.append({
            "method": name,
            "median duration [s]": sub["duration_s"].median(),
            "median iterations": sub["iterations"].median(),
            "mean line distance [mm]": sub["line_distance_mean_mm"].mean(),
            "mean pointing deviation [deg]": sub["pointing_deviation_mean_deg"].mean(),
            "max |P_0 - P_s| [mm]": sub["start_point_error_mm"].max(),
            "max |p_0 - p^s| [deg]": sub["start_pose_error_deg"].max(),
            "median |p_0 - p^s| [deg]": sub["start_pose_error_deg"].median(),
            "start pose spread [deg]": float(np.max(np.ptp(start_poses, axis=0))),
            "start point spread [mm]": float(np.max(np.linalg.norm(
                start_points[:, None] - start_points[None], axis=-1))),
            "max |P_n - P_e| [mm]": sub["end_point_error_mm"].max(),
            "median mean sq. joint step [deg^2]": sub["mean_sq_joint_step_deg2"].median(),
            "median mean sq. jerk [deg^2]": sub["mean_sq_jerk_deg2"].median(),
            "median max joint step [deg]": sub["max_joint_step_deg"].median(),
            "median velocity sign changes": sub["velocity_sign_changes"].median(),
        })
    return pd.DataFrame(rows)


def check_claims(summary: pd.DataFrame) -> pd.DataFrame:
    """The paper's four claims about its baseline, each with numbers and a verdict."""
    ours = summary.set_index("method").loc[OURS]
    base = summary.set_index("method").loc[BASELINE]

    def ratio(a, b):
        return float(a) / float(b) if b else float("inf")

    speed = ratio(ours["median duration [s]"], base["median duration [s]"])
    pointing = ratio(base["mean pointing deviation [deg]"], ours["mean pointing deviation [deg]"])
    start = ratio(base["median |p_0 - p^s| [deg]"], ours["max |p_0 - p^s| [deg]"])
    step = ratio(base["median mean sq. joint step [deg^2]"],
                 ours["median mean sq. joint step [deg^2]"])
    jerk = ratio(base["median mean sq. jerk [deg^2]"], ours["median mean sq. jerk [deg^2]"])

    def comparable(r):
        return 1.0 / COMPARABLE_FACTOR <= r <= COMPARABLE_FACTOR

    claims = [
        ("sequential generation is much faster",
         f"median duration: ours {ours['median duration [s]']:.3g} s, sequential-ik "
         f"{base['median duration [s]']:.3g} s; ratio ours / sequential = {speed:.0f}",
         f"ratio >= {FASTER_FACTOR:g}", speed >= FASTER_FACTOR),
        ("its pointing deviation is much worse",
         f"mean pointing deviation: ours {ours['mean pointing deviation [deg]']:.2f} deg, "
         f"sequential-ik {base['mean pointing deviation [deg]']:.2f} deg; ratio sequential / "
         f"ours = {pointing:.2f}", f"ratio >= {WORSE_FACTOR:g}", pointing >= WORSE_FACTOR),
        ("its start pose varies, while ours is constant",
         f"|p_0 - p^s| [motor deg]: ours max {ours['max |p_0 - p^s| [deg]']:.3f}, "
         f"sequential-ik median {base['median |p_0 - p^s| [deg]']:.2f} (ratio {start:.0f}); "
         f"spread of start poses over the trajectories: ours "
         f"{ours['start pose spread [deg]']:.3f} deg, sequential-ik "
         f"{base['start pose spread [deg]']:.2f} deg; of start points: ours "
         f"{ours['start point spread [mm]']:.2f} mm, sequential-ik "
         f"{base['start point spread [mm]']:.2f} mm; max |P_0 - P_s|: ours "
         f"{ours['max |P_0 - P_s| [mm]']:.2f} mm, sequential-ik "
         f"{base['max |P_0 - P_s| [mm]']:.2f} mm",
         f"ours max <= {CONSTANT_START_DEG:g} deg and sequential median >= "
         f"{VARIES_FACTOR:g} x ours max",
         ours["max |p_0 - p^s| [deg]"] <= CONSTANT_START_DEG and start >= VARIES_FACTOR),
        ("the fluency is comparable",
         f"median mean squared joint step: ours "
         f"{ours['median mean sq. joint step [deg^2]']:.2f}, sequential-ik "
         f"{base['median mean sq. joint step [deg^2]']:.2f} deg^2 (ratio {step:.2f}); median "
         f"mean squared jerk: ours {ours['median mean sq. jerk [deg^2]']:.3f}, sequential-ik "
         f"{base['median mean sq. jerk [deg^2]']:.3f} deg^2 (ratio {jerk:.2f})",
         f"both ratios within 1/{COMPARABLE_FACTOR:g} .. {COMPARABLE_FACTOR:g}",
         comparable(step) and comparable(jerk)),
    ]
    return pd.DataFrame(
        [{"paper's claim": c, "measured": m, "criterion": k,
          "verdict": "holds" if ok else "does not hold"} for c, m, k, ok in claims])


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


def table2_section(table: pd.DataFrame, steps: int | None = None) -> list[str]:
    """Markdown lines: the measured Table 2 beside the paper's, with the unit and ikpy notes."""
    lines = ["## Beside the paper's Table 2", "", TABLE2_UNITS_NOTE, "", PAPER_BASELINE_NOTE, ""]
    if steps is not None and steps != PAPER_STEPS:
        lines += [f"The paper used n = {PAPER_STEPS} segments; this run used n = {steps}.", ""]
    return lines + [markdown_table(table2_comparison(table)), ""]


def plot_pointing_per_step(deviations: dict, tasks, methods: list[str]):
    """Pointing deviation [deg] per step, one panel per trajectory, one line per method."""
    from ikbench.report import _matplotlib

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
    settings = run.record.get("settings", {})
    settings = settings.get("settings", settings) if isinstance(settings, dict) else settings
    text = ", ".join(f"{k}={v}" for k, v in settings.items()
                     if not isinstance(v, dict)) if isinstance(settings, dict) else str(settings)
    return (f"| {run.name} | {text} | {run.record.get('created_utc', '')} | "
            f"{run.record.get('cpu', '')} | {run.record.get('git_revision', '')} |")


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


def _table(frame: pd.DataFrame, digits: dict | None = None) -> str:
    """:func:`markdown_table` with "|" inside headers and cells escaped (|P_0 - P_s| ...)."""
    def escape(text):
        return text.replace("|", "\\|")

    safe = frame.rename(columns=escape).apply(
        lambda column: column.map(lambda v: escape(v) if isinstance(v, str) else v))
    return markdown_table(safe, {escape(k): v for k, v in (digits or {}).items()})


def convergence_lines(output_dir: Path, runs: dict, tasks) -> list[str]:
    """One line per method whose details.csv counts points that missed their tolerance."""
    lines = []
    for name in runs:
        try:
            details = pd.read_csv(output_dir / name / "details.csv", dtype={"trajectory": str})
        except (OSError, ValueError):
            continue
        if "points_not_converged" not in details.columns:
            continue
        counts = details.set_index("trajectory")
        parts = [f"{t.name}: {int(counts.loc[t.name, 'points_not_converged'])}/"
                 f"{int(counts.loc[t.name, 'points_solved'])}" if "points_solved" in counts
                 else f"{t.name}: {int(counts.loc[t.name, 'points_not_converged'])}"
                 for t in tasks if t.name in counts.index]
        lines.append(f"- {name}: points that did not reach the IK tolerance, per trajectory: "
                     + ", ".join(parts))
    return lines + [""] if lines else []


def write_comparison_report(output_dir) -> Path:
    """Write ``output_dir/report.md`` and its figure comparing every method folder there.

    Args:
        output_dir: the ``--output`` directory of ``ikbench run`` runs; it must hold at least
            ``ours/`` and ``sequential-ik/`` on the same targets and n.

    Returns:
        The path of report.md.

    Raises:
        InputError: the directory is missing, lacks one of the two methods, or its runs do
            not match (targets, n, trajectory ids).
    """
    output_dir = Path(output_dir)
    runs, tasks, targets = load_runs(output_dir)
    order = [OURS, BASELINE] + [n for n in runs if n not in (OURS, BASELINE)]
    runs = {name: runs[name] for name in order}
    frame = evaluate_runs(runs, tasks)
    summary = summarise(frame, runs)
    claims = check_claims(summary)
    atomic_savefig(output_dir / FIGURE_NAME,
                   plot_pointing_per_step(pointing_per_step(runs, tasks), tasks, list(runs)))
    base_rows = frame[frame["method"] == BASELINE]
    lines = [
        f"# Comparison: {', '.join(runs)}", "",
        f"Produced by `ikbench report {output_dir}` from the trajectory CSVs in "
        f"`<method>/trajectory_<id>.csv`; every figure is recomputed by `ikbench.metrics` "
        "(only duration and iterations come from each method's table.csv). Targets: "
        f"{targets.source}; trajectories {', '.join(targets.ids)}; n = {targets.steps} "
        "segments. Distances in mm, angles in degrees (poses: motor degrees).", "",
        "| method | settings | run (UTC) | CPU | git |", "|---|---|---|---|---|",
        *[_settings_line(run) for run in runs.values()], "",
        "Durations are each solver's own wall time as recorded by its run; compare them only "
        "between runs on the same machine under similar load.", "",
        "## The paper's claims about its traditional baseline, checked", "",
        _table(claims), "",
        *convergence_lines(output_dir, runs, tasks),
        "The baseline's orientation mode (settings above) decides the pointing claim: "
        "`--orientation frame` (the paper's text: point + line direction + a fixed roll), "
        "`pointing` (point + direction, roll free) or `position` (what the authors' ikpy call "
        "solved, see the last section).", "",
        "## Summary over the trajectories", "",
        _table(summary, {"median duration [s]": 4, "median iterations": 0,
                                 "max |p_0 - p^s| [deg]": 3, "median |p_0 - p^s| [deg]": 3,
                                 "start pose spread [deg]": 3,
                                 "median mean sq. jerk [deg^2]": 3,
                                 "median velocity sign changes": 1}), "",
        "Start pose spread: max over joints of (max - min over trajectories) of the first pose; "
        "start point spread: largest distance between two trajectories' first points. Mean "
        "squared joint step and jerk (third difference) are per step, from "
        "`ikbench.metrics.smoothness`.", "",
        "## Per trajectory, side by side", "",
        _table(_side_by_side(frame), {"duration [s]": 4, "iterations": 0,
                                              "|p_0 - p^s| [deg]": 3,
                                              "mean sq. jerk [deg^2]": 3}), "",
        "## Pointing deviation per step", "", f"![pointing deviation per step]({FIGURE_NAME})",
        "",
    ]
    if targets.is_paper:
        lines += table2_section(base_rows, targets.steps)
    else:
        lines += ["## The paper's baseline", "", PAPER_BASELINE_NOTE, ""]
    path = output_dir / REPORT_NAME
    atomic_write_text(path, "\n".join(lines))
    return path
