"""Targets files: a start pose and named touch poses, in motor degrees.

Format (JSON)::

    {"joint_names": [...dof names, in the robot's order...],
     "start_pose": [...dof...],
     "targets": {"1": [...dof...], "2": [...], ...},
     "steps": 50,                      # optional, default 50
     "obstacles": [...] or "NAME",     # optional, default none
     "description": "..."}             # optional

Poses are in the robot's pose units (motor degrees for NICO; joint degrees, mm for prismatic
joints, for robots without a motor map). Target ids name files (``trajectory_<id>.csv``):
letters (any script's: ``résumé``), digits, ``_``, ``-`` and ``.`` (not first), as
:data:`ID_PATTERN` says; run names follow the same rule. Unknown keys are rejected (a
misspelt "steps" would otherwise be ignored silently). A robot config may name default
targets (``[targets]``); NICO's are the paper's seven touch poses, named ``paper``
(:data:`PAPER_TARGETS`).

``obstacles`` (optional) are put on every task made from the targets (``Task.obstacles``;
:func:`ikbench.core.task.line_tasks`), and ``ikbench compare`` then judges collisions: a list
in the obstacle file format of :mod:`ikbench.core.obstacles` (mm, degrees), or a string: a
named obstacle set of the robot's collision config (``"touchscreen"`` for NICO), an obstacle
file (``*.json``, ``*.yaml``; relative to the targets file's folder) or ``"none"``. Without the
key there are no obstacles.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ikbench.core.errors import InputError, TargetsError, refuse_unknown_keys
from ikbench.core.obstacles import load_file, named_sets, parse_obstacles
from ikbench.core.robot import Robot, load_robot

PAPER_TARGETS = "paper"
MIN_STEPS = 2
#: The largest number of segments n: 5000 poses already give a 2 s movement at 2.5 kHz, and
#: ours (Adam) would run for hours on more.
MAX_STEPS = 5000
KEYS = ("joint_names", "start_pose", "targets", "steps", "obstacles", "description")
#: A target id names files (trajectory_<id>.csv) and is chosen with --only "1,3".
#: A target id or a run name: it names a file or a folder, so letters and digits of any script
#: (what ``str.isalnum`` calls so), ``_``, then also ``-`` and ``.``; never a path separator,
#: a space or a leading dot.
ID_PATTERN = re.compile(r"\w[\w.-]*")


@dataclass(frozen=True)
class Targets:
    """A start pose and touch poses [pose units].

    Attributes:
        joint_names: joint order of every pose.
        start_pose: (dof,) start pose [pose units].
        touch_poses: trajectory id -> (dof,) touch (end) pose, in file order.
        steps: number of segments n (a trajectory has n + 1 poses).
        source: the name of a robot's default targets (``"paper"``), else the file path.
        shipped: the default targets document as shipped (None for other files).
        obstacles: the obstacles every task must keep clear of
            (:class:`ikbench.core.obstacles.Obstacle`, base frame); empty: none.
        obstacles_source: where the obstacles come from (a named set, a file, ``"list"`` for
            a list in the targets file); "" without obstacles.
    """

    joint_names: tuple[str, ...]
    start_pose: np.ndarray
    touch_poses: dict[str, np.ndarray]
    steps: int
    source: str
    shipped: dict | None = None
    obstacles: tuple = ()
    obstacles_source: str = ""

    @property
    def is_default(self) -> bool:
        """True for a robot's shipped targets with their start pose and touch poses unchanged."""
        if self.shipped is None:
            return False
        spec = self.shipped
        return (np.array_equal(self.start_pose, np.asarray(spec["start_pose"], float))
                and all(np.array_equal(pose, np.asarray(spec["targets"][key], float))
                        for key, pose in self.touch_poses.items()))

    @property
    def is_paper(self) -> bool:
        """True for the paper's targets and start pose (reports then show the paper's values
        beside the measured ones, with a note where n differs); False once either is changed."""
        return self.source == PAPER_TARGETS and self.is_default

    @property
    def ids(self) -> list[str]:
        """Trajectory ids in file order."""
        return list(self.touch_poses)

    def select(self, only: str | list[str] | None) -> Targets:
        """Keep only the given trajectory ids (``"1,3"`` or a list); None keeps all."""
        if only is None:
            return self
        wanted = [s.strip() for s in only.split(",")] if isinstance(only, str) else list(only)
        unknown = [w for w in wanted if w not in self.touch_poses]
        if "" in wanted:
            raise TargetsError(f"only: {only!r} names an empty trajectory id; give ids such "
                               f"as 1,3 (available: {', '.join(self.ids)})")
        if unknown or not wanted:
            raise TargetsError(
                f"only: unknown trajectory id(s) {', '.join(map(repr, unknown)) or repr(only)}; "
                f"available: {', '.join(self.ids)}"
            )
        poses = {k: self.touch_poses[k] for k in dict.fromkeys(wanted)}
        return replace(self, touch_poses=poses)

    def with_steps(self, steps: int | None) -> Targets:
        """A copy with another number of segments (None keeps the file's)."""
        if steps is None:
            return self
        _check_steps(steps, "steps")
        return replace(self, steps=steps)

    def with_obstacles(self, obstacles: tuple, source: str) -> Targets:
        """A copy with other obstacles (``--obstacles``; empty: none) from ``source``."""
        obstacles = tuple(obstacles)
        return replace(self, obstacles=obstacles, obstacles_source=source if obstacles else "")


