"""Methods side by side, and the paper's claims about its baseline checked with numbers.

``ikbench report DIR`` (:func:`write_comparison_report`) reads every run folder that
``ikbench run --output DIR [--name NAME]`` wrote (``DIR/<name>/run.json`` +
``trajectory_<id>.csv``; the folders of other commands, :data:`ikbench.studies.run.RESERVED_NAMES`,
and folders without trajectories are not runs), recomputes every figure with
:mod:`ikbench.core.metrics` from the trajectory CSVs (only the solver's own duration and iteration
count come from ``table.csv``, the count of points that missed the IK tolerance from
``details.csv``), and writes ``DIR/report.md`` and ``DIR/pointing_deviation_per_step.png``.

The paper (Section "Results") says of its traditional baseline: generation is much faster,
the pointing vector is much worse, the start pose varies significantly (constant with ours),
and the fluency is comparable. :func:`check_claims` turns each into a measured ratio and a
stated threshold (:data:`FASTER_FACTOR`, ...), with a verdict *holds* / *does not hold*, for
every baseline run against the folder ``ours``. Baseline runs are the folders whose run.json
names a method of the families :data:`METHOD_FAMILIES`: ``sequential-ik`` /
``sequential-ik-walk`` (e.g. one per ``--orientation`` mode) and ``ikpy`` / ``ikpy-walk``,
the authors' own library (``ikpy-walk --ikpy-orientation position`` is the call they made for
Table 2).

Every baseline run states the task it solved, from its scheme (run.json's settings
``scheme``; folders written before the schemes existed have none and are walks):
:data:`SCHEME_TASKS`. The paper's baseline walked back from the touch pose (the start pose is
wherever the walk ends: a touch-pose-only task); a ``track`` run starts at the recorded start
pose and lands on the touch pose (the paper's own task, Sec. 3). The paper's claim that the
baseline's start pose varies is a property of the walk; the report checks it on every run and
says what it shows for each scheme.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_savefig, atomic_write_text
from ikbench.core.metrics import pointing_deviations_deg, trajectory_metrics
from ikbench.paper.values import PAPER_STEPS, accuracy_beside_paper, paper_values
from ikbench.render.run_report import markdown_table
from ikbench.studies.run import RESERVED_NAMES, robot_from_record

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.robot import Robot
    from ikbench.core.targets import Targets
    from ikbench.core.task import Task

OURS, BASELINE = "ours", "sequential-ik"
#: The paper authors' own baseline library; its runs are baseline runs too.
IKPY = "ikpy"
#: The walk variants of the baselines (the paper's Table 2 scheme: back from the touch pose).
BASELINE_WALK, IKPY_WALK = "sequential-ik-walk", "ikpy-walk"
#: Baseline method -> its family (the registered methods that share options and modes).
METHOD_FAMILIES = {BASELINE: BASELINE, BASELINE_WALK: BASELINE, IKPY: IKPY, IKPY_WALK: IKPY}
#: The scheme of a baseline run whose run.json records none (written before the schemes:
#: every such sequential-ik and ikpy run walked back from the touch pose).
DEFAULT_SCHEME = "walk"
#: Scheme -> (how the run solved it, the task it solved) in words.
SCHEME_TASKS = {
    "walk": ("walk from the touch pose", "touch-pose-only task: the start pose is free"),
    "track": ("track from the start pose", "the paper's task: start and touch poses fixed"),
}
#: The schemes in report order (the paper's Table 2 scheme first).
SCHEME_ORDER = ("walk", "track")
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
#: The baseline's orientation modes, in report order, and what each solves per point.
ORIENTATION_MODES = {
    "frame": "goal point, line direction and a fixed roll, the full frame (the paper's text; "
             f"the default of `{BASELINE_WALK}`, and Table 2)",
    "pointing": "goal point and pointing direction, roll free",
    "position": "goal point only (what the authors' ikpy call solved)",
}
#: ikpy's modes (``--ikpy-orientation``), in report order.
IKPY_MODES = {
    "position": "goal point only, by the authors' own call (ikpy's inverse_kinematics_frame "
                f"without orientation_mode; walked, `{IKPY_WALK}`: Table 2 as they ran it)",
    "pointing": "goal point and pointing axis (ikpy's orientation_mode), roll free",
}
#: The baseline method families in report order: the option naming their mode, and their modes.
BASELINE_METHODS = {BASELINE: ("--orientation", ORIENTATION_MODES),
                    IKPY: ("--ikpy-orientation", IKPY_MODES)}
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


@dataclass
class MethodRun:
    """One run folder read back from disk.

    Attributes:
        name: the folder's name (``sequential-ik-position``); how the reports call the run.
        record: its run.json.
        poses: trajectory id -> (n+1, dof) poses [motor deg] read from the CSVs.
        solver: trajectory id -> {"duration_s", "iterations"} from table.csv.
        details: its details.csv (None when missing or unreadable).
    """

    name: str
    record: dict
    poses: dict
    solver: dict
    details: pd.DataFrame | None = None

    @property
    def method(self) -> str:
        """The registered method that produced the run (run.json's ``method``)."""
        return str(self.record.get("method") or self.name)

    @property
    def family(self) -> str:
        """The baseline family of the method (``sequential-ik`` for ``sequential-ik-walk``,
        ``ikpy`` for ``ikpy-walk``), else the method itself."""
        return METHOD_FAMILIES.get(self.method, self.method)

    @property
    def is_baseline(self) -> bool:
        """Whether the run is one of the paper's baseline families (:data:`BASELINE_METHODS`)."""
        return self.family in BASELINE_METHODS

    @property
    def orientation(self) -> str | None:
        """The baseline's ``--orientation`` mode from run.json (None for other methods)."""
        mode = run_settings(self.record).get("orientation")
        return str(mode) if mode is not None else None

    @property
    def scheme(self) -> str | None:
        """``walk`` or ``track``: run.json's settings ``scheme``; a baseline run that records
        none is a walk (:data:`DEFAULT_SCHEME`); None for other methods without one."""
        return scheme_of(self.method, self.record)

    @property
    def task(self) -> str:
        """The task the run solved, in words: ``walk from the touch pose (touch-pose-only
        task: the start pose is free)`` or ``track from the start pose (the paper's task:
        start and touch poses fixed)``; "" when the run has no scheme."""
        return task_text(self.scheme)

    @property
    def mode_flag(self) -> str:
        """The option naming the run's mode: ``--orientation`` or ``--ikpy-orientation``."""
        return BASELINE_METHODS.get(self.family, ("--orientation",))[0]

    @property
    def description(self) -> str:
        """``sequential-ik-walk, --orientation position; walk from the touch pose:
        touch-pose-only task``: the method (when not the folder's name), the mode and the
        task solved; "" when none applies."""
        parts = [] if self.method == self.name else [self.method]
        if self.orientation:
            parts.append(f"{self.mode_flag} {self.orientation}")
        text = ", ".join(parts)
        if self.scheme:
            text += ("; " if text else "") + task_text(self.scheme, short=True)
        return text

    @property
    def label(self) -> str:
        """``sequential-ik-position (sequential-ik-walk, --orientation position; walk from the
        touch pose: touch-pose-only task)`` or the name (:attr:`description`)."""
        return f"{self.name} ({self.description})" if self.description else self.name


def run_settings(record: dict) -> dict:
    """The method's settings from a run.json (``{"settings": {...}}`` or flat), or {}."""
    settings = record.get("settings") or {}
    settings = settings.get("settings", settings) if isinstance(settings, dict) else {}
    return settings if isinstance(settings, dict) else {}


def scheme_of(method: str, record: dict) -> str | None:
    """A run's scheme from its run.json: the settings' ``scheme``, else ``walk`` for the
    baseline families (runs written before the schemes all walked), else None."""
    scheme = run_settings(record).get("scheme")
    if scheme is not None:
        return str(scheme)
    return DEFAULT_SCHEME if METHOD_FAMILIES.get(method, method) in BASELINE_METHODS else None


def task_text(scheme: str | None, short: bool = False) -> str:
    """The task a scheme solves, in words (:data:`SCHEME_TASKS`): ``walk from the touch pose
    (touch-pose-only task: the start pose is free)``; with ``short`` ``walk from the touch
    pose: touch-pose-only task``; "" for None, the scheme itself when unknown."""
    if scheme is None:
        return ""
    if scheme not in SCHEME_TASKS:
        return f"scheme {scheme}"
    how, task = SCHEME_TASKS[scheme]
    return f"{how}: {task.split(':')[0]}" if short else f"{how} ({task})"


def _read_record(folder: Path) -> dict:
    try:
        record = json.loads((folder / "run.json").read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"report: cannot read {folder / 'run.json'}: {exc}") from None
    if not isinstance(record, dict):
        raise InputError(f"report: {folder / 'run.json'} is not a JSON object")
    return record


def _method_folders(output_dir: Path) -> list[Path]:
    """The run folders of ``output_dir``: a run.json naming a method and its trajectories,
    and trajectory CSVs beside it; the folders of other commands are skipped by name."""
    folders = []
    for path in sorted(output_dir.glob("*/run.json")):
        folder = path.parent
        if folder.name in RESERVED_NAMES or not any(folder.glob("trajectory_*.csv")):
            continue
        record = _read_record(folder)
        if isinstance(record.get("method"), str) and isinstance(record.get("trajectories"),
                                                                list):
            folders.append(folder)
    return folders


def load_method_run(folder: Path, robot: Robot) -> MethodRun:
    """Read run.json, the trajectory CSVs, the solver columns of table.csv and details.csv."""
    from ikbench.core.trajectory import read_trajectory_poses

    record = _read_record(folder)
    try:
        table = pd.read_csv(folder / "table.csv", dtype={"trajectory": str})
    except (OSError, ValueError) as exc:
        raise InputError(f"report: cannot read {folder}: {exc}") from None
    try:
        details = pd.read_csv(folder / "details.csv", dtype={"trajectory": str})
    except (OSError, ValueError):
        details = None
    ids = [str(i) for i in record.get("trajectories", [])]
    poses, solver = {}, {}
    for tid in ids:
        poses[tid] = read_trajectory_poses(folder / f"trajectory_{tid}.csv", robot)
        row = table[table["trajectory"] == tid]
        solver[tid] = {"duration_s": float(row["duration_s"].iloc[0]) if len(row) else np.nan,
                       "iterations": float(row["iterations"].iloc[0]) if len(row) else np.nan}
    return MethodRun(folder.name, record, poses, solver, details)


def baseline_names(runs: dict) -> list[str]:
    """The baseline runs (method families :data:`BASELINE_METHODS`) in report order: by
    family, then by scheme (the walk, the paper's Table 2, first), then by mode
    (:data:`ORIENTATION_MODES`, :data:`IKPY_MODES`), the folder named after the family first
    within a mode."""
    families = list(BASELINE_METHODS)

    def key(name):
        run = runs[name]
        modes = list(BASELINE_METHODS[run.family][1])
        mode, scheme = run.orientation, run.scheme
        return (families.index(run.family),
                SCHEME_ORDER.index(scheme) if scheme in SCHEME_ORDER else len(SCHEME_ORDER),
                modes.index(mode) if mode in modes else len(modes), name != run.family, name)

    return sorted((n for n, r in runs.items() if r.is_baseline), key=key)


def table2_run(runs: dict) -> str:
    """The baseline run set beside the paper's Table 2: the first walk of the
    ``sequential-ik`` family in ``frame`` mode (the folder ``sequential-ik`` when it is
    one), else the first baseline walk, else the first baseline run."""
    names = baseline_names(runs)
    return next((n for n in names if runs[n].family == BASELINE and runs[n].scheme == "walk"
                 and runs[n].orientation == "frame"),
                next((n for n in names if runs[n].scheme == "walk"), names[0]))


def ikpy_table2_run(runs: dict) -> str | None:
    """The run of the authors' call beside the paper's Table 2: the first walk of the
    ``ikpy`` family in ``position`` mode, or None."""
    return next((n for n in baseline_names(runs) if runs[n].family == IKPY
                 and runs[n].scheme == "walk" and runs[n].orientation == "position"), None)


def load_runs(output_dir: str | Path) -> tuple[dict[str, MethodRun], list[Task], Targets]:
    """Every run in ``output_dir`` and the shared tasks; InputError if unusable.

    Returns:
        (runs: folder name -> MethodRun in report order (``ours``, the baseline runs, the
        others by name), tasks: the tasks of the trajectories all runs share, targets)
    """
    from ikbench.core.targets import load_targets
    from ikbench.core.task import line_tasks

    output_dir = Path(output_dir)
    if not output_dir.is_dir():
        raise InputError(f"report: {str(output_dir)!r} is not a directory; give the --output "
                         "directory of `ikbench run`")
    folders = _method_folders(output_dir)
    names = [f.name for f in folders]
    methods = {f.name: _read_record(f).get("method") for f in folders}
    baselines = set(methods.values()) & set(METHOD_FAMILIES)
    missing = [m for m, ok in ((OURS, OURS in names), (BASELINE, bool(baselines))) if not ok]
    if missing:
        raise InputError(
            f"report: {str(output_dir)!r} has no {' or '.join(missing)} results (method folders "
            f"found: {', '.join(names) or 'none'}); run `ikbench run --method "
            f"{missing[0]} --output {output_dir}` first")
    robot = robot_from_record(_read_record(output_dir / OURS))
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
    targets = load_targets(source, robot).select(shared).with_steps(int(steps or 0))
    if start:  # the run's own start pose (--start-pose may have replaced the file's)
        targets = replace(targets, start_pose_deg=np.asarray(start, dtype=float))
    order = [OURS, *baseline_names(runs)]
    order += sorted(n for n in runs if n not in order)
    return {n: runs[n] for n in order}, line_tasks(robot, targets), targets


def evaluate_runs(runs: dict[str, MethodRun], tasks: Sequence[Task]) -> pd.DataFrame:
    """One row per (trajectory, run): solver figures + :func:`trajectory_metrics`."""
    robot = robot_from_record(next(iter(runs.values())).record)
    rows = []
    for task in tasks:
        for name, run in runs.items():
            poses = run.poses[task.name]
            if len(poses) != task.steps + 1:
                raise InputError(f"report: {name}/trajectory_{task.name}.csv has {len(poses)} "
                                 f"poses; run.json says n = {task.steps}")
            metrics = trajectory_metrics(robot, task, poses)
            rows.append({"trajectory": task.name, "method": name, **run.solver[task.name],
                         **metrics, "start_point_mm": robot.fk(poses[0]).point_mm[0],
                         **_missed(run, task.name)})
    return pd.DataFrame(rows)


def _missed(run: MethodRun, trajectory: str) -> dict:
    """Points that missed the IK tolerance and points solved, from details.csv (NaN if none)."""
    details = run.details
    if details is None or "points_not_converged" not in details.columns:
        return {"points_not_converged": np.nan, "points_solved": np.nan}
    row = details[details["trajectory"] == trajectory]
    if not len(row):
        return {"points_not_converged": np.nan, "points_solved": np.nan}
    solved = row["points_solved"].iloc[0] if "points_solved" in row else np.nan
    return {"points_not_converged": float(row["points_not_converged"].iloc[0]),
            "points_solved": float(solved)}


def pointing_per_step(runs: dict[str, MethodRun], tasks: Sequence[Task]
                      ) -> dict[tuple[str, str], np.ndarray]:
    """(run, trajectory id) -> (n+1,) pointing deviation [deg] of each pose."""
    robot = robot_from_record(next(iter(runs.values())).record)
    return {(name, task.name): pointing_deviations_deg(robot.fk(run.poses[task.name]).direction,
                                                       task.goal_directions)
            for name, run in runs.items() for task in tasks}


def summarise(frame: pd.DataFrame, runs: dict) -> pd.DataFrame:
    """Per-run summary over the trajectories (medians unless the column says otherwise)."""
    rows = []
    for name, run in runs.items():
        sub = frame[frame["method"] == name]
        start_poses = np.stack([run.poses[t][0] for t in sub["trajectory"]])
        start_points = np.stack(sub["start_point_mm"].to_numpy())
        missed = sub.get("points_not_converged", pd.Series(np.nan, index=sub.index))
        solved = sub.get("points_solved", pd.Series(np.nan, index=sub.index))
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
            "points missing the IK tolerance": missed.sum(min_count=1),
            "points solved": solved.sum(min_count=1),
        })
    return pd.DataFrame(rows)


