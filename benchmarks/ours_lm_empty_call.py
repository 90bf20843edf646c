"""What an ours-lm call costs when the target is already solved (q0 = its answer): the
per-call cost besides the LM iterations, through each way a target reaches the kernel.

- ``adapter``: ``ikbench ik``'s call,
  :meth:`ikbench.methods.ours_lm.pose_solver.OursLMSolver.solve_within` (one row, no budget);
- ``solve_pose``: the public call, :func:`ikbench.solve_pose` (robot, T (4, 4), q0);
- ``kernel``: the compiled kernel alone (``solve_views`` through the dispatcher that never
  compiles), the floor of any Python caller.

Targets: FK of ``--count`` seeded configurations (seed 101), each call's start its own
answer, so the kernel's loop checks the start and returns (0 iterations: one FK and one
Jacobian). Each call timed alone by ``time.perf_counter`` (garbage collection off), the ways
alternating in blocks of 500 calls; medians over all calls; the timer's own median and the
load average before and after are printed.

Run: ``.venv/bin/python benchmarks/ours_lm_empty_call.py [--robot example-robot-data:ur5]
[--count 20000]``.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import time

import numpy as np

import ikbench
from ikbench.methods.ours_lm.pose_solver import OursLMSolver
from ikbench.methods.ours_lm.single_pose_compiled import random_initials

BLOCK = 500


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="example-robot-data:ur5")
    parser.add_argument("--count", type=int, default=20000)
    args = parser.parse_args()
    robot = ikbench.load_robot(args.robot)
    solver = OursLMSolver(robot, "pose", (1.0, 0.5))
    solver.prepare()
    n = args.count
    q = random_initials(robot, (n,), 101)
    T = robot.fk_transform(q)
    rows = q[:, None, :].copy()
    points, rotations = [T[i][:3, 3] for i in range(n)], [T[i][:3, :3] for i in range(n)]
    spec, views, solve_pose, inf = solver.descent.spec, solver._views, ikbench.solve_pose, math.inf
    ways = {
        "adapter": lambda i: solver.solve_within(rows[i], points[i], rotations[i], inf),
        "solve_pose": lambda i: solve_pose(robot, T[i], q[i]),
        "kernel": lambda i: views(spec, points[i], rotations[i], rows[i], inf),
    }
    assert all(solver.solve_within(rows[i], points[i], rotations[i], inf).iterations == 0
               for i in range(100))
    times: dict[str, list[float]] = {way: [] for way in ways}
    for call in ways.values():
        for i in range(200):
            call(i)
    load_before = os.getloadavg()
    clock = time.perf_counter
    gc.disable()
    try:
        for first in range(0, n, BLOCK):
            for way, call in ways.items():
                out = times[way]
                for i in range(first, min(first + BLOCK, n)):
                    start = clock()
                    call(i)
                    out.append(clock() - start)
        empty = []
        for _ in range(n):
            start = clock()
            empty.append(clock() - start)
    finally:
        gc.enable()
    print(f"{args.robot}: {n} calls per way; load {load_before[0]:.2f} -> "
          f"{os.getloadavg()[0]:.2f}; the timer alone {np.median(empty) * 1e6:.3f} us")
    for way, values in times.items():
        p10, p50, p90 = np.percentile(values, (10, 50, 90)) * 1e6
        print(f"  {way:10s} median {p50:6.3f} us  p10 {p10:6.3f}  p90 {p90:6.3f}")


if __name__ == "__main__":
    main()
