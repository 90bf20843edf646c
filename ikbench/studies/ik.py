"""The single-pose IK benchmark (``ikbench ik``): success and time per call of every method on a
robot, under one protocol.

Targets, as PickNik's ik_benchmarking: end-frame poses from forward kinematics of
configurations drawn uniformly within the joint limits (continuous joints: +-180 deg), seeded,
so every target is reachable. The protocol, the same for every method (the leaderboard's
header states it):

- **Initial configurations**: each target k has a seeded sequence (:meth:`Targets.initials`).
  Row 0 is its initial pose: ``random`` (drawn uniformly within the limits, independent of the
  target) or ``nearby`` (the target's configuration moved by up to ``perturb_deg`` per joint,
  the tracking case) or ``learned`` (a pose model of ``ikbench learn``, ``model``: row 0 is its
  best proposal for the target frame, rows 1 .. K - 1 its next ones, the means of its K
  mixture components heaviest first, in pose units within the limits; rows past K as below;
  :func:`learned_initials`). Rows 1, 2, ... (past the model's K under ``learned``) are
  drawn uniformly within the limits from the seed's
  k-th child generator (``SeedSequence(seed).spawn``; restarts are random, as TRAC-IK's,
  KDL's and roboticstoolbox's own).
  Every method gets the same rows.
- **Budget**: ``budget_ms`` of wall-clock time per target under ``auto`` (a fixed-count rule
  has none but TRAC-IK's timeout, :func:`rule_budget_s`) (:data:`BUDGET_MS`: TRAC-IK's
  default timeout, which its own benchmark and MoveIt's default ``kinematics_solver_timeout``
  use; PickNik's ik_benchmarking gives more. At 5 ms the fast solvers restart tens of times,
  and a 10,000-target run of the whole panel stays within minutes per robot).
- **Attempts**, one table per rule (``attempts``): ``"auto"`` restarts from the next row until
  the answer holds, the budget is spent or the :data:`AUTO_ROWS` rows are used; an integer N
  allows at most N rows with **no wall-clock cut** (:func:`rule_budget_s`), so its success is a
  function of seed and code alone: each attempt is bounded by the method's own limits
  (``attempt_bound``), never by the clock; 1 is one descent from row 0, for every method.
  The default is :data:`DEFAULT_ATTEMPTS` (deterministic); ``auto`` is load-dependent.
  TRAC-IK (``deterministic`` False) is the exception under every rule: it restarts from its
  own random draws within a finite timeout, the budget, whatever it is given, and says so.
- **Repeats** (``repeat``): the ``auto`` table, whose success the wall clock decides, is run
  ``repeat`` times on the same targets and rows (column ``run``, 1..R; a fixed-count rule runs
  once, run 1); its leaderboard cells give the median over the runs and their min-max.
- **Restarts**: a method that restarts by itself (``restarts_itself``: TRAC-IK within its
  timeout, ours-lm) gets the rows the rule allows and the budget in one call and honours them.
  Any other is restarted here (:func:`restart`): an attempt starts only while the time spent on
  the target is below the budget (the attempt running when it runs out finishes), and each
  answer is checked as the judge checks it (:class:`AttemptCheck`), inside the timed call.
- **Time**: ``time.perf_counter`` around the call with all its attempts, one target per call
  (set-up untimed; the rows are drawn and converted and the target copied into C-ordered
  arrays, :func:`goal_arrays`, before the clock starts); per method: median, mean, p95, max.
  A method whose adapter converts the target to its library's form in advance
  (:meth:`PoseSolver.prepared_call`: eaik, the 4x4 frame EAIK takes) is timed on that call;
  the others convert on the clock.
  The library's bare call (:meth:`PoseSolver.bare_call`, where a method has one) is timed on
  the same arrays beside the method's first timed run, just before its call on odd targets
  and just after it on even ones (:func:`bare_call_times` times it alone). A method that
  batches (``batched``) also solves all the targets in one call from the same rows within
  the same budget per target: its throughput (targets/s, threads stated) is its own column,
  never mixed with per-call times.
- **Success** is judged here (:func:`judge`), never taken from the method: FK through Pinocchio
  of the answer within ``tolerance_mm`` and ``tolerance_deg`` (position only for
  ``kind="position"``) and within the joint limits. The method's own claim is ``library_ok``.
- **Solutions** are stored: ``q0 .. q{dof-1}``, each answer in URDF units (rad, m) in the
  chain's joint order (named in run.json), so any row can be rechecked from the targets file.

:func:`run_ik` returns an :class:`IKResult` (one row per attempts rule x method x target,
:data:`COLUMNS` and the solution columns); :func:`write` puts it under
``OUTPUT/ik/<robot>/`` (:mod:`ikbench.render.ik_report`).
"""

from __future__ import annotations

import hashlib
import inspect
import math
import os
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core import budget
from ikbench.core.defaults import JUDGE_TOLERANCE_DEG, JUDGE_TOLERANCE_MM
from ikbench.core.errors import InputError
from ikbench.methods.registry import available_solvers, parse_names, solver_status
from ikbench.render.ik_report import robot_slug, write_folder
from ikbench.runtime.harness import Progress, describe
from ikbench.studies.first_call import first_call
from ikbench.studies.folders import WITHIN
from ikbench.studies.ik_truth import (
    analytic_solver,
    branch_columns,
    solution_sets,
    stress,
    unreachable_mix,
)

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.schemes.single_pose import PoseOut, PoseSolver

