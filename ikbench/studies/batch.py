"""Batches: many random reachable touch poses solved at once by ``ours-lm``.

:func:`sample_touch_poses` draws touch poses uniformly within the joint limits (seeded;
continuous joints within +-180 deg) and keeps those the robot's :class:`WorkspaceFilter`
accepts (its config's ``[batch]`` section), against the start pose's end point P_s (base
frame, mm). NICO's keeps the reachable front workspace (torso frame: x behind the robot, z up):

- in front of the torso: fingertip x <= -250 mm (the paper's touch points lie at -420..-510);
- on or above the torso base plane, the table: z >= 0 mm (the paper's: 2..22 mm);
- at least 100 mm below the start point: z <= z(P_s) - 100 mm;
- pointing where it goes: the finger's direction within 20 deg of the line from P_s to the
  touch point (the paper's touch poses: 1.6..9.9 deg).

A robot whose config has no ``[batch]`` keeps every touch point at least
:data:`MIN_LINE_MM` from P_s.

:func:`run_batch` builds one line task per touch pose (the paper's start pose, n segments),
solves them in one batched call per weight setting, measures every trajectory with
:mod:`ikbench.core.metrics` and reports trajectories per second and the share within tolerance.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.defaults import DEFAULT_ROBOT
from ikbench.core.errors import InputError
from ikbench.core.io import write_study_files
from ikbench.core.losses import PAPER_WEIGHTS, TERMS, parse_weights
from ikbench.core.metrics import trajectory_metrics
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, load_targets
from ikbench.core.task import line_task
from ikbench.methods.ours_lm import LMSettings, solve_batch
from ikbench.render.run_report import markdown_table
from ikbench.runtime.executors import Executor, LocalExecutor
from ikbench.runtime.parallel import solve_parts
from ikbench.runtime.progress import Reporter

if TYPE_CHECKING:
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.solver import BatchResult

#: Weight settings of the default batch: the paper's, and two from the weight sweep
#: (results/sweep): c0=100 puts the fingertip ~70x closer to the line for +0.6 deg pointing;
#: c0=1000,c1=200 is closer still and points better (7.8 vs 11.7 deg), with larger joint steps.
DEFAULT_WEIGHTS = ("paper", "c0=100", "c0=1000,c1=200")
LINE_TOLERANCE_MM = 1.0
END_TOLERANCE_MM = 0.5
SAMPLE_CHUNK = 4096
MAX_DRAWS = 10_000_000
#: At most this many touch poses in one batch (held in memory at once; NICO's workspace filter
#: keeps about 2 % of the draws, so 100 000 poses need about half of MAX_DRAWS); a larger set
#: is a dataset of several batches: ``ikbench dataset``.
MAX_COUNT = 100_000
#: Seeds are integers in [0, MAX_SEED) (numpy's default_rng refuses negative ones).
MAX_SEED = 2**63


#: A line shorter than this [mm] is no task (the default filter's only criterion).
MIN_LINE_MM = 50.0


@dataclass(frozen=True)
class WorkspaceFilter:
    """Which touch points a batch keeps (see the module docstring); lengths in mm, None: no
    such criterion."""

    max_x_mm: float | None = None
    min_z_mm: float | None = None
    min_drop_below_start_mm: float | None = None
    max_pointing_angle_deg: float | None = None
    min_line_mm: float = MIN_LINE_MM

    @classmethod
    def of(cls, robot: Robot) -> WorkspaceFilter:
        """The robot config's ``[batch]`` filter (unknown keys refused)."""
        section = dict(robot.config.batch)
        known = {f for f in cls.__dataclass_fields__}
        unknown = [k for k in section if k not in known]
        if unknown:
            raise InputError(f"robot {robot.name}: [batch] key(s) {', '.join(unknown)} unknown; "
                             f"allowed: {', '.join(sorted(known))}")
        return cls(**section)

    def accept(self, points_mm: np.ndarray, directions: np.ndarray, start_point_mm: np.ndarray
               ) -> np.ndarray:
        """(M,) bool for end points (M, 3) [mm] and pointing directions (M, 3)."""
        line = points_mm - start_point_mm
        length = np.linalg.norm(line, axis=1)
        keep = length >= self.min_line_mm
        if self.max_x_mm is not None:
            keep &= points_mm[:, 0] <= self.max_x_mm
        if self.min_z_mm is not None:
            keep &= points_mm[:, 2] >= self.min_z_mm
        if self.min_drop_below_start_mm is not None:
            keep &= points_mm[:, 2] <= start_point_mm[2] - self.min_drop_below_start_mm
        if self.max_pointing_angle_deg is not None:
            unit = line / np.maximum(length, 1e-12)[:, None]
            angle = np.degrees(np.arccos(np.clip(np.sum(unit * directions, axis=1), -1.0, 1.0)))
            keep &= angle <= self.max_pointing_angle_deg
        return keep

    def describe(self) -> str:
        """The criteria in words (batch.md)."""
        parts = [f"at least {self.min_line_mm:g} mm from the start point"]
        if self.max_x_mm is not None:
            parts.append(f"x <= {self.max_x_mm:g} mm")
        if self.min_z_mm is not None:
            parts.append(f"z >= {self.min_z_mm:g} mm")
        if self.min_drop_below_start_mm is not None:
            parts.append(f"at least {self.min_drop_below_start_mm:g} mm below the start point")
        if self.max_pointing_angle_deg is not None:
            parts.append(f"pointing within {self.max_pointing_angle_deg:g} deg of the line "
                         "direction")
        return ", ".join(parts)


