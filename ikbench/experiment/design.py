"""``ikbench experiment design``: trial lists, one per participant, and ``design.json``.

A design crosses cues (conditions) with stopping fractions and targets. ``G`` (gaze only) moves
no arm, so it has no fraction; every other condition has one cell per fraction. Trials are laid
out in blocks: ``blocked`` (one block per cell, as the authors did) or ``interleaved`` (every
cell mixed in ``blocks`` blocks). Block orders are counterbalanced across participants by a
balanced Latin square (Williams design: each cell precedes each other equally often; for an
odd number of cells, the square and its mirror, 2k rows); within a block, trials come in
rounds that show every target once, each round shuffled (the authors' rule:
experiment/batch.py). Everything random is drawn from ``numpy.random.default_rng`` seeded by
(seed, participant), so the same seed writes the same files.

The incongruent gaze target (condition ``I``) follows a stated rule: ``nearest`` (the nearest
other target on the screen; ties drawn), ``authors`` (the authors' pairs, experiment/replay.py
``contras``, for NICO's seven targets) or ``random`` (any other target).

The arm stops at a fraction of the fingertip's path length (the authors cut their pose lists
by count, ``postures[:int(len * p)]``, which on a line of evenly spaced poses is nearly the
same): the stop pose is interpolated, in motor degrees, between the two poses around that
length.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.contract import judge
from ikbench.core.defaults import EXPERIMENT_METHOD
from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_csv, atomic_write_json, read_json, staged_folder
from ikbench.core.metrics import contract_metrics
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, load_robot
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses, write_trajectory_csv
from ikbench.experiment.head import Head, authors_comparison, load_head
from ikbench.experiment.layout import GoalSet, load_goals
from ikbench.methods.registry import get_method

CONDITIONS = ("G", "P", "GP", "I")
CONDITION_NAMES = {"G": "gaze only", "P": "pointing only", "GP": "pointing and congruent gaze",
                   "I": "pointing and incongruent gaze"}
FRACTIONS = (0.6, 0.8)
LAYOUTS = ("blocked", "interleaved")
ORDERS = ("latin", "fixed")
INCONGRUENT_RULES = ("nearest", "authors", "random")
#: The authors' incongruent pairs (github andylucny/nico2, experiment/replay.py ``contras``).
AUTHORS_PAIRS = {1: (3, 6), 2: (7,), 3: (1,), 4: (5,), 5: (4,), 6: (1,), 7: (2,)}
DEFAULT_METHOD = EXPERIMENT_METHOD
DESIGN_FILE = "design.json"
TRIALS_FILE = "trials.csv"
#: gaze_at against the authors' recorded and used head poses, per touch point.
HEAD_CHECK_FILE = "head_check.csv"
TRAJECTORIES = "trajectories"
#: The columns of trials.csv, in order (the contract between design and play).
TRIAL_COLUMNS = ("participant", "trial", "block", "practice", "condition", "fraction", "cell",
                 "target", "gaze_target", "head_z_motor_deg", "head_y_motor_deg",
                 "target_x_px", "target_y_px", "trajectory", "stop_step", "stop_x_mm",
                 "stop_y_mm", "stop_z_mm", "duration_s", "gaze_lead_s")
MAX_PARTICIPANTS = 999


def cell_name(condition: str, fraction: float | None) -> str:
    """``"G"`` for gaze only, else the condition and the fraction in percent (``"GP60"``)."""
    if condition == "G" or fraction is None or (isinstance(fraction, float)
                                                and math.isnan(fraction)):
        return "G"
    return f"{condition}{round(float(fraction) * 100)}"


def participant_folder(index: int) -> str:
    """``participant_01`` for participant 1."""
    return f"participant_{index:02d}"


@dataclass(frozen=True)
class DesignSpec:
    """What ``experiment design`` builds.

    Attributes:
        participants: number of participants (trial lists).
        seed: seed of every random choice.
        conditions: cue conditions, a subset of :data:`CONDITIONS`.
        fractions: stopping fractions of the path length, each in (0, 1].
        goals: the goal set (default: NICO's seven targets).
        repeats: trials per target in each cell.
        incongruent_trials: trials of each ``I`` cell (default: ``repeats`` per target);
            targets cycle through the goal set in a shuffled order.
        layout: ``blocked`` or ``interleaved``.
        blocks: number of blocks of an interleaved layout.
        order: block order across participants, ``latin`` or ``fixed`` (the given order).
        incongruent_rule: one of :data:`INCONGRUENT_RULES`.
        practice: practice trials at the start (GP at the largest fraction), not analysed.
        method: the method whose trajectories the arm plays.
        duration_s: the arm's forward motion over the whole path [s] (truncated motions take
            their share of it).
        gaze_lead_s: the head moves this long before the arm [s].
    """

    participants: int = 20
    seed: int = 1
    conditions: tuple[str, ...] = CONDITIONS
    fractions: tuple[float, ...] = FRACTIONS
    goals: GoalSet | None = None
    repeats: int = 5
    incongruent_trials: int | None = None
    layout: str = "blocked"
    blocks: int = 5
    order: str = "latin"
    incongruent_rule: str = "nearest"
    practice: int = 3
    method: str = DEFAULT_METHOD
    duration_s: float | None = None
    gaze_lead_s: float | None = None
    head: Head = field(default_factory=load_head)

    def validate(self) -> None:
        """Refuse a bad value in one line naming it and what is allowed."""
        if not 1 <= self.participants <= MAX_PARTICIPANTS:
            raise InputError(f"--participants {self.participants}: give 1 to "
                             f"{MAX_PARTICIPANTS}")
        if not 0 <= self.seed < 2**63:
            raise InputError(f"--seed {self.seed}: give an integer in [0, 2^63)")
        check_conditions(self.conditions)
        check_fractions(self.fractions)
        for name, value, low in (("--repeats", self.repeats, 1), ("--practice", self.practice, 0),
                                 ("--blocks", self.blocks, 1)):
            if not low <= value <= 1000:
                raise InputError(f"{name} {value}: give an integer from {low} to 1000")
        if self.incongruent_trials is not None and not 1 <= self.incongruent_trials <= 1000:
            raise InputError(f"--incongruent-trials {self.incongruent_trials}: give 1 to 1000")
        for name, value, allowed in (("--layout", self.layout, LAYOUTS),
                                     ("--order", self.order, ORDERS),
                                     ("--incongruent-rule", self.incongruent_rule,
                                      INCONGRUENT_RULES)):
            if value not in allowed:
                raise InputError(f"{name} {value!r}: one of {', '.join(allowed)}")
        check_method(self.method)
        goals = self.goal_set
        if self.incongruent_rule == "authors" and "I" in self.conditions:
            missing = [t for t in goals.ids if t not in AUTHORS_PAIRS
                       or not set(AUTHORS_PAIRS[t]) <= set(goals.ids)]
            if missing:
                raise InputError(f"--incongruent-rule authors: the authors' pairs cover NICO's "
                                 f"targets 1-7; no pair for target(s) "
                                 f"{', '.join(map(str, missing))} in this goal set")
        for name, value in (("--duration", self.duration_s), ("--gaze-lead", self.gaze_lead_s)):
            if value is not None and not (math.isfinite(value) and 0 <= value <= 60):
                raise InputError(f"{name} {value}: give seconds in [0, 60]")
        if self.duration_s is not None and self.duration_s <= 0:
            raise InputError(f"--duration {self.duration_s}: give a positive time [s]")
        for target in goals.ids:
            self.head.gaze_at(goals.points_mm[goals.index(target)])  # refuses an unseen target

    @property
    def goal_set(self) -> GoalSet:
        return self.goals if self.goals is not None else load_goals()

    @property
    def cells(self) -> list[tuple[str, float | None]]:
        """(condition, fraction) of every cell, conditions in the given order."""
        out: list[tuple[str, float | None]] = []
        for condition in self.conditions:
            if condition == "G":
                out.append(("G", None))
            else:
                out.extend((condition, f) for f in self.fractions)
        return out


def check_method(name: str) -> str:
    """A registered, available method's name, or one line naming ``--method``."""
    from ikbench.methods.registry import method_status

    known = method_status()
    if name not in known or not known[name].available:
        usable = [n for n, status in known.items() if status.available]
        raise InputError(f"--method {name!r}: not an available method; available: "
                         f"{', '.join(usable)} (ikbench methods lists them all)")
    return name


