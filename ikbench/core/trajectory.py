"""Trajectory CSV files: one row per pose, joints in pose units, the end point in mm.

Columns, exactly::

    step,time_s,<joint names...>,x_mm,y_mm,z_mm,dir_x,dir_y,dir_z

``time_s`` = step * T / n for a movement of duration T [s] split into n segments.
The fingertip columns are FK of the pose (Pinocchio, float64), written for convenience;
readers take the poses and recompute anything they need. Trajectories of 6-D pose paths
(tasks with goal frames) add the end frame's unit quaternion (w first, w >= 0) in the base
frame after these columns: ``qw,qx,qy,qz``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_text
from ikbench.core.robot import FILE_RANGE_TOLERANCE_DEG, Robot, load_robot, unwrap_continuous
from ikbench.core.rotations import matrix_to_quat_wxyz

#: How a trajectory CSV writes its numbers (10 significant digits).
FLOAT_FORMAT = "%.10g"
POINT_COLUMNS = ["x_mm", "y_mm", "z_mm"]
DIRECTION_COLUMNS = ["dir_x", "dir_y", "dir_z"]
QUATERNION_COLUMNS = ["qw", "qx", "qy", "qz"]


def trajectory_columns(robot: Robot, quaternion: bool = False) -> list[str]:
    """The exact column list of a trajectory CSV for ``robot`` (``quaternion``: of a pose
    path)."""
    return ["step", "time_s", *robot.joint_names, *POINT_COLUMNS, *DIRECTION_COLUMNS,
            *(QUATERNION_COLUMNS if quaternion else [])]


def trajectory_frame(robot: Robot, poses: npt.ArrayLike,
                     duration_s: float = DEFAULT_DURATION_S,
                     quaternion: bool = False) -> pd.DataFrame:
    """Build the trajectory table for poses (n+1, dof) [motor deg]; returns a DataFrame
    (``quaternion``: add the end frame's orientation, for pose paths). Continuous joints are
    written unwrapped (:func:`ikbench.core.robot.unwrap_continuous`: no step over 180 deg)."""
    poses = unwrap_continuous(robot, np.asarray(poses, dtype=float))
    n = len(poses) - 1
    if n < 1:
        raise InputError(f"a trajectory needs at least 2 poses, got {len(poses)}")
    fk = robot.fk(poses)
    frame = pd.DataFrame(poses, columns=list(robot.joint_names))
    frame.insert(0, "time_s", np.arange(n + 1) * duration_s / n)
    frame.insert(0, "step", np.arange(n + 1))
    frame[POINT_COLUMNS] = fk.point_mm
    frame[DIRECTION_COLUMNS] = fk.direction
    if quaternion:

        frame[QUATERNION_COLUMNS] = matrix_to_quat_wxyz(robot.fk_transform(poses)[:, :3, :3])
    return frame


def trajectory_csv_text(robot: Robot, poses: npt.ArrayLike,
                        duration_s: float = DEFAULT_DURATION_S, quaternion: bool = False) -> str:
    """The text of a trajectory CSV (:func:`trajectory_frame`, :data:`FLOAT_FORMAT`): what
    :func:`write_trajectory_csv` writes, byte for byte."""
    frame = trajectory_frame(robot, poses, duration_s, quaternion)
    return frame.to_csv(index=False, float_format=FLOAT_FORMAT)


def write_trajectory_csv(path: str | Path, robot: Robot, poses: npt.ArrayLike,
                         duration_s: float = DEFAULT_DURATION_S,
                         quaternion: bool = False) -> Path:
    """Write a trajectory CSV atomically; return its path."""
    return atomic_write_text(path, trajectory_csv_text(robot, poses, duration_s,
                                                       quaternion))


def read_trajectory_csv(path: str | Path | TextIO, robot: Robot | None = None,
                        name: str | None = None) -> pd.DataFrame:
    """Read and validate a trajectory CSV; return the whole table.

    Args:
        path: the file, or its text in a buffer (``io.StringIO``: a file not written yet).
        robot: the robot whose joints and limits it holds (default NICO's right arm).
        name: how errors name the file (default its path).

    Raises:
        InputError: unreadable file, missing columns, non-numeric or non-finite joint values,
            fewer than 2 rows, or a pose outside the motor ranges.
    """
    robot = robot or load_robot()
    where = name or str(path)
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(f"trajectory file {where!r} not found") from None
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise InputError(f"cannot read trajectory file {where!r}: {exc}") from None
    missing = [c for c in robot.joint_names if c not in frame.columns]
    if missing:
        raise InputError(
            f"{where}: missing joint column(s) {', '.join(missing)}; a trajectory CSV needs "
            f"{', '.join(robot.joint_names)} (motor degrees)"
        )
    if len(frame) < 2:
        raise InputError(f"{where}: a trajectory needs at least 2 rows, got {len(frame)}")
    joints = frame[list(robot.joint_names)].apply(pd.to_numeric, errors="coerce")
    bad = ~np.isfinite(joints.to_numpy(dtype=float))
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputError(
            f"{where}: line {row + 2} (step {row}) column {robot.joint_names[col]} = "
            f"{_cell_as_written(path, row, robot.joint_names[col])} is not a finite number"
        )
    for row, pose in enumerate(joints.to_numpy(dtype=float)):
        robot.check_pose(pose, f"{where}: line {row + 2} (step {row})",
                         tol_deg=FILE_RANGE_TOLERANCE_DEG)
    frame[list(robot.joint_names)] = joints
    return frame


def _cell_as_written(path, row: int, column: str) -> str:
    """A cell's text as the file has it (pandas reads "NaN", "nan", "NA" and an empty cell
    alike as NaN): ``empty`` for an empty cell, else the text, e.g. ``NaN``."""
    if hasattr(path, "seek"):  # a buffer: read it again from its start
        path.seek(0)
    text = pd.read_csv(path, dtype=str, keep_default_na=False, usecols=[column])[column]
    value = str(text.iloc[row]).strip()
    return value if value else "empty"


def read_trajectory_poses(path: str | Path | TextIO, robot: Robot | None = None,
                          name: str | None = None) -> np.ndarray:
    """Poses (n+1, dof) [motor deg] of a trajectory CSV (validated; a file or a buffer named
    ``name``, see :func:`read_trajectory_csv`)."""
    robot = robot or load_robot()
    frame = read_trajectory_csv(path, robot, name)
    return frame[list(robot.joint_names)].to_numpy(dtype=float)