def sample_touch_poses(robot: Robot, start_pose: npt.ArrayLike, count: int, seed: int = 0,
                       workspace: WorkspaceFilter | None = None) -> tuple[np.ndarray, int]:
    """``count`` touch poses (count, dof) [motor deg] in the front workspace, reproducibly.

    Poses are drawn uniformly within the motor ranges by ``numpy.random.default_rng(seed)``
    in chunks of :data:`SAMPLE_CHUNK`, in order, and kept when ``workspace`` accepts them.

    Returns:
        (poses, draws): the accepted poses and how many were drawn in all.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InputError(f"--count: {count!r} must be an integer >= 1")
    check_seed(seed)
    workspace = workspace or WorkspaceFilter.of(robot)
    kin = robot.chain_kinematics()
    start_mm = robot.fk(start_pose).point_mm[0]
    rng = np.random.default_rng(seed)
    kept: list[np.ndarray] = []
    draws = 0
    while sum(len(k) for k in kept) < count:
        if draws >= MAX_DRAWS:
            raise InputError(f"the workspace filter accepted fewer than {count} of "
                             f"{draws} random poses")
        poses = rng.uniform(robot.sample_lower, robot.sample_upper, (SAMPLE_CHUNK, robot.dof))
        point_m, direction, _, _ = kin(poses, jacobian=False)
        kept.append(poses[workspace.accept(point_m * 1000.0, direction, start_mm)])
        draws += SAMPLE_CHUNK
    return np.concatenate(kept)[:count], draws


def check_count(count: object) -> int:
    """Return ``count`` if it is an integer in [1, MAX_COUNT]; InputError naming it otherwise."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise InputError(f"--count: {count!r} must be an integer >= 1")
    if count > MAX_COUNT:
        raise InputError(f"--count: {count} is more than the maximum, {MAX_COUNT:,} touch poses "
                         "in one batch (ikbench dataset builds larger sets shard by shard)")
    return int(count)


