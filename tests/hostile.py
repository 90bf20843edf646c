"""Feed hostile values to every option of every command, in this process (the driver of
tests/test_hostile_input.py, which runs it in a child with a memory limit).

The cases come from the parser: for each subcommand, each argument that takes a value
(options and positionals), each value of :data:`HOSTILE`. A case runs the real entry point's
parse-and-run (:func:`ikbench.cli.run_parsed`) on a valid base command line with the value put
in; ``ikbench.cli.options.inputs_checked`` is replaced by a stop, so a value a command accepts
ends there, before anything is written or solved. Each case records its exit code (``None``
when accepted), stderr, seconds, the growth of the peak memory, and whether anything was
written.

Run: ``python tests/hostile.py RESULT.json`` (the working directory must be empty); writes a
JSON list, one object per case.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: name -> value; the values a command may accept are in :data:`MAY_ACCEPT`.
HOSTILE = {
    "nan": "nan", "inf": "inf", "-inf": "-inf", "-1": "-1", "0": "0", "1e308": "1e308",
    "1e-300": "1e-300", "1e12": "1e12", "empty": "", "long": "x" * 10_000,
    "directory": "<EMPTY_DIR>", "proc": "/proc", "missing": "<MISSING>",
}
#: Hostile values that are a valid value of some options (a seed of 0, a rate of 0, a folder
#: to write into, a file to create); the others must be refused by every option.
MAY_ACCEPT = {"-1", "0", "1e-300", "1e12", "directory", "missing"}
#: Arguments the base command lines give (replaced by the case's value).
BASE = {
    "ablate": ["ablate", "--output", "<OUT>"],
    "batch": ["batch", "--output", "<OUT>"],
    "bench": ["bench", "--output", "<OUT>"],
    "cartesian": ["cartesian", "--output", "<OUT>"],
    "compare": ["compare", "--output", "<OUT>"],
    "dataset": ["dataset", "--output", "<OUT>"],
    "emulate": ["emulate"],
    "execute": ["execute", "<TRAJ>", "--port", "emulator"],
    "export": ["export", "<TRAJ>", "--format", "csv-rad", "--output", "<OUT>"],
    "experiment analyze": ["experiment", "analyze", "<DESIGN>", "--output", "<OUT>"],
    "experiment design": ["experiment", "design", "--output", "<OUT>"],
    "experiment power": ["experiment", "power", "<DESIGN>", "--output", "<OUT>"],
    "experiment run": ["experiment", "run", "<DESIGN>", "--simulate"],
    "experiment stimuli": ["experiment", "stimuli", "<DESIGN>", "--output", "<OUT>"],
    "fk": ["fk"],
    "ik": ["ik", "--output", "<OUT>"],
    "learn": ["learn", "<DATASET>", "--kind", "pose", "--output", "<OUT>"],
    "legibility": ["legibility", "--output", "<OUT>"],
    "letters": ["letters", "P", "--output", "<OUT>"],
    "plan": ["plan", "<TRAJ>", "--out", "<OUT>"],
    "report": ["report", str(REPO / "results")],
    "recommend": ["recommend", "--output", "<OUT>"],
    "reproduce": ["reproduce", "--output", "<OUT>"],
    "run": ["run", "--output", "<OUT>"],
    "sweep": ["sweep", "--weight", "c0=1,10", "--output", "<OUT>"],
    "view": ["view", str(REPO / "results" / "ours")],
    "warmup": ["warmup"],
}
#: How a command chooses the method whose options are tested.
METHOD_FLAG = {"run": "--method", "letters": "--method", "ablate": "--method",
               "cartesian": "--methods"}


#: A case still running after this long is stopped and recorded as a crash [s] (a command
#: that does its work before ``inputs_checked`` would otherwise run it here).
CASE_ALARM_S = 30


class Reached(BaseException):
    """The command accepted its input (it reached ``inputs_checked``)."""


class TimedOut(BaseException):
    """The case ran past :data:`CASE_ALARM_S`."""


def _stop(args: argparse.Namespace) -> None:
    raise Reached


def _alarm(signum, frame) -> None:
    raise TimedOut(f"still running after {CASE_ALARM_S} s")


def cases(parser: argparse.ArgumentParser) -> list[dict]:
    """One dict per (command, argument, value): command, argument (its flag or metavar),
    value (a key of :data:`HOSTILE`), argv (with placeholders)."""
    from ikbench.methods.registry import method_status

    owners: dict[str, str] = {}
    for name, status in method_status().items():
        for opt in status.cls.options() if status.available and status.cls else []:
            owners.setdefault(opt.dest, name)
    out = []
    for command, sub in _subparsers(parser).items():
        for action in sub._actions:
            if action.nargs == 0 or isinstance(action, argparse._HelpAction):
                continue
            base = list(BASE.get(command, command.split()))
            method = owners.get(action.dest.removeprefix("opt_"))
            if action.dest.startswith("opt_") and command in METHOD_FLAG and method:
                base += [METHOD_FLAG[command], method]
            for value in HOSTILE:
                out.append({"command": command, "argument": _name(action), "value": value,
                            "argv": _put(base, action, sub, "<VALUE>",
                                         len(command.split()))})
    return out


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """command -> its parser; a command with actions of its own (``experiment design``) is
    replaced by them, named by their words."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            out = {}
            for name, sub in action.choices.items():
                nested = _subparsers(sub)
                out.update({f"{name} {k}": v for k, v in nested.items()} if nested
                           else {name: sub})
            return out
    return {}


def _name(action: argparse.Action) -> str:
    if action.option_strings:
        return max(action.option_strings, key=len)
    return str(action.metavar or action.dest)


