"""``ikbench recommend``: which single-pose IK solver for this robot, within this budget.

The panel is ``ikbench ik`` on its deterministic protocol (:func:`ikbench.studies.ik.run_ik`
with a fixed count of attempts and no wall-clock cut: success is a function of the seed and
the code; TRAC-IK, which races its own timeout, is the one method that is not deterministic),
run on three seeds:

1. **Set-up**: every installed method that takes the task's targets is set up once (untimed;
   a method that cannot load the robot keeps its rows, with the library's reason).
2. **Pilot**: :data:`PILOT_TARGETS` targets per method (their own seed), timed whole, give
   the cost of one target per method.
3. **Plan** (:func:`plan_sample`): the targets per seed that fit ``minutes`` after the
   fresh-process first calls (estimated from each method's set-up) and the writing.
4. **Sample**: :data:`SEEDS` seeds x that many targets, every method; then each method's
   first call in a fresh process (:func:`ikbench.studies.first_call.first_call`) while the
   time allows.
5. **Statistics and verdict** (:mod:`ikbench.studies.verdict`): success with its Wilson
   interval, per-call p50 and p99 with bootstrap intervals, the ranking on each seed and
   Kendall's tau between them, a verdict that calls ties ties.

:func:`run` runs a :class:`RecommendSpec` and returns a :class:`Recommendation`;
:meth:`Recommendation.write` writes ``OUTPUT/recommend/<robot>/``
(:func:`ikbench.render.recommend_report.write_folder`); :func:`recommend` does all three.
"""

from __future__ import annotations

import math
import shlex
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from ikbench.core.errors import InputError
from ikbench.core.io import check_folder_writable
from ikbench.core.robot import Robot, load_robot
from ikbench.methods.registry import solver_status
from ikbench.render.recommend_report import duration, folder_of, write_folder
from ikbench.runtime.harness import describe
from ikbench.runtime.progress import Reporter
from ikbench.studies import recommend_path as paths
from ikbench.studies.first_call import first_call, robot_spec
from ikbench.studies.folders import RUNS, WITHIN
from ikbench.studies.ik import IKSettings, load_average, parse_methods, run_ik, sample_targets
from ikbench.studies.verdict import FAILED, Verdict, decide, per_method

FOLDER = WITHIN["recommend"]
PATH = "path"
TASKS = ("pose", "position", PATH)
#: Paths per seed (``--task path``): at least one circle and one line, at most.
MIN_PATHS, MAX_PATHS = 2, 200
#: The default budget per path [ms] (``--task path``): a path of 41 poses.
PATH_BUDGET_MS = 1000.0
#: Seeds of the sample (the ranking is recomputed on each).
SEEDS = 3
#: Targets per method in the pilot that sizes the sample.
PILOT_TARGETS = 20
#: The pilot's seed, apart from the sample's (its targets are not in the statistics).
PILOT_SEED_OFFSET = 1000
#: Targets per seed: at least (intervals need some), at most.
MIN_TARGETS, MAX_TARGETS = 10, 5000
#: The attempts of the deterministic protocol (fixed count, no wall-clock cut).
ATTEMPTS = 10
#: Seconds kept for statistics and writing the folder.
WRITE_RESERVE_S = 6.0
#: Seconds of a fresh process before the method's set-up (interpreter, ikbench, the robot),
#: added to its set-up to estimate its first call.
FRESH_PROCESS_S = 2.0
#: Seconds of statistics per method and target of each seed (the bootstrap: 2000 pooled and
#: 1000 per-seed resamples; measured about 1.4e-4 s here, doubled).
STATS_S_PER_TARGET = 3e-4
#: The margin [s] a run may pass ``--minutes`` by (the statistics and the writing past their
#: reserve; the last first call's clean-up): 10 % of ``--minutes``, at least this.
MARGIN_S = 10.0
#: The longest run ``--minutes`` may ask (a day).
MAX_MINUTES = 1440.0
#: The default budget per call [ms] the p99 must meet (TRAC-IK's default timeout).
BUDGET_MS = 5.0