def check_seed(seed: object) -> int:
    """Return ``seed`` if it is an integer in [0, 2^63); InputError naming it otherwise."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) \
            or not 0 <= seed < MAX_SEED:
        raise InputError(f"--seed: {seed!r} must be an integer in [0, 2^63)")
    return int(seed)


def weight_setting(text: str) -> tuple[str, dict]:
    """``"paper"`` or ``"c0=100,c1=500"`` -> (label, weights)."""
    text = str(text).strip()
    if text == "paper":
        return "paper", dict(PAPER_WEIGHTS)
    return text, parse_weights(text)


@dataclass
class BatchReport:
    """Per-setting summary, per-trajectory rows, the touch poses, and the record.
    :meth:`write` writes the files."""

    summary: pd.DataFrame
    trajectories: pd.DataFrame
    touch_poses: pd.DataFrame
    record: dict

    def write(self, folder: str | Path) -> Path:
        """Write batch.csv, batch_trajectories.csv, touch_poses.csv, batch.json and batch.md
        into ``folder``; return batch.csv's path."""
        return write_study_files(folder, "batch",
                                 {"batch.csv": (self.summary, "%.6g"),
                                  "batch_trajectories.csv": (self.trajectories, "%.6g"),
                                  "touch_poses.csv": (self.touch_poses, "%.10g")},
                                 self.record, lambda: markdown(self))


