"""Cartesian pose-path problems in CppFlow's format: a YAML file naming a robot and a path.

The format is that of jstmn/cppflow (``cppflow/problems/*.yaml``, ``cppflow/paths/*.csv``);
the obstacle-free problems it republishes from TORM ship with ikbench
(``ikbench/data/cppflow/``, see ATTRIBUTION.md there). Keys of a problem file:

- ``robot``: a robot ikbench ships (``panda``, ``fetch_arm``, ``fetch``, ...);
- ``path_name``: ``<path_name>.csv`` next to the YAML file, else a shipped path
  (``hello``, ``rot_yz``, ``rot_yz2``, ``square``);
- ``path_offset_frame``: ``world`` (the robot's base frame) or a link of its URDF, whose
  position at the all-zero joint vector (locked joints at their values) is added to the path;
  that frame must not be rotated against the base;
- ``path_xyz_offset``: [x, y, z] [m] added to every path position;
- ``path_R_offset``: a 3 x 3 rotation matrix (rows) that right-multiplies every path rotation;
- ``obstacles``: boxes (``x, y, z, roll, pitch, yaw, size_x, size_y, size_z``, metres and
  radians, in the robot's base frame), shifted by ``obstacle_xyz_offset`` [m]; the task's
  obstacles (:func:`ikbench.core.obstacles.cppflow_obstacles`);
- ``initial_configuration`` (optional, as CppFlow's ``Problem``): the configuration [URDF
  units: rad, m] the path should start near; a solution is valid only when its first pose is
  within 0.2 of it (Euclidean norm, URDF units; CppFlow's
  ``SUCCESS_THRESHOLD_initial_q_norm_dist``).

The path CSV has the header ``time,x,y,z,qw,qx,qy,qz`` (metres, unit quaternions w first; the
time column is not used), or, as CppFlow's Panda paths, ``,0,1,2,3,4,5,6`` (an index column,
then the same seven values). The goal pose of waypoint i, in the robot's base frame, is
``p_i + path_xyz_offset + t_frame`` and ``R(q_i) @ path_R_offset`` (as CppFlow composes it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.errors import InputError, refuse_unknown_keys
from ikbench.core.kinematics.pinocchio_fk import chain_urdf_xml, link_frame_id
from ikbench.core.obstacles import cppflow_obstacles
from ikbench.core.robot import load_robot, shipped_robots
from ikbench.core.rotations import quat_wxyz_to_matrix
from ikbench.core.targets import load_targets
from ikbench.core.task import frame_task

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

KEYS = ("robot", "path_name", "path_offset_frame", "path_xyz_offset", "path_R_offset",
        "obstacle_xyz_offset", "obstacles", "initial_configuration")
REQUIRED = KEYS[:5]
PATH_HEADER = ["time", "x", "y", "z", "qw", "qx", "qy", "qz"]
#: The header of CppFlow's Panda paths (a pandas index column, then x..qz numbered 0-6).
INDEXED_PATH_HEADER = ["", "0", "1", "2", "3", "4", "5", "6"]
#: CppFlow's benchmark (``--problems cppflow``): the 13 problems of its benchmark list
#: (jstmn/cppflow ``cppflow/data_type_utils.py`` ``ALL_PROBLEM_FILENAMES``), in this order.
BENCHMARK = "cppflow"
BENCHMARK_PROBLEMS = (
    "fetch_arm__circle", "fetch_arm__hello", "fetch_arm__rot_yz2", "fetch_arm__s",
    "fetch_arm__square", "fetch__circle", "fetch__hello", "fetch__rot_yz2", "fetch__s",
    "fetch__square", "panda__1cube", "panda__2cubes", "panda__flappy_bird")
#: Every shipped problem (``--problems shipped``): the benchmark's, ``fetch_arm__rot_yz``,
#: ``fetch__rot_yz`` and ``panda__square``.
SHIPPED = "shipped"
#: A path quaternion whose norm differs from 1 by more than this is refused.
QUATERNION_NORM_TOLERANCE = 1e-3
#: The offset frame counts as unrotated when its rotation is within this of the identity.
FRAME_ROTATION_TOLERANCE = 1e-8


def data_dir() -> Path:
    """The shipped CppFlow data (``ikbench/data/cppflow``)."""
    return Path(__file__).resolve().parents[1] / "data" / "cppflow"


def shipped_problems() -> dict[str, Path]:
    """name -> YAML path of every shipped problem, sorted by name."""
    return {p.stem: p for p in sorted((data_dir() / "problems").glob("*.yaml"))}


def shipped_paths() -> dict[str, Path]:
    """name -> CSV path of every shipped path."""
    return {p.stem: p for p in sorted((data_dir() / "paths").glob("*.csv"))}


@dataclass(frozen=True)
class CartesianProblem:
    """A parsed problem file (positions in metres, as the file gives them).

    Attributes:
        name: the problem's name (the YAML file's stem, e.g. ``fetch_arm__hello``).
        source: the YAML file.
        robot: the robot's name.
        path_name: the path's name; ``path_file`` the CSV it was read from.
        offset_frame: ``world`` or a link name.
        xyz_offset_m: (3,) [m].
        R_offset: (3, 3) rotation.
        path_m: (N, 3) path positions [m]; ``path_quat_wxyz`` (N, 4) unit quaternions.
        obstacles: the boxes [mm] in the robot's base frame (offset applied).
        initial_configuration: (dof,) [rad, m] or None.
    """

    name: str
    source: Path
    robot: str
    path_name: str
    path_file: Path
    offset_frame: str
    xyz_offset_m: np.ndarray
    R_offset: np.ndarray
    path_m: np.ndarray
    path_quat_wxyz: np.ndarray
    obstacles: tuple = ()
    initial_configuration: np.ndarray | None = None


def resolve_problem(spec: str | Path) -> Path:
    """The YAML file of a shipped problem's name or of a path; InputError naming both kinds."""
    text = str(spec)
    shipped = shipped_problems()
    if text in shipped:
        return shipped[text]
    path = Path(text)
    if path.suffix.lower() in (".yaml", ".yml"):
        if not path.is_file():
            raise InputError(f"problem: file {text!r} not found")
        return path
    raise InputError(f"problem: {text!r} is neither a shipped problem ({', '.join(shipped)}) "
                     "nor a problem file (*.yaml)")