@dataclass(frozen=True)
class RecommendSettings:
    """What a recommendation asks.

    Attributes:
        budget_ms: the time per call [ms] a method's p99 must be within (finite, > 0).
        task: ``pose`` (6-D) or ``position`` (rotation free).
        minutes: the time the whole run may take [min] (the sample is sized to fit).
        seed: the first of the :data:`SEEDS` seeds (``seed``, ``seed + 1``, ...).
        attempts: initial configurations per target (the deterministic protocol).
        tolerance_mm, tolerance_deg: the judge's tolerances.
        methods: the methods (None: every installed one that takes the task).
    """

    budget_ms: float = BUDGET_MS
    task: str = "pose"
    minutes: float = 5.0
    seed: int = 1
    attempts: int = ATTEMPTS
    tolerance_mm: float = 1.0
    tolerance_deg: float = 0.5
    methods: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise InputError(f"--task: {self.task!r} is not one of {', '.join(TASKS)}")
        if not (isinstance(self.budget_ms, (int, float)) and math.isfinite(self.budget_ms)
                and self.budget_ms > 0):
            raise InputError(f"--budget-ms: {self.budget_ms!r} must be a finite number of "
                             "milliseconds > 0 (the p99 per call is held against it)")
        if not (isinstance(self.minutes, (int, float)) and math.isfinite(self.minutes)
                and 0 < self.minutes <= MAX_MINUTES):
            raise InputError(f"--minutes: {self.minutes!r} must be more than 0 and at most "
                             f"{MAX_MINUTES:g}")
        # the remaining fields are checked as ikbench ik checks them
        self.ik_settings(1, self.seed)

    def ik_settings(self, count: int, seed: int) -> IKSettings:
        """The ``ikbench ik`` settings of one sample: the deterministic protocol (a path task
        checks its seed and tolerances as a pose task would)."""
        return IKSettings(count=count, seed=seed, kind="pose" if self.task == PATH else self.task,
                          tolerance_mm=self.tolerance_mm, tolerance_deg=self.tolerance_deg,
                          budget_ms=math.inf, attempts=(self.attempts,))

    @property
    def seeds(self) -> tuple[int, ...]:
        """The sample's seeds."""
        return tuple(self.seed + i for i in range(SEEDS))


@dataclass
class Plan:
    """How the sample was sized: the pilot's cost per target [s] per method, each method's
    set-up [s] and estimated first call [s], the targets (paths) per seed and the estimate of
    the sample's time [s]; ``path_shape``: the placed paths' size (``--task path``)."""

    minutes: float
    pilot_targets: int
    cost_s: dict[str, float]
    setup_s: dict[str, float]
    first_call_estimate_s: dict[str, float]
    targets_per_seed: int
    sample_estimate_s: float
    first_calls_fit: bool
    path_shape: dict = field(default_factory=dict)
    #: each method's second set-up in the process [s] (what each seed's run pays again) and
    #: the compile its first one held (first minus second, e.g. ours-lm's numba kernels on a
    #: cold cache): both spent before the sample was sized, so both count in --minutes
    resetup_s: dict[str, float] = field(default_factory=dict)
    compile_s: dict[str, float] = field(default_factory=dict)
    #: the seconds the smallest sample (MIN_TARGETS per seed) is expected to pass --minutes
    #: by, beyond the margin (0: it fits)
    overrun_s: float = 0.0
    #: the seconds the run may end after --minutes (:func:`margin_s`)
    margin_s: float = 0.0


def margin_s(minutes: float) -> float:
    """The seconds a run of ``minutes`` may end after ``--minutes`` (:data:`MARGIN_S`)."""
    return max(MARGIN_S, 0.1 * 60.0 * minutes)


