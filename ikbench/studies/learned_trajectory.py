"""The trajectory half of the learned-start table (issue 61, part 2): does a trajectory model
trained on ikbench's own dataset give ours-lm and ours-exact a better start on the paper's
seven NICO targets than their usual one?

In this order, in one process:

1. a dataset of NICO's right arm as ``ikbench dataset`` writes it
   (:func:`ikbench.studies.dataset.build_dataset`): :data:`TRAJECTORIES` lines of
   :data:`STEPS` segments (the paper's n) from the paper's start pose to touch poses the batch
   sampler draws with seed :data:`DATASET_SEED`;
2. a trajectory model trained on it as ``ikbench learn --kind trajectory``
   (:func:`ikbench.learned.train.train`, :data:`EPOCHS` epochs, seed :data:`TRAIN_SEED`);
3. on each of the paper's seven targets (``urdf/nico_right_arm.targets.json``), for
   :data:`METHODS`: the method from its usual start (its ``solve``: ours-lm's joint
   interpolation, ours-exact's initial solve) and from the model's
   (:class:`ikbench.learned.starts.LearnedStart`: the query, then ``solve_from``); each
   judged by the task contract, each timed by the same rule (:data:`REPEATS` calls after one
   untimed pass over every target and start, the median).

The seven targets are not in the training set: the dataset's touch poses are the sampler's
draws (seed 63), not the paper's; the study measures, for each target, the distance from its
touch point to the nearest training trajectory's (``nearest_training_goal_mm``) and refuses
to go on if a training touch pose equals a target's.

It writes ``OUTPUT/trajectories.csv`` (:data:`COLUMNS`: a row per target, method and start),
``OUTPUT/summary.csv`` (:data:`SUMMARY_COLUMNS`: a row per method and start over the seven
targets, with the paired ratio of times) and ``OUTPUT/learned.json`` (settings, the model's
record with the SHA-256 of its file, the exclusion check, provenance, load). The dataset and
model are made in a temporary folder and removed unless ``--keep FOLDER``.

Run: ``python ikbench/studies/learned_trajectory.py --output OUTPUT`` (the
``learned-trajectory`` entry of ``ikbench reproduce``'s plan). About 3 minutes on the 2-core
machine, most of it the dataset.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ikbench.core.defaults import LEARNED_TRAJECTORY_METHODS

ROBOT = "nico_right_arm"
METHODS = LEARNED_TRAJECTORY_METHODS
STARTS = ("usual", "learned")
#: The training data and model (seeds disjoint from the benchmark seeds 1 and 4 and from the
#: pose study's 61, 62).
TRAJECTORIES, STEPS, EPOCHS = 2000, 50, 40
DATASET_SEED, TRAIN_SEED = 63, 64
#: torch threads of the whole study (training too, as ``ikbench learn``'s default): one
#: query of the small network costs a second thread's wake-up on a loaded machine (measured on
#: the 2-core machine at load 2.3: 32 ms a query with 2 threads, 1.2 ms with 1).
QUERY_THREADS = 1
#: Timed calls per target, method and start (after one untimed pass): the learned start's
#: refinement alone is the ``refine_s`` of the same calls (:class:`LearnedStart`).
REPEATS = 15
COLUMNS = ["robot", "target", "method", "start", "success", "failed_criteria",
           "line_distance_mean_mm", "pointing_deviation_mean_deg", "iterations",
           "time_median_ms", "refine_median_ms", "model_query_ms",
           "raw_line_distance_mean_mm", "raw_pointing_deviation_mean_deg",
           "raw_end_point_error_mm", "start_line_distance_mean_mm",
           "start_pointing_deviation_mean_deg", "nearest_training_goal_mm",
           "training_samples", "training_cpu_min"]
SUMMARY_COLUMNS = ["robot", "method", "start", "targets", "success_count",
                   "line_distance_mean_mm_median", "pointing_deviation_mean_deg_median",
                   "iterations_median", "time_median_ms", "refine_median_ms",
                   "time_ratio_to_usual_median", "time_ratio_to_usual_min",
                   "time_ratio_to_usual_max", "refine_ratio_to_usual_median",
                   "raw_line_distance_mean_mm_median",
                   "raw_pointing_deviation_mean_deg_median", "model_query_ms",
                   "training_samples", "training_cpu_min"]


def _figures(robot, task, poses) -> dict:
    """The contract's figures of ``poses`` and its verdict."""
    from ikbench.core.contract import judge
    from ikbench.core.metrics import contract_metrics

    contract = task.required.contract
    figures = contract_metrics(robot, task, np.asarray(poses, float), contract)
    verdict = judge(contract, figures)
    return {"success": all(verdict.values()),
            "failed_criteria": ";".join(k for k, ok in verdict.items() if not ok),
            "line_distance_mean_mm": figures["line_distance_mean_mm"],
            "pointing_deviation_mean_deg": figures["pointing_deviation_mean_deg"]}


