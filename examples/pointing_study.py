"""The pointing experiment with simulated participants, from design to analysis, once per method:
NICO's arm playing ours-exact's, sequential-ik's and ours-lm's trajectories to the same
simulated people.

Run it with ``python examples/pointing_study.py --output runs/pointing_study`` (about 9 min on
2 cores: 20 participants x 199 trials per method, the authors' design; with
IKBENCH_EXAMPLES_QUICK=1 about 2 min, 3 participants). It writes, per method,
``OUTPUT/METHOD/`` (design.json, head_check.csv, trajectories/, participant_XX/trials.csv and
responses.csv, analysis/ with analysis.md and figures), then ``OUTPUT/methods.csv`` (the cells'
hit rates by method, paired by participant) and ``OUTPUT/power/`` (power of H1 and H2 by
simulation, and the false-positive rate on null studies). Every answer is a model observer's:
the files say SIMULATED wherever they report one.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

from ikbench.core.io import atomic_write_csv, atomic_write_json
from ikbench.core.provenance import provenance
from ikbench.experiment import study
from ikbench.experiment.design import DesignSpec, build
from ikbench.experiment.observers import ObserverModel
from ikbench.experiment.play import PlaySpec, run

QUICK = os.environ.get("IKBENCH_EXAMPLES_QUICK") == "1"
METHODS = ("ours-exact", "sequential-ik", "ours-lm")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", default=None, help="output folder (default: a temporary "
                        "one, removed at the end, when quick)")
    parser.add_argument("--participants", type=int, default=3 if QUICK else 20)
    parser.add_argument("--repetitions", type=int, default=10 if QUICK else 100,
                        help="simulated studies per size in the power analysis")
    args = parser.parse_args()
    if args.output is None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            return study_in(Path(tmp) / "pointing_study", args)
    # a design never replaces a folder with answers, so a new simulated study starts from an
    # empty folder: the old one is set aside, and put back if the new one fails
    out = Path(args.output)
    previous = out.with_name(f".{out.name}.previous")
    shutil.rmtree(previous, ignore_errors=True)
    if out.exists():
        out.rename(previous)
    try:
        code = study_in(out, args)
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        if previous.exists():
            previous.rename(out)
        raise
    shutil.rmtree(previous, ignore_errors=True)
    return code


def study_in(out: Path, args: argparse.Namespace) -> int:
    say = print
    model = ObserverModel()
    folders = {}
    for method in METHODS:
        folder = out / method
        print(f"[pointing_study] {method}: design, simulated run, analysis", file=sys.stderr)
        spec = DesignSpec(participants=args.participants, seed=1, method=method,
                          incongruent_trials=12, practice=3)
        build(spec).write(folder)
        run(PlaySpec(folder, model=model, seed=1, log=lambda line: None))
        say(study.analyze_folder(folder, folder / "analysis"))
        folders[method] = folder
    table = study.compare_methods(folders)
    atomic_write_csv(out / "methods.csv", table)
    atomic_write_json(out / "methods.json", {"kind": "experiment-methods", "simulated": True,
                                             "methods": list(METHODS),
                                             "provenance": provenance()})
    cells = table.pivot(index="cell", columns="method", values="hit_rate")
    say("hit rate by cell and method (SIMULATED participants):")
    say(cells.round(3).to_string())
    sizes = "3,4" if QUICK else "4,6,8,12,20"
    for hypothesis in ("H1", "H2"):
        say(study.power_study(folders[METHODS[0]], out / "power" / hypothesis, model, sizes,
                              args.repetitions, hypothesis, seed=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
