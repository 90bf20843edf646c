"""Throughput of ours-lm: the numpy solver against the numba and torch backends, per batch.

:func:`throughput` solves batches of B line trajectories (B = 7: the paper's seven targets,
the latency case; larger B: touch poses from the batch sampler, seed 0) with the numpy solver
(up to ``numpy_max_batch``), with the numba backend (the same loop compiled, on ``threads``
threads; when numba is installed) and with the torch backend on ``device`` in each dtype, all
in one process: ``warmup`` untimed rounds, then ``repeat`` timed rounds per case, the cases of a
batch taking turns round by round (so a change in the machine's load hits them alike). A
round is one ``solve_batch`` call, tasks in, poses and losses back in host memory (the torch
backend's time on the device, synchronised, is reported too). Per case: median/min/max wall time,
trajectories per second (B / median), the speed-up against numpy at the same B (ratio of
medians), iterations, convergence, and how far the losses are from the numpy solver's
(largest relative difference; from the torch float64 ones where numpy did not run). The
numba backend is compiled (or loaded from numba's cache) before the first round.

Output (:func:`write`): ``throughput.csv`` (one row per case), ``throughput_runs.csv`` (every
timed round), ``throughput.json`` (device, CPU, versions) and ``throughput.md``.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.losses import PAPER_WEIGHTS
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, load_targets
from ikbench.core.task import line_tasks
from ikbench.methods.ours_lm import LMSettings, solve_batch
from ikbench.methods.ours_lm.devices import (
    check_device,
    device_name,
    numba_installed,
)
from ikbench.render.run_report import markdown_table
from ikbench.runtime.progress import Reporter
from ikbench.studies.batch import sample_touch_poses
from ikbench.studies.dataset_shard import line_tasks as sampled_line_tasks
from ikbench.studies.shape import TimedResult

DEFAULT_BATCHES = (7, 1000, 10_000, 100_000)
DEFAULT_DTYPES = ("float64", "float32")
#: The largest batch timed (10x the default's largest; a batch is one solve in memory).
MAX_BATCH = 1_000_000
NUMPY = "numpy"
NUMBA = "numba"


def parse_batches(text: object) -> list[int]:
    """``"7,1000"`` -> [7, 1000] (each an integer from 1 to :data:`MAX_BATCH`)."""
    try:
        values = [int(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or min(values) < 1 or max(values) > MAX_BATCH:
        raise InputError(f"--batches: {text!r} is not a list of batch sizes from 1 to "
                         f"{MAX_BATCH:,}, e.g. 7,1000,10000")
    return list(dict.fromkeys(values))


def parse_dtypes(text: object) -> list[str]:
    """``"float64,float32"`` -> the dtypes (each float64 or float32)."""
    values = [v.strip() for v in str(text).split(",") if v.strip()]
    if not values or any(v not in DEFAULT_DTYPES for v in values):
        raise InputError(f"--dtypes: {text!r} is not a list of float64, float32")
    return list(dict.fromkeys(values))


@dataclass
class ThroughputResult(TimedResult):
    """One row per case (backend, dtype, batch), every timed round, and the record.
    :meth:`write` writes throughput.csv, throughput_runs.csv, throughput.json and
    throughput.md (:class:`~ikbench.studies.shape.TimedResult`)."""

    STEM = "throughput"

    def markdown(self) -> str:
        """The module's :func:`markdown` of this result."""
        return markdown(self)


