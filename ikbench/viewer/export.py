"""Trajectories for other tools: ROS ``trajectory_msgs/JointTrajectory`` and CSV in URDF units.

ROS controllers and MoveIt take joint values in the URDF's units, so positions are the
robot's poses through :meth:`ikbench.core.robot.Robot.to_urdf` (the motor map for NICO):
radians for revolute and continuous joints, metres for prismatic ones. The message, as a
plain dict with ROS 2 field names (what ``ros2 topic pub`` takes as YAML)::

    header: {stamp: {sec: 0, nanosec: 0}, frame_id: ""}
    joint_names: [r_shoulder_z, ...]          # the robot's chain, base to end
    points:
      - positions: [...]                      # rad (m for prismatic joints)
        velocities: [...]                     # rad/s (m/s)
        accelerations: []
        effort: []
        time_from_start: {sec: 0, nanosec: 40000000}

Point i is at ``i * T / n`` (T = ``duration_s``, n + 1 points), computed in whole
nanoseconds (``round(i * T_ns / n)``) and split into ``sec`` and ``0 <= nanosec < 1e9``, so no
float rounding leaks into them (4.35 s is ``{4, 350000000}``).

**Velocities**: central differences ``(q[i+1] - q[i-1]) / (2 T/n)`` at the inner points and
zero at the first and last point. Given positions and velocities, ROS's
joint_trajectory_controller interpolates each segment with a cubic through both, so central
differences make the segments join smoothly; the arm starts at rest and must stop at the
touch, and since ROS 2 Jazzy the controller refuses a non-zero final velocity unless
``allow_nonzero_velocity_at_trajectory_end`` is set. ``end_velocities="one-sided"`` gives the
ends one-sided differences instead (for a piece of a longer motion).

**Retimed** (``--timing min-jerk`` or ``topp``, :mod:`ikbench.core.timing`): the motion is
sampled at a fixed rate (``rate_hz``, default :data:`DEFAULT_RATE_HZ`; points at whole
nanoseconds ``round(k * 1e9 / rate)``, and one at the end) along the timing's cubic spline
through the solved poses, and each point carries the timing's own velocities and
accelerations (the derivatives of the spline and the time law), both at rest at the ends.
``rate_hz=0`` gives one point per solved pose at its retimed time instead. The fingertip's
deviation from the solved path that the spline causes is measured
(:func:`ikbench.core.timing.fingertip_deviation_mm`) and reported in the export's note.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from ikbench.core.budget import check_memory
from ikbench.core.errors import InputError
from ikbench.core.io import atomic_write_text, check_writable
from ikbench.core.robot import unwrap_continuous
from ikbench.core.timing import fingertip_deviation_mm, retime
from ikbench.core.timing_limits import urdf_units_per_pose_unit
from ikbench.core.trajectory import read_trajectory_csv

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ikbench.core.robot import Robot
    from ikbench.core.timing import Limits, TimedPath

NS_PER_S = 1_000_000_000
#: Points per second of a retimed export.
DEFAULT_RATE_HZ = 250.0
#: ``ikbench export --format`` -> what it writes.
FORMATS = {"ros-json": "JointTrajectory as JSON", "ros-yaml": "JointTrajectory as YAML",
           "csv-rad": "step,time_s,<joints> in URDF units (rad; m for prismatic joints)"}


#: The highest rate of a retimed export [Hz] (controllers run at 1 kHz at most).
MAX_RATE_HZ = 10_000.0
#: Memory per exported point while it is built and written (the point's dict in the message,
#: its text, and the four samples per point of the fingertip check) [bytes].
BYTES_PER_POINT = 4_000


def sample_times_ns(count: int, duration_s: float) -> list[int]:
    """Whole-nanosecond times of ``count`` points evenly spread over ``duration_s`` [s]."""
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise InputError(f"--duration: {duration_s!r} must be a positive number of seconds")
    total, n = int(round(duration_s * NS_PER_S)), count - 1
    return [(2 * i * total + n) // (2 * n) for i in range(count)]  # round half up


def split_ns(total_ns: int) -> dict[str, int]:
    """``builtin_interfaces/Duration`` of whole nanoseconds: ``{"sec", "nanosec"}``."""
    sec, nanosec = divmod(int(total_ns), NS_PER_S)
    return {"sec": int(sec), "nanosec": int(nanosec)}


def velocities(q: np.ndarray, dt_s: float,
               end_velocities: Literal["zero", "one-sided"] = "zero") -> np.ndarray:
    """(n+1, dof) velocities [unit of q / s]: central differences inside, ends per
    ``end_velocities`` (see the module doc)."""
    v = np.zeros_like(q)
    v[1:-1] = (q[2:] - q[:-2]) / (2.0 * dt_s)
    if end_velocities == "one-sided":
        v[0], v[-1] = (q[1] - q[0]) / dt_s, (q[-1] - q[-2]) / dt_s
    elif end_velocities != "zero":
        raise InputError(f"end_velocities: {end_velocities!r} is not one of zero, one-sided")
    return v


def joint_trajectory(robot: Robot, poses: npt.ArrayLike, duration_s: float,
                     end_velocities: Literal["zero", "one-sided"] = "zero") -> dict[str, Any]:
    """The ``JointTrajectory`` (a dict, see the module doc) of poses (n+1, dof) [pose units]
    played in ``duration_s`` [s]."""
    poses = robot.check_poses(poses, "poses")
    if poses.ndim != 2 or len(poses) < 2 or not np.all(np.isfinite(poses)):
        raise InputError(f"a trajectory needs at least 2 poses of finite numbers, got an array "
                         f"of shape {poses.shape}")
    q_urdf = np.asarray(robot.to_urdf(poses), dtype=float)
    times = sample_times_ns(len(q_urdf), duration_s)
    v = velocities(q_urdf, duration_s / (len(q_urdf) - 1), end_velocities)
    points = [{"positions": q.tolist(), "velocities": dq.tolist(), "accelerations": [],
               "effort": [], "time_from_start": split_ns(t)}
              for q, dq, t in zip(q_urdf, v, times)]
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
            "joint_names": list(robot.joint_names), "points": points}


def timed_points(robot: Robot, timed: TimedPath, rate_hz: float = DEFAULT_RATE_HZ
                 ) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
    """``(times_ns, q, qd, qdd)`` of a retimed export [URDF units]: the timing sampled at
    ``rate_hz`` (0: at the solved poses), see the module doc."""

    if rate_hz:
        total_ns = int(round(timed.duration_s * NS_PER_S))
        step_ns = NS_PER_S / rate_hz
        check_memory("rate_hz", int(total_ns // step_ns) + 2, "points", BYTES_PER_POINT)
        times_ns = [int(round(k * step_ns)) for k in range(int(total_ns // step_ns) + 1)]
        if total_ns - times_ns[-1] < step_ns / 2 and len(times_ns) > 1:
            times_ns.pop()  # no sliver of a last interval
        times_ns.append(total_ns)
        q, qd, qdd = timed.sample(np.array(times_ns, dtype=float) / NS_PER_S)
    else:
        times_ns = [int(round(t * NS_PER_S)) for t in timed.times_s]
        q, qd, qdd = timed.poses, timed.velocity, timed.acceleration
        qdd = np.zeros_like(q) if qdd is None else qdd
    qd, qdd = qd.copy(), qdd.copy()
    qd[[0, -1]] = 0.0  # at rest (the timing is; this removes round-off)
    factor = urdf_units_per_pose_unit(robot)
    return times_ns, np.asarray(robot.to_urdf(q), dtype=float), qd * factor, qdd * factor


def timed_joint_trajectory(robot: Robot, timed: TimedPath, rate_hz: float = DEFAULT_RATE_HZ
                           ) -> dict[str, Any]:
    """The ``JointTrajectory`` of a retimed path (see the module doc)."""
    times, q, qd, qdd = timed_points(robot, timed, rate_hz)
    points = [{"positions": a.tolist(), "velocities": b.tolist(), "accelerations": c.tolist(),
               "effort": [], "time_from_start": split_ns(t)}
              for a, b, c, t in zip(q, qd, qdd, times)]
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
            "joint_names": list(robot.joint_names), "points": points}


def from_joint_trajectory(message: dict) -> tuple[list[str], np.ndarray, np.ndarray]:
    """``(joint_names, q (n+1, dof) [URDF units], times_s (n+1,))`` of a JointTrajectory."""
    try:
        names = [str(n) for n in message["joint_names"]]
        points = message["points"]
        q = np.array([p["positions"] for p in points], dtype=float).reshape(-1, len(names))
        times = np.array([p["time_from_start"]["sec"] + p["time_from_start"]["nanosec"]
                          / NS_PER_S for p in points], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"not a JointTrajectory: {exc!r}") from None
    return names, q, times


def to_poses(robot: Robot, joint_names: Sequence[str], q_urdf: npt.ArrayLike) -> np.ndarray:
    """Joint values [URDF units] in any column order -> poses (n+1, dof) [pose units]."""
    missing = [n for n in robot.joint_names if n not in joint_names]
    if missing:
        raise InputError(f"joints {', '.join(missing)} of robot {robot.name} are missing; "
                         f"given: {', '.join(joint_names)}")
    columns = [list(joint_names).index(n) for n in robot.joint_names]
    return np.asarray(robot.from_urdf(np.asarray(q_urdf, dtype=float)[:, columns]))


def json_text(message: dict) -> str:
    """JSON of a message (floats in their shortest round-trip form)."""
    return json.dumps(message, indent=1) + "\n"


def yaml_text(message: dict) -> str:
    """YAML of a message, what ``ros2 topic pub TOPIC trajectory_msgs/msg/JointTrajectory``
    takes (PyYAML writes floats in their round-trip form)."""
    import yaml

    return yaml.safe_dump(message, sort_keys=False, default_flow_style=None, width=120)


def csv_rad_text(robot: Robot, poses: npt.ArrayLike, duration_s: float,
                 message: dict | None = None) -> str:
    """``step,time_s,<joint names>`` with the joints in URDF units (rad; m for prismatic), of
    ``message`` (default: the constant timing of ``poses`` over ``duration_s``)."""
    message = message or joint_trajectory(robot, poses, duration_s)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["step", "time_s", *robot.joint_names])
    for i, point in enumerate(message["points"]):
        t = point["time_from_start"]
        writer.writerow([i, repr(t["sec"] + t["nanosec"] / NS_PER_S),
                         *(repr(float(x)) for x in point["positions"])])
    return out.getvalue()


def read_export(path: str | Path, fmt: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """``(joint_names, q [URDF units], times_s)`` of a file :func:`export_trajectory` wrote."""
    text = Path(path).read_text(encoding="utf-8")
    if fmt == "ros-json":
        return from_joint_trajectory(json.loads(text))
    if fmt == "ros-yaml":
        import yaml

        return from_joint_trajectory(yaml.safe_load(text))
    rows = list(csv.reader(io.StringIO(text)))
    if rows[0][:2] != ["step", "time_s"]:
        raise InputError(f"{path}: expected a header step,time_s,<joints>, got {rows[0][:2]}")
    values = np.array([[float(x) for x in row] for row in rows[1:]], dtype=float)
    return rows[0][2:], values[:, 2:], values[:, 1]


def export_trajectory(trajectory_csv: str | Path, fmt: str, output: str | Path, robot: Robot,
                      duration_s: float, timing: str = "constant", limits: Limits | None = None,
                      rate_hz: float = DEFAULT_RATE_HZ) -> tuple[Path, str | None]:
    """Write a trajectory CSV [pose units] as ``fmt`` (:data:`FORMATS`) to ``output``
    atomically, played in ``duration_s`` [s] (or as ``timing`` times it, sampled at
    ``rate_hz``; see the module doc).

    Returns:
        (output path, a note when the CSV's ``time_s`` column ends at another time than
        ``duration_s``, and for a retimed export the timing, its rate and the fingertip's
        deviation from the solved path; else None).
    """

    if fmt not in FORMATS:
        raise InputError(f"--format: {fmt!r} is not one of {', '.join(FORMATS)}")
    sample_times_ns(2, duration_s)  # checks the duration
    frame = read_trajectory_csv(trajectory_csv, robot)
    poses = unwrap_continuous(robot, frame[list(robot.joint_names)].to_numpy(dtype=float))
    check_writable(output)
    if timing != "constant":
        if not (np.isfinite(rate_hz) and 0 <= rate_hz <= MAX_RATE_HZ):
            raise InputError(f"rate_hz: {rate_hz!r}; give a number of points per second from 0 "
                             f"to {MAX_RATE_HZ:g} (0: one point per solved pose)")
        return _export_retimed(robot, frame, poses, fmt, output, duration_s, timing, limits,
                               rate_hz)
    if fmt == "csv-rad":
        text = csv_rad_text(robot, poses, duration_s)
    else:
        message = joint_trajectory(robot, poses, duration_s)
        text = json_text(message) if fmt == "ros-json" else yaml_text(message)
    path = atomic_write_text(output, text)
    note = None
    if "time_s" in frame:
        import pandas as pd

        end = float(pd.to_numeric(frame["time_s"], errors="coerce").iloc[-1])
        if np.isfinite(end) and abs(end - duration_s) > 1e-6:
            note = (f"note: the trajectory's time_s column ends at {end:g} s; exported over "
                    f"{duration_s:g} s (--duration)")
    return path, note


def _export_retimed(robot, frame, poses, fmt, output, duration_s, timing, limits, rate_hz):
    """:func:`export_trajectory` for ``min-jerk`` and ``topp``."""

    timed = retime(robot, poses, timing, duration_s=duration_s, limits=limits)
    message = timed_joint_trajectory(robot, timed, rate_hz)
    if fmt == "csv-rad":
        text = csv_rad_text(robot, poses, duration_s, message)
    else:
        text = json_text(message) if fmt == "ros-json" else yaml_text(message)
    path = atomic_write_text(output, text)
    count = len(message["points"])
    where = (f"{count} points at {rate_hz:g} Hz along the {timed.interpolation}"
             if rate_hz else f"{count} points, one per solved pose")
    note = f"note: --timing {timing}: T = {timed.duration_s:.4g} s, {where}"
    if rate_hz:
        dense = timed.sample(np.linspace(0.0, timed.duration_s, 4 * count))[0]
        tip = robot.fk(poses).point_mm
        deviation = fingertip_deviation_mm(robot, dense, tip)
        linear = retime(robot, poses, "constant", duration_s=1.0)
        baseline = fingertip_deviation_mm(robot, linear.sample(np.linspace(0, 1, 4 * count))[0],
                                          tip)
        note += (f"; the fingertip strays up to {deviation:.3g} mm from the solved path (the "
                 f"polyline through the solved fingertip points; {baseline:.3g} mm when "
                 "moving linearly in the joints between the same poses)")
    if timed.limits is not None:
        note += f"; limits: {timed.limits.source}"
    return path, note