@dataclass(frozen=True)
class BatchSpec:
    """A batch study: the number of touch poses and their sampling seed, the segments per
    trajectory, the weight settings (``"paper"`` or ``"c0=100,..."``), the tolerances [mm], the
    robot (or its name/config/URDF) and where the start pose comes from, the executor and the
    progress lines. :meth:`validate` checks them; :func:`run` runs it
    (:mod:`ikbench.studies.shape`)."""

    count: int = 1000
    seed: int = 0
    steps: int = 50
    weights: tuple[str, ...] = tuple(DEFAULT_WEIGHTS)
    targets: str | Path | Targets | None = None
    line_tolerance_mm: float = LINE_TOLERANCE_MM
    end_tolerance_mm: float = END_TOLERANCE_MM
    progress: bool = True
    robot: Robot | str | None = None
    executor: Executor | None = None

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a tolerance that is not a positive
        number of mm, fewer than 2 steps, a bad count or seed, or a bad weight setting."""
        for flag, value in (("--line-tolerance-mm", self.line_tolerance_mm),
                            ("--end-tolerance-mm", self.end_tolerance_mm)):
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{flag}: {value!r} must be a positive number of mm")
        steps = self.steps
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 2:
            raise InputError(f"--steps: {steps!r} must be an integer >= 2")
        check_count(self.count)
        check_seed(self.seed)
        for w in self.weights:
            weight_setting(w)


def run_batch(count: int = 1000, *, seed: int = 0, steps: int = 50,
              weights: Sequence[str] = DEFAULT_WEIGHTS, targets: str | Path | Targets | None = None,
              line_tolerance_mm: float = LINE_TOLERANCE_MM,
              end_tolerance_mm: float = END_TOLERANCE_MM, progress: bool = True,
              robot: Robot | str | None = None, executor: Executor | None = None) -> BatchReport:
    """Sample ``count`` touch poses, solve them per weight setting, measure (module docstring).

    Args:
        robot: the robot or its name/config/URDF (default NICO's right arm).
        count: number of touch poses N.
        seed: sampling seed, an integer in [0, 2^63).
        steps: number of segments n per trajectory.
        weights: weight settings, each ``"paper"`` or ``"c0=100,..."``.
        targets: where the start pose comes from (default the robot's default targets).
        line_tolerance_mm / end_tolerance_mm: the tolerance: mean line distance and end point
            error below these.
        progress: progress lines on stderr.
        executor: where the solves and metrics run (:mod:`ikbench.runtime.executors`;
            default: one batched call per setting in this process); the per-trajectory
            numbers do not depend on it.
    """

    spec = BatchSpec(count, seed, steps, tuple(weights), targets, line_tolerance_mm,
                     end_tolerance_mm, progress, robot, executor)
    spec.validate()
    return run(spec)


def run(spec: BatchSpec) -> BatchReport:
    """Sample, solve and measure the batch ``spec`` (validated: :meth:`BatchSpec.validate`);
    nothing is written (:meth:`BatchReport.write` writes it)."""
    count, seed, steps, targets, executor, progress = (spec.count, spec.seed, spec.steps,
                                                       spec.targets, spec.executor,
                                                       spec.progress)
    line_tolerance_mm, end_tolerance_mm = spec.line_tolerance_mm, spec.end_tolerance_mm
    settings = [weight_setting(w) for w in spec.weights]
    robot = as_robot(spec.robot)
    workspace = WorkspaceFilter.of(robot)
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    reporter = Reporter("batch", total=len(settings), unit="setting", enabled=progress)
    log = reporter.say
    t0 = time.perf_counter()
    touch, draws = sample_touch_poses(robot, targets.start_pose, count, seed, workspace)
    sample_s = time.perf_counter() - t0
    log(f"sampled {count} touch poses from {draws} draws ({100 * count / draws:.1f}% in the "
        f"front workspace) in {sample_s:.2f} s")
    tasks = [line_task(robot, targets.start_pose, pose, steps, str(k))
             for k, pose in enumerate(touch)]
    rows: list[dict[str, Any]] = []
    summary: list[dict[str, Any]] = []
    for label, w in settings:
        lm = LMSettings(weights=w)
        if executor is None or executor.name == "local":
            def report(iteration, active, _losses, label=label):
                if iteration % 5 == 0:
                    log(f"{label}: iteration {iteration}, {active} of {count} trajectories "
                        "running")
            result = solve_batch(robot, tasks, lm, progress=report)
            log(f"{label}: solved {count} trajectories in {result.duration_s:.2f} s "
                f"({count / result.duration_s:.0f} per s); measuring")
            t1 = time.perf_counter()
            mine = measure_batch(robot, tasks, [w] * count, result, label)
            measure_s = time.perf_counter() - t1
        else:  # solved and measured in parts on the executor's workers
            result, mine = solve_parts(executor, robot, tasks, lm, [w] * count,
                                       partial(measure_batch, label=label))
            assert mine is not None, "measured beside the solve (measure given)"
            log(f"{label}: solved and measured {count} trajectories in "
                f"{result.duration_s:.2f} s on {executor.workers} {executor.name} workers "
                f"({count / result.duration_s:.0f} per s)")
            measure_s = float("nan")  # within the solve's wall time
        reporter.advance(1, f"{label}: measured")
        frame = pd.DataFrame(mine)
        summary.append(_summarise(label, w, frame, result.duration_s, count,
                                  line_tolerance_mm, end_tolerance_mm, measure_s))
        rows.extend(mine)
    poses = pd.DataFrame(touch, columns=list(robot.joint_names))
    poses.insert(0, "trajectory", np.arange(count))
    record = {"count": count, "seed": seed, "steps": steps, "draws": draws,
              "sampling_s": sample_s, "start_pose_deg": targets.start_pose.tolist(),
              "robot": robot.describe(), "workspace_filter": asdict(workspace),
              "workspace": workspace.describe(),
              "line_tolerance_mm": line_tolerance_mm, "end_tolerance_mm": end_tolerance_mm,
              "settings": {label: w for label, w in settings},
              **(executor or LocalExecutor()).describe(), **provenance()}
    return BatchReport(pd.DataFrame(summary), pd.DataFrame(rows), poses, record)


def measure_batch(robot: Robot, tasks: Sequence[Task], weights: Sequence[dict[str, float]],
                  result: BatchResult, label: str) -> list[dict[str, Any]]:
    """One row per trajectory of a solved batch: loss, convergence, the line metrics."""
    rows = []
    for k, task in enumerate(tasks):
        m = trajectory_metrics(robot, task, result.poses[k])
        rows.append({"setting": label, "trajectory": int(task.name), "loss": float(result.loss[k]),
                     "iterations": int(result.iterations[k]),
                     "converged": bool(result.converged[k]),
                     "within_limits": robot.within_limits(result.poses[k]),
                     "line_length_mm": float(np.linalg.norm(task.goal.end_point_mm
                                                            - task.goal.start_point_mm)),
                     **{key: m[key] for key in (
                         "line_distance_mean_mm", "line_distance_std_mm",
                         "pointing_deviation_mean_deg", "start_point_error_mm",
                         "end_point_error_mm", "end_pose_error_deg",
                         "mean_sq_joint_step_deg2", "max_joint_step_deg")}})
    return rows


def _summarise(label, weights, frame, solve_s, count, line_tol, end_tol, measure_s) -> dict:
    line_ok = frame["line_distance_mean_mm"] < line_tol
    end_ok = frame["end_point_error_mm"] < end_tol
    row = {"setting": label, **{f"c{t[1]}": weights[t] for t in TERMS},
           "trajectories": count, "solve_wall_s": solve_s,
           "trajectories_per_s": count / solve_s, "metrics_wall_s": measure_s,
           "share_line_within_tol": float(line_ok.mean()),
           "share_end_within_tol": float(end_ok.mean()),
           "share_within_tol": float((line_ok & end_ok).mean()),
           "share_converged": float(frame["converged"].mean()),
           "share_within_limits": float(frame["within_limits"].mean()),
           "iterations_median": float(frame["iterations"].median())}
    for column in ("line_distance_mean_mm", "pointing_deviation_mean_deg", "end_point_error_mm",
                   "mean_sq_joint_step_deg2"):
        values = frame[column]
        row[f"{column}_median"] = float(values.median())
        row[f"{column}_p90"] = float(values.quantile(0.9))
        row[f"{column}_max"] = float(values.max())
    return row


def write(report: BatchReport, output: str | Path) -> Path:
    """Write batch.csv, batch_trajectories.csv, touch_poses.csv, batch.json and batch.md
    (:meth:`BatchReport.write`)."""
    return report.write(output)


def markdown(report: BatchReport) -> str:
    """batch.md: sampling, throughput, tolerance shares and distributions per setting."""
    rec, s = report.record, report.summary
    line_tol, end_tol = rec["line_tolerance_mm"], rec["end_tolerance_mm"]
    main = s[["setting", "trajectories", "solve_wall_s", "trajectories_per_s"]].copy()
    for column, title in (("share_line_within_tol", f"line dist. mean < {line_tol:g} mm [%]"),
                          ("share_end_within_tol", f"end error < {end_tol:g} mm [%]"),
                          ("share_within_tol", "both [%]"),
                          ("share_converged", "converged [%]"),
                          ("share_within_limits", "within limits [%]")):
        main[title] = 100.0 * s[column]
    main["median iterations"] = s["iterations_median"]
    dist_cols = ["setting"] + [c for c in s.columns if c.endswith(("_median", "_p90", "_max"))
                               and not c.startswith("iterations")]
    return "\n".join([
        "# Batch: random touch poses", "",
        f"{rec['count']} touch poses of {rec.get('robot', {}).get('name', DEFAULT_ROBOT)} "
        f"drawn uniformly within the joint limits "
        f"(`numpy.random.default_rng({rec['seed']})`, {rec['draws']} draws) and kept when "
        f"the end point is {rec['workspace']}. Each is a line task from the start pose "
        f"with n = {rec['steps']}, solved by `ours-lm` in one batched "
        "call per weight setting; trajectories per second count the solve only (sampling "
        f"{rec['sampling_s']:.2f} s and metrics are separate). Shares are fractions of the "
        "trajectories.", "",
        "## Throughput and tolerance", "",
        markdown_table(main, {"solve_wall_s": 2, "trajectories_per_s": 0,
                              "median iterations": 0}), "",
        "## Distributions (median, 90th percentile, max over trajectories)", "",
        markdown_table(s[dist_cols], {c: 3 for c in dist_cols}), "",
        f"Produced by ikbench (git {rec['git_revision']}) on {rec['cpu']} "
        f"({rec['cpu_count']} cores), {rec['created_utc']}.", ""])