@dataclass(frozen=True)
class ThroughputSpec:
    """A throughput study: the torch device, the batch sizes and dtypes, the timed and
    untimed rounds, the numpy solver's largest batch, the segments, the targets and robot (or
    their names), the progress lines and the numba backend's threads and use (the keywords of
    :func:`throughput`). :meth:`validate` checks them; :func:`run` runs it
    (:mod:`ikbench.studies.shape`)."""

    device: str
    batches: tuple[int, ...] = tuple(DEFAULT_BATCHES)
    dtypes: tuple[str, ...] = tuple(DEFAULT_DTYPES)
    repeat: int = 3
    warmup: int = 1
    numpy_max_batch: int = 10_000
    steps: int | None = None
    targets: str | Path | Targets | None = None
    robot: Robot | str | None = None
    progress: bool = True
    threads: int | None = None
    numba: bool | None = None

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for an unknown device or rounds that are
        not integers (repeat >= 1, warm-up >= 0)."""
        check_device(self.device)
        for flag, value, low in (("--repeat", self.repeat, 1), ("--warmup", self.warmup, 0)):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InputError(f"{flag}: {value!r} must be an integer >= {low}")


def throughput(device: str, *, batches: Sequence[int] = DEFAULT_BATCHES,
               dtypes: Sequence[str] = DEFAULT_DTYPES,
               repeat: int = 3, warmup: int = 1, numpy_max_batch: int = 10_000,
               steps: int | None = None, targets: str | Path | Targets | None = None,
               robot: Robot | str | None = None, progress: bool = True,
               threads: int | None = None, numba: bool | None = None) -> ThroughputResult:
    """Time the numpy solver, the numba backend and the torch backend on ``device`` (see the
    module docstring).

    Args:
        device: torch device of the backend (``cpu``, ``cuda``, ``cuda:N``).
        batches: batch sizes B; 7 means the paper's seven targets.
        dtypes: the torch backend's precisions to time.
        repeat / warmup: timed and untimed rounds per case.
        numpy_max_batch: the numpy solver runs only batches up to this size.
        steps: segments n (default: the targets file's, 50).
        targets: targets file (default the robot's); its start pose starts every line.
        robot: the robot (default NICO's right arm).
        progress: progress lines on stderr.
        threads: threads of the numba backend (None: all cores numba sees).
        numba: time the numba backend (None: when numba is installed).
    """

    spec = ThroughputSpec(device, tuple(batches), tuple(dtypes), repeat, warmup,
                          numpy_max_batch, steps, targets, robot, progress, threads, numba)
    spec.validate()
    return run(spec)


def run(spec: ThroughputSpec) -> ThroughputResult:
    """Time the cases of ``spec`` (validated: :meth:`ThroughputSpec.validate`); nothing is
    written (:meth:`ThroughputResult.write` writes it)."""
    device = check_device(spec.device) or "cpu"  # the device's canonical name
    batches, dtypes, repeat, warmup = (list(spec.batches), list(spec.dtypes), spec.repeat,
                                       spec.warmup)
    numpy_max_batch, steps, targets = spec.numpy_max_batch, spec.steps, spec.targets
    progress, threads, numba = spec.progress, spec.threads, spec.numba
    robot = as_robot(spec.robot)
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    targets = targets.with_steps(steps)
    log = Reporter("bench", enabled=progress).say
    pool = _task_pool(robot, targets, batches)
    numba = numba_installed() if numba is None else numba
    cases = [(NUMPY, "float64", LMSettings(backend=NUMPY))]
    if numba:
        cases.append((NUMBA, "float64", LMSettings(backend=NUMBA, threads=threads)))
        _warm_up_numba(robot, log)
    cases += [("torch", dtype, LMSettings(device=device, dtype=dtype)) for dtype in dtypes]
    runs, losses = [], {}
    for b in batches:
        tasks = pool[b]
        mine = [c for c in cases if c[0] != NUMPY or b <= numpy_max_batch]
        for r in range(warmup + repeat):  # rounds interleaved: each case meets the same load
            for backend, dtype, settings in mine:
                row, result = _round(robot, tasks, settings, log,
                                     f"{backend} {dtype} B={b}", r, warmup)
                if row is not None:
                    runs.append({"backend": backend, "dtype": dtype, "batch": b,
                                 "round": r - warmup + 1, **row})
                losses[backend, dtype, b] = result
    summary = summarise(pd.DataFrame(runs), losses)
    record = {"device": device, "device_name": device_name(device), "batches": list(batches),
              "dtypes": list(dtypes), "repeat": repeat, "warmup": warmup,
              "numpy_max_batch": numpy_max_batch, "steps": targets.steps,
              "robot": robot.describe(), "targets": targets.source,
              **_versions(numba, threads), **provenance()}
    return ThroughputResult(summary, pd.DataFrame(runs), record)


def _warm_up_numba(robot, log) -> None:
    start = time.perf_counter()
    importlib.import_module("ikbench.methods.ours_lm.compiled").warm_up(robot)
    log(f"numba backend compiled or loaded from its cache in {time.perf_counter() - start:.1f} s")


def _task_pool(robot, targets, batches) -> dict:
    """The tasks of each batch size: the paper's seven for 7, else sampled touch poses."""
    largest = max([b for b in batches if b != len(targets.ids)] or [0])
    pool: dict[int, list] = {}
    if largest:
        touch, _ = sample_touch_poses(robot, targets.start_pose, largest, seed=0)
        sampled, _, _ = sampled_line_tasks(robot, targets.start_pose, touch, targets.steps)
    for b in batches:
        pool[b] = line_tasks(robot, targets) if b == len(targets.ids) else sampled[:b]
    return pool


def _round(robot, tasks, settings, log, label, r, warmup):
    """One round of one case: (the timed row, or None in a warm-up round; the result)."""

    start = time.perf_counter()
    result = solve_batch(robot, tasks, settings, weights=_paper_weights())
    wall = time.perf_counter() - start
    timed = r >= warmup
    log(f"{label}: {'round ' + str(r - warmup + 1) if timed else 'warm-up'} "
        f"{wall:.4f} s ({len(tasks) / wall:.0f} trajectories/s)")
    if not timed:
        return None, result
    return {"wall_s": wall, "device_loop_s": getattr(result, "loop_s", np.nan),
            "iterations_median": float(np.median(result.iterations)),
            "iterations_max": int(result.iterations.max()),
            "converged_share": float(result.converged.mean()),
            "loss_sum": float(result.loss.sum())}, result


def _paper_weights():

    return dict(PAPER_WEIGHTS)


def summarise(runs: pd.DataFrame, losses: dict) -> pd.DataFrame:
    """One row per (backend, dtype, batch): medians, rates, speed-up and loss agreement."""
    rows = []
    for (backend, dtype, b), group in runs.groupby(["backend", "dtype", "batch"], sort=False):
        wall = group["wall_s"].to_numpy()
        reference = losses.get((NUMPY, "float64", b)) or losses.get(("torch", "float64", b))
        result = losses[backend, dtype, b]
        rel = (np.abs(result.loss - reference.loss) / np.abs(reference.loss)
               if reference is not None else np.full(1, np.nan))
        rows.append({"backend": backend, "dtype": dtype, "batch": b, "rounds": len(wall),
                     "wall_median_s": float(np.median(wall)), "wall_min_s": float(wall.min()),
                     "wall_max_s": float(wall.max()),
                     "device_loop_median_s": float(np.median(group["device_loop_s"])),
                     "trajectories_per_s": b / float(np.median(wall)),
                     "iterations_median": float(group["iterations_median"].iloc[-1]),
                     "iterations_max": int(group["iterations_max"].iloc[-1]),
                     "converged_share": float(group["converged_share"].iloc[-1]),
                     "loss_reference": NUMPY if (NUMPY, "float64", b) in losses
                     else "torch float64",
                     "loss_max_rel_diff": float(rel.max())})
    table = pd.DataFrame(rows)
    speedups = []
    for _, row in table.iterrows():
        base = table[(table["backend"] == NUMPY) & (table["batch"] == row["batch"])]
        speedups.append(float(base["wall_median_s"].iloc[0] / row["wall_median_s"])
                        if len(base) else np.nan)
    table["speedup_vs_numpy"] = speedups
    return table


def _versions(numba: bool, threads: int | None) -> dict:
    import torch

    out: dict[str, Any] = {"torch": torch.__version__, "cuda": torch.version.cuda,
           "cuda_available": torch.cuda.is_available(), "numba": None, "numba_threads": None}
    if numba:
        import numba as nb

        compiled = importlib.import_module("ikbench.methods.ours_lm.compiled")
        most = compiled.max_threads()
        out.update(numba=nb.__version__, numba_threads=min(threads or most, most),
                   numba_threads_rule=f"one thread per {compiled.PER_THREAD} trajectories, "
                   "at most numba_threads")
    return out


def write(result: ThroughputResult, output: str | Path) -> Path:
    """Write throughput.csv, throughput_runs.csv, throughput.json and throughput.md
    (:meth:`ThroughputResult.write`)."""
    return result.write(output)


def markdown(result: ThroughputResult) -> str:
    """throughput.md: the cases side by side, the machine and versions."""
    rec, s = result.record, result.summary.copy()
    s["wall_median_ms"] = 1000.0 * s["wall_median_s"]
    s["loss_max_rel_diff"] = [f"{v:.1e}" for v in s["loss_max_rel_diff"]]
    cols = ["backend", "dtype", "batch", "rounds", "wall_median_ms", "trajectories_per_s",
            "speedup_vs_numpy", "iterations_median", "converged_share", "loss_max_rel_diff"]
    digits = {"wall_median_ms": 1, "trajectories_per_s": 0, "speedup_vs_numpy": 2,
              "iterations_median": 0, "converged_share": 3}
    packages = ", ".join(f"{k} {v}" for k, v in rec["packages"].items() if v)
    return "\n".join([
        "# ours-lm throughput: numpy solver vs numba and torch backends", "",
        f"Torch device `{rec['device']}` ({rec['device_name']}); numba backend "
        f"{_numba_text(rec)}; batch 7 is the paper's seven "
        f"targets (latency), larger batches are touch poses from the batch sampler (seed 0); "
        f"n = {rec['steps']}, the paper's weights, the same stopping rule. {rec['warmup']} "
        f"untimed warm-up round(s), then {rec['repeat']} timed rounds per case in one process, "
        "the cases of a batch taking turns round by round; "
        "a round is one `solve_batch` call, tasks in, results in host memory. Trajectories/s "
        "= batch / median wall time; speed-ups are ratios of medians against the numpy "
        "solver at the same batch, measured in this run; `loss_max_rel_diff` is the largest "
        "relative difference of a trajectory's final loss from the numpy solver's (from "
        "torch float64 where numpy did not run).", "",
        *_headline(s),
        markdown_table(s[cols], digits), "",
        "## Machine", "",
        f"{rec['cpu']} ({rec['cpu_count']} cores, torch threads {rec['torch_threads']}); "
        f"torch {rec['torch']}, CUDA {rec['cuda'] or 'none'}; Python {rec['python']}, "
        f"{rec['platform']}; git {rec['git_revision']}; {packages}; {rec['created_utc']}.", "",
        "Timings on a shared machine vary from run to run; compare the ratios measured "
        "within one run.", ""])


def _numba_text(rec: dict) -> str:
    if not rec.get("numba"):
        return "not timed (`--no-numba`, or numba is not installed: the `[fast]` extra)"
    return (f"numba {rec['numba']} on up to {rec['numba_threads']} thread(s) "
            f"({rec.get('numba_threads_rule', '')})")


def _headline(s: pd.DataFrame) -> list[str]:
    """Lines on the compiled backend: latency of the seven, rate, ratio, largest difference."""
    rows = s[s["backend"] == NUMBA]
    if not len(rows):
        return []
    lines = []
    for _, row in rows.iterrows():
        ratio = row["speedup_vs_numpy"]
        versus = f", {ratio:.1f}x numpy" if np.isfinite(ratio) else ""
        lines.append(f"- numba, batch {row['batch']}: {1000 * row['wall_median_s']:.1f} ms "
                     f"median per call, {row['trajectories_per_s']:.0f} trajectories/s{versus}")
    lines.append(f"- largest relative difference of a final loss from numpy's, numba: "
                 f"{max(float(v) for v in rows['loss_max_rel_diff']):.1e}")
    return [*lines, ""]
