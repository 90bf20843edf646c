"""The plan that makes every committed results folder from one clean commit
(``ikbench reproduce --all``), as spec entries.

:data:`STUDIES` is the plan: each entry (:class:`Study`, a spec that validates itself) names a
study, the command that makes it (an ``ikbench`` command line or a benchmark script), what it
writes under the results directory, and the time it took when last measured here.
:class:`RegenerationSpec` is what a regeneration is asked to do (the results directory, the
studies, force, a dirty tree, a dry run); :func:`run` prints the plan first, then runs each
study in its own process (so one study's imports, caches and threads cannot change another's
timing; ``jobs`` > 1 runs that many at once, never two that write into the same folder nor
one beside a study marked ``alone`` (the per-call timing tables), and records it beside each
study's load), streams its progress, and records each finished study
in ``RESULTS/regenerated.json`` (commit, clean tree, wall time, load, and ``modules``: the
checkout's Python files its processes ran, :mod:`ikbench.core.module_log`) as soon as it
finishes, so an interrupted regeneration keeps every complete study. It is resumable: a
study already made at this commit, or at an ancestor with nothing changed since but the
results, the docs, the tests and this runner (:data:`RESUMABLE_CHANGES`), or, where it
recorded the files it ran, with none of those changed (:func:`stands`; so a partial
regeneration can be committed and finished later, and a change to one solver reruns the
studies that ran it), is skipped unless ``force``; a dirty tree is refused unless
``allow_dirty`` (then recorded as such, and the provenance test refuses the results). After
the studies, every generated block of README.md and docs/ is rendered again
(:mod:`ikbench.render.blocks`). :func:`regenerate` is the keyword form.
"""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ikbench.baselines.ikpy_ik import IkpyIK
from ikbench.baselines.sequential_ik import SequentialIK
from ikbench.core import module_log
from ikbench.core.defaults import EXACT_BENCHMARK_METHODS, REFERENCE_METHOD
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
    """One entry of the plan (a spec): one results folder (or file set) and the command that
    makes it.

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
        alone: with ``--jobs`` > 1, run with no other study beside it (a per-call timing
            table: a neighbour study's threads slowed the committed zoo's per-call medians
            1.8-3.6x against a quiet rerun, unevenly between methods, so the ratios of one
            table's rows carried the neighbour's phases).
    """

    name: str
    argv: tuple[str, ...]
    writes: tuple[str, ...]
    minutes: float
    script: str = ""
    rows_may_fail: bool = False
    alone: bool = False

    def validate(self) -> None:
        """InputError naming the entry and its bad value: a name that ``--only`` cannot take,
        a command that does not write under ``{out}``, a written path outside the results
        directory, a script that is not in the repository, a time that is not positive."""
        where = f"plan entry {self.name!r}"
        if not self.name or any(c in self.name for c in " ,/"):
            raise InputError(f"{where}: the name must be one word without commas or slashes")
        if not any("{out}" in a for a in self.argv):
            raise InputError(f"{where}: its command {shlex.join(self.argv)!r} writes nowhere "
                             "under {out} (the results directory)")
        for w in self.writes or ("",):
            path = PurePosixPath(w)
            if not w or path.is_absolute() or ".." in path.parts:
                raise InputError(f"{where}: writes {w!r}; a path inside the results directory "
                                 "is allowed")
        if self.script and not (REPO / self.script).is_file():
            raise InputError(f"{where}: script {self.script!r} is not a file of the repository")
        if not self.minutes > 0:
            raise InputError(f"{where}: minutes {self.minutes!r}; a positive number is allowed")

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
#: The plan, in the order it runs (cheap and foundational first). The ``paper`` entry's folders
#: are those ``ikbench reproduce`` writes (``ikbench.paper.reproduce.WRITES``; a test keeps the
#: two equal): the runs of ours and of the baseline's three orientation modes, the authors'
#: ikpy run, ours with the text's initialisation, the ablation.
STUDIES: tuple[Study, ...] = (
    Study("paper", ("reproduce", "--output", "{out}"),
          ("README.md", "report.md", "pointing_deviation_per_step.png", Ours.name,
           SequentialIK.name, f"{SequentialIK.name}-pointing", f"{SequentialIK.name}-position",
           IkpyIK.name, f"{Ours.name}-init-interpolation", "ablation"), 4.5),
    Study("compare", ("compare", "--methods", "{compare_methods}", "--first-call", "--output",
                      "{out}"),
          ("compare",), 19.0, rows_may_fail=True),
    Study("compare-panda", ("compare", "--robot", "panda", "--targets",
                            "urdf/panda_lines.targets.json", "--methods", "all",
                            "--first-call", "--output", "{out}/panda"), ("panda",), 23.5,
          rows_may_fail=True),
    Study("bench", ("bench", "--output", "{out}"),
          ("benchmark.csv", "benchmark.json", "benchmark.md", "benchmark_runs.csv"), 2.5),
    Study("exact-benchmark", ("bench", "--methods", ",".join(EXACT_BENCHMARK_METHODS),
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
    Study("cartesian", ("cartesian", "--problems", "cppflow", "--methods", REFERENCE_METHOD,
                        "--seeds", "1-5", "--trajectories", "all", "--first-call",
                        "--output", "{out}"),
          ("cartesian",), 1.0, rows_may_fail=True),
    Study("ik-panda", ("ik", "--robot", "example-robot-data:panda", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/panda",), 3.5, alone=True),
    Study("ik-ur5", ("ik", "--robot", "example-robot-data:ur5", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/ur5",), 3.5, alone=True),
    Study("ik-xarm7", ("ik", "--robot", "example-robot-data:xarm7", *IK_PROTOCOL,
                    "--output", "{out}"),
          ("ik/xarm7",), 3.5, alone=True),
    Study("ik-fetch", ("ik", "--robot", "fetch_arm", *IK_PROTOCOL, "--output", "{out}"),
          ("ik/fetch_arm",), 2.5, alone=True),
    *(Study(f"zoo-{robot.rpartition(':')[2]}", ("ik", "--robot", robot, *ZOO_PROTOCOL,
                                                "--output", "{out}/ik_zoo"),
            (f"ik_zoo/ik/{robot.rpartition(':')[2]}",), 0.8, alone=True) for robot in ZOO),
    # ours-lm's and the eaik adapter's per call against the libraries' bare calls, in one
    # process, interleaved, with paired bootstrap intervals (issues 58, 63): every arm above
    Study("bare-calls", ("--output", "{out}/bare_calls", "--count", "200", "--repeat", "5",
                         *(w for robot in ("example-robot-data:ur5", "example-robot-data:panda",
                                           "example-robot-data:xarm7", "fetch_arm", *ZOO)
                           for w in ("--robot", robot))),
          ("bare_calls",), 0.2, script="benchmarks/ours_lm_vs_bare.py", alone=True),
    Study("ik-unreachable", ("ik", *TRUTH_PROTOCOL, "--unreachable", "0.2", "--output",
                             "{out}/ik_truth/unreachable"), ("ik_truth/unreachable",), 0.7),
    *(Study(f"ik-init-{init}", ("ik", *TRUTH_PROTOCOL, "--init", init, "--output",
                                f"{{out}}/ik_truth/init_{init}"), (f"ik_truth/init_{init}",),
            0.7) for init in ("random", "nominal", "nearby")),
    # learned starts (issue 61): per robot a dataset, a pose model trained on it (seeds 61, 62),
    # then ik with --init random, nominal, nearby and learned, --attempts 1,8 (3.8 min by hand,
    # load 1.4-2.9)
    Study("learned", ("--output", "{out}/learned"), ("learned",), 4.0,
          script="ikbench/studies/learned.py"),
    # learned starts for whole trajectories (issue 61, part 2): a NICO dataset of the paper's
    # n, a trajectory model on it (seeds 63, 64), ours-lm and ours-exact from their usual start
    # and from the model's on the paper's seven targets
    Study("learned-trajectory", ("--output", "{out}/learned_trajectory"),
          ("learned_trajectory",), 3.0, script="ikbench/studies/learned_trajectory.py"),
    Study("cartesian-methods", ("cartesian", "--problems", "cppflow", "--seeds", "1",
                                "--trajectories", "all", "--first-call", "--output",
                                "{out}/cartesian_methods"), ("cartesian_methods",), 12.5,
          rows_may_fail=True),
    # recommend (issue 58): a 6-DoF and a 7-DoF arm at a short budget, so a verdict can be
    # re-checked from its committed results.csv (ikbench.studies.recommend.recheck)
    *(Study(f"recommend-{robot.rpartition(':')[2]}",
            ("recommend", "--robot", robot, "--minutes", "2", "--seed", "1", "--output",
             "{out}"), (f"recommend/{robot.rpartition(':')[2]}",), 2.5)
      for robot in ("example-robot-data:ur5", "example-robot-data:panda")),
    # the pointing experiment's worked example (issue 59): design, simulated participants
    # from two models of the observer, the analysis and the power study
    Study("experiment", ("--output", "{out}/experiment"), ("experiment",), 9.0,
          script="examples/pointing_study.py"),
    Study("ours-speed", ("--output", "{out}/ours_speed.csv"), ("ours_speed.csv",), 0.5,
          script="benchmarks/ours_speed.py", alone=True),
    Study("designer-latency", ("--output", "{out}/designer_latency.csv"),
          ("designer_latency.csv",), 0.5, script="benchmarks/designer_latency.py",
          alone=True),
)


def plan(only: Sequence[str] | None = None) -> list[Study]:
    """The studies to run (all, or those named in ``only``, in plan order), each entry
    validated; InputError naming an unknown name and the known ones."""
    for study in STUDIES:
        study.validate()
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


@dataclass(frozen=True)
class RegenerationSpec:
    """What a regeneration is asked to do.

    Attributes:
        output: the results directory.
        only: study names to run (empty: all).
        force: run studies already made (at this commit or an unchanged ancestor) again.
        allow_dirty: run from a tree with modified code (recorded as dirty).
        dry_run: print the plan and what would be skipped; run nothing.
        jobs: studies run at once (1: one at a time, the default; 2 on a 2-core machine
            roughly halves the wall time, and each study's timings are then made beside
            another study: its load is recorded, and so is ``jobs``).
    """

    output: Path = Path(RESULTS)
    only: tuple[str, ...] = ()
    force: bool = False
    allow_dirty: bool = False
    dry_run: bool = False
    jobs: int = 1

    def validate(self) -> None:
        """InputError for an unknown study or a bad plan entry, or ``jobs`` below 1 (before
        anything runs)."""
        if not (isinstance(self.jobs, int) and self.jobs >= 1):
            raise InputError(f"--jobs: {self.jobs!r}; a whole number >= 1 is allowed")
        plan(self.only)

    def studies(self) -> list[Study]:
        """The entries this regeneration runs, in plan order."""
        return plan(self.only)


@dataclass(frozen=True)
class RegenerationResult:
    """What a regeneration did: each study run and its wall time [s], and the record
    (``regenerated.json``'s content: every study made so far into the results directory)."""

    wall_s: dict[str, float]
    record: dict

    def write(self, folder: Path) -> Path:
        """Write the record into ``folder`` (:func:`run` has already written it after each
        study); return its path."""
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_json(folder / RECORD, self.record)
        return folder / RECORD


def run(spec: RegenerationSpec, say: Callable[[str], None] | None = None,
        runner: Callable[[list[str]], int] | None = None) -> RegenerationResult:
    """Run the plan (see the module docstring).

    Args:
        spec: what to regenerate.
        say: where progress lines go (default stderr).
        runner: runs one command and returns its exit code (default: a subprocess whose
            output streams through).

    Raises:
        InputError: an unknown study or bad entry, or a dirty tree without ``allow_dirty``,
            or a study that failed (its name and exit code).
    """
    say = say or (lambda text: print(text, file=sys.stderr, flush=True))
    out = Path(spec.output)
    studies = spec.studies()
    state = git_state()
    commit, clean = state if state else (None, False)
    if not clean and not spec.allow_dirty and not spec.dry_run:
        raise InputError("the checkout has modified code (git status): commit it first, or "
                         "pass --allow-dirty (the results will say so and the provenance "
                         "test will refuse them)")
    record = read_record(out)

    def made(study: Study) -> bool:
        done = record.get(study.name, {})
        return not spec.force and commit is not None and done.get("clean") == clean and (
            done.get("commit") == commit
            or bool(clean and done.get("commit")
                    and unchanged_since(done["commit"], done.get("modules"))))

    total = sum(s.minutes for s in studies)
    say(f"plan: {len(studies)} studies into {out}/ at commit {str(commit)[:12]}"
        f"{'' if clean else ' (modified tree)'}, about {total:.0f} min when last measured:")
    for s in studies:
        say(f"  {s.name:<16} {s.minutes:5.1f} min  {s.shown(out)}"
            f"{'  (alone)' if s.alone and spec.jobs > 1 else ''}"
            f"{_skipped(record, s) if made(s) else ''}")
    times: dict[str, float] = {}
    if spec.dry_run:
        return RegenerationResult(times, record)
    todo = [(k, s) for k, s in enumerate(studies) if not made(s)]
    if spec.jobs > 1:
        say(f"running {spec.jobs} studies at once (--jobs {spec.jobs}); never two that write "
            "into the same folder, and those marked (alone), the per-call timing tables, "
            "with nothing beside them")
    lock = threading.Lock()  # the record is this process's alone: one writer, no race
    failures: list[str] = []

    def one(k: int, s: Study) -> None:
        say(f"[{k + 1}/{len(studies)}] {s.name}: {s.shown(out)}")
        load_start = load_average()
        started = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="ikbench-modules-") as folder:
            log = Path(folder) / "modules.log"
            code = _run(s.command(out), log) if runner is None else runner(s.command(out))
            modules = module_log.read(log)
        wall = time.perf_counter() - started
        with lock:
            if code != 0 and not (code == 1 and s.rows_may_fail):
                failures.append(f"study {s.name} failed (exit code {code}): {s.shown(out)}")
                return
            times[s.name] = wall
            record[s.name] = {"command": s.shown(out), "commit": commit, "clean": clean,
                              "exit_code": code,
                              "wall_s": round(wall, 1), "load_start": load_start,
                              "load_end": load_average(), "writes": list(s.writes),
                              "jobs": spec.jobs}
            if modules:  # the checkout's files its processes ran (ikbench.core.module_log)
                record[s.name]["modules"] = modules
            RegenerationResult(times, record).write(out)
        say(f"[{k + 1}/{len(studies)}] {s.name} done in {wall / 60:.1f} min")

    try:
        _in_lanes(todo, spec.jobs, one, lambda: bool(failures))
    except BaseException:  # Ctrl-C: no study left running into the results
        _stop_children()
        raise
    if failures:
        raise InputError(failures[0])
    changed = render_files(documents(REPO), REPO) if out.resolve() == (REPO / "results") \
        .resolve() else []
    say(f"generated blocks re-rendered: {', '.join(str(p.relative_to(REPO)) for p in changed)}"
        if changed else "generated blocks: all current")
    return RegenerationResult(times, record)


#: What may change after a study was made without it having to run again on resume: the
#: results themselves, the documents rendered from them, the tests, and this runner (it starts
#: each study's command in a process and records its wall time and load; it computes nothing a
#: study writes). Anything else changed (a solver, a study, the judge, the CLI, a benchmark
#: script, a dependency pin) makes the study run again; where the study recorded the files
#: it ran (``modules``), a Python file it did not run does not (:func:`stands`).
RESUMABLE_CHANGES = ("results*/**", "docs/**", "tests/**", "README.md", "CHANGELOG.md",
                     "ikbench/studies/regeneration.py")


#: The method registry: a study that ran it lists every method, so one added to baselines/
#: since changes what it made.
REGISTRY = "ikbench/methods/registry.py"


def unchanged_since(commit: str, modules: Sequence[str] | None = None) -> bool:
    """Whether a study made at ``commit`` still stands at HEAD: ``commit`` is HEAD, or an
    ancestor of HEAD after which nothing changed but :data:`RESUMABLE_CHANGES` or, where the
    study recorded the files its processes ran (``modules``), nothing it ran
    (:func:`stands`). False outside git or for a commit git does not know."""
    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              timeout=10)

    try:
        if git("merge-base", "--is-ancestor", commit, "HEAD").returncode != 0:
            return False
        changed = git("diff", "--name-only", "--no-renames", commit, "HEAD", "--", ".",
                      *(f":(exclude,glob){path}" for path in RESUMABLE_CHANGES)).stdout.split()
        added = git("diff", "--name-only", "--no-renames", "--diff-filter=A", commit, "HEAD",
                    "--", "baselines").stdout.split() if modules is not None else []
    except (OSError, subprocess.SubprocessError):
        return False
    return stands(changed, modules, added)


def stands(changed: Sequence[str], modules: Sequence[str] | None = None,
           added_methods: Sequence[str] = ()) -> bool:
    """Whether a study stands after ``changed`` (the files changed since it was made, those of
    :data:`RESUMABLE_CHANGES` left out; a rename is the old file deleted and the new added).
    Without ``modules``: when nothing changed. With them (the checkout's Python files its
    processes ran, :mod:`ikbench.core.module_log`): when none of them changed, no file but a
    Python file changed (data, a URDF, a configuration or a pin is read, not imported, so it
    is not in the record), and no method was added to baselines/ (``added_methods``) if it
    ran the registry. A Python file it did not run cannot have changed what it made: a new
    import of it would have changed a file it ran."""
    if modules is None:
        return not changed
    ran = set(modules)
    return not any(path in ran or not path.endswith(".py")
                   or (REGISTRY in ran and path in added_methods) for path in changed)


def _skipped(record: dict, study: Study) -> str:
    """The plan's note on a study that is made already: where it was made."""
    return f"   (made at {str(record[study.name]['commit'])[:12]}: skipped)"


def _overlaps(a: Study, b: Study) -> bool:
    """True when the two studies write into the same place (one's path is the other's or
    inside it), so they must not run at the same time."""
    return any(PurePosixPath(x) == PurePosixPath(y) or PurePosixPath(x) in PurePosixPath(y)
               .parents or PurePosixPath(y) in PurePosixPath(x).parents
               for x in a.writes or ("",) for y in b.writes or ("",))


def _in_lanes(todo: list[tuple[int, Study]], jobs: int, one: Callable[[int, Study], None],
              stop: Callable[[], bool]) -> None:
    """Run ``one(k, study)`` for each of ``todo`` in plan order, at most ``jobs`` at once,
    never two whose ``writes`` overlap (:func:`_overlaps`) and never one beside a study marked
    ``alone`` (it starts when nothing runs and nothing starts while it runs); after ``stop()``
    turns true no new study starts (the running ones finish). One at a time with ``jobs``
    1."""
    if jobs == 1:
        for k, s in todo:
            if stop():
                return
            one(k, s)
        return
    waiting = list(todo)
    running: dict[str, Study] = {}
    done = threading.Condition()

    def lane(k: int, s: Study) -> None:
        try:
            one(k, s)
        finally:
            with done:
                running.pop(s.name, None)
                done.notify_all()

    with done:
        while waiting or running:
            free = len(running) < jobs and not stop()
            free = free and not any(r.alone for r in running.values())
            ready = next(((k, s) for k, s in waiting if free and (not s.alone or not running)
                          and not any(_overlaps(s, r) for r in running.values())), None)
            if ready is not None:
                k, s = ready
                waiting.remove(ready)
                running[s.name] = s
                threading.Thread(target=lane, args=(k, s), daemon=True,
                                 name=f"study-{s.name}").start()
                continue
            if not running:
                return  # stopped, or nothing can start (cannot happen: writes checked alone)
            done.wait()


def regenerate(output: str | Path = RESULTS, only: Sequence[str] | None = None,
               force: bool = False, allow_dirty: bool = False, dry_run: bool = False,
               say: Callable[[str], None] | None = None,
               runner: Callable[[list[str]], int] | None = None,
               jobs: int = 1) -> dict[str, float]:
    """:func:`run` with the spec's fields as keywords; return the wall time [s] of each study
    run."""
    spec = RegenerationSpec(Path(output), tuple(only or ()), force, allow_dirty, dry_run,
                            jobs)
    spec.validate()
    return run(spec, say=say, runner=runner).wall_s


#: The studies' processes running now: ended with the runner (:func:`_stop_children`), so
#: none is left writing into the results after an interrupted regeneration.
_CHILDREN: set[subprocess.Popen] = set()
_CHILDREN_LOCK = threading.Lock()
#: How long an interrupted study has to stop (as after Ctrl-C) before it is killed [s].
STOP_GRACE_S = 10.0


def _run(argv: list[str], modules_log: Path | None = None) -> int:
    """Run one study's command with its output streaming through; with ``modules_log``, its
    processes append the checkout's files they ran there (:mod:`ikbench.core.module_log`).
    Interrupted while it runs, the study is interrupted too (:func:`_stop`)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    if modules_log is not None:
        env[module_log.ENV] = str(modules_log)
    process = subprocess.Popen(argv, cwd=REPO, env=env)
    with _CHILDREN_LOCK:
        _CHILDREN.add(process)
    try:
        return process.wait()
    except BaseException:
        _stop([process])
        raise
    finally:
        with _CHILDREN_LOCK:
            _CHILDREN.discard(process)


def _stop_children(grace_s: float = STOP_GRACE_S) -> None:
    """:func:`_stop` every study still running (those of the other lanes of ``--jobs``, whose
    threads end with the runner)."""
    with _CHILDREN_LOCK:
        children = list(_CHILDREN)
    _stop(children, grace_s)


def _stop(processes: list[subprocess.Popen], grace_s: float = STOP_GRACE_S) -> None:
    """Interrupt each process (SIGINT, what Ctrl-C sends) and kill those still running after
    ``grace_s`` [s]."""
    for process in processes:
        if process.poll() is None:
            try:
                process.send_signal(signal.SIGINT)
            except OSError:  # gone meanwhile
                pass
    deadline = time.monotonic() + grace_s
    for process in processes:
        try:
            process.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