def _timed(call, repeats: int) -> tuple[list, float]:
    """(every call's result, median wall time [ms]) of ``repeats`` calls."""
    times, out = [], []
    for _ in range(repeats):
        began = time.perf_counter()
        out.append(call())
        times.append(time.perf_counter() - began)
    return out, float(np.median(times)) * 1e3


def nearest_training_goals(robot, data, train_ids, tasks) -> tuple[list[float], float]:
    """Per task, the distance [mm] from its end point to the nearest training trajectory's
    touch point, and the smallest max-joint difference [pose units] between a task's touch
    pose and a training touch pose."""
    rows = np.flatnonzero(np.isin(data.trajectory_ids, train_ids))
    goals = data.touch_mm[rows]
    touches = data.poses[rows, -1]
    nearest, closest_pose = [], np.inf
    for task in tasks:
        nearest.append(float(np.min(np.linalg.norm(goals - task.goal.end_point_mm, axis=1))))
        closest_pose = min(closest_pose, float(np.min(np.abs(
            touches - task.required.end_pose).max(axis=1))))
    return nearest, closest_pose


def study(folder: Path, *, trajectories: int, epochs: int, repeats: int,
          progress: bool) -> tuple[list[dict], dict]:
    """The rows of trajectories.csv and the record of the model and the exclusion check."""
    from ikbench.core.errors import InputError
    from ikbench.core.metrics import trajectory_metrics
    from ikbench.core.robot import load_robot
    from ikbench.core.targets import load_targets
    from ikbench.core.task import line_tasks
    from ikbench.learned import train as learn
    from ikbench.learned.starts import LearnedStart, learned_start, resample
    from ikbench.methods.registry import get_method
    from ikbench.studies.dataset import build_dataset

    robot = load_robot(ROBOT)
    targets = load_targets(None, robot)
    tasks = line_tasks(robot, targets)
    data_folder = folder / "dataset"
    build_dataset(trajectories, seed=DATASET_SEED, steps=STEPS, robot=robot, targets=targets,
                  output=data_folder, progress=progress)
    model_file = learn.train(data_folder, "trajectory", folder / "trajectory.pt",
                             epochs=epochs, seed=TRAIN_SEED, robot=robot, progress=progress)
    model = learn.load_model(model_file, robot, kind="trajectory")
    data = learn.read_dataset(data_folder, robot)
    train_ids = np.setdiff1d(data.trajectory_ids, model.held_out_trajectories)
    nearest, closest_pose = nearest_training_goals(robot, data, train_ids, tasks)
    if closest_pose < 1e-6:
        raise InputError("a paper target's touch pose is in the training set; change "
                         "the dataset seed")
    samples, cpu_min = model.meta["samples"]["train"], model.meta["training_cpu_min"]
    start_figures, raw, query_ms = {}, {}, {}
    for task in tasks:
        start_pose = np.asarray(task.required.start_pose, dtype=float)  # line tasks have one
        predicted = model.predict(start_pose, task.goal.end_point_mm)
        predicted = resample(predicted, len(task.goal.points_mm) - 1)
        raw[task.name] = {**_figures(robot, task, predicted), "end_point_error_mm":
                          trajectory_metrics(robot, task, predicted)["end_point_error_mm"]}
        made, query_ms[task.name] = _timed(lambda t=task: learned_start(model, t), repeats)
        start_figures[task.name] = _figures(robot, task, made[-1])
    rows = []
    for name in METHODS:
        solvers = {"usual": get_method(name)(), "learned": LearnedStart(get_method(name)(),
                                                                       model)}
        for solver in solvers.values():
            solver.check_tasks(robot, tasks)
            solver.prepare(robot)
            for task in tasks:  # the untimed pass: compilation, caches
                solver.solve(robot, task)
        for k, task in enumerate(tasks):
            for start, solver in solvers.items():
                solutions, time_ms = _timed(lambda s=solver, t=task: s.solve(robot, t),
                                            repeats)
                solution, refine_ms = solutions[-1], time_ms
                if start == "learned":  # the same calls' refinement alone
                    refine_ms = 1e3 * float(np.median([x.info["refine_s"]
                                                       for x in solutions]))
                row = {"robot": robot.name, "target": task.name, "method": name,
                       "start": start, **_figures(robot, task, solution.poses),
                       "iterations": int(solution.iterations), "time_median_ms": time_ms,
                       "refine_median_ms": refine_ms, "nearest_training_goal_mm": nearest[k]}
                if start == "learned":
                    begun = start_figures[task.name]
                    row.update({
                        "model_query_ms": query_ms[task.name],
                        "raw_line_distance_mean_mm": raw[task.name]["line_distance_mean_mm"],
                        "raw_pointing_deviation_mean_deg":
                            raw[task.name]["pointing_deviation_mean_deg"],
                        "raw_end_point_error_mm": raw[task.name]["end_point_error_mm"],
                        "start_line_distance_mean_mm": begun["line_distance_mean_mm"],
                        "start_pointing_deviation_mean_deg":
                            begun["pointing_deviation_mean_deg"],
                        "training_samples": samples, "training_cpu_min": cpu_min})
                rows.append(row)
                if progress:
                    print(f"{name} {start} target {task.name}: {time_ms:.2f} ms, "
                          f"{'met' if row['success'] else 'not met'}", file=sys.stderr)
    record = {"model_file": model_file.name,
              "model_sha256": hashlib.sha256(model_file.read_bytes()).hexdigest(),
              "dataset": model.meta["dataset"], "samples": model.meta["samples"],
              "epochs": model.meta["epochs"], "training_cpu_min": cpu_min,
              "held_out_error": model.meta.get("held_out_error"),
              "exclusion": {"nearest_training_goal_mm": dict(zip([t.name for t in tasks],
                                                                 nearest)),
                            "closest_training_touch_pose_max_joint_diff": closest_pose,
                            "pose_unit": robot.pose_unit}}
    record["dataset"] = {**record["dataset"], "path": "dataset"}
    return rows, record


