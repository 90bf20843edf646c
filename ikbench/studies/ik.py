"""The single-pose IK benchmark (``ikbench ik``): success and solve time per library on a robot.

As PickNik's ik_benchmarking: targets are end-frame poses from forward kinematics of
configurations drawn uniformly within the joint limits (continuous joints: +-180 deg), seeded,
so every target is reachable. Each method starts from a stated initial pose: ``random`` (drawn
uniformly, seeded, independent of the target) or ``nearby`` (the target's own configuration
moved by up to ``perturb_deg`` per joint, the tracking case). Every library solves the same
targets from the same initial poses (:mod:`ikbench.baselines._common.single_pose`), one call per
target timed here with ``time.perf_counter`` around the call (set-up untimed), an exception being a
failed row; a batched method solves all targets in one call and each target gets its share of the
time (``batched_time_per_ik_s``). Success is judged here, never taken from the library: FK of
the answer through Pinocchio within ``tolerance_mm`` and ``tolerance_deg`` (position only for
``kind="position"``) and within the joint limits.

:func:`run_ik` returns an :class:`IKResult` (one row per method x target, :data:`COLUMNS`);
:func:`write` puts it under ``OUTPUT/ik/<robot>/`` (:mod:`.ik_report`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.runtime.harness import Progress, describe

if TYPE_CHECKING:
    from pathlib import Path

    from ikbench.core.robot import Robot

FOLDER = "ik"
KINDS = ("pose", "position")
INITS = ("random", "nearby")
MAX_SEED = 2**63
#: Bytes held per target (the batched solve's arrays, the targets) and per result row.
BYTES_PER_TARGET, BYTES_PER_ROW = 32_000, 1_000
#: Share of the available memory a run may plan to use.
MEMORY_SHARE = 0.5
#: Progress line at most every this many seconds.
PROGRESS_EVERY_S = 10.0
COLUMNS = ["robot", "method", "target", "kind", "init", "success", "library_ok", "failure",
           "time_s", "batched_time_per_ik_s", "position_error_mm", "rotation_error_deg",
           "within_limits", "joint_distance_deg", "iterations"]


@dataclass(frozen=True)
class IKSettings:
    """What a run asks (see the module docstring); ``max_count``: method -> targets at most
    (the first ones), for slow libraries."""

    count: int = 1000
    seed: int = 1
    kind: str = "pose"
    tolerance_mm: float = 1.0
    tolerance_deg: float = 0.5
    init: str = "random"
    perturb_deg: float = 10.0
    max_count: dict = field(default_factory=dict)

    def __post_init__(self):
        check_settings(self)


@dataclass
class Targets:
    """The targets (B of them): configurations (B, dof) [pose units] and their end-frame
    poses (B, 4, 4) [m] in the base frame, and the initial poses (B, dof) [pose units]."""

    q_target: np.ndarray
    T_target: np.ndarray
    q_init: np.ndarray


@dataclass
class IKResult:
    """What :func:`run_ik` produced."""

    robot: Robot
    settings: IKSettings
    targets: Targets
    table: pd.DataFrame
    methods: dict
    wall_s: float
    load_start: tuple | None = None


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
    for flag, value in (("--tolerance-mm", s.tolerance_mm), ("--tolerance-deg", s.tolerance_deg),
                        ("--perturb-deg", s.perturb_deg)):
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
            raise InputError(f"{flag}: {value!r} must be a finite number > 0")
    for name, n in s.max_count.items():
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"--max-count-per-method: {name}={n!r} must be an integer >= 1")


def check_memory(count: int, methods: int) -> None:
    """InputError when ``count`` targets would not fit in memory (checked up front)."""
    need = count * (BYTES_PER_TARGET + methods * BYTES_PER_ROW)
    try:
        available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # not Linux: assume 4 GiB
        available = 4 * 2**30
    if need > MEMORY_SHARE * available:
        most = int(MEMORY_SHARE * available / (BYTES_PER_TARGET + methods * BYTES_PER_ROW))
        raise InputError(f"--count: {count} targets need about {need / 2**30:.1f} GiB; "
                         f"{available / 2**30:.1f} GiB are free here: at most {most}")


def parse_methods(text: str | Sequence[str] | None, kind: str = "pose") -> list[str]:
    """Method names (comma-separated or a list); None: every installed one that takes
    ``kind`` targets. InputError for unknown, missing or unsuitable ones."""
    from ikbench.baselines._common.single_pose import SOLVERS

    if text is None:
        return [n for n, c in SOLVERS.items() if c.available() and kind in c.kinds]
    items = text if isinstance(text, (list, tuple)) else str(text).split(",")
    names = list(dict.fromkeys(s.strip() for s in items if s.strip()))
    if not names:
        raise InputError(f"--methods: {text!r} names no method; known: {', '.join(SOLVERS)}")
    for name in names:
        cls = SOLVERS.get(name)
        if cls is None:
            raise InputError(f"--methods: {name!r} is not a single-pose IK method; known: "
                             f"{', '.join(SOLVERS)}")
        if not cls.available():
            raise InputError(f"--methods: {name} needs {', '.join(cls.modules)} "
                             "(pip install 'ikbench[libs]')")
        if kind not in cls.kinds:
            raise InputError(f"--methods: {name} takes {', '.join(cls.kinds)} targets, not "
                             f"--kind {kind}")
    return names


def sample_targets(robot: Robot, settings: IKSettings) -> Targets:
    """The seeded targets and initial poses (the same for every method and re-run)."""
    rng = np.random.default_rng(settings.seed)
    lo, hi = robot.sample_lower, robot.sample_upper
    q_target = rng.uniform(lo, hi, (settings.count, robot.dof))
    T = robot.fk_transform(q_target)
    if settings.init == "random":
        q_init = rng.uniform(lo, hi, (settings.count, robot.dof))
    else:
        step = rng.uniform(-settings.perturb_deg, settings.perturb_deg, q_target.shape)
        q_init = np.clip(q_target + step, lo, hi)
    return Targets(q_target, T, q_init)


def judge(robot: Robot, T_target: np.ndarray, poses: npt.ArrayLike, settings: IKSettings
          ) -> dict[str, np.ndarray]:
    """FK through Pinocchio of ``poses`` (B, dof) [pose units] against the targets: errors
    [mm, deg], within the limits, success at the settings' tolerances (NaN poses fail)."""
    poses = np.asarray(poses, dtype=float)
    finite = np.all(np.isfinite(poses), axis=1)
    safe = np.where(finite[:, None], poses, robot.sample_lower)
    T = robot.fk_transform(safe)
    position = np.linalg.norm(T[:, :3, 3] - T_target[:, :3, 3], axis=1) * 1000.0
    cos = (np.einsum("kij,kij->k", T[:, :3, :3], T_target[:, :3, :3]) - 1.0) / 2.0
    rotation = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    within = (np.all(safe >= robot.lower - 1e-6, axis=1)
              & np.all(safe <= robot.upper + 1e-6, axis=1))
    ok = finite & within & (position <= settings.tolerance_mm)
    if settings.kind == "pose":
        ok &= rotation <= settings.tolerance_deg
    position[~finite], rotation[~finite] = np.nan, np.nan
    return {"success": ok, "position_error_mm": position, "rotation_error_deg": rotation,
            "within_limits": within & finite}