FOLDER = WITHIN["ik"]
KINDS = ("pose", "position")
INITS = ("random", "nominal", "nearby", "learned")
AUTO = "auto"
#: The default attempts rule: the deterministic protocol (at most 8 attempts, no wall-clock
#: cut), as the committed studies run it; ``auto`` is asked for.
DEFAULT_ATTEMPTS = 8
MAX_SEED = 2**63
#: The default wall-clock budget per target [ms] (see the module docstring).
BUDGET_MS = 5.0
#: Rows of a target's sequence under ``--attempts auto`` (more than any method uses within
#: a few milliseconds), and the most ``--attempts N`` may ask.
AUTO_ROWS = 256
MAX_ATTEMPTS = 1000
#: ``--unreachable``: at most this fraction of the targets.
MAX_UNREACHABLE = 0.9
#: The generator of the unreachable targets: ``default_rng([seed, UNREACHABLE_STREAM])``.
UNREACHABLE_STREAM = 46
#: Bytes held per target (the batched solve's arrays, the targets) and per result row; a
#: batched method also holds each target's rows (8 bytes per value, twice).
BYTES_PER_TARGET, BYTES_PER_ROW, BYTES_PER_START = 32_000, 1_000, 16
#: Progress line at most every this many seconds.
PROGRESS_EVERY_S = 10.0
#: Slack [pose units] of the limits when judging (round-off of the unit conversions).
LIMIT_SLACK = 1e-6
COLUMNS = ["robot", "method", "attempts_rule", "target", "kind", "init", "budget_ms", "success",
           "library_ok", "failure", "time_s", "attempts", "position_error_mm",
           "rotation_error_deg", "within_limits", "joint_distance_deg", "iterations"]
#: The last column of results.csv: the run (1..``repeat``) of the ``auto`` rule, 1 elsewhere
#: (files written before it have none: one run).
RUN = "run"
#: ``--repeat``: at most this many runs of the ``auto`` table.
MAX_REPEAT = 100

Rule = int | str


@dataclass(frozen=True)
class IKSettings:
    """What a run asks (see the module docstring).

    Attributes:
        count, seed, kind: targets, their seed, ``pose`` or ``position``.
        tolerance_mm, tolerance_deg: the judge's tolerances.
        init, perturb_deg: the initial poses (row 0 of each sequence).
        max_count: method -> targets at most (the first ones), for slow libraries.
        budget_ms: wall-clock budget per target [ms] (``inf``: none).
        attempts: the attempts rules, one table each: ``"auto"`` or an integer >= 1.
        threads: threads of the batched throughput runs (None: every core).
        first_call: also time each method's first call in a fresh process (import, set-up,
            first solve of target 0: :func:`ikbench.studies.first_call.first_call`).
        unreachable: the fraction of the targets replaced by provably unreachable ones
            (:func:`ikbench.studies.ik_truth.unreachable_mix`), 0 to 0.9.
        repeat: runs of the ``auto`` table (the wall-clock budget decides its success);
            fixed-count rules run once.
        model: ``init="learned"``: the pose model file of ``ikbench learn`` whose proposals
            are the initial configurations (None otherwise).
    """

    count: int = 1000
    seed: int = 1
    kind: str = "pose"
    tolerance_mm: float = JUDGE_TOLERANCE_MM
    tolerance_deg: float = JUDGE_TOLERANCE_DEG
    init: str = "random"
    perturb_deg: float = 10.0
    max_count: dict = field(default_factory=dict)
    budget_ms: float = BUDGET_MS
    attempts: tuple[Rule, ...] = (DEFAULT_ATTEMPTS,)
    threads: int | None = None
    unreachable: float = 0.0
    first_call: bool = False
    repeat: int = 1
    model: str | None = None

    def __post_init__(self):
        check_settings(self)

    @property
    def budget_s(self) -> float:
        """The budget per target [s]."""
        return self.budget_ms / 1000.0


@dataclass
class Targets:
    """The targets (B of them) and their initial configurations.

    Attributes:
        q_target: (B, dof) configurations [pose units].
        T_target: (B, 4, 4) their end-frame poses [m] in the base frame.
        q_init: (B, dof) row 0 of each target's sequence [pose units].
        seed: the run's seed (rows 1.. of target k: numpy's k-th child of the seed,
            ``SeedSequence(seed).spawn(...)[k]``, independent of the targets' own draws).
        sample_lower, sample_upper: (dof,) where rows 1.. are drawn [pose units].
        reachable: (B,) False for the targets made unreachable (``--unreachable``).
        unreachable_kind: (B,) "" for a reachable target, else how it is unreachable
            ("beyond_reach", "orientation_impossible":
            :func:`ikbench.studies.ik_truth.unreachable_mix`).
        sigma_min, limit_margin_deg: (B,) the stress of each target's configuration
            (:func:`ikbench.studies.ik_truth.stress`); NaN until annotated.
        branches: each target's analytic solutions within the limits (S_k, dof) [pose
            units], where an analytic solver takes the robot
            (:func:`ikbench.studies.ik_truth.solution_sets`); None elsewhere.
    """

    q_target: np.ndarray
    T_target: np.ndarray
    q_init: np.ndarray
    seed: int = 0
    sample_lower: np.ndarray | None = None
    sample_upper: np.ndarray | None = None
    reachable: np.ndarray | None = None
    unreachable_kind: np.ndarray | None = None
    sigma_min: np.ndarray | None = None
    limit_margin_deg: np.ndarray | None = None
    branches: list[np.ndarray] | None = None
    branches_by: str = ""
    #: ``--init learned``: (B, K, dof) the model's proposals [pose units]; rows 0 .. K - 1 of
    #: each sequence (row 0 is ``q_init``); None otherwise.
    proposals: np.ndarray | None = None
    #: ``--init learned``: what the run records of the model (:func:`learned_initials`).
    init_model: dict | None = None

    def initials(self, k: int, rows: int) -> np.ndarray:
        """Target ``k``'s first ``rows`` initial configurations (rows, dof) [pose units]: row
        0 its initial pose, then uniform draws within the limits; the same for every method,
        and a prefix of any longer sequence."""
        first = (self.q_init[k:k + 1] if self.proposals is None
                 else self.proposals[k, :max(1, rows)])
        if rows <= len(first):
            return first.copy()
        lower = self.q_init[k] if self.sample_lower is None else self.sample_lower
        upper = self.q_init[k] if self.sample_upper is None else self.sample_upper
        rng = np.random.default_rng(np.random.SeedSequence(int(self.seed), spawn_key=(int(k),)))
        # the same child stream under every init: row r is the r-th draw, whatever row 0 is
        draws = rng.uniform(lower, upper, (rows - 1, first.shape[1]))
        return np.concatenate([first, draws[len(first) - 1:]])