def resolve_problems(spec: str | Path | Sequence[str | Path]) -> list[Path]:
    """``cppflow`` (CppFlow's 13, :data:`BENCHMARK_PROBLEMS`), ``shipped`` (every shipped
    problem), names and files separated by commas, or a list."""
    items = spec if isinstance(spec, (list, tuple)) else str(spec).split(",")
    names = [str(s).strip() for s in items if str(s).strip()]
    if not names:
        raise InputError(f"problems: {spec!r} names no problem; give {BENCHMARK}, {SHIPPED}, "
                         f"names ({', '.join(shipped_problems())}) or files (*.yaml)")
    out: list[Path] = []
    shipped = shipped_problems()
    for name in names:
        if name == BENCHMARK:
            out += [shipped[p] for p in BENCHMARK_PROBLEMS]
        elif name == SHIPPED:
            out += list(shipped.values())
        else:
            out.append(resolve_problem(name))
    stems = [p.stem for p in out]
    duplicates = sorted({s for s in stems if stems.count(s) > 1})
    if duplicates:
        raise InputError(f"problems: {', '.join(duplicates)} named twice (results are "
                         "written per problem name)")
    return out


def read_problem(spec: str | Path) -> CartesianProblem:
    """Read and validate a problem (a shipped name or a YAML file) and its path CSV.

    Raises:
        InputError: one line naming the file, the bad key or value, and what is allowed.
    """
    path = resolve_problem(spec)
    doc = _load_yaml(path)
    where = str(path)
    refuse_unknown_keys(doc, KEYS, where)
    missing = [k for k in REQUIRED if k not in doc]
    if missing:
        raise InputError(f"{where}: missing key(s) {', '.join(missing)}; a problem needs "
                         f"{', '.join(REQUIRED)}")
    offset = doc.get("obstacle_xyz_offset")
    if offset is not None:
        offset = _vector(offset, f"{where}: obstacle_xyz_offset")
    obstacles = cppflow_obstacles(doc.get("obstacles"), offset, where)
    initial = doc.get("initial_configuration")
    if initial is not None:
        if not (isinstance(initial, list) and initial and all(map(_is_number, initial))):
            raise InputError(f"{where}: initial_configuration = {initial!r} must be a list of "
                             "finite numbers (rad, m for prismatic joints)")
        initial = np.array(initial, dtype=float)
    for key in ("robot", "path_name", "path_offset_frame"):
        if not isinstance(doc[key], str) or not doc[key].strip():
            raise InputError(f"{where}: {key} = {doc[key]!r} must be a non-empty string")
    xyz = _vector(doc["path_xyz_offset"], f"{where}: path_xyz_offset")
    R_offset = _rotation(doc["path_R_offset"], f"{where}: path_R_offset")
    path_file = _path_file(doc["path_name"], path)
    points, quats = read_path_csv(path_file)
    return CartesianProblem(path.stem, path, doc["robot"], doc["path_name"], path_file,
                            doc["path_offset_frame"], xyz, R_offset, points, quats, obstacles,
                            initial)


