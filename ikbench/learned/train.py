"""``ikbench learn``: networks trained on a dataset ``ikbench dataset`` wrote (issue 61, part 1).

:func:`train` reads a dataset folder (``dataset.json``, ``steps/``, ``trajectories/``: see
:mod:`ikbench.studies.dataset`), splits its trajectories into a training and a held-out set
(by trajectory, seeded: every pose of a trajectory is on one side), trains a network of one
kind on the CPU with torch and writes the model file (``torch.save`` of a dict):

- ``pose``: target end frame -> joint configurations, a mixture density network
  (:class:`ikbench.learned.model.PoseMDN`); its samples are every pose of every
  trajectory, each with its end frame by the robot's own FK.
- ``trajectory``: (start pose, goal point [mm]) -> the whole trajectory (n + 1 poses), a
  mixture density network over whole trajectories
  (:class:`ikbench.learned.model.TrajectoryMDN`): a goal point leaves the touch pose
  open (the dataset's touch poses are drawn at random, several per point), so a single
  regression would average branches; its samples are the dataset's converged trajectories.

Training is seeded and deterministic (``torch.manual_seed``, deterministic algorithms, the
batches of epoch e drawn from a generator seeded by (seed, e)), reports a line per epoch
(:class:`ikbench.runtime.progress.Reporter`) and writes a checkpoint next to the model after
every epoch (``MODEL.checkpoint``); ``resume=True`` continues from it, and ends with the same
weights as an uninterrupted run.

:func:`load_model` reads a model file back as a
:class:`~ikbench.learned.model.LearnedModel` (``propose``, ``predict``, ``error``).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ikbench.core.errors import InputError, OutputError
from ikbench.core.io import atomic_path, check_writable
from ikbench.core.metrics_batch import line_metrics
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot, load_robot
from ikbench.learned.model import (
    KINDS,
    JointScale,
    LearnedModel,
    build_net,
    frame_errors,
    frame_features,
    trajectory_vector,
)
from ikbench.runtime.progress import Reporter
from ikbench.studies.dataset import MANIFEST
from ikbench.studies.dataset_shard import FORMAT as DATASET_FORMAT

FORMAT = "ikbench-learned-model"
VERSION = 1
#: The checkpoint written after every epoch: MODEL + this suffix.
CHECKPOINT_SUFFIX = ".checkpoint"
MAX_EPOCHS = 100_000
MAX_BATCH_SIZE = 1_000_000
#: The held-out error is measured on at most this many held-out samples (a seeded subset).
MAX_EVAL_SAMPLES = 2000
#: The query time is the median of this many single queries (batch of 1).
QUERY_REPEATS = 200


@dataclass(frozen=True)
class Hyper:
    """Hyper-parameters (recorded in the model file; a resumed run must use the same)."""

    hidden: int = 256
    layers: int = 3
    components: int = 8          # pose kind: Gaussians of the mixture
    learning_rate: float = 1e-3  # Adam, constant
    batch_size: int = 512
    holdout: float = 0.1         # share of the trajectories held out


# ----- the dataset ----------------------------------------------------------------------------
@dataclass
class Dataset:
    """A dataset folder read for training: its manifest, robot and tables."""

    path: Path
    manifest: dict[str, Any]
    sha256: str
    robot: Robot
    steps: int
    trajectory_ids: np.ndarray     # (T,) sorted
    poses: np.ndarray              # (T, n + 1, dof) [pose units], trajectories in id order
    touch_mm: np.ndarray           # (T, 3) the goal (touch) points [mm]
    converged: np.ndarray          # (T,) bool

    def describe(self) -> dict[str, Any]:
        config = self.manifest["config"]
        return {"path": str(self.path.resolve()), "sha256": self.sha256,
                "seed": config["seed"], "count": self.manifest["count"], "steps": self.steps,
                "config_hash": self.manifest.get("config_hash"),
                "trajectories": int(len(self.trajectory_ids))}


def read_manifest(path: str | Path) -> tuple[dict[str, Any], str]:
    """(manifest, sha256 of dataset.json) of the dataset folder ``path``; InputError (naming
    DATASET) when it is not a complete dataset of ``ikbench dataset``."""
    folder = Path(path)
    file = folder / MANIFEST
    if not folder.is_dir():
        raise InputError(f"DATASET: {folder} is not a folder; give a folder ikbench dataset "
                         "wrote")
    if not file.is_file():
        raise InputError(f"DATASET: {folder} holds no {MANIFEST}; give a folder ikbench "
                         "dataset wrote")
    try:
        data = file.read_bytes()
        manifest = json.loads(data)
        ok = (isinstance(manifest, dict) and manifest.get("format") == DATASET_FORMAT
              and isinstance(manifest.get("config"), dict)
              and isinstance(manifest["config"].get("robot"), dict))
    except (OSError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"DATASET: {file} is not an ikbench dataset manifest")
    if not manifest.get("complete"):
        raise InputError(f"DATASET: {folder} is not complete (an interrupted or running "
                         "ikbench dataset); run the same ikbench dataset command again to "
                         "finish it")
    if not isinstance(manifest.get("count"), int) or manifest["count"] < 1:
        raise InputError(f"DATASET: {folder} holds no trajectories")
    return manifest, hashlib.sha256(data).hexdigest()


def recorded_robot(want: dict[str, Any], robot: Robot | str | None, what: str,
                   names: tuple[str, str]) -> Robot:
    """The robot a dataset or model file records (``want``: name, urdf_sha256, joints):
    ``robot`` when given (InputError unless it is that robot), else the shipped robot of that
    name. ``what``: the file, for the errors ("the dataset"); ``names``: (what names the
    file, what names the robot) on the command line (("DATASET", "--robot"))."""
    source, flag = names
    if robot is None:
        try:
            robot = load_robot(want["name"])
        except InputError:
            raise InputError(f"{source}: its robot {want['name']!r} is not a shipped robot; "
                             f"give it with {flag}") from None
        flag = source
    robot = as_robot(robot)
    same = (robot.name == want.get("name") and robot.urdf_sha256 == want.get("urdf_sha256")
            and list(robot.joint_names) == list(want.get("joints", [])))
    if not same:
        raise InputError(f"{flag}: {what} is of robot {want.get('name')!r} (URDF "
                         f"{str(want.get('urdf_sha256'))[:12]}), not {robot.name!r} (URDF "
                         f"{robot.urdf_sha256[:12]})")
    return robot


def dataset_robot(manifest: dict[str, Any], robot: Robot | str | None = None) -> Robot:
    """The robot of a dataset: ``robot`` when given (InputError unless it is the dataset's:
    name, URDF hash and joints), else the shipped robot the manifest names."""
    return recorded_robot(manifest["config"]["robot"], robot, "the dataset",
                          ("DATASET", "--robot"))


def read_dataset(path: str | Path, robot: Robot | str | None = None) -> Dataset:
    """Read a complete dataset folder (:func:`read_manifest`, :func:`dataset_robot`) and its
    tables: every trajectory's poses (n + 1 each), touch point and convergence."""
    import pyarrow.dataset as ds

    manifest, sha = read_manifest(path)
    robot = dataset_robot(manifest, robot)
    steps = int(manifest["config"]["steps"])
    folder = Path(path)
    joints = list(robot.joint_names)
    try:
        step_table = ds.dataset(folder / "steps", format="parquet").to_table(
            columns=["trajectory", "step", *joints]).to_pandas()
        traj_table = ds.dataset(folder / "trajectories", format="parquet").to_table(
            columns=["trajectory", "converged", "touch_x_mm", "touch_y_mm", "touch_z_mm"]
        ).to_pandas()
    except (OSError, ValueError, KeyError) as exc:  # pyarrow's errors derive from these
        text = " ".join(str(exc).split())[:200]
        raise InputError(f"DATASET: {folder}'s tables cannot be read ({text})") from None
    if len(traj_table) == 0 or len(step_table) == 0:
        raise InputError(f"DATASET: {folder} holds no trajectories")
    step_table = step_table.sort_values(["trajectory", "step"], kind="stable")
    traj_table = traj_table.sort_values("trajectory", kind="stable")
    ids = traj_table["trajectory"].to_numpy()
    if len(step_table) != len(ids) * (steps + 1) or not np.array_equal(
            step_table["trajectory"].to_numpy()[::steps + 1], ids):
        raise InputError(f"DATASET: {folder}'s steps and trajectories tables do not match "
                         f"({len(step_table)} step rows for {len(ids)} trajectories of "
                         f"{steps + 1} poses)")
    poses = step_table[joints].to_numpy(dtype=float).reshape(len(ids), steps + 1, len(joints))
    return Dataset(folder, manifest, sha, robot, steps, ids, poses,
                   traj_table[["touch_x_mm", "touch_y_mm", "touch_z_mm"]].to_numpy(float),
                   traj_table["converged"].to_numpy(bool))