@dataclass
class IKResult:
    """What :func:`run_ik` produced: ``methods``: name -> facts (library, restarts, ...);
    ``batches``: rule -> name -> the batched throughput run (targets/s, threads, success);
    ``auto_rows``: rows of a sequence under ``--attempts auto``."""

    robot: Robot
    settings: IKSettings
    targets: Targets
    table: pd.DataFrame
    methods: dict
    wall_s: float
    load_start: tuple | None = None
    batches: dict = field(default_factory=dict)
    auto_rows: int = AUTO_ROWS
    #: The command line the leaderboard quotes ("" for none).
    command: str = ""
    #: ``--init learned``: the model's file, training samples and CPU-minutes, its query
    #: time per target and its raw error on these targets (:func:`learned_initials`).
    init_model: dict | None = None

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/ik/<robot>/`` whole (:mod:`ikbench.render.ik_report`); return it."""
        return write_folder(self, Path(folder) / FOLDER / robot_slug(self.robot), self.command)


@dataclass(frozen=True)
class IKSpec:
    """An IK benchmark: the robot, its settings (checked when made), the method names, the
    progress lines and the command line the leaderboard quotes. :meth:`validate` checks the
    rest; :func:`run` runs it (:mod:`ikbench.studies.shape`)."""

    robot: Robot
    settings: IKSettings = field(default_factory=IKSettings)
    methods: tuple[str, ...] = ()
    progress: bool = True
    command: str = ""

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for an unknown or unfit method, a robot
        whose kinematics cannot be built, a ``max_count`` of a method not run, or a run too
        large for this machine's memory."""
        settings = self.settings
        names = parse_methods(list(self.methods), settings.kind)
        self.robot.check_loads()
        if settings.init == "learned":
            init_model(self.robot, settings.model)
        unknown = [n for n in settings.max_count if n not in names]
        if unknown:
            raise InputError(f"--max-count-per-method: {unknown[0]} is not among the methods "
                             f"run ({', '.join(names)})")
        rows = max(rule_rows(r) for r in settings.attempts)
        tables = sum(rule_runs(r, settings) for r in settings.attempts)
        check_memory(settings.count, len(names) * tables, rows, self.robot.dof)


def rule_rows(rule: Rule) -> int:
    """Rows of the sequence a rule allows."""
    return AUTO_ROWS if rule == AUTO else int(rule)


def rule_budget_s(rule: Rule, settings: IKSettings, deterministic: bool = True) -> float:
    """The budget per target [s] a method gets under ``rule``: the settings' for ``auto``;
    none (``inf``) for a fixed count N, whose attempts are bounded by the methods' own limits,
    except for a method that is not deterministic (TRAC-IK: it needs a finite timeout)."""
    return settings.budget_s if rule == AUTO or not deterministic else math.inf


def rule_runs(rule: Rule, settings: IKSettings) -> int:
    """Runs of ``rule``'s table: ``repeat`` for ``auto``, one for a fixed count."""
    return settings.repeat if rule == AUTO else 1


def parse_attempts(text: str | Sequence[Rule]) -> tuple[Rule, ...]:
    """``"auto,1"`` -> ("auto", 1); InputError for anything else."""
    items = text if isinstance(text, (list, tuple)) else str(text).split(",")
    rules: list[Rule] = []
    for item in items:
        word = str(item).strip()
        if word == AUTO:
            rule: Rule = AUTO
        else:
            try:
                rule = int(word)
            except ValueError:
                raise InputError(f"--attempts: {word!r} is neither auto nor an integer "
                                 "(e.g. auto,1)") from None
        if rule not in rules:
            rules.append(rule)
    if not rules:
        raise InputError(f"--attempts: {text!r} names no rule (auto, or an integer >= 1)")
    return tuple(rules)


