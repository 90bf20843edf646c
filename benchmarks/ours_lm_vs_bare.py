"""ours-lm's per-call time against the libraries' bare calls, in one process, interleaved.

Per robot (``--robot``): ``--count`` targets of ``ikbench ik``'s sampler
(:func:`ikbench.studies.ik.sample_targets`, ``--seed``: by default 201, disjoint from the
benchmark seeds 1 and 4 and from the tuning seeds 101 and 102 of
``benchmarks/tune_ours_lm_single_pose.py``, which are all refused), each with its first
initial configuration. Four calls per target, every input prepared before the clock:

- ``ours-lm``: ``ikbench ik``'s adapter call,
  :meth:`ikbench.methods.ours_lm.pose_solver.OursLMSolver.solve_within` of the one row, no
  budget (one descent of at most 100 LM iterations, the goal's columns as they come);
- ``eaik``: EAIK's bare ``calculate_IK(T)`` (all branches, closed form), the robot built as
  ``baselines/eaik_ik.py`` builds it (:meth:`baselines.eaik_ik.EaikSolver.bare_call`, the
  frame assembled before the clock); none of the adapter's branch selection. Skipped (with
  a line) where EAIK has no decomposition;
- ``eaik-adapter``: ``ikbench ik``'s eaik adapter call, the one the study times
  (:meth:`baselines.eaik_ik.EaikSolver.prepared_call`, made before the clock: EAIK's call,
  the reads of its answer arrays and the compiled branch choice nearest the start), so its
  ratio to ``eaik`` is the glue ikbench adds around the library, measured under the same
  interleaved rule;
- ``rtb-lm``: roboticstoolbox's bare ``ets.ik_LM(Tep, q0=..., ilimit=30, slimit=1, tol=TOL,
  joint_limits=True)`` on the ETS ``baselines/rtb.py`` builds (:func:`baselines.rtb.rtb_ets`),
  from the same start in [rad].

Each call is timed alone by ``time.perf_counter`` (garbage collection off), interleaved per
target (the four calls of a target one after the other, their order rotated from target to
target), ``--repeat`` rounds. Per method and target the median over rounds; per method the
median over targets; the ratios of :data:`RATIOS` (ours-lm's to each other's, the eaik
adapter's to EAIK's bare call) with a paired bootstrap 95 % interval over targets
(``scipy.stats.bootstrap``, percentile, 5,000 resamples, seeded).
Success is judged here (Pinocchio FK within 1 mm / 0.5 deg and the joint limits; EAIK's bare
call: any exact branch, its angles moved by whole turns into the limits where that brings
them there, as its branches lie in (-pi, pi]). The load
average is recorded before and after.

Run: ``.venv/bin/python benchmarks/ours_lm_vs_bare.py [--robot example-robot-data:ur5
[--robot ...]] [--count 100] [--seed 201] [--repeat 5] [--output runs/ours_lm_vs_bare]``;
writes to the folder ``summary.csv`` (a row per robot and method: the medians, ratios,
intervals, success and load), ``calls.csv`` (every timed call) and ``bare_calls.json`` (the
settings and the provenance: commit, CPU, load, library versions). The ``bare-calls`` entry of
``ikbench reproduce --all`` runs it on the arms of the IK tables and the zoo into
``results/bare_calls/``.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from ikbench import load_robot
from ikbench.core.errors import InputError
from ikbench.core.io import atomic_path
from ikbench.core.provenance import provenance
from ikbench.core.rotations import geodesic_angle
from ikbench.methods.ours_lm.pose_solver import OursLMSolver
from ikbench.studies.ik import IKSettings, sample_targets

#: The benchmarks' own seeds (``ikbench ik``, the committed tables) and the seeds ours-lm's
#: defaults were tuned on (``benchmarks/tune_ours_lm_single_pose.py``): never used here, so
#: no figure of this script is measured on the targets a setting was chosen on.
BENCHMARK_SEEDS, TUNING_SEEDS = (1, 4), (101, 102)
TOLERANCE_MM, TOLERANCE_DEG = 1.0, 0.5
#: method -> the methods its median is divided by (paired, with a bootstrap interval)
RATIOS = {"ours-lm": ("eaik", "eaik-adapter", "rtb-lm"), "eaik-adapter": ("eaik",)}


def _callers(robot, targets) -> dict:
    """method -> (call(i), answer(i) -> list of (dof,) [rad] answers of the last call)."""
    count = len(targets.T_target)
    T = targets.T_target
    starts = [np.ascontiguousarray(targets.initials(i, 1)) for i in range(count)]
    ours = OursLMSolver(robot, "pose", (TOLERANCE_MM, TOLERANCE_DEG))
    ours.prepare()
    points = [T[i][:3, 3] for i in range(count)]
    rotations = [T[i][:3, :3] for i in range(count)]
    last: dict[str, object] = {}
    # the first start in [rad] (URDF order), for the libraries that take no pose units
    q0s = [np.ascontiguousarray(robot.to_urdf(starts[i][0]), dtype=float) for i in range(count)]
    inf = math.inf

    def ours_call(i: int) -> None:
        last["ours-lm"] = ours.solve_within(starts[i], points[i], rotations[i], inf)

    callers = {"ours-lm": (ours_call, lambda: [robot.to_urdf(last["ours-lm"].q)])}
    try:
        from ikbench.baselines.eaik_ik import EaikSolver

        eaik = EaikSolver(robot)
        eaik.prepare()  # ValueError where EAIK has no decomposition
        calls = [eaik.bare_call(starts[i][0], np.ascontiguousarray(points[i]),
                                np.ascontiguousarray(rotations[i])) for i in range(count)]

        def eaik_call(i: int) -> None:
            last["eaik"] = calls[i]()

        def eaik_answers() -> list:
            solution = last["eaik"]
            Q = np.asarray(solution.Q, dtype=float).reshape(-1, robot.dof)
            ls = np.asarray(solution.is_LS, dtype=bool) if len(Q) else np.zeros(0, bool)
            return list(Q[~ls])

        callers["eaik"] = (eaik_call, eaik_answers)

        # the adapter takes and gives [rad] (no pose units), as the study passes them
        urdf_starts = [q0[None] for q0 in q0s]

        prepared = [eaik.prepared_call(urdf_starts[i], points[i], rotations[i], inf)
                    for i in range(count)]

        def adapter_call(i: int) -> None:
            last["eaik-adapter"] = prepared[i]()

        def adapter_answers() -> list:
            out = last["eaik-adapter"]
            return [out.q] if out.ok else []

        callers["eaik-adapter"] = (adapter_call, adapter_answers)
    except (ImportError, ValueError, RuntimeError) as exc:
        print(f"eaik skipped: {exc}", file=sys.stderr)
    from ikbench.baselines.rtb import ILIMIT, TOL, goal_frame, rtb_ets
    from ikbench.schemes.chain import chain_of

    ets = rtb_ets(chain_of(robot))
    teps = [goal_frame(T[i][:3, 3], T[i][:3, :3]) for i in range(count)]
    ik_lm = ets.ik_LM

    def rtb_call(i: int) -> None:
        last["rtb-lm"] = ik_lm(teps[i], q0=q0s[i], ilimit=ILIMIT, slimit=1, tol=TOL,
                               joint_limits=True)

    callers["rtb-lm"] = (rtb_call, lambda: [np.asarray(last["rtb-lm"].q, dtype=float)])
    return callers


def _judged(robot, answers: list, T: np.ndarray, turns: bool = False) -> bool:
    """Any answer [rad] within the tolerances (Pinocchio FK) and the joint limits; with
    ``turns``, a revolute joint's angle first moved by whole turns into its limits where one
    brings it there (the same frame: EAIK's bare branches lie in (-pi, pi], while Kinova's
    joints 2, 3 and 5, for one, are limited to 47-313 deg)."""
    for q_urdf in answers:
        q_urdf = np.asarray(q_urdf, dtype=float)
        if turns:
            q_urdf = _into_limits_by_turns(robot, q_urdf)
        q = robot.from_urdf(q_urdf)
        if not np.all((q >= robot.lower - 1e-9) & (q <= robot.upper + 1e-9)):
            continue
        got = robot.fk_transform(q[None])[0]
        if (np.linalg.norm(got[:3, 3] - T[:3, 3]) * 1000.0 <= TOLERANCE_MM and np.degrees(
                geodesic_angle(T[None, :3, :3], got[None, :3, :3]))[0] <= TOLERANCE_DEG):
            return True
    return False


def _into_limits_by_turns(robot, q_urdf: np.ndarray) -> np.ndarray:
    """``q_urdf`` [rad] with each revolute joint moved by the whole turns that bring it
    within its limits, the least move (:func:`ikbench.baselines.eaik_ik.in_limit_turns`
    nearest the answer itself), as the eaik adapter moves its branches."""
    from ikbench.baselines.eaik_ik import in_limit_turns

    lower, upper = robot.to_urdf(robot.lower), robot.to_urdf(robot.upper)
    revolute = np.array([kind != "prismatic" for kind in robot.joint_types])
    moved, _ = in_limit_turns(q_urdf, np.minimum(lower, upper), np.maximum(lower, upper),
                              q_urdf, revolute)
    return moved[0]


def _ratio_interval(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """median(a) / median(b) and its paired bootstrap 95 % interval over targets."""
    def statistic(x, y, axis=-1):
        return np.median(x, axis=axis) / np.median(y, axis=axis)

    result = stats.bootstrap((a, b), statistic, paired=True, vectorized=True,
                             n_resamples=5000, confidence_level=0.95, method="percentile",
                             random_state=np.random.default_rng(0))
    ci = result.confidence_interval
    return float(statistic(a, b)), float(ci.low), float(ci.high)


def _measure(robot_name: str, robot, count: int, seed: int, repeat: int
             ) -> tuple[list[dict], pd.DataFrame]:
    """One robot's rows (a row per method) and its per-call times."""
    targets = sample_targets(robot, IKSettings(count=count, seed=seed))
    callers = _callers(robot, targets)
    names = list(callers)
    times = {name: np.zeros((count, repeat)) for name in names}
    success = {name: np.zeros(count, dtype=bool) for name in names}
    for i in range(min(20, count)):  # warm: caches, branch predictors, lazy imports
        for call, _ in callers.values():
            call(i)
    load_before = os.getloadavg()
    clock = time.perf_counter
    gc.disable()
    try:
        for r in range(repeat):
            for i in range(count):
                shift = (i + r) % len(names)
                for name in names[shift:] + names[:shift]:
                    call, answers = callers[name]
                    start = clock()
                    call(i)
                    times[name][i, r] = clock() - start
                    if r == 0:
                        gc.enable()
                        success[name][i] = _judged(robot, answers(), targets.T_target[i],
                                                   turns=name == "eaik")
                        gc.disable()
    finally:
        gc.enable()
    load_after = os.getloadavg()
    per_target = {name: np.median(times[name], axis=1) * 1e6 for name in names}
    rows = []
    for name in names:
        row = {"robot": robot_name, "dof": robot.dof, "method": name, "count": count,
               "seed": seed, "repeat": repeat,
               "median_us": float(np.median(per_target[name])),
               "success_pct": 100.0 * success[name].mean(),
               "load_before": load_before[0], "load_after": load_after[0]}
        for other in RATIOS.get(name, ()):
            if other in names:
                ratio, low, high = _ratio_interval(per_target[name], per_target[other])
                row[f"ratio_to_{other}"] = ratio
                row[f"ratio_to_{other}_ci95_low"], row[f"ratio_to_{other}_ci95_high"] = low, high
        rows.append(row)
    calls = pd.DataFrame([{"robot": robot_name, "method": name, "target": i, "round": r,
                           "time_us": times[name][i, r] * 1e6}
                          for name in names for i in range(count) for r in range(repeat)])
    print(f"{robot_name}: {count} targets (seed {seed}) x {repeat} rounds, "
          f"load {load_before[0]:.2f} -> {load_after[0]:.2f}")
    for row in rows:
        line = f"  {row['method']:12s} median {row['median_us']:8.2f} us  success " \
               f"{row['success_pct']:5.1f} %"
        for other in names:
            key = f"ratio_to_{other}"
            if key in row:
                line += (f"  / {other} {row[key]:.3f} [{row[key + '_ci95_low']:.3f}, "
                         f"{row[key + '_ci95_high']:.3f}]")
        print(line, flush=True)
    return rows, calls


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", action="append", metavar="NAME",
                        help="a robot (repeat for several; default example-robot-data:ur5)")
    parser.add_argument("--count", type=int, default=100, help="targets per robot")
    parser.add_argument("--seed", type=int, default=201,
                        help="seed of the targets and starts (not 1 or 4, the benchmarks', "
                             "nor 101 or 102, ours-lm's tuning seeds)")
    parser.add_argument("--repeat", type=int, default=5, help="timed rounds over the targets")
    parser.add_argument("--output", type=Path, default=Path("runs/ours_lm_vs_bare"),
                        help="folder for summary.csv, calls.csv and bare_calls.json")
    args = parser.parse_args(argv)
    names = args.robot or ["example-robot-data:ur5"]
    try:
        if args.seed in BENCHMARK_SEEDS + TUNING_SEEDS:
            raise InputError(f"--seed: {args.seed} is a benchmark seed {BENCHMARK_SEEDS} or a "
                             f"tuning seed {TUNING_SEEDS}; take a disjoint one (default 201)")
        if args.count < 2 or args.repeat < 1:
            raise InputError(f"--count {args.count} / --repeat {args.repeat}: need >= 2 / >= 1")
        if args.output.suffix or args.output.is_file():
            raise InputError(f"--output: {args.output} is a file name; give a folder")
        robots = [load_robot(name) for name in names]
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    record = provenance(extra=("eaik", "roboticstoolbox-python"))
    rows, calls = [], []
    for name, robot in zip(names, robots, strict=True):
        robot_rows, robot_calls = _measure(name, robot, args.count, args.seed, args.repeat)
        rows += robot_rows
        calls.append(robot_calls)
    with atomic_path(args.output / "summary.csv") as tmp:  # makes the folder
        pd.DataFrame(rows).to_csv(tmp, index=False)
    with atomic_path(args.output / "calls.csv") as tmp:
        pd.concat(calls).to_csv(tmp, index=False)
    settings = {"robots": names, "count": args.count, "seed": args.seed,
                "repeat": args.repeat, "tolerance_mm": TOLERANCE_MM,
                "tolerance_deg": TOLERANCE_DEG, "ratios": {k: list(v) for k, v in RATIOS.items()}}
    with atomic_path(args.output / "bare_calls.json") as tmp:
        tmp.write_text(json.dumps({"study": "ours_lm_vs_bare", "settings": settings,
                                   "provenance": record}, indent=2) + "\n")
    print(f"written to {args.output}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
