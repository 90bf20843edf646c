"""``ikbench learn``: a network trained on a dataset ``ikbench dataset`` wrote."""

from __future__ import annotations

import argparse

from ikbench.cli.options import add_progress_arguments, begin, check_threads
from ikbench.cli.values import OUTPUT, SEED, THREADS, Number, PathValue, Text, count

HELP = "train a network on an ikbench dataset: frame -> configurations, or a whole trajectory"


DESCRIPTION = (
    "Train on the CPU with torch, on a folder ikbench dataset wrote, with a held-out set "
    "split by trajectory (seeded). --kind pose: the end frame of every pose of every "
    "trajectory (the robot's FK) -> its joint configuration, as a mixture density network "
    "(several IK branches are several components); --kind trajectory: (start pose, goal "
    "point) -> the whole trajectory of n + 1 poses, a mixture over whole trajectories learnt "
    "from the converged trajectories. A line "
    "per epoch with the training and held-out loss; a checkpoint MODEL.checkpoint after "
    "every epoch (--resume continues from it, with the same result as an uninterrupted "
    "run). MODEL records the kind, robot, dataset (path, dataset.json's sha256, seed, "
    "count), commit, samples, epochs, training CPU-minutes, hyper-parameters, the raw "
    "held-out error and the query time. See docs/learned.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.learned.model import KINDS
    from ikbench.learned.train import MAX_BATCH_SIZE, MAX_EPOCHS

    parser.add_argument("dataset", metavar="DATASET",
                        type=PathValue("a dataset folder (ikbench dataset --output)",
                                       must_exist="dir"),
                        help="a complete dataset folder ikbench dataset wrote")
    parser.add_argument("--kind", required=True, choices=KINDS,
                        help="pose: frame -> joint configurations; trajectory: (start pose, "
                        "goal point) -> the whole trajectory")
    parser.add_argument("--output", required=True, type=OUTPUT, metavar="MODEL",
                        help="the model file to write (its checkpoint goes next to it, "
                        "MODEL.checkpoint)")
    parser.add_argument("--epochs", type=count("epochs", 1, MAX_EPOCHS), default=20,
                        help="epochs in all; with --resume, the count to continue to "
                        "(default 20)")
    parser.add_argument("--seed", type=SEED, default=0,
                        help="seeds the held-out split, the initial weights and the batches, "
                        "an integer in [0, 2^63) (default 0)")
    parser.add_argument("--batch-size", type=count("samples", 1, MAX_BATCH_SIZE), default=512,
                        help="samples per optimiser step (default 512)")
    parser.add_argument("--holdout", type=Number("a share of the trajectories", 0, 0.9,
                                                 low_open=True),
                        default=0.1,
                        help="share of the dataset's trajectories held out, in (0, 0.9] "
                        "(default 0.1)")
    parser.add_argument("--resume", action="store_true",
                        help="continue from MODEL.checkpoint (refused when it is of another "
                        "kind, dataset, seed or hyper-parameters)")
    parser.add_argument("--robot", default=None, metavar="NAME|PATH",
                        type=Text("a robot name or a config or URDF path"),
                        help="the dataset's robot (refused when the dataset is of another); "
                        "default: the shipped robot the dataset names")
    parser.add_argument("--threads", type=THREADS, default=1,
                        help="torch threads while training (default 1)")
    add_progress_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.core.errors import InputError
    from ikbench.learned import train as learn

    check_threads(args.threads)
    robot = None
    if args.robot is not None:
        from ikbench.core.robot import load_robot

        try:
            robot = load_robot(args.robot)
        except InputError as exc:
            text = str(exc)
            raise InputError(text if "--robot" in text else f"--robot: {text}") from None
    data = learn.read_dataset(args.dataset, robot)
    hyper = learn.Hyper(batch_size=args.batch_size, holdout=float(args.holdout))
    spec = learn.LearnSpec(data, args.kind, Path(args.output), epochs=args.epochs,
                           seed=args.seed, hyper=hyper, resume=args.resume,
                           threads=args.threads, progress=not args.quiet)
    state = spec.validate()
    begin(args)  # not with threads: training sets and restores them itself
    output = learn.run(spec, state)
    import torch

    payload = torch.load(output, map_location="cpu", weights_only=True)
    print(f"{args.kind} model of {data.robot.name} in {output}: {learn.summary(payload)}")
    return 0