def check_settings(s: IKSettings) -> None:
    """InputError naming the bad value (before any heavy import or solve)."""
    if isinstance(s.count, bool) or not isinstance(s.count, (int, np.integer)) or s.count < 1:
        raise InputError(f"--count: {s.count!r} must be an integer >= 1")
    if isinstance(s.seed, bool) or not isinstance(s.seed, (int, np.integer)) \
            or not 0 <= s.seed < MAX_SEED:
        raise InputError(f"--seed: {s.seed!r} must be an integer in [0, 2^63)")
    if s.kind not in KINDS:
        raise InputError(f"--kind: {s.kind!r} is not one of {', '.join(KINDS)}")
    if s.init not in INITS:
        raise InputError(f"--init: {s.init!r} is not one of {', '.join(INITS)}")
    if s.init == "learned" and not s.model:
        raise InputError("--init learned: needs --model MODEL (a pose model file of "
                         "ikbench learn)")
    if s.model is not None and s.init != "learned":
        raise InputError(f"--model: {s.model!r} is used only with --init learned, not "
                         f"--init {s.init}")
    for flag, value in (("--tolerance-mm", s.tolerance_mm), ("--tolerance-deg", s.tolerance_deg),
                        ("--perturb-deg", s.perturb_deg)):
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
            raise InputError(f"{flag}: {value!r} must be a finite number > 0")
    if not (isinstance(s.budget_ms, (int, float)) and s.budget_ms > 0):
        raise InputError(f"--budget-ms: {s.budget_ms!r} must be a number > 0 (inf: none)")
    if not s.attempts:
        raise InputError("--attempts: no rule (auto, or an integer >= 1)")
    for rule in s.attempts:
        if rule != AUTO and (isinstance(rule, bool) or not isinstance(rule, (int, np.integer))
                             or not 1 <= rule <= MAX_ATTEMPTS):
            raise InputError(f"--attempts: {rule!r} must be auto or an integer in "
                             f"[1, {MAX_ATTEMPTS}]")
    if s.threads is not None and (isinstance(s.threads, bool) or
                                  not isinstance(s.threads, (int, np.integer)) or s.threads < 1):
        raise InputError(f"--threads: {s.threads!r} must be an integer >= 1")
    for name, n in s.max_count.items():
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"--max-count-per-method: {name}={n!r} must be an integer >= 1")
    if isinstance(s.repeat, bool) or not isinstance(s.repeat, (int, np.integer)) \
            or not 1 <= s.repeat <= MAX_REPEAT:
        raise InputError(f"--repeat: {s.repeat!r} must be an integer in [1, {MAX_REPEAT}]")
    if not (isinstance(s.unreachable, (int, float)) and 0 <= s.unreachable <= MAX_UNREACHABLE):
        raise InputError(f"--unreachable: {s.unreachable!r} must be a fraction in "
                         f"[0, {MAX_UNREACHABLE:g}]")


