"""CppFlow's problems with obstacles, their obstacles moved: a robustness check of the pose-path
search on problems it was not tuned on.

For every shipped problem with obstacles (by default ``panda__1cube``, ``panda__2cubes`` and
``panda__flappy_bird``), every distance (1, 2 and 3 cm) and every direction (+-x, +-y, +-z of the
robot's base frame), this script writes a copy of the problem file whose obstacles are all moved
by that much (its ``obstacle_xyz_offset``; the path is the shipped one, found by name), named
``<problem>__<axis><sign><distance>mm`` (e.g. ``panda__2cubes__x+30mm``), into
``OUTPUT/problems/``, and writes the ``ikbench cartesian`` command that solves them all to
``OUTPUT/run.sh``.
``--sample K`` keeps K directions per problem and distance, drawn with ``--seed``.

Run: ``.venv/bin/python benchmarks/moved_obstacles.py [--problems panda__1cube,...]
[--distances-mm 10,20,30] [--sample 6] [--seed 0] [--output /tmp/moved] [--check] [--run]``;
``--check`` first judges each moved problem's feasibility by dense sampling
(:func:`feasibility`, written to ``OUTPUT/feasibility.csv``), ``--run`` runs the command
(``ours-lm``, seeds 1-5, into ``OUTPUT``) and prints, per moved problem, its valid seeds and
median solve time from ``OUTPUT/cartesian/summary.csv``.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from ikbench.core.metrics import frame_metrics
from ikbench.core.problems import load_problem, read_problem, resolve_problems
from ikbench.methods.ours_lm import anchor_ik, path_search, self_motion
from ikbench.methods.ours_lm import compiled_paths as kernels
from ikbench.methods.ours_lm.search_common import (
    STITCH_JUMP_COST,
    OursLMSettings,
    distinct,
)

DEFAULT_PROBLEMS = "panda__1cube,panda__2cubes,panda__flappy_bird"
DIRECTIONS = {"x+": (1, 0, 0), "x-": (-1, 0, 0), "y+": (0, 1, 0), "y-": (0, -1, 0),
              "z+": (0, 0, 1), "z-": (0, 0, -1)}


def moved_name(problem: str, direction: str, distance_mm: float) -> str:
    """The moved problem's name, e.g. ``panda__2cubes__x+30mm``."""
    return f"{problem}__{direction}{distance_mm:g}mm"


def write_moved(source: Path, direction: str, distance_mm: float, folder: Path) -> Path:
    """Write ``source`` (a problem YAML) with every obstacle moved ``distance_mm`` along
    ``direction`` (a key of :data:`DIRECTIONS`) into ``folder``; returns the new file."""
    doc = yaml.safe_load(source.read_text())
    offset_m = np.asarray(doc.get("obstacle_xyz_offset") or [0.0, 0.0, 0.0], dtype=float)
    offset_m = offset_m + np.asarray(DIRECTIONS[direction], dtype=float) * distance_mm / 1000.0
    doc["obstacle_xyz_offset"] = [float(v) for v in offset_m]
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{moved_name(source.stem, direction, distance_mm)}.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def moved_set(problems: str, distances_mm: list[float], sample: int, seed: int,
              folder: Path) -> list[Path]:
    """Every moved problem file (see the module docstring), written into ``folder``."""
    rng = np.random.default_rng(seed)
    files = []
    for source in resolve_problems(problems):
        if not read_problem(source).obstacles:
            continue
        for distance_mm in distances_mm:
            chosen = sorted(rng.choice(list(DIRECTIONS), size=sample, replace=False),
                            key=list(DIRECTIONS).index)
            files += [write_moved(source, d, distance_mm, folder) for d in chosen]
    return files


#: The feasibility check: random IK seeds per waypoint, the sweeps' step [deg] and samples
#: each way, a sample within this of an earlier one [deg] is not swept again, and every
#: how-many-th sample of a waypoint seeds its neighbours' IK.
CHECK_SEEDS = 16
CHECK_STEP_DEG = 1.0
CHECK_SAMPLES = 400
CHECK_COVERED_DEG = 2.0
CHECK_EVERY = 4


