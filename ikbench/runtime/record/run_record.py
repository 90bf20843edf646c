"""``run.json``, typed: :class:`RunRecord` writes it and reads it back (old files too).

A run.json says what ran (the command, the method and its settings, or a study's methods),
on what (the robot, the task source, the trajectories, the shape, obstacles), what it wrote
(``files``), how long it took and where (provenance: machine, versions, git revision). Its keys
and their order are a file format users read, so they stay as they were: each kind of record
has its layout (:data:`LAYOUTS`); a study's own keys (compare's contract, the ablation's
variants) sit in :attr:`RunRecord.study`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.obstacles import Obstacle, parse_obstacles
from ikbench.core.provenance import KEYS as provenance_keys
from ikbench.core.robot import Robot, load_robot, shipped_robots
from ikbench.core.targets import Targets, load_targets

if TYPE_CHECKING:
    from ikbench.core.task import Task

#: Stands for the provenance's keys in a layout (:func:`ikbench.core.provenance.provenance`).
PROVENANCE = "*provenance"
#: The keys :func:`ikbench.core.provenance.provenance` writes (read back into
#: :attr:`RunRecord.provenance`).
PROVENANCE_KEYS = provenance_keys
#: Each kind's run.json keys, in the order written; a key ending in ``?`` is left out when
#: its value is None. A key that is no field of :class:`RunRecord` lives in its ``study``.
LAYOUTS: dict[str, tuple[str, ...]] = {
    # one method's run folder: ikbench run, letters, compare's per-method folders
    "run": ("method", "name", "library", "robot", "targets", "trajectories", "failed", "steps",
            "shape", "direction", "size_mm", "start_pose_deg", "task_default_weights",
            "duration_s", "interrupted", "settings", "runtime?", "total_wall_time_s", "files",
            PROVENANCE,
            "problem?", "problem_name?", "obstacles?"),
    # ikbench compare's folder
    "compare": ("methods", "reference", "repeat", "warmup", "robot", "targets", "trajectories",
                "steps", "contract", "tolerances", "schemes", "runtimes?", "identical?",
                "libraries", PROVENANCE,
                "obstacles?", "total_wall_time_s?"),
    # ikbench ablate's folder
    "ablation": ("method", "robot", "targets", "trajectories", "steps", "figure_trajectory",
                 "variants", "total_wall_time_s", PROVENANCE),
    # ikbench cartesian's folder
    "cartesian": ("command", "problems", "methods", "seeds", "settings", "options", "validity",
                  "validity_source", "wall_time_s", "files", PROVENANCE),
    # ikbench ik's folder: methods by name with their facts, provenance as one entry
    # (init_model: the learned model of --init learned, null for every other init)
    "ik": ("command", "robot", "settings", "methods", "batched?", "init_model",
           "solution_columns?", "library_versions", "wall_s", "load_average", "provenance"),
    # ikbench recommend's folder: its plan and verdict before the timing and provenance
    "recommend": ("command", "robot", "settings", "plan", "methods", "recommended", "tied",
                  "kendall_tau", "paired?", "wall_s", "load_average", "library_versions",
                  "provenance"),
}


@dataclass
class RunRecord:
    """A run folder's run.json.

    Attributes:
        kind: its layout in :data:`LAYOUTS` (not written; told from the keys on reading).
        command: the command line (studies that record it).
        method: the registered method that ran (a method's run, an ablation).
        name: the run's folder name (``sequential-ik-position``).
        library: the method's library.
        methods: the methods a study ran (compare, cartesian).
        settings: the method's settings as written (``{"settings": {...}}``; see
            :meth:`method_settings`).
        runtime: what ran the solves (:meth:`ikbench.methods.base.Method.runtime`: the
            backend, numba / numpy / torch or the library, and its threads); None in older
            files.
        robot: the robot as :func:`robot_entry` describes it (None: written before robots
            were recorded, NICO's right arm).
        targets: the task source: a targets file, ``paper``, a problem's robot targets.
        trajectories: the trajectory ids, in order (None: the file lists none).
        failed: the ids whose solve failed.
        steps: number of segments n.
        shape: ``line``, ``letter:P``, ``path`` (a problem), ...
        direction: the goal directions asked for (None: the shape's own).
        size_mm: letter height [mm] (None: the default).
        start_pose_deg: (dof,) start pose [pose units].
        task_default_weights: the loss weights the tasks ask for (letters), or None.
        problem, problem_name: a Cartesian path problem's label and name.
        obstacles: the tasks' obstacles (:func:`obstacles_entry`; compare writes
            ``{"source", "items"}``), None when there are none.
        duration_s: movement duration T [s] of the trajectory files.
        interrupted: Ctrl-C ended the solves (the folder holds those solved before).
        total_wall_time_s: the run's wall time [s].
        files: the files the run wrote (relative names), None for older runs.
        provenance: machine, versions, git revision, creation time.
        study: a study's own keys (compare: reference, repeat, warmup, contract, tolerances,
            schemes, runtimes, identical (groups of methods whose trajectories are equal),
            libraries; ablation: figure_trajectory, variants; ...) and keys this
            version does not know.
        absent: the layout's keys (those always written) that the file read lacked: written
            before they were recorded, their fields hold defaults. Not written.
    """

    kind: str = "run"
    command: str | None = None
    method: str | None = None
    name: str | None = None
    library: str | None = None
    methods: list[str] | None = None
    settings: dict[str, Any] | None = None
    runtime: dict[str, Any] | None = None
    robot: dict[str, Any] | None = None
    targets: str | None = None
    trajectories: list[str] | None = None
    failed: list[str] = field(default_factory=list)
    steps: int | None = None
    shape: str = "line"
    direction: Any = None
    size_mm: float | None = None
    start_pose_deg: list[float] | None = None
    task_default_weights: dict[str, float] | None = None
    problem: str | None = None
    problem_name: str | None = None
    obstacles: list[Any] | dict[str, Any] | None = None
    duration_s: float | None = None
    interrupted: bool = False
    total_wall_time_s: float | None = None
    files: list[str] | None = None
    provenance: dict[str, Any] = field(default_factory=dict)
    study: dict[str, Any] = field(default_factory=dict)
    absent: frozenset[str] = field(default=frozenset(), compare=False, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """run.json's content: the keys of :data:`LAYOUTS` for this kind, in order, then
        any other key of :attr:`study`."""
        layout = LAYOUTS[self.kind]
        out: dict[str, Any] = {}
        for entry in layout:
            if entry == PROVENANCE:
                out.update(self.provenance)
                continue
            key = entry.rstrip("?")
            if key in self.study:  # a study's own meaning of the key (ik's methods mapping)
                value = self.study[key]
            elif key in _FIELDS:
                value = getattr(self, key)
            else:
                continue
            if value is None and entry.endswith("?"):
                continue
            out[key] = value
        out.update({k: v for k, v in self.study.items() if k not in out})
        return out

    def to_json(self) -> str:
        """run.json's text (2-space indent, a final newline)."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunRecord:
        """The record of a run.json's content, of any version: missing keys take their
        defaults, unknown ones go to :attr:`study`."""
        typed = {k: v for k, v in data.items() if k in _FIELDS}
        if not isinstance(typed.get("methods", []), list):  # ik's: a mapping, the study's own
            del typed["methods"]
        trajectories = typed.get("trajectories")
        typed["trajectories"] = ([str(t) for t in trajectories]
                                 if isinstance(trajectories, list) else None)
        typed["failed"] = [str(t) for t in typed.get("failed") or []]
        if not isinstance(typed.get("files"), list):
            typed["files"] = None
        kind = _kind_of(data)
        absent = frozenset(k for k in LAYOUTS[kind]
                           if k != PROVENANCE and not k.endswith("?")) - set(data)
        # the ik layout keeps provenance as one entry: its load_average is the study's own
        flat = PROVENANCE in LAYOUTS[kind]
        provenance = {k: data[k] for k in PROVENANCE_KEYS if k in data} if flat else {}
        return cls(kind=kind, **typed, absent=absent, provenance=provenance,
                   study={k: v for k, v in data.items()
                          if k not in typed and k not in provenance})

    def method_settings(self) -> dict[str, Any]:
        """The method's settings (``{"settings": {...}}`` unwrapped, or flat), or {}."""
        settings = self.settings or {}
        settings = settings.get("settings", settings) if isinstance(settings, dict) else {}
        return settings if isinstance(settings, dict) else {}

    def load_robot(self) -> Robot:
        """The robot the record names (:func:`robot_from_record`)."""
        return robot_from_record(self)

    def run_targets(self, robot: Robot) -> Targets:
        """The targets the run solved: its task source (:attr:`targets`, loaded again) with
        its own start pose (``--start-pose`` may have replaced the file's).

        Raises:
            InputError: the targets file cannot be loaded from here.
        """
        targets = load_targets(self.targets, robot)
        if self.start_pose_deg:
            targets = replace(targets, start_pose=np.asarray(self.start_pose_deg,
                                                                 dtype=float))
        return targets

    def trajectory_obstacles(self, ids: Sequence[str], where: str = "run.json obstacles"
                             ) -> tuple[tuple[Obstacle, ...], dict[str, tuple[Obstacle, ...]]]:
        """The obstacles of :attr:`obstacles`: (those every trajectory shares, each
        trajectory's by id). A list (or compare's ``{"source", "items"}``) is shared by all;
        a mapping gives each trajectory its own (none shared).

        Raises:
            InputError: the entry is not a list or a mapping of obstacle lists (``where``
                names it).
        """
        entry = self.obstacles
        if not entry:  # older run folders, runs without obstacles
            return (), {tid: () for tid in ids}
        if isinstance(entry, dict) and isinstance(entry.get("source"), str) and set(entry) == {
                "source", "items"}:  # ikbench compare's record
            entry = entry["items"]
        if isinstance(entry, list):
            shared = parse_obstacles(entry, where)
            return shared, {tid: shared for tid in ids}
        if not isinstance(entry, dict):
            raise InputError(f"{where}: expected a list of obstacles or a mapping from "
                             f"trajectory id to one, got {type(entry).__name__}")
        return (), {tid: parse_obstacles(entry[tid], f"{where} of trajectory {tid}")
                    if entry.get(tid) else () for tid in ids}