def _load_yaml(path: Path) -> dict:
    import yaml

    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read problem file {str(path)!r}: {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" (line {mark.line + 1})" if mark is not None else ""
        raise InputError(f"{path}: not valid YAML{line}: "
                         f"{' '.join(str(getattr(exc, 'problem', exc)).split())}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: the top level must be a mapping of keys "
                         f"({', '.join(REQUIRED)})")
    return doc


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _vector(value, what: str) -> np.ndarray:
    if not (isinstance(value, list) and len(value) == 3 and all(map(_is_number, value))):
        raise InputError(f"{what}: {value!r} must be [x, y, z], three finite numbers [m]")
    return np.array(value, dtype=float)


def _rotation(value, what: str) -> np.ndarray:
    rows_ok = isinstance(value, list) and len(value) == 3 and all(
        isinstance(r, list) and len(r) == 3 and all(map(_is_number, r)) for r in value)
    if not rows_ok:
        raise InputError(f"{what}: {value!r} must be a 3 x 3 matrix, three rows of three numbers")
    R = np.array(value, dtype=float)
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or abs(np.linalg.det(R) - 1.0) > 1e-6:
        raise InputError(f"{what}: {value!r} is not a rotation matrix (orthonormal, det +1)")
    return R


def _path_file(name: str, problem_file: Path) -> Path:
    beside = problem_file.parent / f"{name}.csv"
    if beside.is_file():
        return beside
    shipped = shipped_paths()
    if name in shipped:
        return shipped[name]
    raise InputError(f"{problem_file}: path_name {name!r}: no {beside.name} next to the problem "
                     f"file and no shipped path of that name ({', '.join(shipped)})")


def read_path_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(positions (N, 3) [m], unit quaternions (N, 4) w first) of a CppFlow path CSV.

    Raises:
        InputError: wrong header, a row that is not 8 finite numbers (naming its line), a
            quaternion far from unit length, or fewer than 2 rows.
    """
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read path file {str(path)!r}: {exc}") from None
    header = [h.strip() for h in lines[0].split(",")] if lines else []
    if header not in (PATH_HEADER, INDEXED_PATH_HEADER):
        raise InputError(f"{path}: line 1 must be the header {','.join(PATH_HEADER)} (or "
                         f"CppFlow's indexed {','.join(INDEXED_PATH_HEADER)}), got "
                         f"{','.join(header) or 'nothing'}")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        try:
            row = [float(v) for v in line.split(",")]
        except ValueError:
            row = []
        if len(row) != 8 or not all(map(math.isfinite, row)):
            raise InputError(f"{path}: line {number}: {line.strip()!r} is not 8 finite numbers "
                             f"({','.join(PATH_HEADER)})")
        norm = math.sqrt(sum(v * v for v in row[4:]))
        if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            raise InputError(f"{path}: line {number}: the quaternion (qw, qx, qy, qz) has norm "
                             f"{norm:.6g}, not 1")
        rows.append(row)
    if len(rows) < 2:
        raise InputError(f"{path}: a path needs at least 2 poses, got {len(rows)}")
    table = np.array(rows)
    quats = table[:, 4:] / np.linalg.norm(table[:, 4:], axis=1, keepdims=True)
    return table[:, 1:4], quats


def offset_frame_position_m(robot: Robot, frame: str) -> np.ndarray:
    """Position [m] of ``frame`` in the robot's base frame at the all-zero joint vector
    (locked joints at their values); ``world`` is the base frame itself.

    Raises:
        InputError: the frame is not a link of the URDF, or it is rotated against the base.
    """
    if frame == "world":
        return np.zeros(3)
    import pinocchio as pin


    model = pin.buildModelFromXML(chain_urdf_xml(robot))
    if not model.existFrame(frame):
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        raise InputError(f"path_offset_frame: {frame!r} is not a link of {robot.name} "
                         f"({robot.urdf_path.name}); use world or one of: {', '.join(links)}")
    q = pin.neutral(model)
    for name, value in robot.locked_urdf.items():
        q[model.idx_qs[model.getJointId(name)]] = value
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    T_world_base = data.oMf[link_frame_id(model, robot.root_link)]
    T = T_world_base.actInv(data.oMf[link_frame_id(model, frame)])
    if np.abs(T.rotation - np.eye(3)).max() > FRAME_ROTATION_TOLERANCE:
        raise InputError(f"path_offset_frame: {frame!r} is rotated against {robot.root_link} "
                         "at the zero configuration; CppFlow's format needs an unrotated frame")
    return np.array(T.translation)


def problem_task(problem: CartesianProblem, robot: Robot) -> Task:
    """The :class:`~ikbench.core.task.Task` of a problem for ``robot``: goal points [mm] and
    rotations in the base frame, the robot's validity limits, its home pose as reference.

    Raises:
        InputError: ``robot`` is not the problem's robot.
    """

    if robot.name != problem.robot:
        raise InputError(f"{problem.source}: the problem is for robot {problem.robot!r}, not "
                         f"{robot.name!r}")
    offset_m = problem.xyz_offset_m + offset_frame_position_m(robot, problem.offset_frame)
    points_mm = (problem.path_m + offset_m) * 1000.0
    rotations = quat_wxyz_to_matrix(problem.path_quat_wxyz) @ problem.R_offset
    initial = None
    if problem.initial_configuration is not None:
        if len(problem.initial_configuration) != robot.dof:
            raise InputError(f"{problem.source}: initial_configuration has "
                             f"{len(problem.initial_configuration)} values; {robot.name} has "
                             f"{robot.dof} joints ({', '.join(robot.joint_names)})")
        initial = robot.from_urdf(problem.initial_configuration)
    return frame_task(robot, problem.name, points_mm, rotations,
                      reference_pose=home_pose(robot) if initial is None else initial,
                      joint_limits=(robot.validity_lower, robot.validity_upper),
                      obstacles=problem.obstacles, initial_pose=initial)


def home_pose(robot: Robot) -> np.ndarray:
    """The robot's home pose [pose units]: its default targets' start pose, else all zeros
    (clipped to the validity limits)."""
    pose = np.zeros(robot.dof)
    if robot.config.targets.file is not None:

        pose = load_targets(None, robot).start_pose
    return np.clip(pose, robot.validity_lower, robot.validity_upper)


def load_problem(spec: str | Path) -> tuple[Robot, Task, CartesianProblem]:
    """(robot, task, problem) of a shipped problem name or a problem file."""

    problem = read_problem(spec)
    if problem.robot not in shipped_robots():
        raise InputError(f"{problem.source}: robot {problem.robot!r} is not a shipped robot; "
                         f"allowed: {', '.join(shipped_robots())}")
    robot = load_robot(problem.robot)
    return robot, problem_task(problem, robot), problem