def summarise(table):
    """summary.csv: per method and start over the targets (medians); the learned rows' ratios
    to the usual start are paired by target (the learned start's time, or its refinement
    alone, over the usual start's time; below 1: faster)."""
    import pandas as pd

    out = []
    for (method, start), part in table.groupby(["method", "start"], sort=False):
        usual = table[(table["method"] == method) & (table["start"] == "usual")]
        usual_ms = usual.set_index("target")["time_median_ms"]
        ratio = part.set_index("target")["time_median_ms"] / usual_ms
        refine_ratio = part.set_index("target")["refine_median_ms"] / usual_ms
        learned = start == "learned"
        out.append({
            "robot": part["robot"].iloc[0], "method": method, "start": start,
            "targets": len(part), "success_count": int(part["success"].sum()),
            "line_distance_mean_mm_median": part["line_distance_mean_mm"].median(),
            "pointing_deviation_mean_deg_median": part["pointing_deviation_mean_deg"].median(),
            "iterations_median": part["iterations"].median(),
            "time_median_ms": part["time_median_ms"].median(),
            "refine_median_ms": part["refine_median_ms"].median(),
            "time_ratio_to_usual_median": ratio.median() if learned else None,
            "time_ratio_to_usual_min": ratio.min() if learned else None,
            "time_ratio_to_usual_max": ratio.max() if learned else None,
            "refine_ratio_to_usual_median": refine_ratio.median() if learned else None,
            "raw_line_distance_mean_mm_median":
                part["raw_line_distance_mean_mm"].median() if learned else None,
            "raw_pointing_deviation_mean_deg_median":
                part["raw_pointing_deviation_mean_deg"].median() if learned else None,
            "model_query_ms": part["model_query_ms"].median() if learned else None,
            "training_samples": part["training_samples"].iloc[0] if learned else None,
            "training_cpu_min": part["training_cpu_min"].iloc[0] if learned else None})
    frame = pd.DataFrame(out, columns=SUMMARY_COLUMNS)
    frame["training_samples"] = frame["training_samples"].astype("Int64")
    return frame


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", required=True, help="folder of trajectories.csv")
    parser.add_argument("--trajectories", type=int, default=TRAJECTORIES,
                        help=f"dataset trajectories (default {TRAJECTORIES})")
    parser.add_argument("--epochs", type=int, default=EPOCHS,
                        help=f"training epochs (default {EPOCHS})")
    parser.add_argument("--repeats", type=int, default=REPEATS,
                        help=f"timed calls per target, method and start (default {REPEATS})")
    parser.add_argument("--keep", metavar="FOLDER", default=None,
                        help="keep the dataset and model under FOLDER (default: a temporary "
                             "folder, removed at the end)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    for flag, value in (("--trajectories", args.trajectories), ("--epochs", args.epochs),
                        ("--repeats", args.repeats)):
        if value < 1:
            print(f"{flag}: {value} must be an integer >= 1", file=sys.stderr)
            return 2
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(QUERY_THREADS)
    try:
        return _write(args)
    finally:
        torch.set_num_threads(threads)