_FIELDS = {f.name for f in dataclasses.fields(RunRecord)} - {"kind", "provenance", "study",
                                                             "absent"}


def _kind_of(data: dict[str, Any]) -> str:
    """The layout of a run.json's content, told from its keys."""
    if "variants" in data:
        return "ablation"
    if "reference" in data and "methods" in data:
        return "compare"
    if "problems" in data and "command" in data:
        return "cartesian"
    if "recommended" in data and "plan" in data:
        return "recommend"
    if "library_versions" in data and "command" in data:
        return "ik"
    return "run"


def jsonable(value: Any) -> Any:
    """``value`` (settings: dataclasses, arrays, paths) as plain JSON values: arrays as
    lists, objects as their attributes, anything else as its text."""
    def default(item: Any) -> Any:
        if isinstance(item, np.ndarray):
            return item.tolist()
        if hasattr(item, "__dict__"):
            return vars(item)
        return str(item)

    return json.loads(json.dumps(value, default=default))


def robot_entry(robot: Robot) -> dict[str, Any]:
    """How run.json names the robot: enough to load it again (:func:`robot_from_record`).
    A shipped robot by its name (not the path of the machine that wrote the run), any other
    by its config or URDF path."""
    config = str(robot.config.config_path) if robot.config.config_path else None
    spec = config if config else str(robot.urdf_path)
    shipped = shipped_robots().get(robot.name)
    if config and shipped is not None and Path(config).resolve() == shipped.resolve():
        spec = robot.name
    return {**robot.describe(), "spec": spec}


