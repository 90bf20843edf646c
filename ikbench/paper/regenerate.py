"""Every committed results folder from one clean commit by one command (``reproduce --all``).

:data:`STUDIES` is the plan: each study's name, the command that makes it (an ``ikbench``
command line or a benchmark script), what it writes under the results directory, and the
time it took when last measured here. :func:`regenerate` prints the plan first, then runs each
study in its own process (so one study's imports, caches and threads cannot change another's
timing), streams its progress, and records each finished study in
``RESULTS/regenerated.json`` (commit, clean tree, wall time, load). It is resumable: a study
already made at this commit is skipped unless ``force``; a dirty tree is refused unless
``allow_dirty`` (then recorded as such, and the provenance test refuses the results). After
the studies, every generated block of README.md and docs/ is rendered again
(:mod:`ikbench.render.blocks`).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_json
from ikbench.core.provenance import REPO, git_state, load_average
from ikbench.methods.ours import Ours
from ikbench.methods.registry import method_status
from ikbench.render.blocks import documents, render_files
from ikbench.studies.folders import RESULTS

#: The record of finished studies, in the results directory.
RECORD = "regenerated.json"


@dataclass(frozen=True)
class Study:
    """One results folder (or file set) and the command that makes it.

    Attributes:
        name: the study's name (``--only`` takes these).
        argv: the command, ``ikbench`` arguments (or ``python SCRIPT`` arguments when
            ``script``), with ``{out}`` standing for the results directory.
        writes: what it writes, relative to the results directory.
        minutes: the wall time it took when last measured on the 2-core machine [min].
        script: a script under the repository (benchmarks/) instead of an ikbench command.
        rows_may_fail: the command exits 1 when a row of its table fails (a method that does
            not meet the contract, an invalid path): the results are complete and say why, so
            exit code 1 is a finished study (recorded as ``exit_code``), not a failed one.
    """

    name: str
    argv: tuple[str, ...]
    writes: tuple[str, ...]
    minutes: float
    script: str = ""
    rows_may_fail: bool = False

    def arguments(self, out: Path) -> list[str]:
        """The arguments with ``{out}`` and ``{compare_methods}`` filled in."""
        return [a.replace("{out}", str(out)).replace("{compare_methods}", compare_methods())
                for a in self.argv]

    def command(self, out: Path) -> list[str]:
        """The command line to run, for the results directory ``out``."""
        args = self.arguments(out)
        if self.script:
            return [sys.executable, str(REPO / self.script), *args]
        return [sys.executable, "-m", "ikbench.cli", *args]

    def shown(self, out: Path) -> str:
        """The command as a reader would type it."""
        args = self.arguments(out)
        head = ["python", self.script] if self.script else ["ikbench"]
        return shlex.join([*head, *args])




def compare_methods() -> str:
    """The NICO comparison's methods: every registered method in registry order but the
    paper's Adam (the ``paper`` study runs it), the walks last (they do not keep the start
    pose, so they cannot meet the paper's contract: shown for the authors' scheme)."""
    names = [n for n in method_status() if n != Ours.name]
    walks = [n for n in names if _walks(n)]
    return ",".join([n for n in names if n not in walks] + walks)


def _walks(name: str) -> bool:
    cls = method_status()[name].cls
    return cls is not None and "start_pose" not in cls().fixed_poses()

#: ``ikbench ik``'s options in every IK study (docs/ik.md): 1,000 targets, seed 1; first the
#: deterministic table (at most 8 attempts from the same seeded rows, no wall-clock cut: the
#: same success table on any machine, TRAC-IK excepted), then the budget table (restarts within
#: 5 ms, whose successes the load partly decides) run 3 times with its spread, then one descent
#: each; then each method's first call in a fresh process. The new tables cost about twice the
#: former ``auto,1`` per target (300 Panda targets, load 3.5-6.5: 191 s against 93 s), so the
#: targets went from 2,000 to 1,000 to keep the regeneration within its hours.
IK_PROTOCOL = ("--count", "1000", "--seed", "1", "--attempts", "8,auto,1", "--repeat", "3",
               "--first-call")
#: The zoo (issue 50): the other serial arms with a known end frame, the deterministic table
#: only, 100 targets each (the four arms of the IK studies above have theirs).
ZOO = ("example-robot-data:ur3", "example-robot-data:ur10", "example-robot-data:kinova",
       "example-robot-data:talos_left_arm", "example-robot-data:tiago_arm",
       "example-robot-data:z1", "nico_right_arm")
ZOO_PROTOCOL = ("--count", "100", "--seed", "1", "--attempts", "8")
#: Ground truth on UR5 (issue 46): 500 targets of which a fifth beyond the reach bound, and the
#: two other first initial configurations.
TRUTH_PROTOCOL = ("--robot", "example-robot-data:ur5", "--count", "500", "--seed", "1",
                  "--attempts", "8")
#: The plan, in the order it runs (cheap and foundational first).
STUDIES: tuple[Study, ...] = (
    Study("paper", ("reproduce", "--output", "{out}"),
          ("README.md", "report.md", "pointing_deviation_per_step.png", "ours",
           "sequential-ik", "sequential-ik-pointing", "sequential-ik-position", "ikpy",
           "ours-init-interpolation", "ablation"), 4.5),
    Study("compare", ("compare", "--methods", "{compare_methods}", "--first-call", "--output",
                      "{out}"),
          ("compare",), 19.0, rows_may_fail=True),
    Study("compare-panda", ("compare", "--robot", "panda", "--targets",
                            "urdf/panda_lines.targets.json", "--methods", "all",
                            "--first-call", "--output", "{out}/panda"), ("panda",), 23.5,
          rows_may_fail=True),
    Study("bench", ("bench", "--output", "{out}"),
          ("benchmark.csv", "benchmark.json", "benchmark.md", "benchmark_runs.csv"), 2.5),
    Study("exact-benchmark", ("bench", "--methods", "ours-lm,ours-exact,drake-trajopt,pyroki",
                              "--repeat", "5", "--output", "{out}/exact_benchmark"),
          ("exact_benchmark",), 2.0),
    Study("throughput", ("bench", "--device", "cpu", "--batches", "7,1000,10000", "--repeat", "3",
                         "--output", "{out}/scale"),
          ("scale",), 6.5),
    Study("sweep", ("sweep", "--weight", "c0=1,10,100,1000", "--weight", "c1=10,50,200,500",
                    "--output", "{out}/sweep"), ("sweep",), 0.5),
    Study("batch", ("batch", "--output", "{out}/batch"), ("batch",), 0.5),
    Study("letters", ("letters", "P,A,S,X", "--output", "{out}/letters"),
          ("letters/ours",), 0.5),
    Study("letters-c0-100", ("letters", "P,A,S,X", "--weights", "c0=100", "--max-iterations",
                             "10000", "--output", "{out}/letters/c0-100"), ("letters/c0-100",),
          1.5),
    Study("letters-sweep", ("sweep", "--shape", "letter:P", "--weight", "c0=1,10,100,1000",
                            "--weight", "c1=10,50,200", "--output", "{out}/letters/sweep"),
          ("letters/sweep",), 0.5),
    Study("cartesian", ("cartesian", "--problems", "cppflow", "--methods", "ours-lm",
                        "--seeds", "1-5", "--trajectories", "all", "--first-call",
                        "--output", "{out}"),
          ("cartesian",), 1.0, rows_may_fail=True),
    Study("ik-panda", ("ik", "--robot", "example-robot-data:panda", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/panda",), 3.5),
    Study("ik-ur5", ("ik", "--robot", "example-robot-data:ur5", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/ur5",), 3.5),
    Study("ik-xarm7", ("ik", "--robot", "example-robot-data:xarm7", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/xarm7",), 3.5),
    Study("ik-fetch", ("ik", "--robot", "fetch_arm", *IK_PROTOCOL, "--output", "{out}"),
          ("ik/fetch_arm",), 2.5),
    *(Study(f"zoo-{robot.rpartition(':')[2]}", ("ik", "--robot", robot, *ZOO_PROTOCOL,
                                                "--output", "{out}/ik_zoo"),
            (f"ik_zoo/ik/{robot.rpartition(':')[2]}",), 0.8) for robot in ZOO),
    Study("ik-unreachable", ("ik", *TRUTH_PROTOCOL, "--unreachable", "0.2", "--output",
                             "{out}/ik_truth/unreachable"), ("ik_truth/unreachable",), 0.7),
    *(Study(f"ik-init-{init}", ("ik", *TRUTH_PROTOCOL, "--init", init, "--output",
                                f"{{out}}/ik_truth/init_{init}"), (f"ik_truth/init_{init}",),
            0.7) for init in ("random", "nominal", "nearby")),
    Study("cartesian-methods", ("cartesian", "--problems", "cppflow", "--seeds", "1",
                                "--trajectories", "all", "--first-call", "--output",
                                "{out}/cartesian_methods"), ("cartesian_methods",), 12.5,
          rows_may_fail=True),
    Study("ours-speed", ("--output", "{out}/ours_speed.csv"), ("ours_speed.csv",), 0.5,
          script="benchmarks/ours_speed.py"),
    Study("designer-latency", ("--output", "{out}/designer_latency.csv"),
          ("designer_latency.csv",), 0.5, script="benchmarks/designer_latency.py"),
)


def plan(only: Sequence[str] | None = None) -> list[Study]:
    """The studies to run (all, or those named in ``only``, in plan order); InputError naming
    an unknown name and the known ones."""
    if not only:
        return list(STUDIES)
    names = [s.name for s in STUDIES]
    unknown = [n for n in only if n not in names]
    if unknown:
        raise InputError(f"--only: {', '.join(unknown)} is not a study; studies: "
                         f"{', '.join(names)}")
    return [s for s in STUDIES if s.name in only]


def read_record(out: Path) -> dict:
    """``OUT/regenerated.json`` (study -> what made it), empty when absent or unreadable."""
    try:
        record = json.loads((out / RECORD).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


def regenerate(output: str | Path = RESULTS, only: Sequence[str] | None = None,
               force: bool = False, allow_dirty: bool = False, dry_run: bool = False,
               say: Callable[[str], None] | None = None,
               runner: Callable[[list[str]], int] | None = None) -> dict[str, float]:
    """Run the plan (see the module docstring); return the wall time [s] of each study run.

    Args:
        output: the results directory.
        only: study names to run (default all).
        force: run studies already made at this commit again.
        allow_dirty: run from a tree with modified code (recorded as dirty).
        dry_run: print the plan and what would be skipped; run nothing.
        say: where progress lines go (default stderr).
        runner: runs one command and returns its exit code (default: a subprocess whose
            output streams through).

    Raises:
        InputError: an unknown study, or a dirty tree without ``allow_dirty``, or a study
            that failed (its name and exit code).
    """
    say = say or (lambda text: print(text, file=sys.stderr, flush=True))
    runner = runner or _run
    out = Path(output)
    studies = plan(only)
    state = git_state()
    commit, clean = state if state else (None, False)
    if not clean and not allow_dirty and not dry_run:
        raise InputError("the checkout has modified code (git status): commit it first, or "
                         "pass --allow-dirty (the results will say so and the provenance "
                         "test will refuse them)")
    record = read_record(out)
    total = sum(s.minutes for s in studies)
    say(f"plan: {len(studies)} studies into {out}/ at commit {str(commit)[:12]}"
        f"{'' if clean else ' (modified tree)'}, about {total:.0f} min when last measured:")
    for s in studies:
        done = record.get(s.name, {})
        skip = not force and done.get("commit") == commit and done.get("clean") == clean \
            and commit is not None
        say(f"  {s.name:<16} {s.minutes:5.1f} min  {s.shown(out)}"
            f"{'   (made at this commit: skipped)' if skip else ''}")
    times: dict[str, float] = {}
    if dry_run:
        return times
    for k, s in enumerate(studies):
        done = record.get(s.name, {})
        if not force and commit is not None and done.get("commit") == commit \
                and done.get("clean") == clean:
            continue
        say(f"[{k + 1}/{len(studies)}] {s.name}: {s.shown(out)}")
        load_start = load_average()
        started = time.perf_counter()
        code = runner(s.command(out))
        wall = time.perf_counter() - started
        if code != 0 and not (code == 1 and s.rows_may_fail):
            raise InputError(f"study {s.name} failed (exit code {code}): {s.shown(out)}")
        times[s.name] = wall
        record[s.name] = {"command": s.shown(out), "commit": commit, "clean": clean,
                          "exit_code": code,
                          "wall_s": round(wall, 1), "load_start": load_start,
                          "load_end": load_average(), "writes": list(s.writes)}
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(out / RECORD, record)
        say(f"[{k + 1}/{len(studies)}] {s.name} done in {wall / 60:.1f} min")
    changed = render_files(documents(REPO), REPO) if out.resolve() == (REPO / "results") \
        .resolve() else []
    say(f"generated blocks re-rendered: {', '.join(str(p.relative_to(REPO)) for p in changed)}"
        if changed else "generated blocks: all current")
    return times


def _run(argv: list[str]) -> int:
    """Run one study's command with its output streaming through."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run(argv, cwd=REPO, env=env).returncode
