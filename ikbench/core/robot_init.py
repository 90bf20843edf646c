"""From a URDF to a robot config and targets file (``ikbench robot init``): a new robot with no
hand-written file.

:func:`init_robot` reads the URDF (a path, or a robot of an installed description package by
its name, ``example-robot-data:z1``), chooses the chain, the pointing axis, a start pose and
touch targets, and returns a config (``<name>.toml``, the keys of :data:`ikbench.core.robot.
CONFIG_KEYS`) and a targets file (``<name>.targets.json``) that ``letters``, ``run --shape``,
``run``, ``compare`` and ``view`` take as they are:

- **Config**: ``urdf`` (and ``source``) name a package robot by its name
  (``"example-robot-data:romeo"``, found in the package installed where the config is loaded:
  :func:`ikbench.core.robot_packages.package_urdf`), a URDF file by its absolute path.
- **Chain**: from ``base_link`` (``--base-link``: a humanoid's chest or shoulder, so the
  trunk's joints stay out; default: the common arm's base in ikbench's table, else the URDF's
  root), which must be an ancestor of the end frame, to the end frame.
- **End frame**: ``end_frame``; else a common arm's in ikbench's table
  (:data:`ikbench.core.robot_packages.ARMS`); else, of the URDF's candidates (leaf links, then
  tool-like names: :meth:`ikbench.core.urdf_model.UrdfModel.end_frame_candidates`), ranked:
  a chain of at least :data:`MIN_JOINTS` moving joints first; sensor, head and foot frames
  (:data:`LAST_WORDS`: gaze, camera, head, imu, sole, ...) last; a gripper's jaws (a chain
  that moves on from the link a tool frame hangs from: a finger beside the hand's frame)
  after; tool-like names (``gripper``, ``tool``, ``hand``, ...) before the others; then the
  most moving joints (the longest arm), of equals the deepest (a fixed tool frame after the
  flange), then file order. The choice and the other candidates are said.
- **Pointing axis**: ``pointing_axis`` (``x``, ``y``, ``z``, ``-x``, ...), the end frame's
  axis that points; ``auto`` (default): the end frame's axis nearest the direction from the
  last moving joint's origin to the end frame's origin at the zero configuration, when that
  offset is at least :data:`MIN_OFFSET_MM` long and within 35 deg of the axis (the tool sticks
  out along it), else ``z``.
- **Start pose**: ``start_pose``; else the middle of every joint's limits (continuous joints
  at 0) when touch targets can be drawn from it, else the first of :data:`START_DRAWS` poses
  drawn within the limits by ``numpy.random.default_rng([seed, 1])`` from which they can (the
  middle of a humanoid's arm can point away from every line it can draw: Romeo's right arm
  from its torso, 112-133 deg), else the middle with the pointing at the start unchecked (said
  in the targets file).
- **Touch targets**: :data:`COUNT` poses drawn by ``numpy.random.default_rng(seed)`` within
  the reaches of :data:`REACHES_DEG` in turn (joint degrees, mm for prismatic joints) of the
  start pose and within the limits, kept when the line from the start point to their end
  point is :data:`MIN_LINE_MM`..:data:`MAX_LINE_MM` long, the end frame points within
  :data:`POINTING_DEG` of the line at the touch pose (the task contract judges the pointing
  there) and within :data:`START_POINTING_DEG` of it at the start pose (the judged part
  begins a fifth of the way along, so the end frame has a few segments at the joints' speed
  limits to turn): lines of a size an arm draws, on the start pose's IK branch where the
  nearest reach holds enough. ``robot init --check-targets``
  (:mod:`ikbench.studies.target_check`) solves each line under the contract and replaces the
  unsolved ones; without it, reachability of every point of the line is not checked here:
  the comparison judges it.
- **Letters**: on the plane through the start point across the pointing direction (u: the
  viewer's right, v: up as far as the pointing allows).
"""

from __future__ import annotations

import itertools
import json
import math
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ikbench.core.contract import DEFAULT_TOLERANCES
from ikbench.core.errors import InputError
from ikbench.core.robot import Robot, robot_from_config
from ikbench.core.robot_packages import ARMS, is_package_name, package_urdf
from ikbench.core.urdf_model import UrdfModel, link_words, load_urdf_model, tool_like

#: The fewest moving joints an end frame's chain may have to be chosen without --end-frame.
MIN_JOINTS = 3
#: Words of a link name that put it last among the end frame candidates: sensors, the head,
#: the feet (an arm's end frame is none of them).
LAST_WORDS = ("gaze", "camera", "cam", "head", "eye", "neck", "sensor", "imu", "gyro", "accel",
              "touch", "fsr", "sole", "foot", "toe", "ankle", "laser", "lidar", "depth", "rgb",
              "optical", "sonar", "kinect", "xtion", "ft")
