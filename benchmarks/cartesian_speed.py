"""Time to a valid solution of ``ours-lm`` on the Cartesian path problems, with repetitions.

``ikbench cartesian`` solves each problem once per seed; this script repeats every (problem,
seed) solve ``--repeat`` times in one process, interleaved (problem by problem, seed by seed,
repetition by repetition, so a burst of load from other jobs does not land on one problem),
after one untimed warm-up solve, and writes every repetition with the phases of the start
search (IK seeds, carrying, LM refinement), the CPU, versions and git revision. It prints per
problem the median over seeds and repetitions and the range.

Run: ``.venv/bin/python benchmarks/cartesian_speed.py [--problems cppflow] [--seeds 1,2,3,4,5]
[--repeat 3] [--output results/cartesian/speed.csv]``.
"""

from __future__ import annotations

import argparse
import statistics
import time

import pandas as pd

from ikbench.core.io import atomic_write_csv, check_writable
from ikbench.core.metrics import frame_metrics
from ikbench.core.problems import load_problem, resolve_problems
from ikbench.core.provenance import provenance
from ikbench.methods.ours_lm import OursLM
from ikbench.studies.cartesian import parse_seeds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="cppflow")
    parser.add_argument("--seeds", default="1,2,3,4,5")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--output", default="results/cartesian/speed.csv")
    args = parser.parse_args()
    check_writable(args.output)
    seeds = parse_seeds(args.seeds)
    loaded = [load_problem(p) for p in resolve_problems(args.problems)]
    record = provenance(extra=("scipy",))
    warm = OursLM(seed=0)
    warm.prepare(loaded[0][0])
    warm.solve(loaded[0][0], loaded[0][1])          # imports, caches: not timed
    rows = []
    for robot, task, problem in loaded:
        for seed in seeds:
            for repetition in range(args.repeat):
                method = OursLM(seed=seed)
                method.prepare(robot)
                started = time.perf_counter()
                solution = method.solve(robot, task)
                wall = time.perf_counter() - started
                valid = frame_metrics(robot, task, solution.poses)["valid"]
                rows.append({"problem": problem.name, "waypoints": task.goal.steps + 1,
                             "seed": seed,
                             "repetition": repetition, "wall_s": wall, "valid": valid,
                             **{k: solution.info[k] for k in ("seeds_s", "carry_s", "refine_s",
                                                              "lm_iterations")},
                             "cpu": record["cpu"], "cpu_count": record["cpu_count"],
                             "git_revision": record["git_revision"],
                             "numpy": record["packages"]["numpy"],
                             "scipy": record["packages"]["scipy"]})
        times = [r["wall_s"] for r in rows if r["problem"] == problem.name]
        print(f"{problem.name:20s} {task.goal.steps + 1:4d} waypoints: median "
              f"{statistics.median(times):.3f} s (min {min(times):.3f}, max {max(times):.3f}) "
              f"over {len(times)} solves; valid "
              f"{sum(r['valid'] for r in rows if r['problem'] == problem.name)}/{len(times)}")
    atomic_write_csv(args.output, pd.DataFrame(rows), float_format="%.6g")
    print(f"written to {args.output} ({record['cpu']}, {record['cpu_count']} cores)")


if __name__ == "__main__":
    main()
