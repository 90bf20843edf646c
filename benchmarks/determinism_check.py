"""Do ``ikbench ik``'s answers survive another machine? A check you can run on one.

Runs ``ikbench ik --robot ROBOT --count N --attempts 8`` once per method under conditions
that stand in for another CPU or another core count, each in a fresh process (the settings
below are read when a library loads, so they cannot change inside one process):

- ``reference``: this machine's defaults;
- ``blas-1-thread``: ``OPENBLAS_NUM_THREADS=1`` (another core count);
- ``blas-haswell`` / ``blas-sandybridge``: ``OPENBLAS_CORETYPE`` (OpenBLAS' kernels for an
  AVX2 CPU such as an AMD EPYC, or an AVX-only one);
- ``numpy-no-avx512``: ``NPY_DISABLE_CPU_FEATURES`` off numpy's AVX-512 loops;
- ``numba-generic``: ``NUMBA_CPU_NAME=generic`` (numba's code for no particular CPU);
- ``xla-avx`` / ``xla-avx512``: ``XLA_FLAGS=--xla_cpu_max_isa=AVX`` or ``AVX512`` (JAX's
  code without AVX2, or with AVX-512 where the CPU has it; pyroki pins AVX2 otherwise, see
  baselines/pyroki_trajopt.py); ``xla-16-threads``: XLA's computations split over 16
  threads (pyroki pins one otherwise).

For each (condition, method) it writes the success count and, target by target, whether the
answer is the reference's (every joint within ``--atol`` rad) to ``--output`` (CSV), and
prints the table. A method is "stable" when every condition gives the reference's success
column and answers. Conditions can only emulate another machine: a check on the other
machine itself is the final word.

    python benchmarks/determinism_check.py --methods sequential-ik,mink --count 100

Each run is cut at ``--timeout-s`` (a cut run is reported, not compared).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

CONDITIONS: dict[str, dict[str, str]] = {
    "reference": {},
    "blas-1-thread": {"OPENBLAS_NUM_THREADS": "1"},
    "blas-haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "blas-sandybridge": {"OPENBLAS_CORETYPE": "SandyBridge"},
    "numpy-no-avx512": {"NPY_DISABLE_CPU_FEATURES":
                        "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL"},
    "numba-generic": {"NUMBA_CPU_NAME": "generic"},
    "xla-avx": {"XLA_FLAGS": "--xla_cpu_max_isa=AVX"},
    "xla-avx512": {"XLA_FLAGS": "--xla_cpu_max_isa=AVX512"},
    "xla-16-threads": {"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true "
                       "intra_op_parallelism_threads=16"},
}
REPO = Path(__file__).resolve().parents[1]


def run_ik(method: str, env: dict[str, str], args: argparse.Namespace, out: Path
           ) -> tuple[pd.DataFrame | None, float, str]:
    """(results.csv rows or None, wall [s], why it has none) of one ``ikbench ik`` run."""
    command = [sys.executable, "-m", "ikbench.cli", "ik", "--robot", args.robot, "--count",
               str(args.count), "--attempts", "8", "--methods", method, "--seed",
               str(args.seed), "--output", str(out)]
    started = time.perf_counter()
    try:
        done = subprocess.run(command, env={**os.environ, **env}, capture_output=True,
                              text=True, timeout=args.timeout_s)
    except subprocess.TimeoutExpired:
        return None, time.perf_counter() - started, f"cut at {args.timeout_s:g} s"
    wall = time.perf_counter() - started
    found = list(out.rglob("results.csv"))
    if done.returncode != 0 or not found:
        return None, wall, f"exit {done.returncode}: {done.stderr.strip()[-200:]}"
    return pd.read_csv(found[0]), wall, ""


def answers(rows: pd.DataFrame) -> np.ndarray:
    """(targets, dof) answers [rad, m] in target order."""
    rows = rows.sort_values("target")
    return rows[[c for c in rows.columns if c[:1] == "q" and c[1:].isdigit()]].to_numpy(float)


def compare(rows: pd.DataFrame, reference: pd.DataFrame, atol: float) -> dict[str, object]:
    """Success count and per-target agreement of ``rows`` with ``reference``."""
    q, q_ref = answers(rows), answers(reference)
    same = np.all(np.isclose(q, q_ref, rtol=0.0, atol=atol, equal_nan=True), axis=1)
    ok = rows.sort_values("target")["success"].to_numpy(bool)
    ok_ref = reference.sort_values("target")["success"].to_numpy(bool)
    diff = np.abs(q - q_ref)
    return {"successes": int(ok.sum()), "success_differs": int(np.sum(ok != ok_ref)),
            "same_answers": int(same.sum()),
            "max_diff_deg": float(np.degrees(np.nanmax(diff))) if diff.size else 0.0}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="example-robot-data:ur5")
    parser.add_argument("--methods", default="sequential-ik,mink,ikpy,pyroki")
    parser.add_argument("--conditions", default=",".join(CONDITIONS))
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--atol", type=float, default=1e-9, help="same answer [rad, m]")
    parser.add_argument("--timeout-s", type=float, default=90.0)
    parser.add_argument("--output", type=Path, default=Path("determinism_check.csv"))
    args = parser.parse_args(argv)
    conditions = args.conditions.split(",")
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown or conditions[0] != "reference":
        parser.error(f"--conditions: {','.join(unknown) or conditions[0]!r}: the first must be "
                     f"reference, the others of {', '.join(CONDITIONS)}")
    table = []
    with tempfile.TemporaryDirectory() as tmp:
        for method in args.methods.split(","):
            reference = None
            for name in conditions:
                rows, wall, why = run_ik(method, CONDITIONS[name], args,
                                         Path(tmp) / method / name)
                line = {"method": method, "condition": name, "targets": args.count,
                        "wall_s": round(wall, 1), "note": why}
                if rows is not None and name == "reference":
                    reference = rows
                if rows is not None and reference is not None:
                    line.update(compare(rows, reference, args.atol))
                table.append(line)
                print(" ".join(f"{k}={v}" for k, v in line.items()), flush=True)
    frame = pd.DataFrame(table)
    frame.to_csv(args.output, index=False)
    for method, rows in frame.groupby("method", sort=False):
        compared = rows.dropna(subset=["same_answers"]) if "same_answers" in rows else rows[:0]
        stable = (len(compared) == len(conditions) and
                  bool((compared["same_answers"] == args.count).all()))
        print(f"{method}: {'stable' if stable else 'NOT stable'} over "
              f"{len(compared)}/{len(conditions)} conditions compared")
    return 0


if __name__ == "__main__":
    sys.exit(main())