def _missing_text(row, name: str) -> str:
    """``sequential-ik: 197 of 350 points missed the IK tolerance`` or "" when unknown."""
    missed = row.get("points missing the IK tolerance", np.nan)
    solved = row.get("points solved", np.nan)
    if pd.isna(missed):
        return ""
    of = f" of {solved:.0f}" if not pd.isna(solved) else ""
    return f"{name}: {missed:.0f}{of} points missed the IK tolerance"


def check_claims(summary: pd.DataFrame, baseline: str = BASELINE,
                 reference: str = OURS, scheme: str | None = None) -> pd.DataFrame:
    """The paper's four claims about its baseline, each with numbers and a verdict.

    Args:
        summary: :func:`summarise` output (one row per run, column ``method``).
        baseline: the baseline run's name (folder) in ``summary``.
        reference: the run of the paper's method (``ours``).
        scheme: the baseline run's scheme (``walk`` / ``track``, :attr:`MethodRun.scheme`):
            the start-pose claim says what it shows for it (a property of the walk; a track
            starts at the recorded start pose by construction). None: not stated.
    """
    ours = summary.set_index("method").loc[reference]
    base = summary.set_index("method").loc[baseline]
    o, b = reference, baseline

    def ratio(a, c):
        return float(a) / float(c) if c else float("inf")

    speed = ratio(ours["median duration [s]"], base["median duration [s]"])
    pointing = ratio(base["mean pointing deviation [deg]"], ours["mean pointing deviation [deg]"])
    start = ratio(base["median |p_0 - p^s| [deg]"], ours["max |p_0 - p^s| [deg]"])
    step = ratio(base["median mean sq. joint step [deg^2]"],
                 ours["median mean sq. joint step [deg^2]"])
    jerk = ratio(base["median mean sq. jerk [deg^2]"], ours["median mean sq. jerk [deg^2]"])

    def comparable(r):
        return 1.0 / COMPARABLE_FACTOR <= r <= COMPARABLE_FACTOR

    line = ""
    if "mean line distance [mm]" in base and "mean line distance [mm]" in ours:
        line = (f"; meanwhile mean line distance: {o} {ours['mean line distance [mm]']:.2f} mm, "
                f"{b} {base['mean line distance [mm]']:.2f} mm")
    missing = _missing_text(base, b)
    claims = [
        ("sequential generation is much faster",
         f"median duration: {o} {ours['median duration [s]']:.3g} s, {b} "
         f"{base['median duration [s]']:.3g} s; ratio {o} / {b} = {speed:.0f}",
         f"ratio >= {FASTER_FACTOR:g}", speed >= FASTER_FACTOR),
        ("its pointing deviation is much worse",
         f"mean pointing deviation: {o} {ours['mean pointing deviation [deg]']:.2f} deg, "
         f"{b} {base['mean pointing deviation [deg]']:.2f} deg; ratio {b} / {o} = "
         f"{pointing:.2f}{line}" + (f"; {missing}" if missing else ""),
         f"ratio >= {WORSE_FACTOR:g}", pointing >= WORSE_FACTOR),
        ("its start pose varies, while ours is constant" + START_CLAIM_NOTES.get(scheme or "", ""),
         f"|p_0 - p^s| [motor deg]: {o} max {ours['max |p_0 - p^s| [deg]']:.3f}, "
         f"{b} median {base['median |p_0 - p^s| [deg]']:.2f} (ratio {start:.0f}); "
         f"spread of start poses over the trajectories: {o} "
         f"{ours['start pose spread [deg]']:.3f} deg, {b} "
         f"{base['start pose spread [deg]']:.2f} deg; of start points: {o} "
         f"{ours['start point spread [mm]']:.2f} mm, {b} "
         f"{base['start point spread [mm]']:.2f} mm; max |P_0 - P_s|: {o} "
         f"{ours['max |P_0 - P_s| [mm]']:.2f} mm, {b} "
         f"{base['max |P_0 - P_s| [mm]']:.2f} mm",
         f"{o} max <= {CONSTANT_START_DEG:g} deg and {b} median >= "
         f"{VARIES_FACTOR:g} x {o} max",
         ours["max |p_0 - p^s| [deg]"] <= CONSTANT_START_DEG and start >= VARIES_FACTOR),
        ("the fluency is comparable",
         f"median mean squared joint step: {o} "
         f"{ours['median mean sq. joint step [deg^2]']:.2f}, {b} "
         f"{base['median mean sq. joint step [deg^2]']:.2f} deg^2 (ratio {step:.2f}); median "
         f"mean squared jerk: {o} {ours['median mean sq. jerk [deg^2]']:.3f}, {b} "
         f"{base['median mean sq. jerk [deg^2]']:.3f} deg^2 (ratio {jerk:.2f})",
         f"both ratios within 1/{COMPARABLE_FACTOR:g} .. {COMPARABLE_FACTOR:g}",
         comparable(step) and comparable(jerk)),
    ]
    return pd.DataFrame(
        [{"paper's claim": c, "measured": m, "criterion": k,
          "verdict": "holds" if ok else "does not hold"} for c, m, k, ok in claims])