def check_conditions(conditions: Sequence[str]) -> tuple[str, ...]:
    """The conditions, or one line naming an unknown or repeated one."""
    if not conditions:
        raise InputError("--conditions: give at least one of " + ", ".join(CONDITIONS))
    for c in conditions:
        if c not in CONDITIONS:
            raise InputError(f"--conditions: {c!r} is not a condition; allowed: "
                             + ", ".join(f"{k} ({v})" for k, v in CONDITION_NAMES.items()))
    if len(set(conditions)) != len(conditions):
        raise InputError(f"--conditions: {','.join(conditions)} names a condition twice")
    return tuple(conditions)


def check_fractions(fractions: Sequence[float]) -> tuple[float, ...]:
    """The fractions, or one line naming one outside (0, 1] or repeated."""
    if not fractions:
        raise InputError("--fractions: give at least one fraction in (0, 1]")
    for f in fractions:
        if not (isinstance(f, (int, float)) and math.isfinite(f) and 0 < f <= 1):
            raise InputError(f"--fractions: {f!r} is outside (0, 1] (the share of the path "
                             "at which the arm stops)")
    if len({round(f * 100) for f in fractions}) != len(fractions):
        raise InputError(f"--fractions: {fractions} repeats a fraction (cells are named in "
                         "whole percent)")
    return tuple(float(f) for f in fractions)


