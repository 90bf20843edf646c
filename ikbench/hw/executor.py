"""Play a motion plan on Dynamixel servos through dynamixel-sdk (Protocol 1.0).

Order of work: ping every motor, read present positions, refuse a start far from the first pose
(or approach it slowly), write goal = present and enable torque, then send one SYNC WRITE per
segment (goal position + moving speed, 4 bytes per motor, address 30) paced by a
:class:`Clock` (``time.monotonic``; tests pass a fake one), with no per-motor round trips in
between unless recording was asked for.
On Ctrl-C (a set ``stop_event``, also while settling after the last segment) or any failure
once motion began (a bad status packet, the port failing, an unexpected error) it stops
sending segments, holds each motor (goal = its present position, sent right after reading it;
the last goal sent for a motor that does not answer), and raises.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ikbench.core.errors import HardwareError
from ikbench.hw.bus import Bus, CommunicationError
from ikbench.hw.motors import speed_to_raw
from ikbench.hw.plan import MotionPlan

__all__ = ["Bus", "Clock", "CommunicationError", "ExecutionInterrupted", "ExecutionResult",
           "ExecutionStopped", "execute"]

DEFAULT_START_TOLERANCE_DEG = 5.0
DEFAULT_APPROACH_SPEED_DEG_S = 20.0
#: Moving speed [deg/s] of the goal = present writes before the move and when holding.
HOLD_SPEED_DEG_S = 10.0
#: After the last segment, wait at most this long [s] for every joint to be within
#: ``SETTLE_TOLERANCE_DEG`` of the final pose.
SETTLE_S = 0.5
SETTLE_TOLERANCE_DEG = 0.2
SETTLE_INTERRUPTED = "interrupted while settling after the last segment"


class Clock:
    """Where the executor reads the time and waits: ``time.monotonic`` and the stop event's
    own wait. A test passes a fake clock (its own ``now`` and ``wait``) to play a plan on the
    emulator without depending on how fast a loaded machine schedules threads."""

    def now(self) -> float:
        """Monotonic time [s]."""
        return time.monotonic()

    def wait(self, event: threading.Event, timeout_s: float) -> bool:
        """Wait until ``event`` is set or ``timeout_s`` [s] passed; return whether it is set."""
        return event.wait(timeout_s)


#: The clock of :func:`execute` when none is given.
DEFAULT_CLOCK = Clock()


class ExecutionStopped(HardwareError):
    """The move was stopped part-way (communication or other failure); the arm holds its
    position. ``result`` is the :class:`ExecutionResult` so far."""

    result: ExecutionResult  # set by the executor before raising


class ExecutionInterrupted(ExecutionStopped):
    """The move was stopped by the user (Ctrl-C)."""

    exit_code = 130


@dataclass
class ExecutionResult:
    """What happened on the bus.

    Attributes:
        port: port name.
        models: id -> model number reported at ping.
        start_deg: (dof,) present pose before anything moved [motor deg].
        segments_sent: SYNC WRITEs sent for trajectory segments.
        n_segments: segments in the plan.
        approached: whether an approach move to the first pose was made.
        duration_s: first segment's SYNC WRITE to the end of settling [s].
        max_late_s: worst lateness of a SYNC WRITE against its schedule [s].
        final_deg: (dof,) last present pose read [motor deg] (None in a dry run).
        settled: every joint within ``SETTLE_TOLERANCE_DEG`` of the final pose.
        record: present poses read (time_s, phase, joints) or None.
        dry_run: nothing was written to the bus.
    """

    port: str
    models: dict
    start_deg: np.ndarray
    n_segments: int
    segments_sent: int = 0
    approached: bool = False
    duration_s: float = 0.0
    max_late_s: float = 0.0
    final_deg: np.ndarray | None = None
    settled: bool = False
    record: pd.DataFrame | None = None
    dry_run: bool = False


def execute(plan: MotionPlan, port_name: str, *, approach: bool = False,
            approach_speed_deg_s: float = DEFAULT_APPROACH_SPEED_DEG_S,
            start_tolerance_deg: float = DEFAULT_START_TOLERANCE_DEG, dry_run: bool = False,
            record_rate_hz: float = 0.0, stop_event: threading.Event | None = None,
            log: Callable[[str], object] = print, clock: Clock | None = None
            ) -> ExecutionResult:
    """Play ``plan`` on the servos at ``port_name``.

    Args:
        plan: an unflagged motion plan (see :meth:`MotionPlan.check_executable`).
        port_name: serial port (``/dev/ttyUSB0``) or an emulator's pty.
        approach: when the arm is farther than ``start_tolerance_deg`` from the first pose, move
            it there at ``approach_speed_deg_s`` [deg/s] instead of refusing.
        dry_run: ping and read only; write nothing.
        record_rate_hz: also read present positions during the move, at most this often [Hz]
            and only when the next segment is not due (0: only after the move).
        stop_event: set it (e.g. from a SIGINT handler) to stop the move and hold.
        log: called with progress lines.
        clock: the time and the waits (default :data:`DEFAULT_CLOCK`, ``time.monotonic``).

    Raises:
        HardwareError: before anything moved (missing motors, far start, ...).
        ExecutionStopped: any failure after motion began (exit code 3); the arm holds.
        ExecutionInterrupted: ``stop_event`` set or Ctrl-C, at any time (exit code 130); the
            arm holds if it was moving, including while settling after the last segment.
    """
    plan.check_executable()
    stop_event = stop_event or threading.Event()
    bus = Bus(port_name, plan.config)
    bus.open()
    try:
        return _Run(plan, bus, stop_event, log, record_rate_hz, clock or DEFAULT_CLOCK).run(
            approach, approach_speed_deg_s, start_tolerance_deg, dry_run)
    finally:
        bus.close()


class _Run:
    """One execution: state shared by its phases."""

    def __init__(self, plan, bus, stop_event, log, record_rate_hz, clock: Clock):
        self.plan, self.bus, self.stop, self.log = plan, bus, stop_event, log
        self.clock = clock
        self.config = plan.config
        self.record_period = 1.0 / record_rate_hz if record_rate_hz > 0 else None
        self.next_sample = 0.0
        self.read_times: list[float] = []
        self.rows: list[tuple] = []
        self.moving = False
        self.t0: float | None = None
        self.result: ExecutionResult | None = None

    def run(self, approach, approach_speed, tolerance, dry_run) -> ExecutionResult:
        try:
            return self._run(approach, approach_speed, tolerance, dry_run)
        except (HardwareError, KeyboardInterrupt) as exc:
            raise self._stopped(exc) from None
        except Exception as exc:
            if not self.moving:
                raise  # nothing moved: an unexpected error is a bug, shown as it is
            raise self._stopped(exc) from exc  # the arm moves: stop and hold first

    def _run(self, approach, approach_speed, tolerance, dry_run) -> ExecutionResult:
        models = self.bus.ping()
        self.log(f"pinged {len(models)} motors on {self.bus.name}: ids "
                 f"{', '.join(str(i) for i in self.config.ids)}")
        start_raw = self.bus.read_all_raw()
        start = self.config.raw_to_poses(start_raw)
        self._sample(start, "start", self.clock.now())
        result = self.result = ExecutionResult(self.bus.name, models, start,
                                               self.plan.n_segments, dry_run=dry_run)
        far = self._check_start(start, tolerance, approach, approach_speed)
        if dry_run:
            every = (f"one every {self.plan.segment_s * 1000:g} ms" if self.plan.timed is None
                     else f"at the times of --timing {self.plan.timing} (T = "
                     f"{self.plan.duration_s:.4g} s)")
            self.log(f"dry run: would send {self.plan.n_segments} SYNC WRITEs, {every}; "
                     "nothing was written")
            result.record = self._record()
            return result
        self._check_stop()
        self._prepare(start_raw)
        if far:
            self._approach(start, approach_speed)
            result.approached = True
        self._play(result)
        self._settle(result)
        result.record = self._record()
        return result

    # ----- phases -------------------------------------------------------------------------
    def _check_start(self, start, tolerance, approach, approach_speed) -> bool:
        gap = np.abs(start - self.plan.poses_motor_deg[0])
        if gap.max() <= tolerance:
            self.log(f"arm within {gap.max():.2f} deg of the first pose")
            return False
        j = int(gap.argmax())
        what = (f"{self.config.joint_names[j]} is at {start[j]:.2f} motor deg, {gap[j]:.2f} deg "
                f"from the first pose ({self.plan.poses_motor_deg[0, j]:g}); tolerance "
                f"{tolerance:g} deg")
        outside = self.config.outside_limits(start)
        if approach and not outside.any():
            self.log(f"{what}: approaching the first pose at <= {approach_speed:g} deg/s "
                     f"(about {gap.max() / approach_speed:.1f} s)")
            return True
        if outside.any():
            motor = self.config.motors[int(np.flatnonzero(outside)[0])]
            angle = start[self.config.joint_names.index(motor.joint)]
            raise HardwareError(f"{motor.joint} is at {angle:.2f} motor deg, outside its limits "
                                f"[{motor.lower_deg:g}, {motor.upper_deg:g}]; move the arm into "
                                f"range first or check offset_deg in {self.config.source}")
        raise HardwareError(f"{what}; move the arm there or pass --approach")

    def _wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` [s] for the stop event; return whether it is set."""
        return self.clock.wait(self.stop, timeout_s)

    def _check_stop(self) -> None:
        if self.stop.is_set():
            raise ExecutionInterrupted("interrupted")

    def _prepare(self, start_raw) -> None:
        """Goal = present (no jump when torque comes on), slow speed, torque on."""
        hold = int(speed_to_raw(HOLD_SPEED_DEG_S))
        for index, raw in enumerate(start_raw):
            low, high = self.config.motors[index].raw_limits
            self.bus.write_goal(index, int(np.clip(raw, low, high)), hold)
            self.bus.enable_torque(index)

    def _approach(self, start, speed_deg_s) -> None:
        first = self.plan.poses_motor_deg[0]
        gap = np.abs(first - start)
        duration = gap.max() / speed_deg_s
        speeds = speed_to_raw(gap / duration)
        goals = self.config.poses_to_raw(first)
        dof = range(len(self.config.motors))
        self.moving = True
        self.bus.sync_write({i: goals[i] for i in dof}, {i: speeds[i] for i in dof})
        deadline = self.clock.now() + duration + 2.0
        while True:
            if self._wait(0.05):
                raise ExecutionInterrupted("interrupted")
            pose = self.config.raw_to_poses(self.bus.read_all_raw())
            if np.abs(pose - first).max() <= SETTLE_TOLERANCE_DEG:
                return
            if self.clock.now() > deadline:
                raise HardwareError(f"approach did not reach the first pose in {duration + 2:.1f} "
                                    f"s (worst joint off by {np.abs(pose - first).max():.1f} deg)")

    def _play(self, result: ExecutionResult) -> None:
        plan, dof = self.plan, range(len(self.config.motors))
        segment_s = plan.segment_s
        times_s = plan.times_s  # constant timing: k * T/n
        if plan.timed is None:
            self.log(f"playing {plan.n_segments} segments of {segment_s * 1000:g} ms "
                     f"(T = {plan.duration_s:g} s)")
        else:
            self.log(f"playing {plan.n_segments} segments of {segment_s * 1000:.3g} ms or more "
                     f"(--timing {plan.timing}, T = {plan.duration_s:.4g} s)")
        self.moving = True
        t0 = self.t0 = self.clock.now()
        for k in range(plan.n_segments):
            due = t0 + times_s[k]
            if self._wait(max(0.0, due - self.clock.now())):
                raise ExecutionInterrupted("interrupted")
            result.max_late_s = max(result.max_late_s, self.clock.now() - due)
            self.bus.sync_write({i: plan.goal_raw[k, i] for i in dof},
                                {i: plan.speed_raw[k, i] for i in dof})
            result.segments_sent = k + 1
            if self.record_period:
                self._sample_between_segments(t0 + times_s[k + 1])
        if self._wait(max(0.0, t0 + plan.duration_s - self.clock.now())):
            raise ExecutionInterrupted("interrupted")

    def _sample_between_segments(self, next_due: float) -> None:
        """Read the present pose if a sample is due and it fits before ``next_due``."""
        now = self.clock.now()
        assert self.t0 is not None, "sampled before the move started"
        elapsed = now - self.t0
        typical_s = float(np.median(self.read_times)) if self.read_times else 0.0
        early_s = 0.25 * self.plan.segment_s  # samples follow segment starts, give or take
        if elapsed < self.next_sample - early_s or next_due - now <= 2 * typical_s:
            return
        pose = self.config.raw_to_poses(self.bus.read_all_raw())
        self.read_times.append(self.clock.now() - now)
        self._sample(pose, "move", now)
        self.next_sample = elapsed + (self.record_period or 0.0)  # set when sampling

    def _settle(self, result: ExecutionResult) -> None:
        """Read the present pose until it is within ``SETTLE_TOLERANCE_DEG`` of the last pose,
        for at most ``SETTLE_S``. Ctrl-C here is an interruption like any other (the arm may
        still be moving): it raises, and the arm holds."""
        final = self.plan.poses_motor_deg[-1]
        deadline = self.clock.now() + SETTLE_S
        while True:
            now = self.clock.now()
            pose = self.config.raw_to_poses(self.bus.read_all_raw())
            self._sample(pose, "settle", now)
            result.final_deg = pose
            result.settled = bool(np.abs(pose - final).max() <= SETTLE_TOLERANCE_DEG)
            if self.stop.is_set() or (not result.settled and now <= deadline
                                      and self._wait(0.01)):
                raise ExecutionInterrupted(SETTLE_INTERRUPTED)
            if result.settled or now > deadline:
                break
        assert self.t0 is not None, "settled before the move started"
        result.duration_s = self.clock.now() - self.t0
        self.moving = False

    # ----- failure ------------------------------------------------------------------------
    def _stopped(self, exc) -> HardwareError:
        """The error to raise for ``exc``; holds the arm first when it was moving."""
        interrupted = isinstance(exc, (KeyboardInterrupt, ExecutionInterrupted))
        if not self.moving:
            if interrupted:
                return ExecutionInterrupted("interrupted before anything moved")
            if isinstance(exc, CommunicationError):
                return CommunicationError(f"{exc}; nothing moved", exc.timeout)
            return exc  # a refusal (far start, wrong model, ...): nothing was sent
        if isinstance(exc, ExecutionInterrupted):
            reason = str(exc)
        elif interrupted:
            reason = "interrupted"
        elif isinstance(exc, HardwareError):
            reason = str(exc)
        else:
            reason = f"unexpected {type(exc).__name__}: {exc}"
        assert self.result is not None, "moving without a result"
        sent = self.result.segments_sent
        where = (f"sent {sent} of {self.plan.n_segments} segments"
                 + (f" (last: segment {sent - 1})" if sent else ""))
        error = (ExecutionInterrupted if interrupted else ExecutionStopped)(
            f"{reason}; {where}; {self._hold()}")
        self.result.record = self._record()
        error.result = self.result
        return error

    def _hold(self) -> str:
        """Stop every motor where it is; return what was done, for the error message.

        Motor by motor: READ its present position and at once send goal = present at
        ``HOLD_SPEED_DEG_S`` in a SYNC WRITE for that motor alone, so that no goal is older
        than one read (reading all motors first would make the early goals stale by the
        later reads, up to a status timeout each, and pull those joints back). A motor that
        does not answer is sent the last goal it was sent (clipped to its limits) at the hold
        speed: it stops there, at most one segment further.
        """
        self.bus.port.is_using = False
        speed = int(speed_to_raw(HOLD_SPEED_DEG_S))
        silent, unsent = [], []
        for index, motor in enumerate(self.config.motors):
            try:
                goal = self.bus.read_present_raw(index)
            except HardwareError:
                silent.append(index)
                goal = self.bus.last_goal_raw.get(index)
                if goal is None:
                    unsent.append(index)
                    continue
            low, high = motor.raw_limits
            try:
                self.bus.sync_write({index: int(np.clip(goal, low, high))}, {index: speed})
            except HardwareError:
                unsent.append(index)
        return self._describe_hold(silent, unsent)

    def _describe_hold(self, silent: list[int], unsent: list[int]) -> str:
        """Plain words for the outcome of :meth:`_hold` (motor indices that did not answer,
        and those the hold could not be sent to)."""
        n = len(self.config.motors)

        def who(indices) -> str:
            return "any motor" if len(indices) == n else ", ".join(
                self.config.label(i) for i in indices)

        held = [i for i in range(n) if i not in silent and i not in unsent]
        if len(held) == n:
            return "holding present position"
        resent = [i for i in silent if i not in unsent]
        lost = [i for i in silent if i in unsent]
        refused = [i for i in unsent if i not in silent]
        details = []
        if resent:
            details.append(f"no answer from {who(resent)}: sent the last goal again at "
                           f"{HOLD_SPEED_DEG_S:g} deg/s")
        if lost:
            details.append(f"no answer from {who(lost)}, and the hold could not be sent")
        if refused:
            details.append(f"the hold could not be sent to {who(refused)}")
        if not held:
            return (f"no motor could be held: {'; '.join(details)}; each motor stops at the "
                    f"last goal it received")
        return (f"holding present position of {len(held)} of {n} motors; {'; '.join(details)}; "
                f"a motor not held stops at the last goal it received")

    # ----- recording ----------------------------------------------------------------------
    def _sample(self, pose, phase: str, t: float) -> None:
        self.rows.append((t, phase, *pose))

    def _record(self) -> pd.DataFrame:
        t0 = self.t0 if self.t0 is not None else (self.rows[0][0] if self.rows else 0.0)
        frame = pd.DataFrame(self.rows, columns=["t", "phase", *self.config.joint_names])
        frame.insert(0, "time_s", frame.pop("t") - t0)
        return frame