#: What the start-pose claim is about for each scheme (appended to the claim).
START_CLAIM_NOTES = {
    "walk": " (a property of the walk: this run walked from the touch pose, a touch-pose-only "
            "task, so its start pose is wherever the walk ends)",
    "track": " (this run tracked from the start pose, the paper's task: it starts at the "
             "recorded start pose by construction, so the claim cannot hold here: it describes "
             "the walk, not point-by-point IK as such)",
}


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


def pointing_tradeoff_note(summary: pd.DataFrame, baseline: str = BASELINE,
                           reference: str = OURS) -> str:
    """A plain sentence when the baseline points better than ours only by leaving the line
    (its mean line distance at least :data:`WORSE_FACTOR` x ours), else ""."""
    rows = summary.set_index("method")
    ours, base = rows.loc[reference], rows.loc[baseline]
    if "mean line distance [mm]" not in rows.columns:
        return ""
    ours_line, base_line = ours["mean line distance [mm]"], base["mean line distance [mm]"]
    better_pointing = (base["mean pointing deviation [deg]"]
                       < WORSE_FACTOR * ours["mean pointing deviation [deg]"])
    if not (better_pointing and base_line >= WORSE_FACTOR * max(ours_line, 1e-12)):
        return ""
    missing = _missing_text(base, f"`{baseline}`")
    return (f"Why the pointing claim fails for `{baseline}`: damped least squares weighs "
            "metres against radians, and where the target cannot be reached it keeps the "
            f"orientation and gives up the position. Its mean line distance is "
            f"{base_line:.2f} mm against {ours_line:.2f} mm for `{reference}` "
            f"({base_line / max(ours_line, 1e-12):.0f}x)"
            + (f" and {missing.split(': ', 1)[1]}" if missing else "")
            + ": it points along the line without following it, so its small pointing "
            "deviation is not a like-for-like win.")


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
    from ikbench.render.run_report import _matplotlib

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
    return (f"| {run.name} | {run.method} | {text} | {run.record.get('created_utc', '')} | "
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


def escaped_table(frame: pd.DataFrame, digits: dict | None = None) -> str:
    """:func:`markdown_table` with "|" inside headers and cells escaped (|P_0 - P_s| ...)."""
    def escape(text):
        return text.replace("|", "\\|")

    safe = frame.rename(columns=escape).apply(
        lambda column: column.map(lambda v: escape(v) if isinstance(v, str) else v))
    return markdown_table(safe, {escape(k): v for k, v in (digits or {}).items()})


@dataclass
class Comparison:
    """Every run of an output directory, measured and judged (:func:`compare`).

    Attributes:
        runs: folder name -> :class:`MethodRun`, in report order.
        tasks: the shared tasks.
        targets: their targets.
        frame: :func:`evaluate_runs` (one row per trajectory and run).
        summary: :func:`summarise` (one row per run).
    """

    runs: dict[str, MethodRun]
    tasks: list[Task]
    targets: Targets
    frame: pd.DataFrame
    summary: pd.DataFrame

    @property
    def baselines(self) -> list[str]:
        """The baseline runs, in report order (:func:`baseline_names`)."""
        return baseline_names(self.runs)

    def claims(self, baseline: str) -> pd.DataFrame:
        """:func:`check_claims` of one baseline run against ``ours``."""
        return check_claims(self.summary, baseline)

    def claims_lines(self, level: int = 3) -> list[str]:
        """:func:`claims_lines` for every baseline run."""
        return claims_lines(self.summary, self.runs, self.frame, level)

    def modes_table(self) -> pd.DataFrame:
        """:func:`modes_table` with the paper's row on the paper's targets."""
        return modes_table(self.frame, self.runs, self.targets.steps, self.targets.is_paper)


def compare(output_dir: str | Path) -> Comparison:
    """Load, measure and summarise every run in ``output_dir`` (see :func:`load_runs`)."""
    runs, tasks, targets = load_runs(output_dir)
    frame = evaluate_runs(runs, tasks)
    return Comparison(runs, tasks, targets, frame, summarise(frame, runs))


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
    result = compare(output_dir)
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
        *result.claims_lines(level=3),
        "## The baseline's orientation modes", "",
        "Each baseline run with the task it solved (its scheme), beside `ours`:", "",
        escaped_table(result.modes_table()), "", MODES_NOTE, "",
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