@dataclass
class Recommendation:
    """What :func:`recommend` found.

    Attributes:
        verdict: the paragraph (markdown) naming the recommended method, its ties and the
            trade-off.
        table: one row per method: success and its interval, per-call p50 and p99 and
            theirs, first call, joint distance, nearest-branch share, rank per seed, role.
        files: the files written (empty when nothing was written).
        recommended: the recommended method (None when none meets the budget).
        tied: the methods statistically tied with it.
        kendall_tau: "seed a vs seed b" -> tau of the two seeds' rankings.
        plan: how the sample was sized.
        results: the raw rows (one per seed x method x target, ``ikbench ik``'s columns and
            ``seed``).
        settings, robot, wall_s, methods (name -> facts), load_average (start).
        command: the command line recommend.md quotes ("": :func:`command_line`).
        paired: the recommended method against the runner-up over the same targets
            (:func:`paired`; empty when there is no pair).
    """

    verdict: str
    table: pd.DataFrame
    files: list[Path]
    recommended: str | None
    tied: list[str]
    kendall_tau: dict[str, float]
    plan: Plan
    results: pd.DataFrame
    settings: RecommendSettings
    robot: Any
    wall_s: float
    methods: dict[str, dict] = field(default_factory=dict)
    load_start: tuple | None = None
    decision: Verdict | None = None
    command: str = ""
    paired: dict = field(default_factory=dict)

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/recommend/<robot>/`` whole (:mod:`ikbench.render.recommend_report`;
        the command recorded: :attr:`command`, else :func:`command_line` into ``folder``);
        set :attr:`files`; return the folder written."""
        out = folder_of(folder, self.robot)
        self.files = write_folder(self, out, self.command or command_line(self, folder))
        return out


def plan_sample(remaining_s: float, cost_s: dict[str, float],
                first_call_s: dict[str, float]) -> tuple[int, float, bool]:
    """Targets per seed that fit ``remaining_s`` [s] (solving, and the statistics of the
    target's rows, :data:`STATS_S_PER_TARGET`): the first calls' estimate comes first
    when at least half the time is left for the sample, else the sample gets half and the
    first calls what the time then allows. Returns (targets per seed, the sample's estimate
    [s], whether the first calls are planned in)."""
    per_target = (max(sum(cost_s.values()), 1e-6) + STATS_S_PER_TARGET * len(cost_s)) * SEEDS
    first = sum(first_call_s.values())
    fit = remaining_s - first >= remaining_s / 2
    usable = remaining_s - first if fit else remaining_s / 2
    n = int(np.clip(math.floor(max(usable, 0.0) / per_target), MIN_TARGETS, MAX_TARGETS))
    return n, n * per_target, fit


def _setup(robot: Robot, names: Sequence[str], settings: RecommendSettings,
           report: Reporter) -> tuple[dict[str, Any], dict[str, float], dict[str, float]]:
    """Each method's solver, set up twice (untimed by the study; both times kept for the
    plan): the first set-up holds what the process then caches (a compile), the second is
    what each seed's run pays again. The failure (``"prepare: ..."``) where the library
    cannot take the robot. Returns (solvers, first set-up [s], second set-up [s])."""
    ik = settings.ik_settings(1, settings.seed)
    solvers: dict[str, Any] = {}
    setup_s: dict[str, float] = {}
    resetup_s: dict[str, float] = {}
    for name in names:
        cls = solver_status()[name].cls
        report.say(f"{name}: setting up")
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            solver = cls(robot, ik.kind, (ik.tolerance_mm, ik.tolerance_deg), ik.budget_s)
            try:
                solver.prepare()
                solvers[name] = solver
            except Exception as exc:  # the library cannot take this robot: failed rows
                solvers[name] = f"prepare: {describe(exc)}"
                report.note(f"{name}: cannot take {robot.name}: {describe(exc)}")
            times.append(time.perf_counter() - t0)
            if isinstance(solvers[name], str):
                break
        setup_s[name], resetup_s[name] = times[0], times[-1]
        report.advance(1, f"{name}: set up")
    return solvers, setup_s, resetup_s


def _sample(robot: Robot, names: Sequence[str], count: int, seed: int,
            settings: RecommendSettings, report: Reporter
            ) -> tuple[pd.DataFrame, dict[str, float], dict[str, dict]]:
    """Every method on ``count`` targets of ``seed`` (one ``run_ik`` per method; a set-up the
    library caches in the process, as PyRoki's compiled solve, is reused): the rows, each
    method's wall time [s] and its facts."""
    frames, wall, info = [], {}, {}
    for name in names:
        report.say(f"seed {seed}: {name}: {count} targets")
        t0 = time.perf_counter()
        result = run_ik(robot, settings.ik_settings(count, seed), [name], progress=False)
        wall[name] = time.perf_counter() - t0
        info.update(result.methods)
        frames.append(result.table.assign(seed=seed))
        report.advance(1, f"seed {seed}: {name}: {int(result.table['success'].sum())}/"
                          f"{count} succeeded")
    return pd.concat(frames, ignore_index=True), wall, info


def _first_calls(robot: Robot, names: Sequence[str], settings: RecommendSettings,
                 estimate_s: dict[str, float], deadline: float, report: Reporter
                 ) -> dict[str, dict]:
    """Each method's first call in a fresh process, cheapest estimate first, while it fits
    before ``deadline`` (perf_counter seconds); else the reason it was not measured."""
    ik = settings.ik_settings(1, settings.seed + PILOT_SEED_OFFSET)
    targets = sample_targets(robot, ik)
    out: dict[str, dict] = {}
    for name in sorted(names, key=lambda n: estimate_s[n]):
        left = deadline - time.perf_counter()
        if estimate_s[name] > left:
            out[name] = {"error": f"not measured: about {estimate_s[name]:.0f} s, "
                                  f"{max(left, 0):.0f} s of --minutes left"}
        else:
            report.say(f"{name}: first call in a fresh process")
            out[name] = first_call(robot, name, ik.kind, (ik.tolerance_mm, ik.tolerance_deg),
                                   ik.budget_s, targets.T_target[0],
                                   targets.initials(0, settings.attempts),
                                   timeout_s=max(left, 1.0))
        report.advance(1, f"{name}: first call")
    return out


def _run_poses(robot: Robot, names: Sequence[str], settings: RecommendSettings,
               deadline: float, report: Reporter) -> tuple[pd.DataFrame, dict, Plan]:
    """The single-pose panel (steps 1 to 4 of the module docstring): rows, facts, plan."""
    solvers, setup_s, resetup_s = _setup(robot, names, settings, report)
    pilot_rows, pilot_wall, _ = _sample(robot, names, PILOT_TARGETS,
                                        settings.seed + PILOT_SEED_OFFSET, settings, report)
    working = [n for n in names if not isinstance(solvers[n], str)]
    compile_s = {n: max(setup_s[n] - resetup_s[n], 0.0) for n in working}
    # each sample's run_ik sets a method up again (the process's caches warm, as in the
    # pilot): per target the pilot's wall time without that second set-up, never less than
    # its calls on the solver's clock; each seed's set-ups taken off the time left. The
    # first set-up (a compile included) is already spent: the time left counts it.
    solved_s = pilot_rows.groupby("method")["time_s"].sum(min_count=1)
    cost_s = {n: max(pilot_wall[n] - resetup_s[n], float(np.nan_to_num(solved_s.get(n, 0.0))),
                     0.0) / PILOT_TARGETS for n in names}
    # a fresh process reads the caches the first set-up filled: its second set-up's time
    estimate = {n: resetup_s[n] + FRESH_PROCESS_S for n in working}
    remaining = (deadline - time.perf_counter() - WRITE_RESERVE_S
                 - SEEDS * sum(resetup_s[n] for n in working))
    n, sample_s, fit = plan_sample(remaining, cost_s, estimate)
    over = max(sample_s - remaining - margin_s(settings.minutes), 0.0)
    plan = Plan(settings.minutes, PILOT_TARGETS, cost_s, setup_s, estimate, n, sample_s, fit,
                resetup_s=resetup_s, compile_s=compile_s, overrun_s=over,
                margin_s=margin_s(settings.minutes))
    report.note(f"{n} targets per seed x {SEEDS} seeds x {len(names)} methods: about "
                f"{sample_s:.0f} s (pilot: {PILOT_TARGETS} targets per method; per target "
                + ", ".join(f"{m} {duration(c)}" for m, c in cost_s.items()) + ")")
    spent = sum(compile_s.values())
    if spent >= 1.0:
        report.note(f"the first set-ups took {spent:.0f} s more than the second ("
                    + ", ".join(f"{m} {c:.0f} s" for m, c in compile_s.items() if c >= 1.0)
                    + ": a compile or a compiled cache loaded), counted in --minutes")
    if over > 0:
        report.note(f"the smallest sample ({MIN_TARGETS} targets per seed) does not fit: the "
                    f"run will pass --minutes {settings.minutes:g} by about {over:.0f} s more "
                    f"than its {margin_s(settings.minutes):.0f} s margin")
    frames, info = [], {}
    for s in settings.seeds:
        frame, _, facts = _sample(robot, names, n, s, settings, report)
        frames.append(frame)
        info.update(facts)
    calls = _first_calls(robot, working, settings, estimate, deadline - WRITE_RESERVE_S / 2,
                         report)
    for name in names:
        info[name]["first_call"] = calls.get(name, {"error": str(solvers[name])})
    return pd.concat(frames, ignore_index=True), info, plan


def _run_paths(robot: Robot, names: Sequence[str], settings: RecommendSettings,
               deadline: float, report: Reporter) -> tuple[pd.DataFrame, dict, Plan]:
    """The path panel (:mod:`ikbench.studies.recommend_path`): a one-path pilot per method
    (set-up included), then as many paths per seed as fit."""
    report.say("pilot: one path per method")
    cost_s = paths.pilot(robot, names, settings.seed + PILOT_SEED_OFFSET,
                         deadline - WRITE_RESERVE_S)
    report.advance(len(names), "pilot done")
    remaining = deadline - time.perf_counter() - WRITE_RESERVE_S
    # the cheapest methods first, as many as fit the smallest sample; the others say why
    fits: list[str] = []
    total = 0.0
    for name in sorted(names, key=lambda n: cost_s[n]):
        total += cost_s[name] * SEEDS * MIN_PATHS
        if total <= remaining or (not fits and np.isfinite(cost_s[name])):
            fits.append(name)
    per_path = max(sum(cost_s[n] for n in fits), 1e-6) * SEEDS
    n = int(np.clip(math.floor(max(remaining, 0.0) / per_path), MIN_PATHS, MAX_PATHS))
    shape = {"segments": paths.SEGMENTS, "circle_radius_share": paths.CIRCLE_RADIUS_SHARE,
             "line_length_share": paths.LINE_LENGTH_SHARE}
    plan = Plan(settings.minutes, 1, cost_s, {}, {}, n, n * per_path, True, shape)
    report.note(f"{n} paths per seed x {SEEDS} seeds x {len(fits)} methods: about "
                f"{n * per_path:.0f} s (pilot: one path per method)")
    frames = []
    for s in settings.seeds:
        tasks = paths.place_paths(robot, s, n)
        for name in names:
            if name not in fits or time.perf_counter() > deadline - WRITE_RESERVE_S:
                why = (f"not run: --minutes {settings.minutes:g} spent" if name in fits else
                       f"not run: its pilot path took {cost_s[name]:.3g} s, more than "
                       f"--minutes {settings.minutes:g} leaves" if np.isfinite(cost_s[name])
                       else "not run: its pilot path did not finish within its share of "
                       f"--minutes {settings.minutes:g}")
                frames.append(paths.not_run(name, s, tasks, why))
            else:
                report.say(f"seed {s}: {name}: {n} paths")
                frames.append(paths.solve_paths(robot, name, tasks, s))
            report.advance(1, f"seed {s}: {name}: {int(frames[-1]['success'].sum())}/{n} "
                              "valid")
    return pd.concat(frames, ignore_index=True), paths.facts(names), plan


def method_names(settings: RecommendSettings) -> list[str]:
    """The methods ``settings`` asks (its ``methods``; None: every installed one that takes
    the task), checked (:func:`checked_names`)."""
    return checked_names(settings.methods, settings.task)


def checked_names(methods: Sequence[str] | None, task: str) -> list[str]:
    """``methods`` (None: every installed one that takes ``task``) checked for ``task``:
    :func:`~ikbench.studies.recommend_path.path_methods` for ``path``,
    :func:`~ikbench.studies.ik.parse_methods` else."""
    if task == PATH:
        return paths.path_methods(methods)
    return parse_methods(methods, task)


@dataclass(frozen=True)
class RecommendSpec:
    """A recommendation: the robot, its settings (checked when made), the method names, the
    progress bar and the command line recommend.md quotes. :meth:`validate` checks the
    rest; :func:`run` runs it (:mod:`ikbench.studies.shape`)."""

    robot: Robot
    settings: RecommendSettings = field(default_factory=RecommendSettings)
    methods: tuple[str, ...] = ()
    progress: bool = True
    command: str = ""

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for an unknown or unfit method, no method
        that takes the task, or a robot whose kinematics cannot be built."""
        task = self.settings.task
        if not checked_names(list(self.methods), task):
            raise InputError(f"--methods: no installed method takes --task {task}")
        self.robot.check_loads()


def recommend(robot: Robot | str, end_frame: str | None = None, *,
              budget_ms: float | None = None, task: str = "pose", minutes: float = 5.0,
              methods: str | Sequence[str] | None = None, seed: int = 1,
              attempts: int = ATTEMPTS, output: str | Path | None = RUNS,
              progress: bool = True, command: str = "") -> Recommendation:
    """Recommend a single-pose IK method for ``robot`` (see the module docstring): builds a
    :class:`RecommendSpec`, validates it, :func:`run` and :meth:`Recommendation.write`.

    Args:
        robot: a :class:`~ikbench.core.robot.Robot`, or a name, config or URDF path.
        end_frame: the end link (with a URDF or a package robot that needs one).
        budget_ms: the time per call [ms] (per path for ``path``) the p99 must be within
            (None: :data:`BUDGET_MS`, :data:`PATH_BUDGET_MS` for ``path``).
        task: ``pose``, ``position`` or ``path``.
        minutes: the time the run may take [min]; the sample is sized to fit.
        methods: method names (None: every installed one that takes the task).
        seed: the first of the three seeds.
        attempts: initial configurations per target (no wall-clock cut).
        output: writes ``output/recommend/<robot>/``; None writes nothing.
        progress: a progress bar (or lines) on stderr.
        command: the command line to record (default: a ``ikbench recommend`` line).

    Returns:
        a :class:`Recommendation`.
    """
    names_given = None if methods is None else tuple(
        methods.split(",") if isinstance(methods, str) else methods)
    if budget_ms is None:
        budget_ms = PATH_BUDGET_MS if task == PATH else BUDGET_MS
    settings = RecommendSettings(budget_ms, task, minutes, seed, attempts,
                                 methods=names_given)
    if isinstance(robot, str):
        robot = load_robot(robot, end_frame)
    spec = RecommendSpec(robot, settings, tuple(method_names(settings)), progress, command)
    spec.validate()
    if output is not None:
        check_folder_writable(folder_of(output, robot))
    result = run(spec)
    if output is not None:
        result.write(output)
    return result


def run(spec: RecommendSpec) -> Recommendation:
    """Run the recommendation ``spec`` (validated: :meth:`RecommendSpec.validate`); nothing is
    written (:meth:`Recommendation.write` writes it). ``wall_s``: the run's time, the
    writing not included."""
    started = time.perf_counter()
    load = load_average()
    robot, settings, names, task = spec.robot, spec.settings, list(spec.methods), \
        spec.settings.task
    deadline = started + settings.minutes * 60.0
    panel = _run_paths if task == PATH else _run_poses
    steps = len(names) * (1 + SEEDS) + (0 if task == PATH else 2 * len(names)) + 1
    with Reporter(FOLDER, total=steps, unit="step", enabled=spec.progress) as report:
        table, info, plan = panel(robot, names, settings, deadline, report)
        n = plan.targets_per_seed
        report.say("statistics and verdict")
        table = table.assign(recommend_task=task, recommend_robot=robot.name,
                             recommend_budget_ms=settings.budget_ms)
        decision, pair = verdict_of(table, info, n)
        result = Recommendation(decision.text, decision.table, [], decision.recommended,
                                decision.tied, decision.kendall_tau, plan, table, settings,
                                robot, 0.0, info, load, decision, spec.command, pair)
        report.advance(1, "verdict")
    result.wall_s = time.perf_counter() - started
    return result


def command_line(result: Recommendation, output: str | Path = RUNS) -> str:
    """The ``ikbench recommend`` command that reproduces ``result`` into ``output``."""
    spec, end_frame = robot_spec(result.robot)
    s = result.settings
    words = ["ikbench", "recommend", "--robot", spec, "--end-frame", end_frame,
             "--task", s.task, "--budget-ms", f"{s.budget_ms:g}", "--minutes", f"{s.minutes:g}",
             "--seed", str(s.seed), "--attempts", str(s.attempts)]
    if s.methods:
        words += ["--methods", ",".join(s.methods)]
    words += ["--output", str(output)]
    return " ".join(shlex.quote(w) for w in words)


#: The level below which the paired sign test calls a difference in success a difference.
ALPHA = 0.05
#: Resamples of the paired bootstrap of the per-target time ratio.
PAIRED_RESAMPLES = 2000


def target_key(rows: pd.DataFrame) -> list[str]:
    """The columns naming one target (a path for ``--task path``) within the rows."""
    return ["seed", "path" if "path" in rows else "target"]


def paired(rows: pd.DataFrame, first: str, second: str) -> dict:
    """``first`` against ``second`` over the targets both were given (same seed and target):
    success by the exact sign test on the discordant targets (McNemar's exact test:
    ``scipy.stats.binomtest``), time by the geometric mean of the per-target time ratio
    ``second / first`` over the targets both timed, with a seeded paired-bootstrap 95 %
    interval. A difference is called only where the test rejects at :data:`ALPHA` (success)
    or the interval excludes 1 (time); else it is a tie."""
    key = target_key(rows)
    a = rows[rows["method"] == first].set_index(key)
    b = rows[rows["method"] == second].set_index(key)
    both = a.index.intersection(b.index)
    a, b = a.loc[both], b.loc[both]
    sa, sb = a["success"].astype(bool).to_numpy(), b["success"].astype(bool).to_numpy()
    only_a, only_b = int(np.sum(sa & ~sb)), int(np.sum(~sa & sb))
    p = binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
    ta, tb = a["time_s"].to_numpy(dtype=float), b["time_s"].to_numpy(dtype=float)
    timed = np.isfinite(ta) & np.isfinite(tb) & (ta > 0) & (tb > 0)
    log_ratio = np.log(tb[timed] / ta[timed])
    ratio = low = high = float("nan")
    if len(log_ratio):
        rng = np.random.default_rng(zlib.crc32(f"{first} {second}".encode()))
        means = log_ratio[rng.integers(0, len(log_ratio), (PAIRED_RESAMPLES,
                                                            len(log_ratio)))].mean(axis=1)
        ratio = float(np.exp(log_ratio.mean()))
        low, high = (float(np.exp(q)) for q in np.percentile(means, (2.5, 97.5)))
    success = ("tie" if p >= ALPHA else first if only_a > only_b else second)
    time_call = ("tie" if not np.isfinite(low) or low <= 1.0 <= high
                 else first if low > 1.0 else second)
    return {"first": first, "second": second, "targets": len(both), "first_only": only_a,
            "second_only": only_b, "sign_test_p": float(p), "success": success,
            "timed": int(timed.sum()), "time_ratio": ratio, "time_ratio_low": low,
            "time_ratio_high": high, "faster": time_call}


def paired_sentence(pair: dict, unit: str = "targets") -> str:
    """The paired comparison as one sentence of the verdict."""
    a, b = pair["first"], pair["second"]
    won = {"tie": "a tie on success", a: f"{a} succeeds more often",
           b: f"{b} succeeds more often"}[pair["success"]]
    text = (f"Paired over the same {pair['targets']} {unit}, {a} against the runner-up {b}: "
            f"they differ on {pair['first_only'] + pair['second_only']} ({a} alone "
            f"{pair['first_only']}, {b} alone {pair['second_only']}; exact sign test p = "
            f"{pair['sign_test_p']:.2g}), {won}")
    if np.isfinite(pair["time_ratio"]):
        fast = {"tie": "a tie on time", a: f"{a} faster", b: f"{b} faster"}[pair["faster"]]
        text += (f"; {b}'s time per target is {pair['time_ratio']:.3g}x {a}'s [95 % paired "
                 f"bootstrap {pair['time_ratio_low']:.3g}, {pair['time_ratio_high']:.3g}] "
                 f"over the {pair['timed']} both timed, {fast}")
    return text + "."


def verdict_of(rows: pd.DataFrame, info: dict[str, dict], per_seed: int
               ) -> tuple[Verdict, dict]:
    """The statistics and the verdict of the raw rows (those :func:`run` makes, which carry
    the task, robot and budget), the paired comparison of the recommended method with the
    runner-up appended; a method no call of which ran keeps no rate or interval."""
    budget_ms = float(rows["recommend_budget_ms"].iloc[0])
    seeds = sorted(int(s) for s in rows["seed"].unique())
    task, robot = str(rows["recommend_task"].iloc[0]), str(rows["recommend_robot"].iloc[0])
    summary = per_method(rows, info, budget_ms, seeds)
    pairs: dict[tuple[str, str], dict] = {}

    def pair_of(a: str, b: str) -> dict:  # each pair once: the verdict's and the runner-up's
        if (a, b) not in pairs:
            pairs[a, b] = paired(rows, a, b)
        return pairs[a, b]
    decision = decide(summary, budget_ms, task, robot, per_seed, seeds, pair_of)
    cannot = decision.table["budget"] == FAILED
    for column in ("success_pct", "success_low_pct", "success_high_pct"):
        decision.table.loc[cannot, column] = np.nan
    ran = decision.table.loc[~cannot, "method"].tolist()
    pair: dict = {}
    if decision.recommended is not None and len(ran) > 1:
        second = next(m for m in ran if m != decision.recommended)
        pair = pair_of(decision.recommended, second)
        decision.text += " " + paired_sentence(pair, "paths" if task == PATH else "targets")
    return decision, pair


@dataclass
class Recheck:
    """A committed recommendation recomputed from its results.csv alone: ``counts`` (per
    method: successes, targets and the Wilson 95 % interval from ``scipy.stats``), the
    verdict (``decision``) and the paired comparison (``paired``)."""

    counts: pd.DataFrame
    decision: Verdict
    paired: dict


def recheck(folder: str | Path) -> Recheck:
    """Recompute a recommendation's intervals and verdict from ``folder/results.csv`` alone
    (``folder``: an ``OUTPUT/recommend/<robot>/``): the Wilson intervals by
    ``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``, the verdict by the same
    rules (:func:`verdict_of`; the bootstrap is seeded by the method's name). Compare with
    the folder's recommend.csv and recommend.md."""
    rows = pd.read_csv(Path(folder) / "results.csv", dtype={"failure": object})
    rows["failure"] = rows["failure"].fillna("")  # an empty failure: the call ran
    counts = []
    for method, g in rows.groupby("method", sort=False):
        k, n = int(g["success"].astype(bool).sum()), len(g)
        ci = binomtest(k, n).proportion_ci(method="wilson")
        counts.append({"method": method, "successes": k, "targets": n,
                       "success_low_pct": 100.0 * ci.low, "success_high_pct": 100.0 * ci.high})
    per_seed = int(rows.groupby(["method", "seed"]).size().max())
    decision, pair = verdict_of(rows, {}, per_seed)
    return Recheck(pd.DataFrame(counts), decision, pair)
