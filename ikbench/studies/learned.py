"""The learned-start table (issue 61): does a pose model trained on ikbench's own data lift
one descent and the deterministic protocol of ``ikbench ik``?

Per robot (:data:`ROBOTS`: Panda, UR10, NICO's right arm), in this order:

1. a dataset (:func:`ikbench.studies.dataset.build_dataset`, as ``ikbench dataset``:
   :data:`TRAJECTORIES` line trajectories of :data:`STEPS` segments, seed :data:`DATASET_SEED`);
2. a pose model (:func:`ikbench.learned.train.train`, as ``ikbench learn --kind pose``:
   :data:`EPOCHS` epochs, seed :data:`TRAIN_SEED`). Neither seed is a benchmark seed (1, 4),
   and the IK targets below are FK of uniform draws, not the dataset's poses;
3. ``ikbench ik`` on :data:`COUNT` targets of seed 1 for :data:`METHODS` with ``--init``
   random, nominal, nearby and learned (the model's proposals), ``--attempts 1,8``.

It writes ``OUTPUT/learned.csv`` (:data:`COLUMNS`: one row per robot, method, init and
attempts rule; the model's columns empty for the other inits, the training columns in every
learned row) and ``OUTPUT/learned.json`` (settings, each model's record with the SHA-256 of
its file and of its dataset, provenance, load). The datasets and models (~4.5 MB a robot) are
made in a temporary folder and not kept, unless ``--keep FOLDER`` names one: the seeds make
them again.

Run: ``python ikbench/studies/learned.py --output OUTPUT`` (the ``learned`` entry of
``ikbench reproduce``'s plan). Sized to run within 6 minutes on the 2-core machine (measured:
3.8 min at load 1.4-2.9, most of it UR10's dataset).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from ikbench.core.defaults import LEARNED_STUDY_METHODS

#: The robots of the table.
ROBOTS = ("example-robot-data:panda", "example-robot-data:ur10", "nico_right_arm")
#: The methods, the first configurations and the attempts rules of the IK runs.
METHODS = LEARNED_STUDY_METHODS
INITS = ("random", "nominal", "nearby", "learned")
ATTEMPTS = (1, 8)
#: IK targets per robot and their seed (the benchmark's).
COUNT, IK_SEED = 200, 1
#: The training data and model: trajectories, segments each, epochs, seeds (disjoint from the
#: benchmark seeds 1 and 4).
TRAJECTORIES, STEPS, EPOCHS = 1200, 10, 40
DATASET_SEED, TRAIN_SEED = 61, 62
COLUMNS = ["robot", "method", "init", "attempts_rule", "success_pct", "per_call_median_ms",
           "model_error_mm", "model_error_deg", "model_query_ms", "training_samples",
           "training_cpu_min"]


def slug(robot: str) -> str:
    return robot.rpartition(":")[2]


def start_targets(robot):
    """The robot's default targets where it ships them (NICO: the paper's start pose), else
    the middle of its sampling range as the start pose (Panda and UR10 ship none): the
    dataset's lines start there and end at the batch sampler's touch poses."""
    from ikbench.core.errors import InputError
    from ikbench.core.targets import Targets, load_targets

    try:
        return load_targets(None, robot)
    except InputError:
        middle = (robot.sample_lower + robot.sample_upper) / 2.0
        return Targets(tuple(robot.joint_names), middle, {"middle": middle.copy()}, STEPS,
                       "the middle of the sampling range")


def robot_rows(robot_name: str, folder: Path, *, trajectories: int, epochs: int,
               count: int, progress: bool) -> tuple[list[dict], dict]:
    """The table's rows for one robot, and the record of its model."""
    from ikbench.core.robot import load_robot
    from ikbench.learned import train as learn
    from ikbench.render.ik_report import summarise
    from ikbench.studies import ik
    from ikbench.studies.dataset import build_dataset

    robot = load_robot(robot_name)
    data = folder / "dataset"
    build_dataset(trajectories, seed=DATASET_SEED, steps=STEPS, robot=robot,
                  targets=start_targets(robot), output=data, progress=progress)
    model_file = learn.train(data, "pose", folder / "pose.pt", epochs=epochs, seed=TRAIN_SEED,
                             robot=robot, progress=progress)
    rows, facts = [], {}
    for init in INITS:
        settings = ik.IKSettings(count=count, seed=IK_SEED, init=init, attempts=ATTEMPTS,
                                 model=str(model_file) if init == "learned" else None)
        result = ik.run_ik(robot, settings, list(METHODS), progress=progress)
        summary = summarise(result.table, result.batches)
        model = result.init_model or {}
        if model:
            facts = model
        for _, s in summary.iterrows():
            rows.append({
                "robot": robot.name, "method": s["method"], "init": init,
                "attempts_rule": s["attempts_rule"], "success_pct": s["success_pct"],
                "per_call_median_ms": s["time_median_ms"],
                "model_error_mm": model.get("model_error_mm"),
                "model_error_deg": model.get("model_error_deg"),
                "model_query_ms": model.get("model_query_ms"),
                "training_samples": model.get("training_samples"),
                "training_cpu_min": model.get("training_cpu_min")})
    return rows, facts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", required=True, help="folder of learned.csv")
    parser.add_argument("--robots", default=",".join(ROBOTS),
                        help=f"comma-separated robots (default {','.join(ROBOTS)})")
    parser.add_argument("--trajectories", type=int, default=TRAJECTORIES,
                        help=f"dataset trajectories per robot (default {TRAJECTORIES})")
    parser.add_argument("--epochs", type=int, default=EPOCHS,
                        help=f"training epochs (default {EPOCHS})")
    parser.add_argument("--count", type=int, default=COUNT,
                        help=f"IK targets per robot (default {COUNT})")
    parser.add_argument("--keep", metavar="FOLDER", default=None,
                        help="keep each robot's dataset and model under FOLDER/<robot>/ "
                             "(default: a temporary folder, removed at the end)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)

    import os

    import pandas as pd

    from ikbench.core.errors import InputError
    from ikbench.core.io import atomic_write_csv, atomic_write_json
    from ikbench.core.provenance import provenance

    for flag, value in (("--trajectories", args.trajectories), ("--epochs", args.epochs),
                        ("--count", args.count)):
        if value < 1:
            print(f"{flag}: {value} must be an integer >= 1", file=sys.stderr)
            return 2
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    started, load_start = time.perf_counter(), os.getloadavg()
    rows, models, wall = [], {}, {}
    scratch = tempfile.TemporaryDirectory(prefix="ikbench-learned-")
    work = Path(args.keep) if args.keep else Path(scratch.name)
    try:
        for name in [r.strip() for r in args.robots.split(",") if r.strip()]:
            t0 = time.perf_counter()
            got, facts = robot_rows(name, work / slug(name), trajectories=args.trajectories,
                                    epochs=args.epochs, count=args.count,
                                    progress=not args.quiet)
            rows += got
            models[name], wall[name] = _portable(facts, work), time.perf_counter() - t0
    except InputError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    finally:
        scratch.cleanup()
    table = pd.DataFrame(rows, columns=COLUMNS)
    table["training_samples"] = table["training_samples"].astype("Int64")  # empty or whole
    atomic_write_csv(out / "learned.csv", table)
    atomic_write_json(out / "learned.json", {
        "settings": {"robots": list(models), "methods": list(METHODS), "inits": list(INITS),
                     "attempts": list(ATTEMPTS), "count": args.count, "ik_seed": IK_SEED,
                     "trajectories": args.trajectories, "steps": STEPS,
                     "epochs": args.epochs, "dataset_seed": DATASET_SEED,
                     "train_seed": TRAIN_SEED},
        "models": models, "wall_s": {"total": time.perf_counter() - started, **wall},
        "load_average": {"start": load_start, "end": os.getloadavg()},
        "provenance": provenance()})
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"written to {out / 'learned.csv'}")
    return 0


def _portable(facts: dict, work: Path) -> dict:
    """A model's record with its file and dataset named relative to the work folder (the
    record names no machine's folders; the SHA-256s identify them)."""
    facts = dict(facts)

    def relative(path: str) -> str:
        try:
            return Path(path).resolve().relative_to(work.resolve()).as_posix()
        except ValueError:
            return Path(path).name
    if facts.get("model_file"):
        facts["model_file"] = relative(facts["model_file"])
    if isinstance(facts.get("dataset"), dict) and facts["dataset"].get("path"):
        facts["dataset"] = {**facts["dataset"], "path": relative(facts["dataset"]["path"])}
    return facts


if __name__ == "__main__":
    sys.exit(main())
