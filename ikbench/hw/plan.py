"""Motion plan: per-segment goals and speeds for playing a trajectory in a duration T.

Segment k runs from pose k to pose k+1 in T/n seconds (``--timing constant``, the paper's), or
from the time the timing reaches pose k to the time it reaches pose k+1 (``min-jerk``,
``topp``: :mod:`ikbench.core.timing`); each joint's speed is ``|delta| / duration`` in motor
deg/s. The goals are always the solved poses (no resampling): between them each servo moves at
its constant moving speed, as with the paper's timing. A segment is flagged when a joint would
exceed its motor's speed limit or when either end pose leaves the motor's angle limits.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.core.timing import TimedPath, retime
from ikbench.core.trajectory import read_trajectory_csv
from ikbench.hw.motors import MotorConfig, speed_to_raw

if TYPE_CHECKING:
    from pathlib import Path

    from ikbench.core.robot import Robot
    from ikbench.core.timing import Limits

#: Shortest segment [s] the executor accepts (one sync write takes ~0.5 ms at 1 Mbaud).
MIN_SEGMENT_S = 0.005


@dataclass(frozen=True)
class MotionPlan:
    """Goals and speeds of every segment.

    Attributes:
        config: the motors.
        poses_motor_deg: (n+1, dof) trajectory poses [motor deg].
        duration_s: T [s].
        speed_deg_s: (n, dof) joint speeds [motor deg/s].
        goal_raw: (n, dof) goal position register values (pose k+1).
        speed_raw: (n, dof) moving-speed register values (1..1023).
        over_speed: (n, dof) speed above the motor's ``max_speed_deg_s``.
        out_of_limits: (n, dof) pose k or k+1 outside the motor's angle limits.
        timed: the timing (None: ``constant``, segments of T/n).
    """

    config: MotorConfig
    poses_motor_deg: np.ndarray
    duration_s: float
    speed_deg_s: np.ndarray
    goal_raw: np.ndarray
    speed_raw: np.ndarray
    over_speed: np.ndarray
    out_of_limits: np.ndarray
    timed: TimedPath | None = None

    @property
    def n_segments(self) -> int:
        return len(self.speed_deg_s)

    @property
    def timing(self) -> str:
        """``constant``, ``min-jerk`` or ``topp``."""
        return "constant" if self.timed is None else self.timed.timing

    @property
    def segment_s(self) -> float:
        """Duration of one segment [s] (the shortest one for a retimed plan)."""
        if self.timed is None:
            return self.duration_s / self.n_segments
        return float(self.timed.segment_s.min())

    @property
    def times_s(self) -> np.ndarray:
        """(n+1,) the time each pose is reached [s]."""
        if self.timed is None:
            return np.arange(self.n_segments + 1) * self.segment_s
        return self.timed.times_s

    @property
    def flagged(self) -> np.ndarray:
        """(n,) True where a segment exceeds a speed limit or leaves the angle limits."""
        return np.asarray(self.over_speed.any(axis=1) | self.out_of_limits.any(axis=1))

    def table(self) -> pd.DataFrame:
        """The segment table: one row per segment, speeds in motor deg/s, flags as text."""
        n, names = self.n_segments, self.config.joint_names
        times = self.times_s
        frame = pd.DataFrame({
            "segment": np.arange(n),
            "from_step": np.arange(n),
            "to_step": np.arange(1, n + 1),
            "t_start_s": times[:-1],
            "t_end_s": times[1:],
        })
        for j, name in enumerate(names):
            frame[f"{name}_goal_deg"] = self.poses_motor_deg[1:, j]
            frame[f"{name}_speed_deg_s"] = self.speed_deg_s[:, j]
            if self.timed is not None:  # the timing's own, at the goal pose
                frame[f"{name}_velocity_deg_s"] = self.timed.velocity[1:, j]
                if self.timed.acceleration is not None:
                    frame[f"{name}_acceleration_deg_s2"] = self.timed.acceleration[1:, j]
        for j, name in enumerate(names):
            frame[f"{name}_goal_raw"] = self.goal_raw[:, j]
            frame[f"{name}_speed_raw"] = self.speed_raw[:, j]
        frame["over_speed"] = [_names(row, names) for row in self.over_speed]
        frame["out_of_limits"] = [_names(row, names) for row in self.out_of_limits]
        frame["flagged"] = self.flagged
        return frame

    def problems(self) -> list[str]:
        """One line per joint and kind of flag, e.g. ``"r_wrist_z: 50 segments above ..."``."""
        lines = []
        for j, motor in enumerate(self.config.motors):
            fast = np.flatnonzero(self.over_speed[:, j])
            if len(fast):
                k = fast[np.argmax(self.speed_deg_s[fast, j])]
                lines.append(f"{motor.joint}: {len(fast)} segment(s) above its speed limit "
                             f"{motor.max_speed_deg_s:g} deg/s (peak "
                             f"{self.speed_deg_s[k, j]:.1f} deg/s in segment {k})")
            outside = np.flatnonzero(self.out_of_limits[:, j])
            if len(outside):
                k = outside[0]
                a, b = self.poses_motor_deg[k:k + 2, j]
                lines.append(f"{motor.joint}: {len(outside)} segment(s) outside its limits "
                             f"[{motor.lower_deg:g}, {motor.upper_deg:g}] deg (first: segment "
                             f"{k}, {a:g} -> {b:g} deg)")
        return lines

    def check_executable(self) -> None:
        """Raise InputError when any segment is flagged (the executor plays only clean plans)."""
        if self.flagged.any():
            raise InputError(
                f"{int(self.flagged.sum())} of {self.n_segments} segments are flagged; "
                f"{'; '.join(self.problems())}; use a longer --duration or fix the "
                f"trajectory (see ikbench plan)"
            )


def make_plan(poses_motor_deg: npt.ArrayLike, config: MotorConfig,
              duration_s: float = DEFAULT_DURATION_S, timed: TimedPath | None = None) -> MotionPlan:
    """Plan the segments of a trajectory.

    Args:
        poses_motor_deg: (n+1, dof) poses [motor deg] in the config's joint order.
        config: the motors.
        duration_s: T [s], the duration of the whole movement (``constant`` timing).
        timed: a ``min-jerk`` or ``topp`` timing of these poses (None or ``constant``: segments
            of T/n).
    """
    poses = np.asarray(poses_motor_deg, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != len(config.motors) or len(poses) < 2:
        raise InputError(f"a plan needs (n+1, {len(config.motors)}) poses with n >= 1, "
                         f"got shape {poses.shape}")
    if not np.isfinite(poses).all():
        raise InputError("a plan needs finite poses")
    n = len(poses) - 1
    if timed is not None and timed.timing != "constant":
        return _retimed_plan(poses, config, timed)
    if not (np.isfinite(duration_s) and duration_s / n >= MIN_SEGMENT_S):
        raise InputError(f"--duration {duration_s:g} s gives segments of "
                         f"{duration_s / n * 1000:g} ms; give at least "
                         f"{MIN_SEGMENT_S * n:g} s for {n} segments "
                         f"({MIN_SEGMENT_S * 1000:g} ms each)")
    speed = np.abs(np.diff(poses, axis=0)) / (duration_s / n)
    outside = config.outside_limits(poses)
    return MotionPlan(
        config=config,
        poses_motor_deg=poses,
        duration_s=float(duration_s),
        speed_deg_s=speed,
        goal_raw=config.poses_to_raw(poses[1:]),
        speed_raw=speed_to_raw(speed),
        over_speed=speed > config.max_speed_deg_s,
        out_of_limits=outside[:-1] | outside[1:],
    )


def _retimed_plan(poses: np.ndarray, config: MotorConfig, timed: TimedPath) -> MotionPlan:
    """The plan of a ``min-jerk`` or ``topp`` timing: goal k+1 at the time it is reached."""
    segment_s = timed.segment_s
    if not segment_s.min() >= MIN_SEGMENT_S:
        k = int(segment_s.argmin())
        raise InputError(f"--timing {timed.timing} gives segment {k} {segment_s[k] * 1000:.3g} "
                         f"ms; the bus needs at least {MIN_SEGMENT_S * 1000:g} ms per segment; "
                         "use a longer --duration or lower --max-velocity")
    speed = np.abs(np.diff(poses, axis=0)) / segment_s[:, None]
    outside = config.outside_limits(poses)
    return MotionPlan(
        config=config,
        poses_motor_deg=poses,
        duration_s=timed.duration_s,
        speed_deg_s=speed,
        goal_raw=config.poses_to_raw(poses[1:]),
        speed_raw=speed_to_raw(speed),
        over_speed=speed > config.max_speed_deg_s,
        out_of_limits=outside[:-1] | outside[1:],
        timed=timed,
    )


def plan_trajectory_file(path: str | Path, config: MotorConfig,
                         duration_s: float = DEFAULT_DURATION_S, strict: bool = True,
                         robot: Robot | None = None,
                         timing: str = "constant", limits: Limits | None = None
                         ) -> tuple[MotionPlan, str | None]:
    """Read a trajectory CSV and plan it; return the plan and a note when the file's own
    ``time_s`` column ends at another duration than ``duration_s`` (else None).

    Args:
        strict: reject poses outside the robot's motor ranges (as the executor must); with
            False they are let through so that the plan flags them.
        robot: the robot whose joints the CSV holds (default NICO's right arm).
        timing: ``constant`` (segments of T/n), ``min-jerk`` or ``topp``
            (:mod:`ikbench.core.timing`).
        limits: the :class:`~ikbench.core.timing.Limits` for ``topp``.
    """
    robot = robot or load_robot()
    if not strict:
        unbounded = np.full(robot.dof, np.inf)
        robot = dataclasses.replace(robot, lower=-unbounded, upper=unbounded,
                                    _cache={})
    frame = read_trajectory_csv(path, robot)
    poses = frame[list(config.joint_names)].to_numpy(dtype=float)  # the robot's order too
    timed = None
    if timing != "constant":
        timed = retime(robot, poses, timing, duration_s=duration_s, limits=limits)
    plan = make_plan(poses, config, duration_s, timed)
    note = None
    if "time_s" in frame and timing != "topp":
        file_end = float(pd.to_numeric(frame["time_s"], errors="coerce").iloc[-1])
        if np.isfinite(file_end) and abs(file_end - duration_s) > 1e-6:
            note = (f"note: the trajectory's time_s column ends at {file_end:g} s; playing it "
                    f"in {duration_s:g} s (--duration)")
    return plan, note


def _names(mask, names) -> str:
    return ";".join(name for name, bad in zip(names, mask) if bad)
