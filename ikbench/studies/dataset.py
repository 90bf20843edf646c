"""Datasets: N random reachable line trajectories solved by ours-lm, as Parquet shards.

The study shape (:mod:`ikbench.studies.shape`): a :class:`DatasetSpec`, its
:meth:`~DatasetSpec.validate`, :func:`run` and :meth:`DatasetReport.write`;
:func:`build_dataset` is the keyword function that does all three. Unlike the other studies,
:func:`run` writes as it goes (a dataset can be larger than the memory, and a stopped run is
resumed): the shards and a first manifest go into the spec's ``output`` folder while it runs;
:meth:`DatasetReport.write` writes only the final manifest (``dataset.json``, complete, with
this run's figures and the summary).

:func:`run` splits N trajectories into shards of ``shard_size`` (the last one
smaller), builds each missing shard (:func:`ikbench.studies.dataset_shard.build_shard`: touch
poses from the batch sampler seeded by (seed, shard), one batched solve, vectorised metrics) on
an executor, and writes it as two Parquet files, each atomically:

```
OUTPUT/dataset.json                     manifest: options, schema with units, shards, totals
OUTPUT/steps/part-000000.parquet        long form: one row per trajectory and step
OUTPUT/trajectories/part-000000.parquet one row per trajectory (written second)
```

``pandas.read_parquet("OUTPUT/steps")`` reads all shards (hidden temporary files are
skipped). A run that is stopped and started again with the same options keeps every complete
shard (both files present, readable, with the right options and row counts) and builds only
the others; since a shard depends only on its index, the result is the same as an
uninterrupted run, with any executor. In this process (the local executor) the shards go
through a pipeline (:func:`ikbench.studies.dataset_shard.pipelined`): while one is solved,
the next is sampled and the previous one measured and written. A larger ``--count`` later
extends a dataset (the last, partial shard is rebuilt); anything else that changes the
content is refused. The solver is ours-lm's fastest on the CPU by default: its numba backend
when numba is installed (recorded in the manifest's config; a dataset made by one backend is
not resumed by another, their numbers differ by rounding).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import json
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_path, atomic_write_json
from ikbench.core.losses import TERMS, parse_weights
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, load_targets
from ikbench.methods.ours_lm import LMSettings
from ikbench.methods.ours_lm.devices import cpu_backend
from ikbench.runtime.executors import SCALE_EXTRA, Executor, LocalExecutor, portable_robot
from ikbench.runtime.parallel import gpus_for
from ikbench.runtime.progress import Reporter
from ikbench.studies.batch import MAX_COUNT as MAX_SHARD_SIZE
from ikbench.studies.batch import WorkspaceFilter, check_seed
from ikbench.studies.dataset_shard import (
    FORMAT,
    METADATA_KEY,
    VERSION,
    ShardSpec,
    build_shard,
    pipelined,
)
from ikbench.studies.folders import default_output
from ikbench.studies.shape import run_and_write

DEFAULT_SHARD_SIZE = 10_000
#: At most this many trajectories (a million took 76 min on one CPU core, docs/scale.md).
MAX_COUNT = 1_000_000_000
#: At most this many shards: the plan of the dataset holds one entry per shard.
MAX_SHARDS = 100_000
MAX_STEPS = 5000
MANIFEST = "dataset.json"
TABLES = ("steps", "trajectories")     # written in this order: trajectories marks a shard done

#: Where the dataset goes by default.
DEFAULT_OUTPUT = default_output("dataset")


def shard_path(output: str | Path, table: str, shard: int) -> Path:
    """``OUTPUT/<table>/part-<shard>.parquet``."""
    return Path(output) / table / f"part-{shard:06d}.parquet"


@dataclass
class DatasetReport:
    """What :func:`run` did: the final manifest (in memory until :meth:`write`) and this
    run's figures. The shards are already in the spec's ``output`` folder."""

    manifest: dict
    written: list[int]          # shards built by this run
    kept: list[int]             # complete shards found and kept

    def write(self, folder: str | Path) -> Path:
        """Write the final manifest, ``folder/dataset.json`` (atomically; ``folder`` is the
        dataset's folder, the spec's ``output``); return ``folder``. The shards are not
        written here: :func:`run` wrote them as it built them."""
        atomic_write_json(Path(folder) / MANIFEST, self.manifest)
        return Path(folder)


@dataclass(frozen=True)
class DatasetSpec:
    """A dataset: ``count`` trajectories of ``steps`` segments on ``robot`` from the start
    pose of ``targets``, seeded by ``seed``, in shards of ``shard_size``, solved by ours-lm
    with ``lm_settings`` on ``executor`` (None: one shard after another in this process),
    written to ``output``. :meth:`validate` checks it; :func:`run` builds it."""

    count: int
    robot: Robot
    targets: Targets
    seed: int = 0
    steps: int = 50
    shard_size: int = DEFAULT_SHARD_SIZE
    lm_settings: LMSettings = field(default_factory=LMSettings)
    output: Path = Path(DEFAULT_OUTPUT)
    executor: Executor | None = None
    progress: bool = True

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a bad count, seed, steps or shard
        size (:func:`check_options`), weights ours-lm refuses, a missing pyarrow, or an
        ``output`` that holds a dataset made with other options or more trajectories
        (:func:`check_manifest`)."""
        check_options(self.count, self.seed, self.steps, self.shard_size)
        check_manifest(self.output, _prepared(self)[0], self.count)