#: Touch targets drawn.
COUNT = 7
#: Touch poses are drawn this far from the start pose on every joint [deg, mm], the nearest
#: reach first (a line can join poses on one IK branch without a flip).
REACHES_DEG = (30.0, 45.0, 60.0, 90.0)
#: At the touch pose, the end frame points within this of the line's direction [deg]: the
#: contract's pointing tolerance (the judged part ends there).
POINTING_DEG = DEFAULT_TOLERANCES["pointing_judged_mean_deg"]
#: At the start pose, the end frame points within this of the line's direction [deg]: the
#: contract judges the pointing from a fifth of the way on, and the joints' speed limits allow
#: a turn of a few tens of degrees before it.
START_POINTING_DEG = 45.0
#: Start poses drawn at most when the middle of the limits gives no touch target.
START_DRAWS = 64
#: Candidates per reach when probing a start pose for a touch target (a tenth of DRAWS).
PROBE_DRAWS = 2_000
#: A touch target's line from the start point is this long [mm].
MIN_LINE_MM, MAX_LINE_MM = 80.0, 400.0
#: Candidates drawn at most per reach before the next, in batches of BATCH.
DRAWS, BATCH = 20_000, 500
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


def _moving(path: tuple) -> int:
    return sum(j.type in ("revolute", "continuous", "prismatic") for j in path)


def sensor_like(link: str) -> bool:
    """True when a word of ``link`` names a sensor, the head or a foot (:data:`LAST_WORDS`):
    frames an arm's end frame is not."""
    return any(word.startswith(last) for word in link_words(link) for last in LAST_WORDS)


def _jaws(paths: dict[str, tuple]) -> set[str]:
    """The candidates that are a gripper's jaws: a chain that leaves the link a tool frame
    (another candidate with a tool-like name, :data:`MIN_JOINTS` moving joints or more, no
    sensor) hangs from by fixed joints only, and moves after it (a finger beside the hand's
    frame)."""
    rests: dict[str, str] = {}  # the link an arm's frame hangs from -> that frame
    for link, path in paths.items():
        if _moving(path) < MIN_JOINTS or sensor_like(link) or not tool_like(link):
            continue
        k = len(path)
        while path[k - 1].type == "fixed":
            k -= 1
        rests[path[k - 1].child] = link
    jaws = set()
    for link, path in paths.items():
        if any(j.parent in rests and rests[j.parent] != link and _moving(path[k:])
               for k, j in enumerate(path)):
            jaws.add(link)
    return jaws


def ancestors(model: UrdfModel, link: str) -> list[str]:
    """The links above ``link``, its parent first, the root last."""
    parent = {j.child: j.parent for j in model.joints}
    out = []
    while link in parent:
        link = parent[link]
        out.append(link)
    return out


def check_base_link(model: UrdfModel, base_link: str, end_frame: str | None) -> None:
    """InputError naming ``--base-link`` when it is no link of the URDF or not an ancestor of
    ``end_frame`` (when one is given)."""
    name = model.path.name
    if base_link not in model.links:
        raise InputError(f"--base-link: {base_link!r} is not a link of {name}; links: "
                         f"{', '.join(model.links)}")
    if end_frame is not None and end_frame in model.links \
            and base_link not in ancestors(model, end_frame):
        raise InputError(f"--base-link: {base_link!r} is not an ancestor of the end frame "
                         f"{end_frame!r} in {name}; its ancestors: "
                         f"{', '.join(ancestors(model, end_frame)) or 'none (it is the root)'}")


def choose_end_frame(urdf_path: Path, base_link: str | None) -> tuple[str, list[str]]:
    """(the end frame chosen, every candidate, best first) of a URDF (see the module
    docstring)."""
    model = load_urdf_model(urdf_path)
    base = base_link or model.root_link
    if base_link is not None:
        check_base_link(model, base_link, None)
    found = list(model.end_frame_candidates(base))
    paths = {link: model.path_between(base, link) for link in found}
    jaws = _jaws(paths)
    order = {link: k for k, link in enumerate(found)}

    def rank(link: str) -> tuple:
        path = paths[link]
        return (_moving(path) < MIN_JOINTS, sensor_like(link), link in jaws,
                not tool_like(link), -_moving(path), -len(path), order[link])

    candidates = sorted(found, key=rank)
    if not candidates or _moving(paths[candidates[0]]) < MIN_JOINTS:
        raise InputError(f"--end-frame: no link of {urdf_path.name} has a chain of at least "
                         f"{MIN_JOINTS} moving joints from {base!r}; give one "
                         f"({model.candidates_text(base)})")
    return candidates[0], candidates