def _check_steps(steps, what: str) -> int:
    if isinstance(steps, bool) or not isinstance(steps, int) or not \
            MIN_STEPS <= steps <= MAX_STEPS:
        raise TargetsError(f"{what}: steps = {steps!r} must be an integer in [{MIN_STEPS}, "
                           f"{MAX_STEPS}]")
    return steps


def _check_pose(robot: Robot, value, what: str) -> np.ndarray:
    if not isinstance(value, list) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    ):
        raise TargetsError(
            f"{what}: {value!r} is not a list of {robot.dof} numbers ({robot.pose_unit})"
        )
    try:
        return robot.check_pose(value, what)
    except TargetsError:
        raise
    except Exception as exc:  # InputError from the robot: re-raise as a targets error
        raise TargetsError(str(exc)) from None


def parse_targets_obstacles(value: object, robot: Robot, where: str,
                            folder: Path | None = None) -> tuple[tuple, str]:
    """(obstacles, source) of a targets file's ``obstacles`` value: a list in the obstacle
    file format, a named set of ``robot`` (``"touchscreen"``), an obstacle file (relative to
    ``folder``, the targets file's) or ``"none"``; :class:`TargetsError` naming the bad value."""

    here = f"{where}: obstacles"
    try:
        if isinstance(value, list):
            return parse_obstacles(value, here), "list"
        if not isinstance(value, str) or not value.strip():
            raise TargetsError(f"{here}: {value!r} must be a list of obstacles (mm, see "
                               "docs/collisions.md), a named obstacle set of the robot, an "
                               "obstacle file (*.json, *.yaml) or 'none'")
        text = value.strip()
        if text.lower() == "none":
            return (), ""
        sets = named_sets(robot)
        if text in sets:
            return parse_obstacles(load_file(sets[text]), str(sets[text])), text
        path = Path(text)
        if not path.is_absolute() and folder is not None:
            path = folder / path
        if path.suffix.lower() not in (".json", ".yaml", ".yml"):
            named = f"a named set of {robot.name} ({', '.join(sets)}), " if sets else ""
            raise TargetsError(f"{here}: {text!r} is neither {named}nor an obstacle file "
                               "(*.json, *.yaml), nor none")
        if not path.is_file():
            raise TargetsError(f"{here}: file {str(path)!r} not found (a relative path is "
                               "relative to the targets file's folder)")
        return parse_obstacles(load_file(path), str(path)), text
    except TargetsError:
        raise
    except InputError as exc:  # the obstacle parser's message, already naming the entry
        raise TargetsError(str(exc)) from None