def parse_list(text: str, option: str) -> list[str]:
    """Comma-separated words, stripped; one line for an empty item."""
    items = [w.strip() for w in str(text).split(",")]
    if any(not w for w in items):
        raise InputError(f"{option}: {text!r} has an empty item")
    return items


def parse_fractions(text: str) -> tuple[float, ...]:
    """``"0.6,0.8"`` -> (0.6, 0.8), checked."""
    values = []
    for word in parse_list(text, "--fractions"):
        try:
            values.append(float(word))
        except ValueError:
            raise InputError(f"--fractions: {word!r} is not a number in (0, 1]") from None
    return check_fractions(values)


def williams_square(k: int) -> list[list[int]]:
    """Rows of a balanced Latin square of ``k`` items (Williams 1949): k rows for even k,
    2k for odd k (the square and its reversed rows)."""
    first, low, high = [0], 1, k - 1
    while len(first) < k:
        first.append(low)
        low += 1
        if len(first) < k:
            first.append(high)
            high -= 1
    rows = [[(x + r) % k for x in first] for r in range(k)]
    return rows if k % 2 == 0 else rows + [row[::-1] for row in rows]


def stop_of(robot: Robot, poses: np.ndarray, fraction: float
            ) -> tuple[np.ndarray, int, np.ndarray]:
    """Where the arm stops at ``fraction`` of the fingertip's path length.

    Returns:
        (the stop pose (dof,) [motor deg], the index of the last whole pose before it, the
        fingertip there (3,) [mm]).
    """
    points = robot.fk(poses).point_mm
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    goal = fraction * length[-1]
    step = int(np.clip(np.searchsorted(length, goal, side="right") - 1, 0, len(poses) - 2))
    span = length[step + 1] - length[step]
    t = 0.0 if span <= 0 else float(np.clip((goal - length[step]) / span, 0.0, 1.0))
    pose = poses[step] + t * (poses[step + 1] - poses[step])
    if fraction >= 1.0:
        pose, step = poses[-1].copy(), len(poses) - 1
    return pose, step, robot.fk(pose[None]).point_mm[0]


@dataclass(frozen=True)
class Design:
    """A built design: the trial list of every participant and what made them."""

    spec: DesignSpec
    trials: dict[str, pd.DataFrame]
    trajectories: dict[int, np.ndarray]
    record: dict

    def write(self, folder: str | Path) -> Path:
        """Write ``design.json``, ``trajectories/METHOD/trajectory_<id>.csv``,
        ``participant_XX/trials.csv`` and ``head_check.csv`` (the head's gaze against the
        authors' head poses), the folder whole or not at all."""
        answered = sorted(Path(folder).glob("participant_*/responses.csv"))
        if answered:
            raise InputError(f"{folder}: holds responses ({answered[0].relative_to(folder)}); "
                             "a design never replaces a study with answers: give a new "
                             "--output")
        robot = load_robot()
        with staged_folder(folder) as stage:
            for target, poses in self.trajectories.items():
                write_trajectory_csv(stage / trajectory_path(self.spec.method, target), robot,
                                     poses, self.spec.duration_s or self.spec.goal_set.duration_s)
            for name, table in self.trials.items():
                atomic_write_csv(stage / name / TRIALS_FILE, table)
            atomic_write_csv(stage / HEAD_CHECK_FILE, authors_comparison(self.spec.head, robot))
            atomic_write_json(stage / DESIGN_FILE, self.record)
        return Path(folder)


def trajectory_path(method: str, target: int) -> str:
    """The trajectory file of a target, relative to the design folder."""
    return f"{TRAJECTORIES}/{method}/trajectory_{target}.csv"


