"""A Dynamixel Protocol 1.0 bus of emulated MX servos on a pseudo-terminal.

The emulator holds the master side of a pty; dynamixel-sdk's ``PortHandler`` opens the slave
path (``emulator.port``) like a serial port. Each servo keeps an MX control table; its present
position moves towards the goal at the commanded moving speed. Every packet is logged with a
``time.monotonic()`` timestamp (or the ``clock`` given: tests share a fake one with the
executor), and faults can be injected into status packets.

Example::

    with Emulator(load_motor_config(), start_pose_deg) as emulator:
        execute(plan, emulator.port)
        emulator.sync_writes()      # what the executor sent
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.hw import protocol as p1
from ikbench.hw.motors import (
    ADDR_CCW_ANGLE_LIMIT,
    ADDR_CW_ANGLE_LIMIT,
    ADDR_GOAL_POSITION,
    ADDR_MODEL_NUMBER,
    ADDR_MOVING_SPEED,
    ADDR_PRESENT_POSITION,
    ADDR_TORQUE_ENABLE,
    DEG_PER_STEP,
    RAW_MAX,
    SPEED_RAW_MAX,
    SPEED_UNIT_DEG_S,
    Motor,
    MotorConfig,
)

TABLE_SIZE = 74
ADDR_ID, ADDR_BAUD, ADDR_STATUS_RETURN = 3, 4, 16
ADDR_PRESENT_SPEED, ADDR_MOVING = 38, 46
READ_ONLY = set(range(3)) | set(range(36, 47))
#: Model number reported by a motor configured as plain "MX".
GENERIC_MX_MODEL_NUMBER = 29
#: Speed [deg/s] of moving speed 0 ("no speed control").
FULL_SPEED_DEG_S = SPEED_RAW_MAX * SPEED_UNIT_DEG_S
FAULT_KINDS = ("drop", "corrupt", "error")


#: The pty paths an :class:`Emulator` of this process serves now. Its servos answer from a
#: thread that shares the interpreter with the client, so on a loaded machine a status packet can
#: come later than a real servo's; :class:`ikbench.hw.bus.Bus` gives these ports a longer wait.
SERVED_PORTS: set[str] = set()


@dataclass
class Fault:
    """Tamper with status packets.

    Attributes:
        kind: ``"drop"`` (send nothing), ``"corrupt"`` (wrong checksum) or ``"error"`` (set
            ``error_bits`` in the error byte).
        motor_id: only this id (None: any).
        instruction: only replies to this instruction (``protocol.PING``/``READ``/``WRITE``;
            None: any).
        after: let this many matching status packets through first.
        count: tamper with this many, then stop (None: all from then on).
        error_bits: error byte bits for ``kind="error"`` (default: overload).
    """

    kind: str
    motor_id: int | None = None
    instruction: int | None = None
    after: int = 0
    count: int | None = None
    error_bits: int = p1.ERR_OVERLOAD
    seen: int = field(default=0, repr=False)

    def __post_init__(self):
        if self.kind not in FAULT_KINDS:
            raise InputError(f"fault kind {self.kind!r}; allowed: {', '.join(FAULT_KINDS)}")

    def applies(self, motor_id: int, instruction: int) -> bool:
        """Count a matching status packet; True when this one is to be tampered with."""
        if self.motor_id not in (None, motor_id) or self.instruction not in (None, instruction):
            return False
        self.seen += 1
        index = self.seen - 1 - self.after
        return index >= 0 and (self.count is None or index < self.count)


@dataclass(frozen=True)
class LogEntry:
    """One packet on the bus. ``direction``: ``"rx"`` (to the servos) or ``"tx"`` (status)."""

    t: float
    direction: str
    motor_id: int
    name: str
    data: bytes
    note: str = ""


@dataclass(frozen=True)
class SyncWrite:
    """A decoded SYNC WRITE: per id, the bytes written and the present position before it."""

    t: float
    address: int
    data: dict[int, bytes]
    present_before: dict[int, int]

    def word(self, motor_id: int, offset: int = 0) -> int:
        """Little-endian 2-byte value at ``address + offset`` for ``motor_id``."""
        chunk = self.data[motor_id]
        return chunk[offset] | chunk[offset + 1] << 8


class Servo:
    """One emulated MX servo: control table plus a position that moves towards the goal."""

    def __init__(self, motor: Motor, start_raw: int, now: float):
        self.motor = motor
        self.table = bytearray(TABLE_SIZE)
        model = motor.model_number or GENERIC_MX_MODEL_NUMBER
        low, high = motor.raw_limits
        for address, value in ((ADDR_MODEL_NUMBER, model), (ADDR_CW_ANGLE_LIMIT, low),
                               (ADDR_CCW_ANGLE_LIMIT, high), (ADDR_GOAL_POSITION, start_raw)):
            self._set_word(address, value)
        self.table[2], self.table[ADDR_ID], self.table[ADDR_BAUD] = 39, motor.id, 1
        self.table[5], self.table[ADDR_STATUS_RETURN] = 250, 2
        self.position = float(start_raw)
        self.t = now

    def word(self, address: int) -> int:
        return self.table[address] | self.table[address + 1] << 8

    def _set_word(self, address: int, value: int) -> None:
        self.table[address:address + 2] = int(value).to_bytes(2, "little")

    @property
    def speed_steps_s(self) -> float:
        speed_raw = self.word(ADDR_MOVING_SPEED) & 0x3FF
        deg_s = speed_raw * SPEED_UNIT_DEG_S if speed_raw else FULL_SPEED_DEG_S
        return deg_s / DEG_PER_STEP

    def advance(self, now: float) -> None:
        """Move the present position towards the goal up to time ``now``."""
        if self.table[ADDR_TORQUE_ENABLE]:
            gap = self.word(ADDR_GOAL_POSITION) - self.position
            step = min(abs(gap), self.speed_steps_s * max(0.0, now - self.t))
            self.position += step if gap > 0 else -step
        self.t = now
        moving = abs(self.word(ADDR_GOAL_POSITION) - self.position) >= 0.5 and \
            self.table[ADDR_TORQUE_ENABLE]
        self._set_word(ADDR_PRESENT_POSITION, round(self.position))
        self._set_word(ADDR_PRESENT_SPEED, self.word(ADDR_MOVING_SPEED) if moving else 0)
        self.table[ADDR_MOVING] = int(bool(moving))

    def read(self, address: int, length: int, now: float) -> bytes | None:
        """Bytes of the control table, or None when the range is outside it."""
        if address + length > TABLE_SIZE or length < 1:
            return None
        self.advance(now)
        return bytes(self.table[address:address + length])

    def write(self, address: int, data: bytes, now: float) -> tuple[int, str]:
        """Write bytes; return (status error bits, note such as a limit violation)."""
        span = set(range(address, address + len(data)))
        if not data or address + len(data) > TABLE_SIZE or span & READ_ONLY:
            return p1.ERR_RANGE, f"write of {len(data)} bytes at {address} rejected"
        self.advance(now)
        new = self.table.copy()
        new[address:address + len(data)] = data
        goal, speed = new[30] | new[31] << 8, new[32] | new[33] << 8
        if goal > RAW_MAX or speed > 2047 or new[ADDR_TORQUE_ENABLE] > 1:
            return p1.ERR_RANGE, f"value out of range (goal {goal}, speed {speed})"
        error, note = 0, ""
        low, high = self.word(ADDR_CW_ANGLE_LIMIT), self.word(ADDR_CCW_ANGLE_LIMIT)
        if ADDR_GOAL_POSITION in span and not low <= goal <= high:
            error, note = p1.ERR_ANGLE, f"LIMIT VIOLATION: goal {goal} outside [{low}, {high}]"
            goal = min(max(goal, low), high)
            new[30:32] = goal.to_bytes(2, "little")
        if ADDR_GOAL_POSITION in span:
            new[ADDR_TORQUE_ENABLE] = 1  # as on MX servos: a goal position enables torque
        self.table[:] = new
        self.advance(now)
        return error, note


class Emulator:
    """Emulated servos (one per motor of ``config``) on a pseudo-terminal.

    Args:
        config: the motors to emulate (ids, limits, orientation).
        pose_motor_deg: (dof,) start pose [motor deg] (default: all zero).
        missing_ids: ids that never answer (as if unplugged).
        faults: :class:`Fault` rules for status packets (a list; may be extended while running).
        clock: returns the time [s] that moves the servos and stamps the log (default
            ``time.monotonic``).
    """

    def __init__(self, config: MotorConfig, pose_motor_deg: npt.ArrayLike | None = None, *,
                 missing_ids: Iterable[int] = (), faults: Iterable[Fault] = (),
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.config = config
        self._clock = clock
        pose = np.zeros(len(config.motors)) if pose_motor_deg is None else pose_motor_deg
        start_raw = config.poses_to_raw(np.asarray(pose, dtype=float))
        now = self._clock()
        self.servos = {m.id: Servo(m, int(raw), now) for m, raw in zip(config.motors, start_raw)}
        self.missing_ids = set(missing_ids)
        self.faults = list(faults)
        self.log: list[LogEntry] = []
        self.sync_write_log: list[SyncWrite] = []
        self.violations: list[str] = []
        self.port: str | None = None
        self.t_start = now
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    # ----- lifecycle ----------------------------------------------------------------------
    def start(self) -> str:
        """Open the pty and serve packets in a background thread; return the port path."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # 8-bit clean, no echo, even before a client configures it
        self.port = os.ttyname(self._slave)
        SERVED_PORTS.add(self.port)
        self._stop_r, self._stop_w = os.pipe()
        thread = self._thread = threading.Thread(target=self._serve, name="dynamixel-emulator",
                                                 daemon=True)
        thread.start()
        return self.port

    def close(self) -> None:
        """Stop serving and close the pty."""
        if self._thread is None:
            return
        os.write(self._stop_w, b"x")
        self._thread.join(timeout=2.0)
        SERVED_PORTS.discard(self.port or "")
        for fd in (self._master, self._slave, self._stop_r, self._stop_w):
            os.close(fd)
        self._thread = None

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ----- state --------------------------------------------------------------------------
    def present_raw(self) -> np.ndarray:
        """(dof,) present positions (register values) now, in the config's joint order."""
        now = self._clock()
        with self._lock:
            for servo in self.servos.values():
                servo.advance(now)
            return np.array([self.servos[i].word(ADDR_PRESENT_POSITION) for i in self.config.ids])

    def present_deg(self) -> np.ndarray:
        """(dof,) present pose [motor deg] now."""
        return self.config.raw_to_poses(self.present_raw())

    def sync_writes(self) -> list[SyncWrite]:
        """Every SYNC WRITE received so far, in order."""
        with self._lock:
            return list(self.sync_write_log)

    def log_frame(self) -> pd.DataFrame:
        """The packet log: t_s (since start), direction, id, instruction, bytes (hex), note."""
        with self._lock:
            entries = list(self.log)
        return pd.DataFrame({
            "t_s": [e.t - self.t_start for e in entries],
            "direction": [e.direction for e in entries],
            "id": [e.motor_id for e in entries],
            "instruction": [e.name for e in entries],
            "bytes": [e.data.hex(" ") for e in entries],
            "note": [e.note for e in entries],
        }, columns=["t_s", "direction", "id", "instruction", "bytes", "note"])

    # ----- serving ------------------------------------------------------------------------
    def _serve(self) -> None:
        reader = p1.PacketReader()
        while True:
            ready, _, _ = select.select([self._master, self._stop_r], [], [])
            if self._stop_r in ready:
                # serve what was sent before close() (e.g. a last hold command), then stop
                if self._master not in select.select([self._master], [], [], 0)[0]:
                    return
            try:
                data = os.read(self._master, 4096)
            except OSError:  # no client has the slave open: wait for one
                time.sleep(0.01)
                continue
            for packet in reader.feed(data):
                with self._lock:
                    reply = self._handle(packet, self._clock())
                if reply:
                    os.write(self._master, reply)

    def _log(self, t, direction, motor_id, name, data, note="") -> None:
        self.log.append(LogEntry(t, direction, motor_id, name, data, note))

    def _handle(self, packet: p1.Packet, now: float) -> bytes | None:
        note = "" if packet.checksum_ok else "bad checksum"
        self._log(now, "rx", packet.motor_id, packet.name, packet.raw, note)
        if packet.motor_id == p1.BROADCAST_ID:
            if packet.checksum_ok and packet.code == p1.SYNC_WRITE:
                self._sync_write(packet.params, now)
            return None
        servo = self.servos.get(packet.motor_id)
        if servo is None or packet.motor_id in self.missing_ids:
            return None
        if not packet.checksum_ok:
            return self._status(servo, packet.code, p1.ERR_CHECKSUM, b"", now)
        error, params, note = 0, b"", ""
        if packet.code == p1.READ and len(packet.params) == 2:
            data = servo.read(packet.params[0], packet.params[1], now)
            error, params = (p1.ERR_RANGE, b"") if data is None else (0, data)
        elif packet.code == p1.WRITE and len(packet.params) >= 2:
            error, note = servo.write(packet.params[0], packet.params[1:], now)
        elif packet.code != p1.PING:
            error = p1.ERR_INSTRUCTION
        if "LIMIT" in note:
            self.violations.append(f"id {servo.motor.id}: {note}")
        return self._status(servo, packet.code, error, params, now, note)

    def _status(self, servo: Servo, instruction, error, params, now, note="") -> bytes | None:
        for fault in self.faults:
            if fault.applies(servo.motor.id, instruction):
                if fault.kind == "drop":
                    self._log(now, "tx", servo.motor.id, "STATUS", b"", "fault: status dropped")
                    return None
                if fault.kind == "error":
                    error |= fault.error_bits
                    note = f"fault: error bits 0x{fault.error_bits:02x}"
                else:
                    corrupted = bytearray(p1.packet(servo.motor.id, error, params))
                    corrupted[-1] ^= 0x5A
                    self._log(now, "tx", servo.motor.id, "STATUS", bytes(corrupted),
                              "fault: corrupted checksum")
                    return bytes(corrupted)
                break
        reply = p1.packet(servo.motor.id, error, params)
        self._log(now, "tx", servo.motor.id, "STATUS", reply, note)
        return reply

    def _sync_write(self, params: bytes, now: float) -> None:
        if len(params) < 2 or params[1] < 1 or (len(params) - 2) % (params[1] + 1):
            self.log[-1] = LogEntry(now, "rx", p1.BROADCAST_ID, "SYNC_WRITE", self.log[-1].data,
                                    "malformed sync write ignored")
            return
        address, length = params[0], params[1]
        data, before = {}, {}
        for start in range(2, len(params), length + 1):
            motor_id, chunk = params[start], params[start + 1:start + 1 + length]
            servo = self.servos.get(motor_id)
            data[motor_id] = bytes(chunk)
            if servo is None or motor_id in self.missing_ids:
                continue
            servo.advance(now)
            before[motor_id] = servo.word(ADDR_PRESENT_POSITION)
            _, note = servo.write(address, chunk, now)
            if "LIMIT" in note:
                self.violations.append(f"id {motor_id}: {note}")
        self.sync_write_log.append(SyncWrite(now, address, data, before))