def check_memory(count: int, methods: int, rows: int = 1, dof: int = 7) -> None:
    """InputError when ``count`` targets would not fit in memory (checked up front): the
    estimate against the memory available now (MemAvailable, not the free pages: the page
    cache counts as available), both stated, and the most that fit."""
    per_target = BYTES_PER_TARGET + methods * BYTES_PER_ROW + rows * dof * BYTES_PER_START
    need, available = count * per_target, budget.available_memory_bytes()
    if need > budget.MEMORY_SHARE * available:
        most = int(budget.MEMORY_SHARE * available // per_target)
        raise InputError(f"--count: {count} targets need about {need / 2**30:.1f} GiB; "
                         f"{available / 2**30:.1f} GiB are available here (MemAvailable; a "
                         f"run plans at most {budget.MEMORY_SHARE:.0%} of it): at most {most}")


def parse_methods(text: str | Sequence[str] | None, kind: str = "pose") -> list[str]:
    """Method names (comma-separated or a list); None: every installed one that takes
    ``kind`` targets. InputError for unknown, missing or unsuitable ones
    (:func:`~ikbench.methods.registry.parse_names`)."""

    def takes_kind(cls: type[PoseSolver]) -> str:
        return "" if kind in cls.kinds else (f"takes {', '.join(cls.kinds)} targets, not "
                                              f"--kind {kind}")

    return parse_names(text, solvers=True, accepts=takes_kind,
                       default=lambda: [n for n, c in available_solvers().items()
                                        if kind in c.kinds])


def sample_targets(robot: Robot, settings: IKSettings) -> Targets:
    """The seeded targets and initial poses (the same for every method and re-run)."""
    rng = np.random.default_rng(settings.seed)
    lo, hi = robot.sample_lower, robot.sample_upper
    q_target = rng.uniform(lo, hi, (settings.count, robot.dof))
    T = robot.fk_transform(q_target)
    if settings.init == "learned":  # after the unreachable mix below; no draw from rng
        q_init = np.full((settings.count, robot.dof), np.nan)
    elif settings.init == "random":
        q_init = rng.uniform(lo, hi, (settings.count, robot.dof))
    elif settings.init == "nominal":  # the middle of the limits, as TRAC-IK's benchmark seeds
        q_init = np.tile((np.asarray(lo) + np.asarray(hi)) / 2.0, (settings.count, 1))
    else:
        step = rng.uniform(-settings.perturb_deg, settings.perturb_deg, q_target.shape)
        q_init = np.clip(q_target + step, lo, hi)
    reachable = np.ones(settings.count, dtype=bool)
    kinds = np.full(settings.count, "", dtype=object)
    if settings.unreachable > 0:  # their own generator: the other draws stay as without
        mixer = np.random.default_rng([int(settings.seed), UNREACHABLE_STREAM])
        n = int(round(settings.unreachable * settings.count))
        chosen = np.sort(mixer.choice(settings.count, n, replace=False))
        truth = analytic_solver(robot) if settings.kind == "pose" and n > 1 else None
        T[chosen], kinds[chosen] = unreachable_mix(robot, T[chosen], mixer, truth)
        reachable[chosen] = False
    proposals = facts = None
    if settings.init == "learned":  # the model's proposals for the frames as posed
        learned = learned_initials(robot, settings, T)
        proposals, facts = learned["proposals"], learned["facts"]
        q_init = proposals[:, 0].copy()
    return Targets(q_target, T, q_init, int(settings.seed), np.asarray(lo), np.asarray(hi),
                   reachable, kinds, proposals=proposals, init_model=facts)


def init_model(robot: Robot, path: str | Path | None):
    """The pose model of ``--init learned`` (:func:`ikbench.learned.train.load_model`),
    InputError (``--model: ...``) for a file that is missing or not a model, of a trajectory
    model, or of a model of another robot (name, URDF hash, joints)."""
    from ikbench.learned.train import load_model

    try:
        return load_model(str(path), robot=robot, kind="pose")
    except InputError as exc:
        text = str(exc)
        for head in ("model: ", "robot: "):
            if text.startswith(head):
                text = text[len(head):]
                break
        raise InputError(f"--model: {text}") from None


def learned_initials(robot: Robot, settings: IKSettings, T: np.ndarray) -> dict[str, Any]:
    """``--init learned``: the model's K proposals per target frame T (B, 4, 4) [m] (the
    means of its mixture's components, heaviest first: ``LearnedModel.propose(T, K)``, in pose
    units, clipped into the limits), one target per query as a method gets one per call;
    with what the run records of the model: its file, training samples, epochs and
    CPU-minutes, the median query time per target [ms] and the raw error of row 0 against
    these targets (median position [mm] and rotation [deg] error, no refinement)."""
    model = init_model(robot, settings.model)
    k = int(model.meta["hyper"]["components"])
    proposals = np.empty((len(T), k, robot.dof))
    times = np.empty(len(T))
    model.propose(T[0], k)  # warm-up, untimed
    for i in range(len(T)):
        t0 = time.perf_counter()
        proposals[i] = model.propose(T[i], k)
        times[i] = time.perf_counter() - t0
    proposals = np.clip(proposals, robot.lower, robot.upper)
    position_mm, rotation_deg = model.error(T, proposals[:, 0])
    meta = model.meta
    facts = {"model_file": str(settings.model),  # as given: no machine's folders recorded
             "model_sha256": hashlib.sha256(Path(str(settings.model)).read_bytes()).hexdigest(),
             "training_samples": int(meta["samples"]["train"]),
             "training_cpu_min": float(meta["training_cpu_min"]),
             "epochs": int(meta["epochs"]), "seed": meta.get("seed"),
             "components": k, "dataset": meta.get("dataset"),
             "model_query_ms": 1000.0 * float(np.median(times)),
             "model_error_mm": float(np.median(position_mm)),
             "model_error_deg": float(np.median(rotation_deg))}
    return {"proposals": proposals, "facts": facts}


def annotate(robot: Robot, targets: Targets, settings: IKSettings) -> None:
    """The ground truth of the targets (:mod:`ikbench.studies.ik_truth`): each one's stress,
    and, where an analytic solver takes the robot (6-D targets only), its solution set."""
    load = stress(robot, targets.q_target)
    targets.sigma_min, targets.limit_margin_deg = load["sigma_min"], load["limit_margin_deg"]
    truth = analytic_solver(robot) if settings.kind == "pose" else None
    if truth is not None:
        targets.branches = solution_sets(truth, robot, targets.T_target, targets.q_init)
        targets.branches_by = truth.name


def _errors(T: np.ndarray, T_target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position error [mm] and rotation angle [deg] of frames T (B, 4, 4) [m] from T_target."""
    position = np.linalg.norm(T[:, :3, 3] - T_target[:, :3, 3], axis=1) * 1000.0
    cos = (np.einsum("kij,kij->k", T[:, :3, :3], T_target[:, :3, :3]) - 1.0) / 2.0
    return position, np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def judge(robot: Robot, T_target: np.ndarray, poses: npt.ArrayLike, settings: IKSettings
          ) -> dict[str, np.ndarray]:
    """FK through Pinocchio of ``poses`` (B, dof) [pose units] against the targets: errors
    [mm, deg], within the limits, success at the settings' tolerances (NaN poses fail)."""
    poses = np.asarray(poses, dtype=float)
    finite = np.all(np.isfinite(poses), axis=1)
    safe = np.where(finite[:, None], poses, robot.sample_lower)
    position, rotation = _errors(robot.fk_transform(safe), T_target)
    within = (np.all(safe >= robot.lower - LIMIT_SLACK, axis=1)
              & np.all(safe <= robot.upper + LIMIT_SLACK, axis=1))
    ok = finite & within & (position <= settings.tolerance_mm)
    if settings.kind == "pose":
        ok &= rotation <= settings.tolerance_deg
    position[~finite], rotation[~finite] = np.nan, np.nan
    return {"success": ok, "position_error_mm": position, "rotation_error_deg": rotation,
            "within_limits": within & finite}


class AttemptCheck:
    """The judge (:func:`judge`) for one answer, cheap enough to run after every attempt of a
    method the study restarts: Pinocchio FK of ``q`` [rad, m], the same errors, tolerances
    and limits. ``check(q_urdf, T_target) -> bool``."""

    def __init__(self, robot: Robot, settings: IKSettings) -> None:
        fk = robot.pinocchio_fk()
        self.robot, self.model, self.frame = robot, fk.model, fk.frame_id
        self.data = fk.model.createData()
        self.lower, self.upper = robot.lower - LIMIT_SLACK, robot.upper + LIMIT_SLACK
        self.settings = settings

    def __call__(self, q_urdf: np.ndarray, T_target: np.ndarray) -> bool:
        import pinocchio as pin

        q = np.asarray(q_urdf, dtype=float)
        if not np.all(np.isfinite(q)):
            return False
        pose = self.robot.from_urdf(q)
        if np.any(pose < self.lower) or np.any(pose > self.upper):
            return False
        pin.framesForwardKinematics(self.model, self.data, q)
        M = self.data.oMf[self.frame]
        s = self.settings
        if np.linalg.norm(M.translation - T_target[:3, 3]) * 1000.0 > s.tolerance_mm:
            return False
        if s.kind == "position":
            return True
        cos = (float(np.sum(M.rotation * T_target[:3, :3])) - 1.0) / 2.0
        return bool(math.degrees(math.acos(min(1.0, max(-1.0, cos)))) <= s.tolerance_deg)


def goal_arrays(T_target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The target frame (4, 4) as every method is given it: C-ordered float64 copies of its
    point [m] (3,) and rotation (3, 3), made before the clock (the same arrays for the
    method's call and for its library's bare call)."""
    return (np.ascontiguousarray(T_target[:3, 3], dtype=float),
            np.ascontiguousarray(T_target[:3, :3], dtype=float))


def restart(solve: Callable[[np.ndarray, np.ndarray, np.ndarray], PoseOut],
            starts: np.ndarray, T_target: np.ndarray,
            holds: Callable[[np.ndarray, np.ndarray], bool], budget_s: float,
            clock: Callable[[], float] = time.perf_counter,
            goal: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[PoseOut, float]:
    """One descent per row of ``starts`` (A, dof), in order, until the answer holds
    (``holds(q, T_target)``), the rows are used up or the solver has run ``budget_s`` [s]
    (checked before each new attempt); the last answer, its iterations summed and the attempts
    made, and the solver's time [s]. Only the calls to ``solve`` are timed (by ``clock``): the
    judge's check of each attempt runs outside the clock and outside the budget, so a
    library the study restarts is timed as one that restarts itself. ``goal``: the point and
    rotation ``solve`` is given (default :func:`goal_arrays` of ``T_target``)."""
    point, rotation = goal_arrays(T_target) if goal is None else goal
    iterations, a, spent_s = 0, 0, 0.0
    while True:
        t0 = clock()
        out = solve(starts[a], point, rotation)
        spent_s += clock() - t0
        iterations += int(out.iterations)
        a += 1
        if a == len(starts) or spent_s >= budget_s or holds(out.q, T_target):
            return out._replace(iterations=iterations, attempts=a), spent_s


@dataclass
class _Outcome:
    """One method's answers to the first ``count`` targets under one rule."""

    q_urdf: np.ndarray
    times: np.ndarray
    iterations: np.ndarray
    attempts: np.ndarray
    library_ok: np.ndarray
    failures: list[str]
    #: the library's bare call [s] on the reachable targets, timed beside the solve (None:
    #: not asked for, or the method has no bare call)
    bare_s: list[float] | None = None

    @classmethod
    def failed(cls, count: int, dof: int, failure: str) -> _Outcome:
        """Every row failed (a library that could not be set up)."""
        return cls(np.full((count, dof), np.nan), np.full(count, np.nan),
                   np.zeros(count, dtype=int), np.zeros(count, dtype=int),
                   np.full(count, None, dtype=object), [failure] * count)


def run_ik(robot: Robot, settings: IKSettings | None = None,
           methods: str | Sequence[str] | None = None,
           progress: bool = True) -> IKResult:
    """Run the benchmark (see the module docstring); nothing is written.

    Args:
        robot: a :class:`~ikbench.core.robot.Robot`.
        settings: count, seed, kind, tolerances, initial poses, budget, attempts rules,
            per-method caps.
        methods: method names; None: every installed one (:func:`parse_methods`).
        progress: progress lines on stderr.
    """

    settings = settings or IKSettings()
    spec = IKSpec(robot, settings, tuple(parse_methods(methods, settings.kind)), progress)
    spec.validate()
    return run(spec)


def run(spec: IKSpec) -> IKResult:
    """Run the benchmark ``spec`` (validated: :meth:`IKSpec.validate`); nothing is written
    (:meth:`IKResult.write` writes it)."""
    started = time.perf_counter()
    load = load_average()
    robot, settings, names, progress = spec.robot, spec.settings, list(spec.methods), \
        spec.progress
    targets = sample_targets(robot, settings)
    annotate(robot, targets, settings)
    check = AttemptCheck(robot, settings)
    # closed when the solving ends, so no heartbeat speaks while the caller writes
    with Progress(FOLDER, enabled=progress) as reporter:
        say = reporter.say
        frames, info = [], {}
        batches: dict[str, dict[str, dict[str, float]]] = {}
        solvers: dict[str, Any] = {}
        bare: dict[str, dict[str, Any]] = {}
        for rule in settings.attempts:
            batches[str(rule)] = {}
            runs = rule_runs(rule, settings)
            for round_ in range(1, runs + 1):
                for name in names:
                    cls = solver_status()[name].cls
                    count = min(settings.count, settings.max_count.get(name, settings.count))
                    info[name] = {"library": cls.library, "deterministic": cls.deterministic,
                                  "restarts_itself": cls.restarts_itself,
                                  "one_descent": cls.one_descent, "batched": cls.batched,
                                  "iterations_are": cls.iterations_are,
                                  "attempt_bound": cls.attempt_bound, "count": count,
                                  "stable_across_machines": cls.stable_across_machines}
                    if name not in solvers:
                        solvers[name] = _prepared(cls, robot, settings, say, count)
                    solver = solvers[name]
                    info[name]["runtime"] = None if isinstance(solver, str) else solver.runtime()
                    label = f"attempts {rule}" + (f", run {round_}/{runs}" if runs > 1 else "")
                    if isinstance(solver, str):  # the library cannot take this robot
                        outcome = _Outcome.failed(count, robot.dof, solver)
                    else:
                        say(f"{label}: {name}: solving {count} targets, one per call")
                        outcome = _solve_calls(solver, targets, count, settings, rule, check, say,
                                               with_bare=name not in bare)
                        if name not in bare:  # its first timed run, the bare call beside it
                            bare[name] = bare_facts(solver, outcome.bare_s)
                        if solver.batched and round_ == 1:  # throughput: the first run's
                            batches[str(rule)][name] = _batch(solver, targets, count, settings,
                                                              rule)
                    frames.append(_rows(robot, name, rule, targets, count, settings, outcome,
                                        round_))
                    done = frames[-1]
                    say(f"{label}: {name}: {int(done['success'].sum())}/{count} succeeded, "
                        f"{np.nansum(done['time_s']):.1f} s")
        if settings.first_call:  # after the timed runs: numba's cache as they left it
            rule = settings.attempts[0]
            for name in names:
                if isinstance(solvers.get(name), str):
                    continue
                say(f"{name}: timing its first call in a fresh process")
                info[name]["first_call"] = first_call(
                    robot, name, settings.kind, (settings.tolerance_mm, settings.tolerance_deg),
                    rule_budget_s(rule, settings, solvers[name].deterministic), targets.T_target[0],
                    targets.initials(0, rule_rows(rule)))
        for name, facts in bare.items():
            info[name].update(facts)
    table = pd.concat(frames, ignore_index=True)
    table = table[COLUMNS + [c for c in table.columns if c not in COLUMNS]]
    return IKResult(robot, settings, targets, table, info, time.perf_counter() - started, load,
                    batches, command=spec.command,
                    init_model=targets.init_model)


def _prepared(cls: type[PoseSolver], robot: Robot, settings: IKSettings, say, count: int
              ) -> PoseSolver | str:
    """The solver, set up (untimed); the failure (``"prepare: ..."``) when it cannot be."""
    solver = cls(robot, settings.kind, (settings.tolerance_mm, settings.tolerance_deg),
                 settings.budget_s)
    say(f"{cls.name}: preparing ({count} targets)")
    try:
        solver.prepare()
    except Exception as exc:  # the library cannot take this robot: failed rows
        say(f"{cls.name}: FAILED to prepare: {describe(exc)}")
        return f"prepare: {describe(exc)}"
    return solver


def _solve_calls(solver: PoseSolver, targets: Targets, count: int, settings: IKSettings,
                 rule: Rule, check: AttemptCheck, say, with_bare: bool = False) -> _Outcome:
    """Solve the first ``count`` targets one call each under ``rule`` (see the module doc);
    ``with_bare``: the library's bare call timed beside each reachable target's solve
    (:func:`bare_call_times`)."""
    robot = solver.robot
    dof, rows = robot.dof, rule_rows(rule)
    budget_s = rule_budget_s(rule, settings, solver.deterministic)
    out_q = np.full((count, dof), np.nan)
    times = np.zeros(count)
    iterations, attempts = np.zeros(count, dtype=int), np.zeros(count, dtype=int)
    library_ok = np.empty(count, dtype=object)
    failures = [""] * count
    bare_s: list[float] | None = [] if with_bare else None

    def to_urdf(q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float).reshape(dof)
        return robot.to_urdf(q) if solver.pose_units else q

    def holds(q: np.ndarray, T: np.ndarray) -> bool:
        return check(to_urdf(q), T)

    last = time.perf_counter()
    for k in range(count):
        initials = targets.initials(k, rows)
        starts = np.ascontiguousarray(initials if solver.pose_units
                                      else robot.to_urdf(initials))
        T = targets.T_target[k]
        point, rotation = goal_arrays(T)
        call: Callable[[], object] | None = None
        out: PoseOut | None
        prepared = _prepared_call(solver, starts, point, rotation, budget_s)
        if bare_s is not None and (targets.reachable is None or targets.reachable[k]):
            call = solver.bare_call(starts[0], point, rotation)
            if call is None:  # the method has no bare call
                bare_s = None
        if call is not None and k % 2:  # alternating which runs first
            _time_into(bare_s, call)
        t0 = time.perf_counter()
        try:
            if prepared is not None:  # the inputs in the library's form, made in advance
                out = prepared()
                times[k] = time.perf_counter() - t0
            elif solver.restarts_itself:
                out = solver.solve_within(starts, point, rotation, budget_s)
                times[k] = time.perf_counter() - t0
            else:  # the study's check of each attempt is untimed
                out, times[k] = restart(solver.solve, starts, T, holds, budget_s,
                                        goal=(point, rotation))
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # one failed solve is a row
            times[k] = time.perf_counter() - t0
            failures[k] = describe(exc)
            out = None
        if call is not None and not k % 2:
            _time_into(bare_s, call)
        if out is None:
            continue
        out_q[k] = to_urdf(out.q)
        iterations[k], attempts[k], library_ok[k] = out.iterations, out.attempts, out.ok
        if time.perf_counter() - last > PROGRESS_EVERY_S:
            last = time.perf_counter()
            say(f"attempts {rule}: {solver.name}: {k + 1}/{count} solved")
    return _Outcome(out_q, times, iterations, attempts, library_ok, failures, bare_s)


def _prepared_call(solver: PoseSolver, starts: np.ndarray, point: np.ndarray,
                   rotation: np.ndarray, budget_s: float) -> Callable[[], PoseOut] | None:
    """The method's :meth:`PoseSolver.prepared_call` of one target (untimed; None: the
    method has none, or its preparation failed and the timed :meth:`solve_within` will say
    why)."""
    if not solver.restarts_itself:
        return None
    try:
        return solver.prepared_call(starts, point, rotation, budget_s)
    except KeyboardInterrupt:
        raise
    except Exception:  # the timed call fails the same way and its row says so
        return None


def _time_into(times: list[float] | None, call: Callable[[], Any]) -> None:
    """``call()`` timed by ``time.perf_counter`` as a solve is, appended to ``times`` [s]; a
    call that raises is not timed."""
    t0 = time.perf_counter()
    try:
        call()
    except Exception:  # a failed call is not timed
        return
    if times is not None:
        times.append(time.perf_counter() - t0)


def bare_facts(solver: PoseSolver, times_s: Sequence[float] | None) -> dict[str, Any]:
    """run.json's facts of a method's bare call from its times [s] (None: no bare call):
    ``bare_call_median_ms`` (None where the method has no bare call or every call raised)
    and ``bare_call``, what the call is (its docstring's first paragraph, markdown)."""
    if times_s is None:
        return {"bare_call_median_ms": None, "bare_call": None}
    doc = " ".join((inspect.getdoc(type(solver).bare_call) or "").split("\n\n")[0].split())
    doc = re.sub(r"\s*\(see :meth:`[^`]*`\)", "", doc).replace("``", "`")  # markdown
    return {"bare_call_median_ms": 1000.0 * float(np.median(times_s)) if times_s else None,
            "bare_call": doc}


def bare_call_times(solver: PoseSolver, targets: Targets, count: int) -> dict[str, Any]:
    """The library's own call alone (:meth:`PoseSolver.bare_call`) on the first ``count``
    targets (the reachable ones, as the tables), each from its row 0 converted in advance,
    one call each timed by ``time.perf_counter`` as the study times a solve
    (:func:`bare_facts`). ``ikbench ik`` itself times it interleaved with the method's first
    timed run (``_solve_calls``: before the solve on odd targets, after it on even ones, so
    neither is favoured by the caches the other warms); this is the call alone, back to back.
    The glue an adapter adds is its per-call median minus this
    (:func:`ikbench.render.ik_report.with_bare_calls`)."""
    robot, times = solver.robot, list[float]()
    for k in range(count):
        if targets.reachable is not None and not targets.reachable[k]:
            continue
        q0 = targets.initials(k, 1)[0]
        start = np.ascontiguousarray(q0 if solver.pose_units else robot.to_urdf(q0))
        call = solver.bare_call(start, *goal_arrays(targets.T_target[k]))
        if call is None:
            return bare_facts(solver, None)
        _time_into(times, call)
    return bare_facts(solver, times)


def _batch(solver: PoseSolver, targets: Targets, count: int, settings: IKSettings, rule: Rule
           ) -> dict[str, float]:
    """The batched throughput run: every target in one call, from the same rows within the
    same budget per target; targets/s, threads, success (judged), mean attempts."""
    rows, budget_s = rule_rows(rule), rule_budget_s(rule, settings, solver.deterministic)
    initials = np.stack([targets.initials(k, rows) for k in range(count)])
    T = targets.T_target[:count]
    t0 = time.perf_counter()
    out = solver.solve_batch(initials, np.ascontiguousarray(T[:, :3, 3]),
                             np.ascontiguousarray(T[:, :3, :3]), budget_s, settings.threads)
    wall = time.perf_counter() - t0
    verdict = judge(solver.robot, T, out.q, settings)
    return {"targets_per_s": count / wall, "threads": int(out.threads), "wall_s": wall,
            "success_pct": 100.0 * float(verdict["success"].mean()),
            "attempts_mean": float(np.mean(out.attempts))}


def _rows(robot: Robot, name: str, rule: Rule, targets: Targets, count: int,
          settings: IKSettings, outcome: _Outcome, run: int = 1) -> pd.DataFrame:
    poses = robot.from_urdf(outcome.q_urdf)
    verdict = judge(robot, targets.T_target[:count], poses, settings)
    distance = np.linalg.norm(poses - targets.q_init[:count], axis=1)
    solutions = {f"q{j}": outcome.q_urdf[:, j] for j in range(robot.dof)}
    reachable = (np.ones(count, dtype=bool) if targets.reachable is None
                 else targets.reachable[:count])
    branch = ({"on_nearest_branch": np.full(count, np.nan),
               "branch_excess_deg": np.full(count, np.nan)} if targets.branches is None
              else branch_columns(robot, targets.branches[:count], targets.q_init[:count],
                                  poses, verdict["success"]))
    return pd.DataFrame({
        "robot": robot.name, "method": name, "attempts_rule": str(rule),
        "target": np.arange(count), "kind": settings.kind, "init": settings.init,
        "budget_ms": 1000.0 * rule_budget_s(rule, settings,
                                            solver_status()[name].cls.deterministic),
        **verdict, "library_ok": outcome.library_ok,
        "failure": outcome.failures, "time_s": outcome.times, "attempts": outcome.attempts,
        "joint_distance_deg": distance, "iterations": outcome.iterations, **solutions,
        "reachable": reachable, **branch, RUN: run})


def recheck(robot: Robot, table: pd.DataFrame, T_target: np.ndarray, settings: IKSettings
            ) -> np.ndarray:
    """Success of every row of ``table`` recomputed from its stored solution (``q0 ..``,
    URDF units) and the targets' frames (B, 4, 4) [m]: what :func:`judge` said."""
    q_urdf = table[[f"q{j}" for j in range(robot.dof)]].to_numpy(dtype=float)
    T = T_target[table["target"].to_numpy(dtype=int)]
    return judge(robot, T, robot.from_urdf(q_urdf), settings)["success"]


def load_average() -> tuple | None:
    """The machine's 1, 5 and 15 min load averages (other jobs slow every timing), or None
    where the platform has none."""
    try:
        return tuple(round(v, 2) for v in os.getloadavg())
    except (OSError, AttributeError):
        return None


def write(result: IKResult, output: str | Path, command: str = "") -> Path:
    """Write ``OUTPUT/ik/<robot>/`` whole (:mod:`ikbench.render.ik_report`); return the
    folder."""
    return replace(result, command=command).write(output)
