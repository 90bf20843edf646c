"""Tune ours-lm's single-pose defaults on seeds no benchmark uses.

ours-lm's compiled single-pose LM (``ikbench.methods.ours_lm.single_pose_compiled``) has four
settings whose defaults were chosen by measurement: ``RESTART_AFTER`` (iterations of an attempt
before the next start), ``MAX_STEP`` (the largest joint step of an iteration [deg]),
``DAMPING`` (lambda at each start) and ``ABANDON`` (an attempt still far off after t
iterations restarts). This script is that measurement, committed: on the four robots of the IK
studies (Panda, UR5, xArm7, the Fetch arm), targets and starts drawn as ``ikbench ik`` draws
them but from **seeds 101 and 102** (the committed studies, the zoo and the tests use seeds
1-5), every combination of the grid below solves every target from its sequence of starts with
no wall-clock budget. Criterion, machine-independent: success (every target must be solved
within the 256 rows) first, then the mean LM iterations per target over the robots; the
wall time of the grid's solves is printed beside it, not used.

    python benchmarks/tune_ours_lm_single_pose.py [--count 1000] [--output runs/tune_ours_lm.csv]

``--rows``: the solver of the deterministic table instead (``ikbench ik --attempts 8``: 8 rows,
each attempt at most MAX_STEPS iterations, no early abandon, no clock;
``ikbench.methods.ours_lm.pose_solver.ROWS_DAMPING`` and ``ROWS_CRAWL``), its grid
:data:`ROWS_GRID` on the same robots and the UR10, the same seeds and criterion.

Writes one row per setting and robot; prints the best settings and the current defaults' rank.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.robot import load_robot
from ikbench.methods.ours_lm import pose_solver
from ikbench.methods.ours_lm import single_pose_compiled as spc
from ikbench.schemes.single_pose import MAX_STEPS
from ikbench.studies.ik import AUTO_ROWS, IKSettings, sample_targets

ROBOTS = ("example-robot-data:panda", "example-robot-data:ur5", "example-robot-data:xarm7",
          "fetch_arm")
#: Seeds of the tuning targets: disjoint from every benchmark's (1-5).
SEEDS = (101, 102)
GRID = {"restart_after": (8, 10, 12, 14, 16, 20), "max_step": (30.0, 60.0, 90.0, 120.0),
        "damping": (1e-3, 1e-2, 1e-1), "abandon": ((0, 0.0), (6, 100.0))}
#: ``--rows``: lambda at each start and the crawl check (window, ratio, kick; window 0: off).
ROWS = 8
#: ``--rows`` adds the UR10, whose stretched-elbow saddle held every row of a zoo target.
ROWS_ROBOTS = (*ROBOTS, "example-robot-data:ur10")
ROWS_GRID = {"damping": (0.1, 0.3, 1.0),
             "crawl": ((0, 0.0, 0.0), (6, 0.5, 1.0), (10, 0.5, 1.0), (10, 0.3, 1.0),
                       (10, 0.5, 1.5), (10, 0.5, 2.0), (15, 0.5, 2.0))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=1000, help="targets per robot and seed")
    parser.add_argument("--output", default="runs/tune_ours_lm.csv")
    parser.add_argument("--rows", action="store_true",
                        help="tune the deterministic table's solver (ROWS_GRID)")
    args = parser.parse_args(argv)
    grid = ROWS_GRID if args.rows else GRID
    fixed = (dict(max_iterations=MAX_STEPS * ROWS, restart_after=MAX_STEPS, abandon=(0, 0.0))
             if args.rows else {})
    rows = []
    for name in ROWS_ROBOTS if args.rows else ROBOTS:
        robot = load_robot(name)
        for seed in SEEDS:
            targets = sample_targets(robot, IKSettings(count=args.count, seed=seed))
            starts = [np.ascontiguousarray(targets.initials(k, ROWS if args.rows else AUTO_ROWS))
                      for k in range(args.count)]
            goals = np.ascontiguousarray(targets.T_target)
            for values in itertools.product(*grid.values()):
                setting = dict(zip(grid, values))
                lm = spc.SinglePoseLM(robot, "pose", (1.0, 0.5), **fixed, **setting)
                lm.solve(goals[0], None, starts[0], float("inf"))  # compiled or loaded
                began = time.perf_counter()
                outs = [lm.solve(goals[k], None, starts[k], float("inf"))
                        for k in range(args.count)]
                rows.append({"robot": robot.name, "seed": seed, **setting,
                             **{key: ",".join(f"{v:g}" for v in value)
                                for key, value in setting.items() if isinstance(value, tuple)},
                             "success_pct": 100.0 * np.mean([o.success for o in outs]),
                             "iterations_mean": float(np.mean([o.iterations for o in outs])),
                             "wall_s": time.perf_counter() - began})
            print(f"{robot.name} seed {seed}: {len(rows)} rows", file=sys.stderr, flush=True)
    table = pd.DataFrame(rows)
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    keys = list(grid)
    score = (table.groupby(keys, sort=False)
             .agg(success_min=("success_pct", "min"), iterations=("iterations_mean", "mean"),
                  wall_s=("wall_s", "sum")).reset_index()
             .sort_values(["success_min", "iterations"], ascending=[False, True]))
    score["rank"] = np.arange(1, len(score) + 1)
    current = ({"damping": pose_solver.ROWS_DAMPING, "crawl": pose_solver.ROWS_CRAWL} if args.rows
               else {"restart_after": spc.RESTART_AFTER, "max_step": spc.MAX_STEP,
                     "damping": spc.DAMPING, "abandon": spc.ABANDON})
    chosen = np.ones(len(score), dtype=bool)
    for key, value in current.items():
        chosen &= score[key] == (",".join(f"{v:g}" for v in value) if isinstance(value, tuple)
                                 else value)
    default = score[chosen]
    print(score.head(10).to_string(index=False))
    print("defaults:\n" + default.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