def _settings(spec: DatasetSpec) -> LMSettings:
    """The spec's ours-lm settings with their weights parsed (InputError for bad ones)."""
    settings = spec.lm_settings
    return replace(settings, weights=settings.weights if isinstance(settings.weights, dict)
                   else parse_weights(settings.weights))


def _prepared(spec: DatasetSpec) -> tuple[dict[str, Any], LMSettings, WorkspaceFilter]:
    """The spec's :func:`dataset_config`, with the settings (:func:`_settings`) and the
    workspace filter it was made from."""
    settings, workspace = _settings(spec), WorkspaceFilter.of(spec.robot)
    return (dataset_config(spec.robot, spec.targets.start_pose, spec.steps, spec.seed,
                           spec.shard_size, workspace, settings), settings, workspace)


def check_sizes(count: int, shard_size: int) -> None:
    """InputError, before anything is planned, for a count or shard size beyond the stated
    maxima (a count of 10^12 used to fill the memory with the plan of its shards)."""
    if count > MAX_COUNT:
        raise InputError(f"--count: {count} is more than the maximum, {MAX_COUNT:,} "
                         "trajectories")
    if shard_size > MAX_SHARD_SIZE:
        raise InputError(f"--shard-size: {shard_size} is more than the maximum, "
                         f"{MAX_SHARD_SIZE:,} (one shard is one batch in memory)")
    if count >= 1 and shard_size >= 1 and -(-count // shard_size) > MAX_SHARDS:
        raise InputError(f"--count {count} in shards of {shard_size} makes "
                         f"{-(-count // shard_size):,} shards, more than the maximum, "
                         f"{MAX_SHARDS:,}; raise --shard-size to at least "
                         f"{-(-count // MAX_SHARDS)}")


def check_options(count: Any, seed: Any, steps: Any, shard_size: Any) -> None:
    """InputError naming the flag for a bad count, seed, steps or shard size (beyond the
    maxima: :func:`check_sizes`), or when pyarrow (the Parquet writer) is not installed."""
    for flag, value, low in (("--count", count, 1), ("--steps", steps, 2),
                             ("--shard-size", shard_size, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise InputError(f"{flag}: {value!r} must be an integer >= {low}")
    check_sizes(count, shard_size)
    if steps > MAX_STEPS:
        raise InputError(f"--steps: {steps} must be at most {MAX_STEPS}")
    check_seed(seed)
    if importlib.util.find_spec("pyarrow") is None:
        raise InputError(f"ikbench dataset writes Parquet with pyarrow, which is not installed; "
                         f"{SCALE_EXTRA}")


def dataset_config(robot: Robot, start_pose: np.ndarray, steps: int, seed: int,
                   shard_size: int, workspace: WorkspaceFilter, settings: LMSettings
                   ) -> dict[str, Any]:
    """Everything that determines the shards' content (hashed into each shard)."""

    solver: dict[str, Any] = {"max_iterations": settings.max_iterations,
                              "tolerance": settings.tolerance, "damping": settings.damping}
    if settings.device is None:  # numpy or numba (equal to ~1e-12, but not bit for bit)
        solver.update(backend=cpu_backend(settings), kinematics=settings.kinematics,
                      linear_solver=settings.linear_solver)
    else:
        solver.update(backend="torch", device_type=settings.device.split(":")[0],
                      dtype=settings.dtype)
    weights = cast("dict[str, float]", settings.weights)  # a dict: build_dataset parsed them
    return {"format": FORMAT, "version": VERSION,
            "robot": {"name": robot.name, "urdf_sha256": robot.urdf_sha256,
                      "end_frame": robot.end_frame, "joints": list(robot.joint_names)},
            "start_pose_deg": [float(v) for v in start_pose], "steps": steps,
            "seed": seed, "shard_size": shard_size, "workspace": asdict(workspace),
            "weights": {f"c{t[1]}": weights[t] for t in TERMS}, "solver": solver}


def config_hash(config: dict) -> str:
    """A short hash of a dataset config."""
    return hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:16]


def plan(count: int, config: dict[str, Any], robot: Robot, start_pose: npt.ArrayLike,
         settings: LMSettings, workspace: WorkspaceFilter) -> list[ShardSpec]:
    """The shards of a dataset of ``count`` trajectories, in order."""
    size, digest = config["shard_size"], config_hash(config)
    portable = portable_robot(robot)
    return [ShardSpec(portable, np.asarray(start_pose, dtype=float), config["steps"],
                      config["seed"], s, s * size, min(size, count - s * size), settings,
                      workspace, digest)
            for s in range(math.ceil(count / size))]


def is_complete(output: str | Path, spec: ShardSpec) -> bool:
    """True when both files of the shard exist, are readable Parquet and describe it."""
    import pyarrow.parquet as pq

    for table in TABLES:
        path = shard_path(output, table, spec.shard)
        try:
            rows = pq.ParquetFile(path).metadata.num_rows
            stored = json.loads((pq.read_schema(path).metadata or {})[METADATA_KEY])
        except (OSError, KeyError, ValueError, TypeError):
            return False
        expected = spec.count * (spec.steps + 1) if table == "steps" else spec.count
        if stored != spec.metadata(table) or rows != expected:
            return False
    return True


def check_manifest(output: str | Path, config: dict[str, Any], count: int) -> None:
    """InputError when OUTPUT holds a dataset made with other options, or more trajectories."""
    path = Path(output) / MANIFEST
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
        old_config, old_count = old["config"], int(old["count"])
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"{path} is not an ikbench dataset manifest; use another "
                         "--output") from None
    if old_config != config:
        keys = sorted(k for k in set(config) | set(old_config)
                      if config.get(k) != old_config.get(k))
        raise InputError(f"{output} holds a dataset made with other options (different: "
                         f"{', '.join(keys)}); use the same options to resume it, or another "
                         "--output")
    if count < old_count:
        raise InputError(f"{output} holds {old_count} trajectories; --count {count} would leave "
                         "shards that do not belong; give --count >= that, or another --output")


def build_dataset(count: int, *, seed: int = 0, steps: int = 50,
                  shard_size: int = DEFAULT_SHARD_SIZE, lm_settings: LMSettings | None = None,
                  targets: str | Path | Targets | None = None,
                  robot: Robot | str | None = None, output: str | Path = DEFAULT_OUTPUT,
                  executor: Executor | None = None, progress: bool = True) -> DatasetReport:
    """Build (or resume) a dataset of ``count`` trajectories (see the module docstring):
    :class:`DatasetSpec`, its :meth:`~DatasetSpec.validate`, :func:`run` and
    :meth:`DatasetReport.write` into ``output``.

    Args:
        count: number of trajectories N.
        seed: the dataset's seed, an integer in [0, 2^63).
        steps: segments n per trajectory.
        shard_size: trajectories per shard (and per batched solve).
        lm_settings: ours-lm settings (weights: changes on the paper's; backend, threads,
            device, dtype). By default the fastest on the CPU: the numba backend when numba
            is installed (``backend="auto"``), else the numpy solver.
        targets: where the start pose comes from (default the robot's default targets).
        robot: the robot or its name/config/URDF (default NICO's right arm).
        output: the dataset folder.
        executor: where shards are built (default: one after another in this process).
        progress: progress on stderr (:mod:`ikbench.runtime.progress`).

    Ctrl-C keeps the complete shards (the same command resumes) and marks dataset.json
    ``"interrupted"`` (``complete`` false) before the KeyboardInterrupt goes on.
    """

    robot = as_robot(robot)
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    spec = DatasetSpec(count, robot, targets, seed=seed, steps=steps, shard_size=shard_size,
                       lm_settings=lm_settings or LMSettings(), output=Path(output),
                       executor=executor, progress=progress)
    return run_and_write(spec, run, spec.output)


def run(spec: DatasetSpec) -> DatasetReport:
    """Build (or resume) the dataset ``spec`` (validated: :meth:`DatasetSpec.validate`).

    Writes as it goes, into ``spec.output``: a first manifest (``complete`` false), then
    each shard as it is built. The final manifest is returned, not written:
    :meth:`DatasetReport.write` writes it. Ctrl-C keeps the complete shards (the same spec
    resumes) and marks dataset.json ``"interrupted"`` before the KeyboardInterrupt goes on.
    """
    count, shard_size, output = spec.count, spec.shard_size, spec.output
    config, settings, workspace = _prepared(spec)
    executor = spec.executor or LocalExecutor()
    specs = plan(count, config, spec.robot, spec.targets.start_pose, settings, workspace)
    _remove_temporary_files(output)
    kept = [s.shard for s in specs if is_complete(output, s)]
    missing = [s for s in specs if s.shard not in set(kept)]
    log = Reporter("dataset", total=count, unit="trajectory", enabled=spec.progress)
    log.note(f"{count} trajectories in {len(specs)} shard(s) of up to {shard_size}: "
             f"{len(kept)} complete (kept), {len(missing)} to build on {executor.name} "
             f"({executor.workers} worker(s)) with {_solver_name(settings)}")
    log.advance(count - sum(s.count for s in missing))
    manifest = _manifest(config, count, specs, output, executor, None)
    atomic_write_json(Path(output) / MANIFEST, manifest)
    began, written, done = time.perf_counter(), [], count - sum(s.count for s in missing)
    draws = 0
    if isinstance(executor, LocalExecutor):  # in this process: sample, solve, write overlap
        results = pipelined(missing)
    else:
        results = executor.map(build_shard, missing, gpus=gpus_for(settings))
    try:
        for shard, result in zip(missing, results):
            _write_shard(output, shard, result)
            written.append(shard.shard)
            done += shard.count
            draws += result.draws
            elapsed = time.perf_counter() - began
            rate = sum(s.count for s in missing if s.shard in written) / elapsed
            log.advance(shard.count, f"shard {shard.shard + 1}/{len(specs)}: {shard.count} "
                        f"trajectories in {result.total_s:.1f} s (solve {result.solve_s:.1f} s); "
                        f"{done}/{count} done ({100 * done / count:.0f} %), {rate:.0f} "
                        f"trajectories/s, ETA {_eta((count - done) / rate if rate else 0)}")
    except KeyboardInterrupt:  # complete shards stay (a rerun resumes); the manifest says so
        manifest = {**_manifest(config, count, specs, output, executor, None),
                    "interrupted": {"shards_built": len(written), "shards_kept": len(kept)}}
        atomic_write_json(Path(output) / MANIFEST, manifest)
        raise
    finally:
        log.close()
    wall = time.perf_counter() - began
    this_run = {"shards_built": len(written), "shards_kept": len(kept),
                "trajectories_built": int(sum(s.count for s in missing)), "draws": draws,
                "wall_s": wall, "trajectories_per_s": (sum(s.count for s in missing) / wall
                                                       if wall > 0 and missing else None)}
    manifest = _manifest(config, count, specs, output, executor, this_run)
    log.note(f"done: {count} trajectories in {output}/ "
             f"({manifest['summary']['converged_share']:.1%} converged); this run built "
             f"{len(written)} shard(s) in {wall:.1f} s")
    return DatasetReport(manifest, written, kept)


def _write_shard(output, spec: ShardSpec, result) -> None:
    import pyarrow.parquet as pq

    for table, data in zip(TABLES, (result.steps, result.trajectories)):
        with atomic_path(shard_path(output, table, spec.shard)) as tmp:
            pq.write_table(data, tmp, compression="zstd")


def _manifest(config, count, specs, output, executor, run) -> dict:
    manifest = {"format": FORMAT, "version": VERSION, "count": count, "config": config,
                "config_hash": config_hash(config), "shards": len(specs),
                "files": {t: f"{t}/part-NNNNNN.parquet" for t in TABLES},
                "columns": columns(config["robot"]["joints"]), **executor.describe(),
                "complete": run is not None}
    if run is not None:
        manifest["this_run"] = run
        manifest["summary"] = summarise(output)
    manifest.update(provenance())
    return manifest


def summarise(output: str | Path) -> dict[str, Any]:
    """Shares and medians over every trajectory of the dataset (read from its shards)."""
    import pyarrow.dataset as ds

    names = ["converged", "within_limits", "iterations", "loss", "line_distance_mean_mm",
             "pointing_deviation_mean_deg", "end_point_error_mm"]
    frame = ds.dataset(Path(output) / "trajectories", format="parquet").to_table(
        columns=names).to_pandas()
    return {"trajectories": len(frame), "converged_share": float(frame["converged"].mean()),
            "within_limits_share": float(frame["within_limits"].mean()),
            **{f"{c}_median": float(frame[c].median()) for c in names[2:]}}


def columns(joints: Sequence[str]) -> dict[str, Any]:
    """The tables' columns and their units (the manifest's schema)."""
    pose = "pose units (motor deg for NICO; joint deg, mm for prismatic joints)"
    steps = {"trajectory": "id", "step": "index 0..n", **{j: pose for j in joints},
             **{f"{a}_mm": "mm, base frame" for a in "xyz"},
             **{f"dir_{a}": "unit pointing direction" for a in "xyz"}}
    metrics = {"line_distance_mean_mm": "mm", "line_distance_std_mm": "mm",
               "pointing_deviation_mean_deg": "deg", "pointing_deviation_std_deg": "deg",
               "start_point_error_mm": "mm", "end_point_error_mm": "mm",
               "start_pose_error_deg": "pose units", "end_pose_error_deg": "pose units",
               "mean_sq_joint_step_deg2": "pose units^2", "max_joint_step_deg": "pose units",
               "mean_sq_jerk_deg2": "pose units^2", "velocity_sign_changes": "count"}
    trajectories = {"trajectory": "id", "shard": "index",
                    **{f"start_{j}": pose for j in joints},
                    **{f"touch_{j}": pose for j in joints},
                    **{f"start_{a}_mm": "mm, P^s" for a in "xyz"},
                    **{f"touch_{a}_mm": "mm, P^e" for a in "xyz"},
                    "line_length_mm": "mm", "loss": "the paper's objective (cm, motor deg)",
                    **{t: "loss term" for t in TERMS}, "iterations": "LM iterations",
                    "converged": "bool", "within_limits": "bool", **metrics}
    return {"steps": steps, "trajectories": trajectories}


def _remove_temporary_files(output) -> None:
    """Temporary files of an earlier run that was killed (they are hidden, but take space)."""
    for table in TABLES:
        for path in (Path(output) / table).glob(".part-*.tmp"):
            path.unlink(missing_ok=True)


def _solver_name(settings) -> str:

    if settings.device is None:
        if cpu_backend(settings) == "numba":
            max_threads = importlib.import_module("ikbench.methods.ours_lm.compiled").max_threads
            threads = min(settings.threads or max_threads(), max_threads())
            return f"the numba backend (up to {threads} thread(s))"
        return "the numpy solver"
    return f"the torch backend on {settings.device} ({settings.dtype})"


def _eta(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"