def robot_from_record(record: RunRecord | dict[str, Any]) -> Robot:
    """The robot a run.json names (NICO for runs written before robots were recorded).

    Raises:
        InputError: the robot cannot be loaded, or its URDF changed since the run.
    """
    entry = record.robot if isinstance(record, RunRecord) else record.get("robot")
    if not isinstance(entry, dict):
        return load_robot()
    name, spec = entry.get("name"), entry.get("spec")
    if name in shipped_robots():
        spec = name
    robot = load_robot(str(spec), entry.get("end_frame"))
    if entry.get("urdf_sha256") and entry["urdf_sha256"] != robot.urdf_sha256:
        raise InputError(f"the URDF of robot {name!r} ({robot.urdf_path}) changed since this "
                         "run was written (sha256 differs); rerun it")
    return robot


def obstacles_entry(tasks: Sequence[Task]) -> list[Any] | dict[str, Any] | None:
    """How run.json records the tasks' obstacles (``Obstacle.to_dict`` items, base frame,
    mm): one list when every task has the same ones (a problem's), else a mapping from
    trajectory id to its list (tasks without obstacles left out); None when no task has any.
    :meth:`RunRecord.trajectory_obstacles` reads it back."""
    items = {t.name: [o.to_dict() for o in t.required.obstacles] for t in tasks}
    if not any(items.values()):
        return None
    lists = list(items.values())
    if all(entry == lists[0] for entry in lists):
        return lists[0]
    return {name: entry for name, entry in items.items() if entry}
