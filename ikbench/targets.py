"""Targets files: a start pose and named touch poses, in motor degrees.

Format (JSON)::

    {"joint_names": [...dof names, in the robot's order...],
     "start_pose": [...dof...],
     "targets": {"1": [...dof...], "2": [...], ...},
     "steps": 50,                      # optional, default 50
     "description": "..."}             # optional

Target ids name files (``trajectory_<id>.csv``): letters, digits, ``_``, ``-`` and ``.``.
Unknown keys are rejected (a misspelt "steps" would otherwise be ignored silently).
The paper's seven touch poses ship as the default (:data:`PAPER_TARGETS`).
"""

from __future__ import annotations

import functools
import json
import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ikbench.errors import TargetsError
from ikbench.robot import Robot, load_robot

PAPER_TARGETS = "paper"
MIN_STEPS = 2
KEYS = ("joint_names", "start_pose", "targets", "steps", "description")
#: A target id names files (trajectory_<id>.csv) and is chosen with --only "1,3".
ID_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class Targets:
    """A start pose and touch poses [motor deg].

    Attributes:
        joint_names: joint order of every pose.
        start_pose_deg: (dof,) start pose.
        touch_poses_deg: trajectory id -> (dof,) touch (end) pose, in file order.
        steps: number of segments n (a trajectory has n + 1 poses).
        source: ``"paper"`` for the shipped targets, else the file path.
    """

    joint_names: tuple[str, ...]
    start_pose_deg: np.ndarray
    touch_poses_deg: dict[str, np.ndarray]
    steps: int
    source: str

    @property
    def is_paper(self) -> bool:
        """True for the paper's targets and start pose (reports then show the paper's values
        beside the measured ones, with a note where n differs); False once either is changed."""
        if self.source != PAPER_TARGETS:
            return False
        paper = _paper_spec()
        return (np.array_equal(self.start_pose_deg, np.asarray(paper["start_pose"], float))
                and all(np.array_equal(pose, np.asarray(paper["targets"][key], float))
                        for key, pose in self.touch_poses_deg.items()))

    @property
    def ids(self) -> list[str]:
        """Trajectory ids in file order."""
        return list(self.touch_poses_deg)

    def select(self, only: str | list[str] | None) -> Targets:
        """Keep only the given trajectory ids (``"1,3"`` or a list); None keeps all."""
        if only is None:
            return self
        wanted = [s.strip() for s in only.split(",")] if isinstance(only, str) else list(only)
        unknown = [w for w in wanted if w not in self.touch_poses_deg]
        if "" in wanted:
            raise TargetsError(f"--only: {only!r} names an empty trajectory id; give ids such "
                               f"as 1,3 (available: {', '.join(self.ids)})")
        if unknown or not wanted:
            raise TargetsError(
                f"--only: unknown trajectory id(s) {', '.join(map(repr, unknown)) or repr(only)}; "
                f"available: {', '.join(self.ids)}"
            )
        poses = {k: self.touch_poses_deg[k] for k in dict.fromkeys(wanted)}
        return Targets(self.joint_names, self.start_pose_deg, poses, self.steps, self.source)

    def with_steps(self, steps: int | None) -> Targets:
        """A copy with another number of segments (None keeps the file's)."""
        if steps is None:
            return self
        _check_steps(steps, "--steps")
        return Targets(self.joint_names, self.start_pose_deg, self.touch_poses_deg, steps,
                       self.source)


def _check_steps(steps, what: str) -> int:
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < MIN_STEPS:
        raise TargetsError(f"{what}: steps = {steps!r} must be an integer >= {MIN_STEPS}")
    return steps


def _check_pose(robot: Robot, value, what: str) -> np.ndarray:
    if not isinstance(value, list) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    ):
        raise TargetsError(
            f"{what}: {value!r} is not a list of {robot.dof} numbers (motor degrees)"
        )
    try:
        return robot.check_pose(value, what)
    except TargetsError:
        raise
    except Exception as exc:  # InputError from the robot: re-raise as a targets error
        raise TargetsError(str(exc)) from None