def split(ids: np.ndarray, holdout: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(training ids, held-out ids) of trajectory ids: a seeded permutation, the first
    round(holdout x T) held out. InputError when either side would be empty."""
    count = len(ids)
    held = int(round(holdout * count))
    if held < 1 or held >= count:
        raise InputError(f"--holdout: {holdout:g} of {count} trajectories holds out {held}; "
                         "both the training and the held-out set need at least one "
                         "trajectory")
    order = np.random.default_rng([seed, 1]).permutation(count)
    return np.sort(ids[order[held:]]), np.sort(ids[order[:held]])


# ----- samples --------------------------------------------------------------------------------
@dataclass
class Samples:
    """Training tensors of one kind (float32): inputs and targets."""

    x: Any
    y: Any

    def __len__(self) -> int:
        return int(self.x.shape[0])


def _frames(robot: Robot, poses: np.ndarray) -> np.ndarray:
    """End frames (B, 4, 4) [m] of poses (B, dof) [pose units], by the vectorised chain."""
    point_m, rotation, _, _ = robot.chain_kinematics().transforms(poses)
    T = np.zeros((len(poses), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = rotation, point_m, 1.0
    return T


def _normalisation(kind: str, data: Dataset, train_rows: np.ndarray,
                   scale: JointScale) -> dict[str, list[float]]:
    if kind == "pose":
        T = _frames(data.robot, data.poses[train_rows].reshape(-1, data.robot.dof))
        values = T[:, :3, 3]
    else:
        values = data.touch_mm[train_rows]
    std = np.maximum(values.std(axis=0), 1e-9)
    return {"input_mean": values.mean(axis=0).tolist(), "input_std": std.tolist(),
            "joint_lower": scale.lower.tolist(), "joint_upper": scale.upper.tolist()}


def _samples(kind: str, data: Dataset, rows: np.ndarray, scale: JointScale,
             norm: dict[str, list[float]]) -> Samples:
    import torch

    mean, std = np.asarray(norm["input_mean"]), np.asarray(norm["input_std"])
    if kind == "pose":
        q = data.poses[rows].reshape(-1, data.robot.dof)
        x = frame_features(_frames(data.robot, q), mean, std)
        return Samples(torch.as_tensor(x, dtype=torch.float32),
                       torch.as_tensor(scale.to_unit(q), dtype=torch.float32))
    start = scale.to_unit(data.poses[rows, 0])
    x = np.concatenate([start, (data.touch_mm[rows] - mean) / std], axis=1)
    y = trajectory_vector(scale.to_unit(data.poses[rows]))
    return Samples(torch.as_tensor(x, dtype=torch.float32),
                   torch.as_tensor(y, dtype=torch.float32))


def _loss(net, kind: str, samples: Samples, index=None):
    if index is None:
        index = slice(None)
    return net.loss(samples.x[index], samples.y[index])


def _mean_loss(net, kind: str, samples: Samples, chunk: int = 8192) -> float:
    import torch

    total = 0.0
    with torch.inference_mode():
        for begin in range(0, len(samples), chunk):
            index = slice(begin, begin + chunk)
            total += float(_loss(net, kind, samples, index)) * (min(begin + chunk,
                                                                    len(samples)) - begin)
    return total / len(samples)


def _batches(count: int, batch_size: int, seed: int, epoch: int) -> Iterator[Any]:
    """Epoch ``epoch``'s batches of indices: a permutation seeded by (seed, epoch) only, so a
    resumed run draws the same batches as an uninterrupted one."""
    import torch

    order = torch.as_tensor(np.random.default_rng([seed, 2, epoch]).permutation(count))
    for begin in range(0, count, batch_size):
        yield order[begin:begin + batch_size]


# ----- training -------------------------------------------------------------------------------
def checkpoint_path(output: str | Path) -> Path:
    """Where the checkpoint of ``output`` goes: next to it, ``MODEL.checkpoint``."""
    output = Path(output)
    return output.with_name(output.name + CHECKPOINT_SUFFIX)


def _identity(kind: str, data: Dataset, seed: int, hyper: Hyper) -> dict[str, Any]:
    """What a checkpoint must match to be resumed."""
    return {"kind": kind, "dataset_sha256": data.sha256, "robot": data.robot.name,
            "seed": seed, "hyper": asdict(hyper)}


def read_checkpoint(path: Path, identity: dict[str, Any]) -> dict[str, Any]:
    """The checkpoint at ``path``; InputError (naming --resume) when it is missing,
    unreadable or of another kind, dataset, seed or hyper-parameters."""
    import torch

    if not path.is_file():
        raise InputError(f"--resume: no checkpoint {path} to resume; run without --resume")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        old = state["identity"]
    except Exception:  # torch.load raises many kinds of errors for a file that is not its own
        raise InputError(f"--resume: {path} is not a checkpoint of ikbench learn") from None
    if old != identity:
        keys = sorted(k for k in set(identity) | set(old) if identity.get(k) != old.get(k))
        raise InputError(f"--resume: {path} is a checkpoint of another run (different: "
                         f"{', '.join(keys)}); give the same options, or run without --resume")
    return state


def check_output(output: str | Path) -> Path:
    """OutputError (the CLI names --output) when the model file or its checkpoint cannot be
    written."""
    output = Path(output)
    for path in (output, checkpoint_path(output)):
        try:
            check_writable(path)
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(f"cannot write {path} ({exc.strerror})") from None
    return output


@dataclass(frozen=True)
class LearnSpec:
    """One training run: ``kind`` on the dataset folder ``dataset`` (read), written to
    ``output``, ``epochs`` epochs in all (a resumed run continues to that count)."""

    dataset: Dataset
    kind: str
    output: Path
    epochs: int = 20
    seed: int = 0
    hyper: Hyper = Hyper()
    resume: bool = False
    threads: int = 1
    progress: bool = True

    def validate(self) -> dict[str, Any] | None:
        """InputError for a bad kind, epochs, seed, batch size or hold-out share, an output
        that cannot be written, or a checkpoint that does not match (``resume``); returns
        the checkpoint to resume (None: start afresh)."""
        if self.kind not in KINDS:
            raise InputError(f"--kind: {self.kind!r} is not one of {', '.join(KINDS)}")
        for flag, value, high in (("--epochs", self.epochs, MAX_EPOCHS),
                                  ("--batch-size", self.hyper.batch_size, MAX_BATCH_SIZE)):
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= high:
                raise InputError(f"{flag}: {value!r} must be an integer from 1 to {high:,}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not (
                0 <= self.seed < 2**63):
            raise InputError(f"--seed: {self.seed!r} must be an integer in [0, 2^63)")
        if not (isinstance(self.hyper.holdout, float) and 0 < self.hyper.holdout < 1):
            raise InputError(f"--holdout: {self.hyper.holdout!r} must be a share in (0, 1)")
        self.split()
        if self.kind == "trajectory" and not self.dataset.converged[
                np.isin(self.dataset.trajectory_ids, self.split()[0])].any():
            raise InputError("DATASET: no converged trajectory in the training set (the "
                             "trajectory kind learns from converged trajectories)")
        check_output(self.output)
        if not self.resume:
            return None
        state = read_checkpoint(checkpoint_path(self.output), _identity(
            self.kind, self.dataset, self.seed, self.hyper))
        if int(state["epoch"]) > self.epochs:
            raise InputError(f"--epochs: {self.epochs} is fewer than the {state['epoch']} "
                             f"epochs of the checkpoint {checkpoint_path(self.output)}; give "
                             f"--epochs {state['epoch']} or more")
        return state

    def split(self) -> tuple[np.ndarray, np.ndarray]:
        return split(self.dataset.trajectory_ids, self.hyper.holdout, self.seed)


def train(dataset: str | Path | Dataset, kind: str, output: str | Path, *, epochs: int = 20,
          seed: int = 0, batch_size: int = 512, holdout: float = 0.1, resume: bool = False,
          robot: Robot | str | None = None, threads: int = 1, progress: bool = True,
          hyper: Hyper | None = None) -> Path:
    """Train a ``kind`` model (``pose`` or ``trajectory``) on a dataset folder and write the
    model file ``output``; return its path (see the module docstring).

    Args:
        dataset: a folder ``ikbench dataset`` wrote (complete), or one read by
            :func:`read_dataset`.
        kind: ``pose`` (frame -> configurations) or ``trajectory`` ((start pose, goal point)
            -> the whole trajectory).
        output: the model file to write; its checkpoint goes next to it
            (:func:`checkpoint_path`).
        epochs: epochs in all (a resumed run continues up to this count).
        seed: seeds the split, the initial weights and the batches.
        batch_size: samples per optimiser step.
        holdout: the share of the trajectories held out.
        resume: continue from the checkpoint (InputError when it is of another run).
        robot: the dataset's robot (InputError when the dataset is of another); default the
            shipped robot the dataset names.
        threads: torch threads while training (restored afterwards).
        progress: a line per epoch (:class:`ikbench.runtime.progress.Reporter`).
        hyper: further hyper-parameters (:class:`Hyper`; ``batch_size`` and ``holdout``
            override its own).
    """
    data = dataset if isinstance(dataset, Dataset) else read_dataset(dataset, robot)
    if robot is not None and isinstance(dataset, Dataset):
        dataset_robot(data.manifest, robot)
    base = hyper or Hyper()
    hyper = Hyper(**{**asdict(base), "batch_size": batch_size, "holdout": float(holdout)})
    spec = LearnSpec(data, kind, Path(output), epochs=epochs, seed=seed, hyper=hyper,
                     resume=resume, threads=threads, progress=progress)
    state = spec.validate()
    return run(spec, state)


def run(spec: LearnSpec, state: dict[str, Any] | None = None) -> Path:
    """Train ``spec`` (validated; ``state`` the checkpoint to resume) and write its model."""
    import torch

    data, kind, hyper, seed = spec.dataset, spec.kind, spec.hyper, spec.seed
    robot = data.robot
    record = provenance()  # the commit and tree as the training starts
    train_ids, held_ids = spec.split()
    train_rows = np.flatnonzero(np.isin(data.trajectory_ids, train_ids))
    held_rows = np.flatnonzero(np.isin(data.trajectory_ids, held_ids))
    if kind == "trajectory":  # an amortised optimiser learns the solved trajectories
        train_rows = train_rows[data.converged[train_rows]]
        held_rows = held_rows[data.converged[held_rows]]
    scale = JointScale(robot.sample_lower, robot.sample_upper)
    norm = _normalisation(kind, data, train_rows, scale)
    threads_before, deterministic_before = (torch.get_num_threads(),
                                            torch.are_deterministic_algorithms_enabled())
    torch.set_num_threads(spec.threads)
    torch.use_deterministic_algorithms(True)
    log = Reporter("learn", total=spec.epochs, unit="epoch", enabled=spec.progress)
    try:
        training = _samples(kind, data, train_rows, scale, norm)
        held = _samples(kind, data, held_rows, scale, norm) if len(held_rows) else None
        h = {**asdict(hyper), "steps": data.steps}
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            net = build_net(kind, robot.dof, h)
        optimiser = torch.optim.Adam(net.parameters(), lr=hyper.learning_rate)
        done, history, cpu_s, wall_s, runs = 0, [], 0.0, 0.0, []
        if state is not None:
            net.load_state_dict(state["net"])
            optimiser.load_state_dict(state["optimiser"])
            done, history = int(state["epoch"]), list(state["history"])
            cpu_s, wall_s = float(state["cpu_s"]), float(state["wall_s"])
            runs = list(state.get("runs", []))
        # every run (the first and each --resume) with the commit it ran at and its epochs
        runs.append({"git_commit": record["git_commit"], "git_clean": record["git_clean"],
                     "first_epoch": done + 1, "last_epoch": done})
        log.note(f"{kind} model of {robot.name}: {len(training)} training and "
                 f"{len(held) if held is not None else 0} held-out samples "
                 f"({len(train_ids)} and {len(held_ids)} trajectories), epochs "
                 f"{done + 1}..{spec.epochs}" + (f" (resumed after epoch {done})"
                                                 if state is not None else ""))
        log.advance(min(done, spec.epochs))
        identity = _identity(kind, data, seed, hyper)
        for epoch in range(done, spec.epochs):
            cpu0, wall0 = time.process_time(), time.perf_counter()
            net.train()
            total = 0.0
            for index in _batches(len(training), hyper.batch_size, seed, epoch):
                optimiser.zero_grad(set_to_none=True)
                loss = _loss(net, kind, training, index)
                loss.backward()
                optimiser.step()
                total += float(loss.detach()) * len(index)
            net.eval()
            train_loss = total / len(training)
            held_loss = _mean_loss(net, kind, held) if held is not None else math.nan
            cpu_s += time.process_time() - cpu0
            wall_s += time.perf_counter() - wall0
            history.append({"epoch": epoch + 1, "train_loss": train_loss,
                            "held_out_loss": held_loss})
            runs[-1]["last_epoch"] = epoch + 1
            _save(checkpoint_path(spec.output), {
                "identity": identity, "epoch": epoch + 1, "net": net.state_dict(),
                "optimiser": optimiser.state_dict(), "history": history, "cpu_s": cpu_s,
                "wall_s": wall_s, "runs": runs})
            log.advance(1, f"epoch {epoch + 1}/{spec.epochs}: train loss {train_loss:.4f}, "
                        f"held-out loss {held_loss:.4f}")
        payload = _payload(spec, net, norm, history, cpu_s, wall_s, train_ids, held_ids,
                           len(training), len(held) if held is not None else 0, record, runs)
        model = LearnedModel(payload, robot)
        payload["held_out_error"] = held_out_error(model, data, held_rows, seed)
        payload["model_query_ms"] = query_ms(model, data, held_rows)
        _save(spec.output, payload)
        log.note(f"wrote {spec.output}: {summary(payload)}")
    finally:
        log.close()
        torch.set_num_threads(threads_before)
        torch.use_deterministic_algorithms(deterministic_before)
    return spec.output


def _save(path: Path, value: dict[str, Any]) -> None:
    import torch

    with atomic_path(path) as tmp:
        torch.save(value, tmp)


def _payload(spec: LearnSpec, net, norm, history, cpu_s, wall_s, train_ids, held_ids,
             train_samples: int, held_samples: int, record: dict[str, Any],
             runs: list[dict[str, Any]]) -> dict[str, Any]:
    import torch

    robot, data = spec.dataset.robot, spec.dataset
    return {"format": FORMAT, "version": VERSION, "kind": spec.kind,
            "robot": {"name": robot.name, "dof": robot.dof, "joints": list(robot.joint_names),
                      "urdf_sha256": robot.urdf_sha256, "end_frame": robot.end_frame,
                      "pose_unit": robot.pose_unit},
            "dataset": data.describe(),
            "git_commit": record["git_commit"], "git_clean": record["git_clean"],
            "runs": runs,
            "samples": {"train": train_samples, "held_out": held_samples,
                        "train_trajectories": int(len(train_ids)),
                        "held_out_trajectories": int(len(held_ids))},
            "epochs": len(history), "seed": spec.seed,
            "training_cpu_min": cpu_s / 60.0, "training_wall_min": wall_s / 60.0,
            "threads": spec.threads, "torch_version": str(torch.__version__),
            "hyper": {**asdict(spec.hyper), "steps": data.steps}, "history": history,
            "normalisation": norm, "provenance": record,
            "held_out": torch.as_tensor(np.asarray(held_ids, dtype=np.int64)),
            "state_dict": net.state_dict()}


# ----- measures -------------------------------------------------------------------------------
def _eval_rows(rows: np.ndarray, per_row: int, seed: int) -> np.ndarray:
    """A seeded subset of at most MAX_EVAL_SAMPLES (trajectory, step) samples of ``rows``."""
    pairs = np.stack(np.meshgrid(rows, np.arange(per_row), indexing="ij"), -1).reshape(-1, 2)
    if len(pairs) > MAX_EVAL_SAMPLES:
        pick = np.random.default_rng([seed, 3]).choice(len(pairs), MAX_EVAL_SAMPLES,
                                                       replace=False)
        pairs = pairs[np.sort(pick)]
    return pairs


def _quantiles(values: np.ndarray, name: str) -> dict[str, float]:
    return {f"{name}_median": float(np.median(values)),
            f"{name}_p95": float(np.quantile(values, 0.95))}


def held_out_error(model: LearnedModel, data: Dataset, held_rows: np.ndarray,
                   seed: int = 0) -> dict[str, Any]:
    """The raw error (no refinement) of ``model`` on held-out samples (at most
    :data:`MAX_EVAL_SAMPLES`): pose kind, position [mm] and rotation [deg] error of the best
    proposal (row 0 of ``propose``: the heaviest component's mean) and of the best of the
    K component means by FK; trajectory kind, the raw predicted trajectory's (``predict``:
    the heaviest component's) mean line distance, end point error [mm] and mean pointing
    deviation [deg], and those of the best of the K candidates by line distance."""
    if len(held_rows) == 0:
        return {"samples": 0}
    robot = data.robot
    if model.kind == "pose":
        pairs = _eval_rows(held_rows, data.steps + 1, seed)
        T = _frames(robot, data.poses[pairs[:, 0], pairs[:, 1]])
        k = model.meta["hyper"]["components"]
        q = model.propose(T, count=k)                       # (B, K, dof)
        pos, rot = frame_errors(robot, np.repeat(T, k, axis=0), q.reshape(-1, robot.dof))
        pos, rot = pos.reshape(-1, k), rot.reshape(-1, k)
        best = np.argmin(pos / 10.0 + rot, axis=1)  # 10 mm weighs as 1 deg
        pick = np.arange(len(best))
        return {"samples": int(len(T)), **_quantiles(pos[:, 0], "position_mm"),
                **_quantiles(rot[:, 0], "rotation_deg"),
                **_quantiles(pos[pick, best], "best_of_k_position_mm"),
                **_quantiles(rot[pick, best], "best_of_k_rotation_deg")}
    rows = held_rows[:MAX_EVAL_SAMPLES]
    start, goal = data.poses[rows, 0], data.touch_mm[rows]
    candidates = model.candidates(start, goal)                 # (B, K, n + 1, dof)
    b, k, n1, dof = candidates.shape
    flat = candidates.reshape(b * k, n1, dof)
    point_m, rotation, _, _ = robot.chain_kinematics().transforms(flat.reshape(-1, dof))
    points = (point_m * 1000.0).reshape(b * k, n1, 3)
    directions = (rotation @ robot.pointing_axis).reshape(b * k, n1, 3)
    start_mm = robot.chain_kinematics().transforms(start)[0] * 1000.0
    figures = line_metrics(points, directions, flat, np.repeat(start_mm, k, axis=0),
                           np.repeat(goal, k, axis=0), np.repeat(start, k, axis=0),
                           flat[:, -1])
    names = ("line_distance_mean_mm", "end_point_error_mm", "pointing_deviation_mean_deg")
    table = {name: figures[name].reshape(b, k) for name in names}
    best = np.argmin(table["line_distance_mean_mm"], axis=1)
    pick = np.arange(b)
    out: dict[str, Any] = {"samples": int(b)}
    for name in names:
        out.update(_quantiles(table[name][:, 0], name))
        out.update(_quantiles(table[name][pick, best], f"best_of_k_{name}"))
    return out


def query_ms(model: LearnedModel, data: Dataset, rows: np.ndarray) -> float:
    """Median time [ms] of one query, batch of 1 (``propose(T, 1)`` or ``predict``), over
    :data:`QUERY_REPEATS` calls after a warm-up."""
    row = int(rows[0]) if len(rows) else 0
    if model.kind == "pose":
        T = _frames(data.robot, data.poses[row, -1:])[0]

        def call():
            model.propose(T, 1)
    else:
        start, goal = data.poses[row, 0], data.touch_mm[row]

        def call():
            model.predict(start, goal)
    for _ in range(10):
        call()
    times = []
    for _ in range(QUERY_REPEATS):
        began = time.perf_counter()
        call()
        times.append(time.perf_counter() - began)
    return float(np.median(times) * 1000.0)


def summary(payload: dict[str, Any]) -> str:
    """One line: samples, epochs, CPU-minutes, held-out error, query time."""
    err = payload.get("held_out_error", {})
    if payload["kind"] == "pose" and "position_mm_median" in err:
        figures = (f"held-out raw error of the best proposal {err['position_mm_median']:.1f} mm"
                   f" / {err['rotation_deg_median']:.1f} deg median, "
                   f"{err['position_mm_p95']:.1f} mm / {err['rotation_deg_p95']:.1f} deg p95")
    elif "line_distance_mean_mm_median" in err:
        figures = (f"held-out raw line distance {err['line_distance_mean_mm_median']:.1f} mm "
                   f"median, end point error {err['end_point_error_mm_median']:.1f} mm median")
    else:
        figures = "no held-out sample"
    return (f"{payload['samples']['train']} training samples, {payload['epochs']} epochs, "
            f"{payload['training_cpu_min']:.2f} CPU-min; {figures}; query "
            f"{payload.get('model_query_ms', math.nan):.3f} ms")


# ----- loading --------------------------------------------------------------------------------
def load_model(path: str | Path, robot: Robot | str | None = None,
               kind: str | None = None) -> LearnedModel:
    """Read a model file of :func:`train`. ``robot``: InputError unless the model was trained
    for it (name, URDF hash, joints); default the shipped robot the model names. ``kind``:
    InputError unless the model is of that kind."""
    import torch

    path = Path(path)
    if not path.is_file():
        raise InputError(f"model: {path} not found; give a model file ikbench learn wrote")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        ok = isinstance(payload, dict) and payload.get("format") == FORMAT
    except Exception:  # torch.load raises many kinds of errors for a file that is not its own
        ok = False
    if not ok:
        raise InputError(f"model: {path} is not a model file of ikbench learn")
    if payload.get("version") != VERSION:
        raise InputError(f"model: {path} is of format version {payload.get('version')}; this "
                         f"ikbench reads version {VERSION}")
    if kind is not None and payload["kind"] != kind:
        raise InputError(f"model: {path} is a {payload['kind']} model, not a {kind} model")
    robot = recorded_robot(payload["robot"], robot, f"the model {path}", ("model", "robot"))
    return LearnedModel(payload, robot)