def _put(base: list[str], action: argparse.Action, sub: argparse.ArgumentParser,
         value: str, words_of_command: int = 1) -> list[str]:
    """``base`` with ``action`` given ``value`` (replacing what the base gave it); the first
    ``words_of_command`` words name the command."""
    if not action.option_strings:  # a positional: the k-th word after the command
        positionals = [a for a in sub._actions if not a.option_strings
                       and a.nargs != 0 and not isinstance(a, argparse._SubParsersAction)]
        k = positionals.index(action)
        if len(positionals) == 1:  # after "--", as a user gives a value such as -inf
            given = _positionals(base, words_of_command)
            return [w for i, w in enumerate(base) if i < words_of_command or w not in given] \
                + ["--", value]
        words, index = list(base), 0
        for i, word in enumerate(words[words_of_command:], start=words_of_command):
            if not word.startswith("-") and not words[i - 1].startswith("-"):
                if index == k:
                    words[i] = value
                    return words
                index += 1
        return words + [value]
    flags = set(action.option_strings)
    words, skip = [], False
    for word in base:
        if skip:
            skip = False
            continue
        if word in flags:
            skip = True
            continue
        words.append(word)
    return words + [f"{max(action.option_strings, key=len)}={value}"]


def _positionals(base: list[str], words_of_command: int = 1) -> list[str]:
    """The words of ``base`` that are positional arguments (not options nor their values)."""
    return [w for i, w in enumerate(base[words_of_command:], start=words_of_command)
            if not w.startswith("-") and not base[i - 1].startswith("-")]


def run_cases(selected: list[dict], parser: argparse.ArgumentParser, fixtures: dict
              ) -> list[dict]:
    """Run every case in this process (see the module docstring)."""
    import ikbench.cli.options
    from ikbench.cli import run_parsed

    ikbench.cli.options.inputs_checked = _stop
    signal.signal(signal.SIGALRM, _alarm)
    results = []
    for case in selected:
        with tempfile.TemporaryDirectory(dir=fixtures["scratch"]) as tmp:
            empty_dir = Path(tmp) / "empty"
            empty_dir.mkdir()
            places = {"<OUT>": str(Path(tmp) / "out"), "<TRAJ>": fixtures["traj"],
                      "<DESIGN>": fixtures["design"], "<DATASET>": fixtures["dataset"],
                      "<EMPTY_DIR>": str(empty_dir), "<MISSING>": str(Path(tmp) / "missing")}
            value = HOSTILE[case["value"]]
            argv = [places.get(w, w) for w in case["argv"]]
            argv = [w.replace("<VALUE>", places.get(value, value)) for w in argv]
            results.append({**case, **_run_one(parser, argv, run_parsed)})
            written = sorted(str(p.relative_to(tmp)) for p in Path(tmp).rglob("*"))
            results[-1]["written"] = [w for w in written if w != "empty"]
            results[-1]["written"] += [f"cwd/{n}" for n in os.listdir(".")]
    return results


def _run_one(parser, argv, run_parsed) -> dict:
    err, out = io.StringIO(), io.StringIO()
    before = peak_rss_kib()
    started = time.perf_counter()
    code: int | None
    crash = None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        signal.alarm(CASE_ALARM_S)
        try:
            code = run_parsed(parser, argv)
        except Reached:
            code = None
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except BaseException as exc:  # a crash: what the test must never see
            code, crash = -1, f"{type(exc).__name__}: {exc}"[:500]
        finally:
            signal.alarm(0)
    seconds = time.perf_counter() - started
    after = peak_rss_kib()
    return {"code": code, "stderr": err.getvalue()[-2000:], "seconds": seconds,
            "peak_growth_kib": after - before, "crash": crash}


def peak_rss_kib() -> int:
    """This process's own peak resident size so far [KiB]: ``VmHWM`` of /proc/self/status.
    Not ``getrusage(RUSAGE_SELF).ru_maxrss``: Linux carries that over ``exec`` from the
    forked copy of the parent, so a child of a large pytest process reads the parent's size
    (2.06 GiB in one CI run, where this process itself peaks below 1 GiB)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise RuntimeError("no VmHWM in /proc/self/status")


def fixtures(scratch: Path) -> dict:
    """A trajectory CSV to read (NICO's start pose, 5 times), a small experiment design
    folder and a small dataset (for ``learn``), in ``scratch``."""
    from ikbench.core.robot import load_robot
    from ikbench.core.trajectory import write_trajectory_csv

    robot = load_robot()
    pose = [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67]
    folder = scratch / "fixtures"
    folder.mkdir()
    traj = write_trajectory_csv(folder / "t.csv", robot, [pose] * 5)
    from ikbench.experiment.design import DesignSpec, build

    design = folder / "design"
    build(DesignSpec(participants=1, repeats=1, practice=0, conditions=("G", "GP"),
                     fractions=(0.6,))).write(design)
    from ikbench.studies.dataset import build_dataset

    dataset = folder / "dataset"
    build_dataset(8, seed=3, steps=4, shard_size=8, output=dataset, progress=False)
    return {"traj": str(traj), "scratch": str(scratch), "design": str(design),
            "dataset": str(dataset)}


def main(argv: list[str]) -> int:
    from ikbench.cli import build_parser

    target = Path(argv[0])
    only = set(argv[1].split(",")) if len(argv) > 1 else None
    parser = build_parser(None)
    with tempfile.TemporaryDirectory() as scratch:
        given = fixtures(Path(scratch))
        selected = [c for c in cases(parser) if only is None or c["command"] in only]
        results = run_cases(selected, parser, given)
    target.write_text(json.dumps({"peak_rss_kib": peak_rss_kib(), "cases": results}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