def run_ik(robot: Robot, settings: IKSettings | None = None,
           methods: str | Sequence[str] | None = None,
           progress: bool = True) -> IKResult:
    """Run the benchmark (see the module docstring); nothing is written.

    Args:
        robot: a :class:`~ikbench.core.robot.Robot`.
        settings: count, seed, kind, tolerances, initial poses, per-method caps.
        methods: method names; None: every installed one (:func:`parse_methods`).
        progress: progress lines on stderr.
    """
    from ikbench.baselines._common.single_pose import SOLVERS

    started = time.perf_counter()
    load = load_average()
    settings = settings or IKSettings()
    names = parse_methods(methods, settings.kind)
    unknown = [n for n in settings.max_count if n not in names]
    if unknown:
        raise InputError(f"--max-count-per-method: {unknown[0]} is not among the methods run "
                         f"({', '.join(names)})")
    check_memory(settings.count, len(names))
    targets = sample_targets(robot, settings)
    say = Progress(FOLDER, enabled=progress).say
    frames, info = [], {}
    for name in names:
        solver = SOLVERS[name](robot, settings.kind)
        count = min(settings.count, settings.max_count.get(name, settings.count))
        say(f"{name}: preparing ({count} targets)")
        try:
            solver.prepare()
        except Exception as exc:  # the library cannot take this robot: failed rows
            say(f"{name}: FAILED to prepare: {describe(exc)}")
            outcome = _unprepared(robot, count, f"prepare: {describe(exc)}")
        else:
            outcome = _solve(solver, targets, count, settings, say)
        poses, times, iterations, library_ok, failures, batch = outcome
        frames.append(_rows(robot, name, targets, count, settings, poses, times, iterations,
                            library_ok, failures, batch))
        info[name] = {"library": solver.library, "deterministic": solver.deterministic,
                      "batched": solver.batched, "iterations_are": solver.iterations_are,
                      "count": count}
        done = frames[-1]
        say(f"{name}: {int(done['success'].sum())}/{count} succeeded, "
            f"{np.nansum(done['time_s']):.1f} s")
    table = pd.concat(frames, ignore_index=True)[COLUMNS]
    return IKResult(robot, settings, targets, table, info, time.perf_counter() - started, load)