def solve_trajectories(robot: Robot, goals: GoalSet, method: str
                       ) -> tuple[dict[int, np.ndarray], dict[str, dict]]:
    """The arm's trajectory to every target by ``method``, with the contract's verdict."""
    solver = get_method(method)()
    tasks = line_tasks(robot, goals.targets)
    out, judged = {}, {}
    for target, task in zip(goals.ids, tasks):
        poses = np.asarray(solver.solve(robot, task).poses, float)
        contract = task.required.contract
        assert contract is not None                    # line_tasks gives every task one
        figures = contract_metrics(robot, task, poses, contract)
        verdict = judge(contract, figures)
        out[target] = poses
        judged[str(target)] = {"success": all(verdict.values()),
                               "failed": [k for k, ok in verdict.items() if not ok],
                               "line_distance_max_mm": float(figures["line_distance_max_mm"]),
                               "pointing_deviation_mean_deg":
                                   float(figures["pointing_deviation_mean_deg"])}
    return out, judged


def _gaze_target(spec: DesignSpec, goals: GoalSet, target: int, rng: np.random.Generator
                 ) -> int:
    others = [t for t in goals.ids if t != target]
    if spec.incongruent_rule == "authors":
        return int(rng.choice(AUTHORS_PAIRS[target]))
    if spec.incongruent_rule == "random":
        return int(rng.choice(others))
    here = goals.pixels[goals.index(target)]
    distance = np.array([np.linalg.norm(goals.pixels[goals.index(t)] - here) for t in others])
    nearest = [t for t, d in zip(others, distance) if d <= distance.min() + 1e-9]
    return int(rng.choice(nearest))


def _cell_targets(spec: DesignSpec, goals: GoalSet, condition: str, rng: np.random.Generator
                  ) -> list[int]:
    """The targets of one cell's trials, in rounds that show every target once, shuffled."""
    count = (spec.incongruent_trials if condition == "I" and spec.incongruent_trials
             else spec.repeats * len(goals.ids))
    order: list[int] = []
    while len(order) < count:
        order.extend(int(t) for t in rng.permutation(goals.ids))
    return order[:count]


def _row(spec: DesignSpec, goals: GoalSet, stops: dict, condition: str,
         fraction: float | None, target: int, gaze_target: int | None) -> dict:
    """One trial's columns but participant, trial, block and practice."""
    head = spec.head
    if condition == "P":
        head_pose = np.asarray(head.neutral_motor_deg, float)
    else:
        head_pose = head.gaze_at(goals.points_mm[goals.index(gaze_target or target)])
    duration = spec.duration_s or goals.duration_s
    if condition == "G":
        _, step, point = stops[(target, 0.0)]
        trajectory, share = "", 0.0
    else:
        assert fraction is not None
        _, step, point = stops[(target, fraction)]
        trajectory, share = trajectory_path(spec.method, target), fraction
    return {"condition": condition, "fraction": np.nan if fraction is None else fraction,
            "cell": cell_name(condition, fraction), "target": target,
            "gaze_target": gaze_target if condition != "P" else None,
            "head_z_motor_deg": round(float(head_pose[0]), 4),
            "head_y_motor_deg": round(float(head_pose[1]), 4),
            "target_x_px": float(goals.pixels[goals.index(target)][0]),
            "target_y_px": float(goals.pixels[goals.index(target)][1]),
            "trajectory": trajectory, "stop_step": step,
            "stop_x_mm": round(float(point[0]), 4), "stop_y_mm": round(float(point[1]), 4),
            "stop_z_mm": round(float(point[2]), 4),
            "duration_s": round(duration * share, 6),
            "gaze_lead_s": spec.gaze_lead_s if spec.gaze_lead_s is not None else goals.gaze_lead_s}


def _participant(spec: DesignSpec, goals: GoalSet, stops: dict, index: int) -> pd.DataFrame:
    rng = np.random.default_rng([spec.seed, index])
    cells = spec.cells
    square = williams_square(len(cells))
    order = square[(index - 1) % len(square)] if spec.order == "latin" else range(len(cells))
    rows: list[dict] = []
    for _ in range(spec.practice):
        target = int(rng.choice(goals.ids))
        condition = "GP" if "GP" in spec.conditions else spec.conditions[-1]
        fraction = None if condition == "G" else max(spec.fractions)
        rows.append({"block": 0, "practice": True,
                     **_row(spec, goals, stops, condition, fraction, target, target)})
    cell_trials = {}
    for condition, fraction in cells:
        trials = []
        for target in _cell_targets(spec, goals, condition, rng):
            gaze = _gaze_target(spec, goals, target, rng) if condition == "I" else target
            trials.append(_row(spec, goals, stops, condition, fraction, target, gaze))
        cell_trials[cell_name(condition, fraction)] = trials
    if spec.layout == "blocked":
        for block, c in enumerate(order, start=1):
            name = cell_name(*cells[c])
            rows.extend({"block": block, "practice": False, **t} for t in cell_trials[name])
    else:
        mixed = [t for c in order for t in cell_trials[cell_name(*cells[c])]]
        mixed = [mixed[i] for i in rng.permutation(len(mixed))]
        for i, chunk in enumerate(np.array_split(np.arange(len(mixed)), spec.blocks), start=1):
            rows.extend({"block": i, "practice": False, **mixed[j]} for j in chunk)
    table = pd.DataFrame(rows)
    table.insert(0, "participant", f"{index:02d}")
    table.insert(1, "trial", np.arange(1, len(table) + 1))
    table["gaze_target"] = table["gaze_target"].astype("Int64")
    return table[list(TRIAL_COLUMNS)]


