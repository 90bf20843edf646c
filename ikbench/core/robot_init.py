"""From a URDF to a robot config and targets file (``ikbench robot init``): a new robot with no
hand-written file.

:func:`init_robot` reads the URDF (a path, or a robot of an installed description package by
its name, ``example-robot-data:z1``), chooses the chain, the pointing axis, a start pose and
touch targets, and returns a config (``<name>.toml``, the keys of :data:`ikbench.core.robot.
CONFIG_KEYS`) and a targets file (``<name>.targets.json``) that ``letters``, ``run --shape``,
``run``, ``compare`` and ``view`` take as they are:

- **End frame**: ``end_frame`` or, when none is given, of the URDF's candidates (leaf links,
  then tool-like names: :meth:`ikbench.core.urdf_model.UrdfModel.end_frame_candidates`) those
  whose chain from the base has at least :data:`MIN_JOINTS` moving joints, the one with the
  fewest (an arm without its gripper's jaws), and of equals the deepest (a fixed tool frame
  after the flange). The choice and the other candidates are said.
- **Pointing axis**: ``pointing_axis`` (``x``, ``y``, ``z``, ``-x``, ...), the end frame's
  axis that points; ``auto`` (default): the end frame's axis nearest the direction from the
  last moving joint's origin to the end frame's origin at the zero configuration, when that
  offset is at least :data:`MIN_OFFSET_MM` long and within 35 deg of the axis (the tool sticks
  out along it), else ``z``.
- **Start pose**: ``start_pose``, or the middle of every joint's limits (continuous joints at 0).
- **Touch targets**: :data:`COUNT` poses drawn by ``numpy.random.default_rng(seed)`` within
  :data:`REACH_DEG` (joint degrees, mm for prismatic joints) of the start pose and within the
  limits, kept when the line from the start point to their end point is
  :data:`MIN_LINE_MM`..:data:`MAX_LINE_MM` long: lines of a size an arm draws, on the start
  pose's IK branch (a line can join them without a flip). Reachability of every point of the
  line is not checked here: the comparison judges it.
- **Letters**: on the plane through the start point across the pointing direction (u: the
  viewer's right, v: up as far as the pointing allows).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot, load_robot
from ikbench.core.robot_packages import is_package_name, resolve
from ikbench.core.urdf_model import load_urdf_model

#: The fewest moving joints an end frame's chain may have to be chosen without --end-frame.
MIN_JOINTS = 3
#: Touch targets drawn, at most this far from the start pose on every joint [deg, mm].
COUNT, REACH_DEG = 7, 30.0
#: A touch target's line from the start point is this long [mm].
MIN_LINE_MM, MAX_LINE_MM = 80.0, 400.0
#: Candidates drawn at most before giving up.
DRAWS = 20_000
#: ``--pointing-axis`` words -> axes of the end frame.
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
        "-x": (-1.0, 0.0, 0.0), "-y": (0.0, -1.0, 0.0), "-z": (0.0, 0.0, -1.0)}
#: Segments of every line.
STEPS = 50
#: ``auto`` pointing axis: the last offset must be this long [mm] and this close to an axis.
MIN_OFFSET_MM, AXIS_COS = 1.0, 0.82


def auto_axis(robot: Robot) -> str:
    """The ``auto`` pointing axis of ``robot`` (see the module docstring)."""
    import pinocchio as pin

    fk = robot.pinocchio_fk()
    data = fk.model.createData()
    pin.framesForwardKinematics(fk.model, data, pin.neutral(fk.model))
    end = data.oMf[fk.frame_id]
    offset = end.rotation.T @ (end.translation - data.oMi[fk.model.njoints - 1].translation)
    length = float(np.linalg.norm(offset))
    if length * 1000.0 < MIN_OFFSET_MM:
        return "z"
    k = int(np.argmax(np.abs(offset)))
    if abs(offset[k]) / length < AXIS_COS:
        return "z"
    return ("-" if offset[k] < 0 else "") + "xyz"[k]


def pointing_axis(word: str) -> tuple[float, float, float]:
    """The axis a ``--pointing-axis`` word names; InputError naming the allowed words."""
    if word not in AXES:
        raise InputError(f"--pointing-axis: {word!r} is not one of auto, {', '.join(AXES)}")
    return AXES[word]


def choose_end_frame(urdf_path: Path, base_link: str | None) -> tuple[str, list[str]]:
    """(the end frame chosen, every candidate) of a URDF (see the module docstring)."""
    model = load_urdf_model(urdf_path)
    base = base_link or model.root_link
    candidates = list(model.end_frame_candidates(base))
    moving = {}
    for link in candidates:
        path = model.path_between(base, link)
        count = sum(j.type in ("revolute", "continuous", "prismatic") for j in path)
        if count >= MIN_JOINTS:
            moving[link] = (count, -len(path))
    if not moving:
        raise InputError(f"--end-frame: no link of {urdf_path.name} has a chain of at least "
                         f"{MIN_JOINTS} moving joints from {base!r}; give one "
                         f"({model.candidates_text(base)})")
    return min(moving, key=lambda link: moving[link]), candidates


def draw_targets(robot: Robot, start: np.ndarray, seed: int, count: int = COUNT
                 ) -> list[np.ndarray]:
    """``count`` touch poses [pose units] (see the module docstring); InputError when the
    draws find fewer."""
    rng = np.random.default_rng(seed)
    lo = np.maximum(robot.sample_lower, start - REACH_DEG)
    hi = np.minimum(robot.sample_upper, start + REACH_DEG)
    start_point = robot.fk(start).point_mm[0]
    found: list[np.ndarray] = []
    for _ in range(DRAWS // 200):
        poses = rng.uniform(lo, hi, (200, robot.dof))
        lengths = np.linalg.norm(robot.fk(poses).point_mm - start_point, axis=1)
        keep = (lengths >= MIN_LINE_MM) & (lengths <= MAX_LINE_MM)
        found += [np.round(p, 2) for p in poses[keep]]
        if len(found) >= count:
            return found[:count]
    raise InputError(f"robot init: only {len(found)} of {count} touch poses within "
                     f"{REACH_DEG:g} deg of the start pose put the end frame {MIN_LINE_MM:g}-"
                     f"{MAX_LINE_MM:g} mm from its start point; give --start-pose")


def letter_plane(robot: Robot, start: np.ndarray) -> tuple[list[float], list[float]]:
    """(u, v) of the plane across the pointing direction at the start pose: u horizontal (the
    viewer's right, facing the end frame), v as near up as the plane allows."""
    normal = robot.fk(start).direction[0]
    up = np.array([0.0, 0.0, 1.0])
    u = np.cross(up, normal)
    if np.linalg.norm(u) < 1e-6:  # pointing straight up or down: the plane is horizontal
        u = np.array([0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    return [round(float(x), 6) for x in u], [round(float(x), 6) for x in v]


def init_robot(urdf: str, end_frame: str | None = None, base_link: str | None = None,
               axis: str = "auto", name: str | None = None,
               start_pose: np.ndarray | None = None, seed: int = 1) -> dict[str, Any]:
    """The config and targets of a new robot (see the module docstring): ``{"name", "config"
    (dict, the TOML's keys), "targets" (dict, the JSON), "end_frame", "candidates",
    "axis"}``."""
    if is_package_name(urdf):
        path, package_base, _, _ = resolve(urdf, end_frame or "?")
        base_link = base_link or package_base
        name = name or urdf.partition(":")[2]
    else:
        path = Path(urdf)
        if not path.is_file():
            raise InputError(f"robot init: {urdf!r} is neither a URDF file nor a robot of an "
                             "installed package (example-robot-data:NAME)")
        name = name or path.stem
    path = path.resolve()
    chosen, candidates = (end_frame, []) if end_frame else choose_end_frame(path, base_link)
    config: dict[str, Any] = {"name": name, "source": str(path), "urdf": str(path),
                              **({"base_link": base_link} if base_link else {}),
                              "end_frame": chosen}
    if axis != "auto":
        config["pointing_axis"] = list(pointing_axis(axis))
    with tempfile.TemporaryDirectory() as folder:  # the robot exactly as its config loads
        draft = Path(folder) / f"{name}.toml"
        draft.write_text(toml_text(config), encoding="utf-8")
        robot = load_robot(draft)  # validates the URDF and the chain
        if axis == "auto":
            axis = auto_axis(robot)
            config["pointing_axis"] = list(pointing_axis(axis))
            draft.write_text(toml_text(config), encoding="utf-8")
            robot = load_robot(draft)
    bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    middle = np.where(bounded, (np.where(bounded, robot.lower, 0.0)
                                + np.where(bounded, robot.upper, 0.0)) / 2.0, 0.0)
    start = middle if start_pose is None else robot.check_pose(start_pose, "--start-pose")
    start = np.round(start, 2)
    touches = draw_targets(robot, start, seed)
    u, v = letter_plane(robot, start)
    config = {"name": name, "description": f"{name}: {robot.dof} joints, {robot.root_link} -> "
              f"{robot.end_frame} (written by ikbench robot init)",
              "source": str(path), "urdf": str(path), "base_link": robot.root_link,
              "end_frame": robot.end_frame, "pointing_axis": list(pointing_axis(axis)),
              "joints": list(robot.joint_names),
              "targets": {"file": f"{name}.targets.json", "name": "default"},
              "letters": {"start_pose": [float(x) for x in start], "plane_u": u,
                          "plane_v": v}}
    targets = {"description": f"{name}: the start pose (the middle of the limits unless "
               f"given) and {len(touches)} touch poses drawn by seed {seed} within "
               f"{REACH_DEG:g} of it, ikbench robot init",
               "joint_names": list(robot.joint_names),
               "start_pose": [float(x) for x in start],
               "targets": {str(k + 1): [float(x) for x in pose]
                           for k, pose in enumerate(touches)},
               "steps": STEPS}
    return {"name": name, "config": config, "targets": targets, "end_frame": robot.end_frame,
            "candidates": candidates, "axis": axis}


def toml_text(config: dict[str, Any]) -> str:
    """The config as TOML (strings, numbers, lists of them, and one level of tables)."""
    def value(v: Any) -> str:
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(float(v)) if isinstance(v, float) else str(v)

    lines = [f"{k} = {value(v)}" for k, v in config.items() if not isinstance(v, dict)]
    for key, table in config.items():
        if isinstance(table, dict):
            lines += ["", f"[{key}]", *(f"{k} = {value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"