def _solve(solver, targets: Targets, count: int, settings: IKSettings, say):
    """Solve the first ``count`` targets; per target: poses, times, iterations, library's
    claim, failure; and the batched time per IK (NaN unless batched)."""
    robot = solver.robot
    T = targets.T_target[:count]
    dof = robot.dof
    if solver.batched:
        t0 = time.perf_counter()
        poses, iterations, ok = solver.solve_batch(
            targets.q_init[:count], T[:, :3, 3] * 1000.0, T[:, :3, :3],
            (settings.tolerance_mm, settings.tolerance_deg), settings.seed)
        share = (time.perf_counter() - t0) / count
        return (poses, np.full(count, share), iterations, ok.astype(object),
                [""] * count, share)
    poses = np.full((count, dof), np.nan)
    times = np.zeros(count)
    iterations = np.zeros(count, dtype=int)
    library_ok = np.empty(count, dtype=object)
    failures = [""] * count
    q_init = robot.to_urdf(targets.q_init[:count])
    last = time.perf_counter()
    for k in range(count):
        point, rotation = T[k, :3, 3], T[k, :3, :3]
        t0 = time.perf_counter()
        try:
            out = solver.solve(q_init[k], point, rotation)
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # one failed solve is a row
            times[k] = time.perf_counter() - t0
            failures[k] = describe(exc)
            continue
        times[k] = time.perf_counter() - t0
        poses[k] = robot.from_urdf(np.asarray(out.q, dtype=float).reshape(dof))
        iterations[k], library_ok[k] = out.iterations, out.ok
        if time.perf_counter() - last > PROGRESS_EVERY_S:
            last = time.perf_counter()
            say(f"{solver.name}: {k + 1}/{count} solved")
    return poses, times, iterations, library_ok, failures, np.nan


def _unprepared(robot, count: int, failure: str):
    """What :func:`_solve` returns for a library that could not be set up: every row failed."""
    return (np.full((count, robot.dof), np.nan), np.full(count, np.nan),
            np.zeros(count, dtype=int), np.full(count, None, dtype=object), [failure] * count,
            np.nan)


def _rows(robot, name, targets, count, settings, poses, times, iterations, library_ok,
          failures, batch) -> pd.DataFrame:
    verdict = judge(robot, targets.T_target[:count], poses, settings)
    distance = np.linalg.norm(poses - targets.q_init[:count], axis=1)
    return pd.DataFrame({
        "robot": robot.name, "method": name, "target": np.arange(count), "kind": settings.kind,
        "init": settings.init, **verdict, "library_ok": library_ok, "failure": failures,
        "time_s": times, "batched_time_per_ik_s": batch, "joint_distance_deg": distance,
        "iterations": iterations})


def load_average() -> tuple | None:
    """The machine's 1, 5 and 15 min load averages (other jobs slow every timing), or None
    where the platform has none."""
    try:
        return tuple(round(v, 2) for v in os.getloadavg())
    except (OSError, AttributeError):
        return None


def robot_slug(robot: Robot) -> str:
    """The robot's folder name (its name, without a package prefix)."""
    return str(robot.name).split(":")[-1].replace("/", "_")


def write(result: IKResult, output: str | Path, command: str = "") -> Path:
    """Write ``OUTPUT/ik/<robot>/`` whole (:mod:`.ik_report`); return the folder."""
    from pathlib import Path

    from ikbench.render.ik_report import write_folder

    return write_folder(result, Path(output) / FOLDER / robot_slug(result.robot), command)