def parse_targets(spec: dict, robot: Robot, source: str, folder: Path | None = None) -> Targets:
    """Validate a parsed targets document; raise :class:`TargetsError` naming the bad entry.
    ``folder``: where a relative obstacle file is looked for (the targets file's folder)."""
    where = "targets file" if source == PAPER_TARGETS else source
    if not isinstance(spec, dict):
        raise TargetsError(f"{where}: top level must be a JSON object")
    refuse_unknown_keys(spec, KEYS, where, TargetsError)
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
    if "obstacles" not in spec:
        return Targets(robot.joint_names, start, poses, steps, source)
    obstacles, origin = parse_targets_obstacles(spec["obstacles"], robot, where, folder)
    return Targets(robot.joint_names, start, poses, steps, source, obstacles=obstacles,
                   obstacles_source=origin if obstacles else "")


def _reject_duplicate_keys(pairs):
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise TargetsError(f"duplicate key {key!r}")
        seen[key] = value
    return seen


def default_targets(robot: Robot) -> tuple[Path, str]:
    """(file, name) of the robot's default targets; TargetsError if it ships none."""
    entry = robot.config.targets
    if entry.file is None:
        raise TargetsError(f"targets: robot {robot.name} ships no default targets; give a "
                           f"targets file (start and touch poses in {robot.pose_unit}, joints "
                           f"{', '.join(robot.joint_names)})")
    folder = robot.config.folder or robot.urdf_path.parent
    return folder / entry.file, str(entry.name or "default")


def load_targets(path: str | Path | None = None, robot: Robot | None = None) -> Targets:
    """Load and validate a targets file; ``None`` (or the default's name, ``"paper"`` for
    NICO) gives the robot's default targets."""
    robot = robot or load_robot()
    shipped = None
    default_name = robot.config.targets.name
    if path is None or (default_name and str(path) == default_name):
        file, source = default_targets(robot)
        text = file.read_text(encoding="utf-8")
        shipped = json.loads(text)
        folder = file.parent
    else:
        source = str(path)
        folder = Path(path).parent
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise TargetsError(f"targets: cannot read targets file {source!r}: "
                               f"{getattr(exc, 'strerror', None) or exc}") from None
    try:
        # NaN/Infinity parse as floats; check_pose then names the target and joint
        spec = json.loads(text, object_pairs_hook=_reject_duplicate_keys)
    except TargetsError as exc:
        raise TargetsError(f"{source}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise TargetsError(f"{source}: not valid JSON ({exc})") from None
    return replace(parse_targets(spec, robot, source, folder), shipped=shipped)


def select_targets(targets: str | Path | Targets | None, robot: Robot,
                   only: str | list[str] | None = None,
                   steps: int | None = None) -> Targets:
    """``targets`` (a file, :class:`Targets` or None for the robot's own) with the trajectory
    ids ``only`` (``"1,3"``) and ``steps`` segments (None keeps the file's)."""
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    return targets.select(only).with_steps(steps)


def pose_words(robot: Robot) -> str:
    """``motor angles`` (NICO) or ``joint values [joint deg, mm for prismatic]``."""
    return "motor angles" if robot.has_motor_map else f"joint values [{robot.pose_unit}]"


def parse_pose(text: str, robot: Robot | None = None, what: str = "pose") -> np.ndarray:
    """Parse ``"a,b,c,..."`` (pose units) into a validated pose."""
    robot = robot or load_robot()
    parts = [p.strip() for p in str(text).split(",")]
    values = []
    for part in parts:
        try:
            value = float(part)
        except ValueError:
            raise TargetsError(
                f"{what}: {part!r} is not a number; give {robot.dof} comma-separated "
                f"{pose_words(robot)} ({', '.join(robot.joint_names)})"
            ) from None
        if not math.isfinite(value):
            raise TargetsError(f"{what}: {part!r} is not a finite number")
        values.append(value)
    try:
        return robot.check_pose(values, what)
    except Exception as exc:
        raise TargetsError(str(exc)) from None