def parse_targets(spec: dict, robot: Robot, source: str) -> Targets:
    """Validate a parsed targets document; raise :class:`TargetsError` naming the bad entry."""
    where = "targets file" if source == PAPER_TARGETS else source
    if not isinstance(spec, dict):
        raise TargetsError(f"{where}: top level must be a JSON object")
    unknown = [k for k in spec if k not in KEYS]
    if unknown:
        raise TargetsError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; "
                           f"allowed: {', '.join(KEYS)}")
    missing = [k for k in ("joint_names", "start_pose", "targets") if k not in spec]
    if missing:
        raise TargetsError(
            f"{where}: missing key(s) {', '.join(missing)}; required: joint_names, start_pose, "
            "targets (steps, description optional)"
        )
    names = spec["joint_names"]
    if not isinstance(names, list) or tuple(names) != robot.joint_names:
        raise TargetsError(
            f"{where}: joint_names {names!r} must be exactly {list(robot.joint_names)}"
        )
    start = _check_pose(robot, spec["start_pose"], f"{where}: start_pose")
    targets = spec["targets"]
    if not isinstance(targets, dict) or not targets:
        raise TargetsError(f"{where}: targets must be a non-empty object of id -> pose")
    poses = {}
    for key, value in targets.items():
        if not ID_PATTERN.fullmatch(key):
            raise TargetsError(f"{where}: target id {key!r} is not allowed; ids are letters, "
                               "digits, '_', '-' and '.' (not first), as they name files")
        if key in poses:
            raise TargetsError(f"{where}: duplicate target id {key!r}")
        poses[key] = _check_pose(robot, value, f"{where}: target {key!r}")
    steps = _check_steps(spec.get("steps", 50), f"{where}")
    return Targets(robot.joint_names, start, poses, steps, source)


def _reject_duplicate_keys(pairs):
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise TargetsError(f"duplicate key {key!r}")
        seen[key] = value
    return seen


@functools.lru_cache(maxsize=1)
def _paper_spec() -> dict:
    return json.loads(resources.files("ikbench").joinpath("data/paper_targets.json").read_text())


def load_targets(path: str | Path | None = None, robot: Robot | None = None) -> Targets:
    """Load and validate a targets file; ``None`` or ``"paper"`` gives the paper's targets."""
    robot = robot or load_robot()
    if path is None or str(path) == PAPER_TARGETS:
        text = resources.files("ikbench").joinpath("data/paper_targets.json").read_text()
        source = PAPER_TARGETS
    else:
        source = str(path)
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise TargetsError(f"cannot read targets file {source!r}: {exc}") from None
    try:
        # NaN/Infinity parse as floats; check_pose then names the target and joint
        spec = json.loads(text, object_pairs_hook=_reject_duplicate_keys)
    except TargetsError as exc:
        raise TargetsError(f"{source}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise TargetsError(f"{source}: not valid JSON ({exc})") from None
    return parse_targets(spec, robot, source)


def parse_pose(text: str, robot: Robot | None = None, what: str = "--pose") -> np.ndarray:
    """Parse ``"a,b,c,..."`` (motor degrees) into a validated pose."""
    robot = robot or load_robot()
    parts = [p.strip() for p in str(text).split(",")]
    values = []
    for part in parts:
        try:
            value = float(part)
        except ValueError:
            raise TargetsError(
                f"{what}: {part!r} is not a number; give {robot.dof} comma-separated motor "
                f"angles ({', '.join(robot.joint_names)})"
            ) from None
        if not math.isfinite(value):
            raise TargetsError(f"{what}: {part!r} is not a finite number")
        values.append(value)
    try:
        return robot.check_pose(values, what)
    except Exception as exc:
        raise TargetsError(str(exc)) from None