def touch_pose_draws(robot: Robot, start: np.ndarray, seed: int,
                     start_pointing_deg: float | None = START_POINTING_DEG,
                     draws: int = DRAWS) -> Iterator[np.ndarray]:
    """Touch poses [pose units], best first (see the module docstring): drawn by
    ``numpy.random.default_rng(seed)`` within each reach of :data:`REACHES_DEG` of the start
    pose in turn (``draws`` each), kept when their line is :data:`MIN_LINE_MM`..
    :data:`MAX_LINE_MM` long and the end frame points within :data:`POINTING_DEG` of it at
    the touch pose (the contract judges the pointing at the line's end) and within
    ``start_pointing_deg`` of it at the start pose (None: not checked)."""
    rng = np.random.default_rng(seed)
    start_fk = robot.fk(start)
    start_point, start_direction = start_fk.point_mm[0], start_fk.direction[0]
    cos_max = math.cos(math.radians(POINTING_DEG))
    cos_start = -1.0 if start_pointing_deg is None else math.cos(math.radians(
        start_pointing_deg))
    for reach in REACHES_DEG:
        lo = np.maximum(robot.sample_lower, start - reach)
        hi = np.minimum(robot.sample_upper, start + reach)
        for _ in range(max(1, draws // BATCH)):
            poses = rng.uniform(lo, hi, (BATCH, robot.dof))
            fk = robot.fk(poses)
            lines = fk.point_mm - start_point
            lengths = np.linalg.norm(lines, axis=1)
            along = np.sum(fk.direction * lines, axis=1) / np.maximum(lengths, 1e-9)
            along_start = lines @ start_direction / np.maximum(lengths, 1e-9)
            keep = (lengths >= MIN_LINE_MM) & (lengths <= MAX_LINE_MM) & (along >= cos_max) \
                & (along_start >= cos_start)
            yield from (np.round(p, 2) for p in poses[keep])


def start_poses(robot: Robot, middle: np.ndarray, seed: int) -> Iterator[np.ndarray]:
    """The start poses :func:`init_robot` tries without ``--start-pose``: ``middle``, then
    :data:`START_DRAWS` drawn within the limits by ``numpy.random.default_rng([seed, 1])``
    (rounded to 0.01 deg), each only when a quick probe (:data:`PROBE_DRAWS` candidates per
    reach) finds a touch target from it."""
    rng = np.random.default_rng([seed, 1])
    candidates = itertools.chain(
        [middle], (np.round(rng.uniform(robot.sample_lower, robot.sample_upper), 2)
                   for _ in range(START_DRAWS)))
    for start in candidates:
        if next(touch_pose_draws(robot, start, seed, draws=PROBE_DRAWS), None) is not None:
            yield start


def draw_targets(robot: Robot, start: np.ndarray, seed: int, count: int = COUNT,
                 start_pointing_deg: float | None = START_POINTING_DEG) -> list[np.ndarray]:
    """The first ``count`` of :func:`touch_pose_draws`; InputError when the draws find
    fewer."""
    found = list(itertools.islice(touch_pose_draws(robot, start, seed, start_pointing_deg),
                                  count))
    if len(found) < count:
        raise InputError(f"robot init: only {len(found)} of {count} touch poses within "
                         f"{REACHES_DEG[-1]:g} deg of the start pose put the end frame "
                         f"{MIN_LINE_MM:g}-{MAX_LINE_MM:g} mm from its start point, pointing "
                         f"within {POINTING_DEG:g} deg of the line; give --start-pose or "
                         "--pointing-axis")
    return found


def choose_start(robot: Robot, middle: np.ndarray, seed: int
                 ) -> tuple[np.ndarray, list[np.ndarray], str]:
    """(start pose, touch poses, how the start was chosen) without ``--start-pose`` (see the
    module docstring)."""
    for start in start_poses(robot, middle, seed):
        try:
            touches = draw_targets(robot, start, seed)
        except InputError:
            continue
        how = "the middle of the limits" if np.array_equal(start, middle) else (
            f"drawn within the limits by seed [{seed}, 1]: from the middle of the limits the "
            f"end frame points more than {START_POINTING_DEG:g} deg away from every line")
        return start, touches, how
    touches = draw_targets(robot, middle, seed, start_pointing_deg=None)
    return middle, touches, (f"the middle of the limits, though the end frame points more "
                             f"than {START_POINTING_DEG:g} deg away from the lines there and "
                             f"from every start drawn (the contract's pointing may not hold)")


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
        path = package_urdf(urdf)
        arm = ARMS.get(urdf.partition(":")[0], {}).get(urdf.partition(":")[2])
        base_link = base_link or (arm.base_link if arm else None)
        name = name or urdf.partition(":")[2]
        reference = urdf  # the config names the package robot, not a path into the venv
    else:
        path = Path(urdf)
        if not path.is_file():
            raise InputError(f"robot init: {urdf!r} is neither a URDF file nor a robot of an "
                             "installed package (example-robot-data:NAME)")
        name = name or path.stem
        arm = None
        reference = str(path.resolve())
    path = path.resolve()
    model = load_urdf_model(path)
    if base_link is not None:
        check_base_link(model, base_link, end_frame)
    candidates = [] if end_frame else choose_end_frame(path, base_link)[1]
    if end_frame:
        chosen = end_frame
    elif arm is not None and (base_link == arm.base_link):  # ikbench's table of common arms
        chosen = arm.end_frame
    else:
        chosen = candidates[0]
    config: dict[str, Any] = {"name": name, "source": reference, "urdf": reference,
                              **({"base_link": base_link} if base_link else {}),
                              "end_frame": chosen}
    if axis != "auto":
        config["pointing_axis"] = list(pointing_axis(axis))
    with tempfile.TemporaryDirectory() as folder:  # the robot exactly as its config loads
        draft = Path(folder) / f"{name}.toml"
        draft.write_text(toml_text(config), encoding="utf-8")
        robot = robot_from_config(draft)  # validates the URDF and the chain
        if axis == "auto":
            axis = auto_axis(robot)
            config["pointing_axis"] = list(pointing_axis(axis))
            draft.write_text(toml_text(config), encoding="utf-8")
            robot = robot_from_config(draft)  # not load_robot: it caches by path
    bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    middle = np.where(bounded, (np.where(bounded, robot.lower, 0.0)
                                + np.where(bounded, robot.upper, 0.0)) / 2.0, 0.0)
    if start_pose is None:
        start, touches, how = choose_start(robot, np.round(middle, 2), seed)
    else:
        start = np.round(robot.check_pose(start_pose, "--start-pose"), 2)
        touches, how = draw_targets(robot, start, seed), "given (--start-pose)"
    u, v = letter_plane(robot, start)
    config = {"name": name, "description": f"{name}: {robot.dof} joints, {robot.root_link} -> "
              f"{robot.end_frame} (written by ikbench robot init)",
              "source": reference, "urdf": reference, "base_link": robot.root_link,
              "end_frame": robot.end_frame, "pointing_axis": list(pointing_axis(axis)),
              "joints": list(robot.joint_names),
              "targets": {"file": f"{name}.targets.json", "name": "default"},
              "letters": {"start_pose": [float(x) for x in start], "plane_u": u,
                          "plane_v": v}}
    targets = {"description": targets_description(name, len(touches), seed,
                                                  reach_of(start, touches), start=how),
               "joint_names": list(robot.joint_names),
               "start_pose": [float(x) for x in start],
               "targets": {str(k + 1): [float(x) for x in pose]
                           for k, pose in enumerate(touches)},
               "steps": STEPS}
    return {"name": name, "config": config, "targets": targets, "end_frame": robot.end_frame,
            "candidates": candidates, "axis": axis, "robot": robot, "start": start,
            "seed": seed, "start_from": how}


def reach_of(start: np.ndarray, touches: list[np.ndarray]) -> float:
    """The smallest reach of :data:`REACHES_DEG` that holds every touch pose."""
    far = max(float(np.abs(t - start).max()) for t in touches)
    return next((r for r in REACHES_DEG if far <= r + 1e-6), REACHES_DEG[-1])


def targets_description(name: str, count: int, seed: int, reach: float, checked: str = "",
                        start: str = "the middle of the limits") -> str:
    """The targets file's ``description``: how its poses were drawn (``start``: how the start
    pose was chosen; ``checked``: what the check under the task contract found, when it
    ran)."""
    return (f"{name}: the start pose ({start}) and {count} touch "
            f"poses drawn by seed {seed} within {reach:g} deg of it, each line "
            f"{MIN_LINE_MM:g}-{MAX_LINE_MM:g} mm long with the end frame pointing within "
            f"{POINTING_DEG:g} deg of it at the touch pose and within {START_POINTING_DEG:g} "
            "deg at the start pose; "
            + (checked or "not checked by a solve under the task contract (ikbench robot init "
               "--check-targets)") + "; ikbench robot init")


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