def _check_speed(trajectories: dict[int, np.ndarray], duration_s: float) -> None:
    """Refuse a duration that drives a motor beyond its speed limit (the bus would refuse
    the motion in the middle of a study)."""
    from ikbench.hw.motors import load_motor_config

    limits = load_motor_config().max_speed_deg_s
    for target, poses in trajectories.items():
        speed = np.abs(np.diff(poses, axis=0)).max(axis=0) / (duration_s / (len(poses) - 1))
        if (speed > limits).any():
            joint = int(np.argmax(speed / limits))
            raise InputError(f"--duration {duration_s:g} s: trajectory {target} moves joint "
                             f"{joint + 1} at {speed[joint]:.0f} deg/s, above its motor's "
                             f"{limits[joint]:.0f} deg/s; give a longer --duration")


def build(spec: DesignSpec) -> Design:
    """Build the design (trajectories solved once, then every participant's trial list)."""
    spec.validate()
    robot = load_robot()
    goals = spec.goal_set
    trajectories, judged = solve_trajectories(robot, goals, spec.method)
    _check_speed(trajectories, spec.duration_s or goals.duration_s)
    stops = {}
    for target, poses in trajectories.items():
        stops[(target, 0.0)] = (poses[0], 0, robot.fk(poses[:1]).point_mm[0])
        for fraction in spec.fractions:
            stops[(target, fraction)] = stop_of(robot, poses, fraction)
    trials = {participant_folder(i): _participant(spec, goals, stops, i)
              for i in range(1, spec.participants + 1)}
    record = {
        "kind": "experiment-design",
        "participants": spec.participants, "seed": spec.seed,
        "conditions": list(spec.conditions), "fractions": list(spec.fractions),
        "cells": [cell_name(*c) for c in spec.cells],
        "repeats": spec.repeats, "incongruent_trials": spec.incongruent_trials,
        "layout": spec.layout, "blocks": spec.blocks if spec.layout == "interleaved" else None,
        "order": spec.order, "incongruent_rule": spec.incongruent_rule,
        "practice": spec.practice, "method": spec.method,
        "duration_s": spec.duration_s or goals.duration_s,
        "gaze_lead_s": spec.gaze_lead_s if spec.gaze_lead_s is not None else goals.gaze_lead_s,
        "response_window_s": goals.response_window_s,
        "fraction_rule": "share of the fingertip's path length (stop pose interpolated)",
        "goals": goals.describe(),
        "screen": {"size_px": list(goals.screen.size_px), "size_mm": list(goals.screen.size_mm),
                   "origin_mm": goals.screen.origin_mm.round(3).tolist(),
                   "u": goals.screen.u.round(6).tolist(), "v": goals.screen.v.round(6).tolist()},
        "viewpoint_mm": goals.viewpoint_mm.tolist(),
        "head": {"source": Path(spec.head.source).name,
                 "neutral_motor_deg": list(map(float, spec.head.neutral_motor_deg))},
        "trajectories": judged,
        "trials_per_participant": int((~trials[participant_folder(1)]["practice"]).sum()),
        "simulated": False,
        "provenance": provenance(),
    }
    return Design(spec, trials, trajectories, record)


def read_design(folder: str | Path) -> dict:
    """design.json of a design folder."""
    path = Path(folder) / DESIGN_FILE
    if not path.is_file():
        raise InputError(f"DIR {str(folder)!r} is not an experiment folder: no {DESIGN_FILE} "
                         "(make one with ikbench experiment design)")
    record = read_json(path, "design file")
    if record.get("kind") != "experiment-design":
        raise InputError(f"{path}: not an experiment design (kind {record.get('kind')!r})")
    return record


def read_trajectory(folder: str | Path, relative: str, robot: Robot) -> np.ndarray:
    """The poses (n+1, dof) [motor deg] of a trial's trajectory file."""
    return read_trajectory_poses(Path(folder) / relative, robot)