def feasibility(spec: str | Path, seed: int = 0) -> dict:
    """Whether a pose path can be followed at all, by dense sampling: at every waypoint, the
    self-motion manifolds (:func:`.self_motion.sweep_manifolds`, every :data:`CHECK_STEP_DEG`)
    of the IK solutions from :data:`CHECK_SEEDS` random seeds and, in a forward and a backward
    pass, from the neighbouring waypoint's samples (so that every branch of the arm met at one
    waypoint is swept at the next); then the shortest path through the collision-free samples
    with every step held below CppFlow's 7 deg where it can be (the stitch's dynamic
    programme, a step above the limit costing 1e6 per degree over). Feasible when that path's
    steps are all below the limit (it is then polished by the pose-path LM and judged by
    :func:`ikbench.core.metrics.frame_metrics`); otherwise the path with the least excess shows
    where the problem cannot be passed (evidence, not proof: the samples are finitely many).

    Returns:
        dict: problem, samples per waypoint (median, fewest), waypoints without a
        collision-free sample, the best path's largest step [deg] and where, its steps above
        the limit, feasible, the polished path's validity, seconds.
    """
    started = time.perf_counter()
    robot, task, problem = load_problem(spec)
    s = path_search._Search(robot, task, OursLMSettings(seed=seed))
    n, dof = s.n, robot.dof
    rng = np.random.default_rng(seed)
    settings = self_motion.sweep_settings(CHECK_STEP_DEG)
    samples: list[np.ndarray] = [np.zeros((0, dof)) for _ in range(n)]

    def sweep_new(i: int, poses: np.ndarray) -> None:
        fresh: list[np.ndarray] = []
        for q in poses:
            near = np.abs(samples[i] - q).max(axis=1).min() if len(samples[i]) else np.inf
            if near > CHECK_COVERED_DEG and all(np.abs(q - f).max() > CHECK_COVERED_DEG
                                                 for f in fresh):
                fresh.append(q)
        if fresh:
            swept = self_motion.sweep_manifolds(s.spec, s.goals_p, s.goals_R,
                                                np.full(len(fresh), i), np.array(fresh),
                                                CHECK_SAMPLES, settings).reshape(-1, dof)
            samples[i] = np.concatenate([samples[i], swept[~np.isnan(swept[:, 0])]])

    def solutions(i: int, seeds: np.ndarray) -> np.ndarray:
        q, position, rotation, _ = anchor_ik.first_waypoint_ik(s.spec, s.goals_p[i],
                                                               s.goals_R[i], seeds)
        return q[distinct(q, (position < 1e-3) & (rotation < 1e-3))]

    for i in range(n):
        sweep_new(i, solutions(i, rng.uniform(s.low, s.high, (CHECK_SEEDS, dof))))
    for order in (range(1, n), range(n - 2, -1, -1)):
        for i in order:
            j = i - order.step
            if len(samples[j]):
                sweep_new(i, solutions(i, samples[j][::CHECK_EVERY]))
    most = max(len(v) for v in samples)
    tracks = np.full((most, n, dof), np.nan)
    for i, v in enumerate(samples):
        tracks[:len(v), i] = v
    nodes = kernels.track_nodes(s.spec, s.goals_p, s.goals_R, tracks, 0.1)
    free = nodes.sum(axis=0)
    out = {"problem": problem.name, "samples_median": int(np.median([len(v) for v in samples])),
           "free_samples_fewest": int(free.min()),
           "waypoints_without_free_sample": np.flatnonzero(free == 0).tolist()}
    limit = s.step_limit  # CppFlow's step limits, a hair inside, as the search holds them
    choice = None if free.min() == 0 else kernels.stitch_choice(
        np.nan_to_num(tracks), nodes, s.weights, limit, STITCH_JUMP_COST, s.period)
    if choice is None:
        return {**out, "feasible": False, "seconds": time.perf_counter() - started}
    path = path_search.unwrap(tracks[choice, np.arange(n)], s.period)
    steps = (np.abs(np.diff(path, axis=0)) / limit).max(axis=1)
    over = np.flatnonzero(steps >= 1.0)
    out.update(largest_step_deg=float((np.abs(np.diff(path, axis=0))).max()),
               at_waypoint=int(np.argmax(steps)), steps_over_limit=over.tolist(),
               feasible=not over.size)
    if not over.size:
        poses = s.refine(path, {"L0": 1.0, "L1": 1.0, "L6": 0.001})[0]
        out["polished_valid"] = bool(frame_metrics(robot, task, poses)["valid"])
    return {**out, "seconds": time.perf_counter() - started}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default=DEFAULT_PROBLEMS)
    parser.add_argument("--distances-mm", default="10,20,30")
    parser.add_argument("--sample", type=int, default=len(DIRECTIONS),
                        help="directions per problem and distance (all six by default)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", default="1-5", help="ikbench cartesian's seeds")
    parser.add_argument("--methods", default="ours-lm")
    parser.add_argument("--output", default="/tmp/moved")
    parser.add_argument("--run", action="store_true")
    parser.add_argument("--check", action="store_true",
                        help="check each moved problem's feasibility (dense sampling; minutes "
                        "each) and write OUTPUT/feasibility.csv")
    args = parser.parse_args()
    output = Path(args.output)
    distances = [float(v) for v in args.distances_mm.split(",")]
    files = moved_set(args.problems, distances, min(args.sample, len(DIRECTIONS)), args.seed,
                      output / "problems")
    command = [str(Path(sys.executable).parent / "ikbench"), "cartesian",
               *[a for f in files for a in ("--problems", str(f))], "--methods", args.methods,
               "--seeds", args.seeds, "--output", str(output), "--trajectories", "all",
               "--quiet"]
    script = output / "run.sh"
    script.write_text(shlex.join(command) + "\n")
    print(f"{len(files)} moved problems in {output / 'problems'}; command: {script}")
    if args.check:
        rows = []
        for f in files:
            rows.append(feasibility(f))
            print({k: v for k, v in rows[-1].items() if k != "steps_over_limit"}, flush=True)
        pd.DataFrame(rows).to_csv(output / "feasibility.csv", index=False)
    if not args.run:
        return
    subprocess.run(command, check=True)
    summary = pd.read_csv(output / "cartesian" / "summary.csv")
    for row in summary.itertuples():
        print(f"{row.problem:32s} {row.method:10s} valid {row.valid_runs}/{row.runs}  median "
              f"solve {row.duration_median_s:.3f} s")


if __name__ == "__main__":
    main()