def _write(args: argparse.Namespace) -> int:
    """The study of ``main``'s checked arguments, written (0), or a refusal (2)."""
    import pandas as pd

    from ikbench.core.errors import InputError
    from ikbench.core.io import atomic_write_csv, atomic_write_json
    from ikbench.core.provenance import provenance

    out = Path(args.output)
    started, load_start, made_by = time.perf_counter(), os.getloadavg(), provenance()
    scratch = tempfile.TemporaryDirectory(prefix="ikbench-learned-trajectory-")
    work = Path(args.keep) if args.keep else Path(scratch.name)
    try:
        rows, record = study(work, trajectories=args.trajectories, epochs=args.epochs,
                             repeats=args.repeats, progress=not args.quiet)
    except InputError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    finally:
        scratch.cleanup()
    table = pd.DataFrame(rows, columns=COLUMNS)
    table["training_samples"] = table["training_samples"].astype("Int64")
    summary = summarise(table)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_csv(out / "trajectories.csv", table)
    atomic_write_csv(out / "summary.csv", summary)
    atomic_write_json(out / "learned.json", {
        "settings": {"robot": ROBOT, "targets": "paper", "methods": list(METHODS),
                     "starts": list(STARTS), "trajectories": args.trajectories,
                     "steps": STEPS, "epochs": args.epochs, "dataset_seed": DATASET_SEED,
                     "train_seed": TRAIN_SEED, "repeats": args.repeats,
                     "torch_threads": QUERY_THREADS,
                     "timing": "median of the repeats after one untimed pass; the learned "
                               "start's time is the model's query and the refinement"},
        "model": record, "wall_s": time.perf_counter() - started,
        "load_average": {"start": load_start, "end": os.getloadavg()},
        "provenance": made_by})
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"written to {out / 'trajectories.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
