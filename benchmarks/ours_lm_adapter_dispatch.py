"""What ``ikbench ik``'s ours-lm adapter costs per call beside the kernel: the two ways it hands
a target to the compiled kernel, timed in one process.

- ``compiled-only``: as :meth:`ikbench.methods.ours_lm.pose_solver.OursLMSolver.solve_within`
  calls it now: the frame's column views go as they are to a dispatcher that never compiles
  (:func:`ikbench.methods.ours_lm.single_pose_compiled.compiled_only`);
- ``checked-copies``: the same kernel call after each array's layout check and copy
  (``_f64``, what every call did before, and what the adapter still does for a layout the
  kernel was not compiled for).

Both solve the same targets from the same starts with a zero budget (one FK and Jacobian, no
LM iteration: what a call costs besides its iterations), each call timed alone by
``time.perf_counter``, the two ways alternating in blocks of 100 calls, ``--repeat`` rounds;
medians, their ratio and the load average before and after are printed and written.

Run: ``.venv/bin/python benchmarks/ours_lm_adapter_dispatch.py [--robots
example-robot-data:ur10,panda] [--count 2000] [--repeat 5] [--output
runs/ours_lm_adapter_dispatch.csv]``.
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench import load_robot
from ikbench.methods.ours_lm.pose_solver import OursLMSolver, _f64
from ikbench.methods.ours_lm.single_pose_compiled import random_initials

BLOCK = 100


def time_robot(name: str, args: argparse.Namespace) -> list[dict]:
    """The two ways' rows of one robot (see the module docstring)."""
    robot = load_robot(name)
    solver = OursLMSolver(robot)
    solver.prepare()
    T = robot.fk_transform(random_initials(robot, (args.count,), 0))
    starts = random_initials(robot, (args.count, 1), 1)
    spec = solver.descent.spec

    def compiled_only(i: int) -> None:
        solver._views(spec, T[i][:3, 3], T[i][:3, :3], starts[i], 0.0)

    def checked_copies(i: int) -> None:
        solver._views_any(spec, _f64(T[i][:3, 3]), _f64(T[i][:3, :3]), _f64(starts[i]), 0.0)

    ways = {"compiled-only": compiled_only, "checked-copies": checked_copies}
    times: dict[str, list[float]] = {way: [] for way in ways}
    load_before = os.getloadavg()[0]
    gc.disable()
    try:
        for _ in range(args.repeat):
            for first in range(0, args.count, BLOCK):
                for call in ways.values():
                    for i in range(first, min(first + BLOCK, args.count)):
                        began = time.perf_counter()
                        call(i)
                        times[call.__name__.replace("_", "-")].append(
                            time.perf_counter() - began)
    finally:
        gc.enable()
    load_after = os.getloadavg()[0]
    medians = {way: float(np.median(t)) * 1e6 for way, t in times.items()}
    return [{"robot": robot.name, "way": way, "calls": len(times[way]), "median_us": median_us,
             "ratio_to_checked_copies": median_us / medians["checked-copies"],
             "load_before": load_before, "load_after": load_after}
            for way, median_us in medians.items()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="example-robot-data:ur10,panda")
    parser.add_argument("--count", type=int, default=2000, help="targets per robot")
    parser.add_argument("--repeat", type=int, default=5, help="rounds over the targets")
    parser.add_argument("--output", default="runs/ours_lm_adapter_dispatch.csv")
    args = parser.parse_args(argv)
    rows = [row for name in args.robots.split(",") for row in time_robot(name, args)]
    table = pd.DataFrame(rows)
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.output, index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
