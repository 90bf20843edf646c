"""Iterations per second of ``ours`` vs the paper's own FK formulation, in one process.

The paper (section 2.2) computes FK as a product of 25 elementary 4x4 matrices per pose,
built from the motor angles and multiplied batch-wise (``torch.bmm``); the authors' code
reaches about 250 it/s on a 2-core CPU. This script times one Adam iteration (forward,
L0..L6, backward, step) at n = 50 in float32 for

- ``pytorch-kinematics``: ikbench's ``ours`` step (FK through the URDF), and
- ``paper-matrix-chain``: the same step with FK written as the paper's matrix chain (written
  here from Eq. 4-11, not taken from the authors' code),

with several repetitions after a warm-up, and prints medians and the ratio.

Run: ``.venv/bin/python benchmarks/ours_speed.py [--repeat 7] [--iterations 300] [--threads 1]
[--output results/ours_speed.csv]``; the CSV has one row per (repetition, formulation) with the
CPU, versions and git revision in every row.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import pandas as pd
import torch

from ikbench import load_robot, load_targets
from ikbench.core.io import atomic_write_csv, check_writable
from ikbench.core.losses import PAPER_WEIGHTS, LossGoals, loss_terms, weighted_loss
from ikbench.core.provenance import provenance
from ikbench.core.task import line_tasks
from ikbench.methods.ours import initial_logits


def _rot(axis: str, deg):
    """(B, 4, 4) rotation about a principal axis by ``deg`` (B,) degrees."""
    a = deg * (math.pi / 180.0)
    c, s = torch.cos(a), torch.sin(a)
    one, zero = torch.ones_like(a), torch.zeros_like(a)
    rows = {
        "x": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    m = torch.zeros(a.shape[0], 4, 4, dtype=a.dtype)
    for i in range(3):
        for j in range(3):
            m[:, i, j] = rows[i][j]
    m[:, 3, 3] = 1.0
    return m


def _trans(batch, x, y, z, dtype):
    m = torch.eye(4, dtype=dtype).repeat(batch, 1, 1)
    m[:, 0, 3], m[:, 1, 3], m[:, 2, 3] = x, y, z
    return m


def paper_chain_fk(q):
    """Eq. 4-11 as a product of 4x4 matrices (cm); returns (point_cm, z-axis), (B, 3) each."""
    b, dt = q.shape[0], q.dtype

    def const(deg):
        return torch.full((b,), float(deg), dtype=dt)

    t1, t2, t3, t4, t5, t6, t7 = q.unbind(1)
    factors = [
        _trans(b, 0, 5, 19.5, dt), _rot("z", const(90)), _rot("z", t1),
        _trans(b, 0, -1.5, 2.5, dt), _rot("y", const(90)), _rot("z", t2),
        _trans(b, 3, 0, 9.5, dt), _rot("x", const(-90)), _rot("z", -t3),
        _trans(b, 17.5, 0, 0, dt), _rot("x", const(90)), _rot("z", const(180)), _rot("z", -t4),
        _trans(b, 10, 0, 0, dt), _rot("y", const(90)), _rot("z", -t5 / 2),
        _trans(b, 0, 0, 10, dt), _rot("x", const(-90)), _rot("z", const(-90)),
        _rot("z", t6 / 4.5 + 10),
        _trans(b, 0, -1, 0, dt), _trans(b, 6, 0, 0, dt), _rot("z", 20 + (t7 + 180) / 4.5),
        _trans(b, 6, 0, 0, dt), _rot("y", const(90)),
    ]
    m = factors[0]
    for f in factors[1:]:
        m = torch.bmm(m, f)
    return m[:, :3, 3], m[:, :3, 2]


def time_iterations(robot, task, fk_kind: str, iterations: int) -> float:
    """Iterations per second of Adam on ``task`` with the given FK."""
    dtype = torch.float32
    lo = torch.as_tensor(robot.lower, dtype=dtype)
    span = torch.as_tensor(robot.upper - robot.lower, dtype=dtype)
    goals = LossGoals.from_task(task, dtype)
    z = initial_logits(robot, task, dtype).requires_grad_(True)
    optimiser = torch.optim.Adam([z], lr=0.1)
    torch_fk = robot.torch_fk(dtype)
    start = time.perf_counter()
    for _ in range(iterations):
        optimiser.zero_grad()
        poses = lo + torch.sigmoid(z) * span
        if fk_kind == "pytorch-kinematics":
            point_m, direction = torch_fk(poses)
            point_cm = point_m * 100.0
        else:
            point_cm, direction = paper_chain_fk(poses)
        loss = weighted_loss(loss_terms(point_cm, direction, poses, goals), PAPER_WEIGHTS)
        loss.backward()
        optimiser.step()
    return iterations / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="timed repetitions (default 7)")
    parser.add_argument("--iterations", type=int, default=300,
                        help="Adam iterations per repetition (default 300)")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch threads (default 1, as ikbench run uses)")
    parser.add_argument("--output", default="results/ours_speed.csv",
                        help="CSV of every repetition (default results/ours_speed.csv)")
    args = parser.parse_args()
    if min(args.repeat, args.iterations, args.threads) < 1:
        parser.error("--repeat, --iterations and --threads must be >= 1")
    check_writable(args.output)
    torch.set_num_threads(args.threads)
    robot = load_robot()
    task = line_tasks(robot, load_targets().select("1"))[0]
    kinds = ["pytorch-kinematics", "paper-matrix-chain"]
    for kind in kinds:  # warm-up
        time_iterations(robot, task, kind, 20)
    rows = []
    for rep in range(args.repeat):
        for kind in kinds:  # interleaved, so background load hits both sides alike
            rows.append({"repetition": rep, "fk": kind, "steps": task.goal.steps,
                         "iterations": args.iterations,
                         "iterations_per_s": time_iterations(robot, task, kind, args.iterations)})
    info = provenance()
    frame = pd.DataFrame(rows).assign(
        cpu=info["cpu"], cpu_count=info["cpu_count"], torch_threads=info["torch_threads"],
        torch=info["packages"]["torch"], pytorch_kinematics=info["packages"]["pytorch-kinematics"],
        git_revision=info["git_revision"], created_utc=info["created_utc"])
    atomic_write_csv(args.output, frame)
    print(f"CPU: {info['cpu']} ({info['cpu_count']} cores, torch threads "
          f"{info['torch_threads']}), torch {info['packages']['torch']}, "
          f"pytorch-kinematics {info['packages']['pytorch-kinematics']}")
    print(f"n = {task.goal.steps}, float32, {args.iterations} iterations x {args.repeat} "
          "repetitions")
    rates = {k: frame.loc[frame["fk"] == k, "iterations_per_s"].tolist() for k in kinds}
    for kind in kinds:
        r = rates[kind]
        print(f"{kind:>20}: median {statistics.median(r):7.1f} it/s "
              f"(min {min(r):.1f}, max {max(r):.1f})")
    ratio = statistics.median(rates[kinds[0]]) / statistics.median(rates[kinds[1]])
    print(f"ratio pytorch-kinematics / paper-matrix-chain: {ratio:.2f}")
    print(f"written to {args.output}")


if __name__ == "__main__":
    main()
