"""Dynamixel Protocol 1.0 packets, for the servo side (the emulator).

The executor talks through dynamixel-sdk; the emulator *is* the servo, so it parses instruction
packets and builds status packets itself::

    instruction: 0xFF 0xFF ID LEN INSTRUCTION PARAM... CHECKSUM     (LEN = params + 2)
    status:      0xFF 0xFF ID LEN ERROR PARAM... CHECKSUM
    checksum = ~(ID + LEN + INSTRUCTION/ERROR + sum(PARAM)) & 0xFF
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

HEADER = b"\xff\xff"
BROADCAST_ID = 0xFE
PING, READ, WRITE, SYNC_WRITE = 0x01, 0x02, 0x03, 0x83
INSTRUCTION_NAMES = {PING: "PING", READ: "READ", WRITE: "WRITE", 0x04: "REG_WRITE",
                     0x05: "ACTION", 0x06: "RESET", SYNC_WRITE: "SYNC_WRITE", 0x92: "BULK_READ"}
#: Status error bits.
ERROR_BITS = {0x01: "input voltage", 0x02: "angle limit", 0x04: "overheating", 0x08: "range",
              0x10: "checksum", 0x20: "overload", 0x40: "instruction"}
ERR_ANGLE, ERR_RANGE, ERR_CHECKSUM, ERR_OVERLOAD, ERR_INSTRUCTION = 0x02, 0x08, 0x10, 0x20, 0x40
#: A partial packet older than this [s] is dropped (a servo's receive timeout).
STALE_S = 0.1


def checksum(body: bytes) -> int:
    """Protocol 1.0 checksum of ID..last parameter."""
    return ~sum(body) & 0xFF


def packet(motor_id: int, code: int, params: bytes = b"") -> bytes:
    """An instruction (``code`` = instruction) or status (``code`` = error byte) packet."""
    body = bytes([motor_id, len(params) + 2, code]) + bytes(params)
    return HEADER + body + bytes([checksum(body)])


def describe_error(error: int) -> str:
    """Names of the bits set in a status error byte, e.g. ``"overload"``."""
    names = [name for bit, name in ERROR_BITS.items() if error & bit]
    return ", ".join(names) or "none"


@dataclass(frozen=True)
class Packet:
    """A received packet: ``code`` is the instruction (or error byte for a status)."""

    motor_id: int
    code: int
    params: bytes
    raw: bytes
    checksum_ok: bool

    @property
    def name(self) -> str:
        return INSTRUCTION_NAMES.get(self.code, f"0x{self.code:02x}")


class PacketReader:
    """Split a byte stream into packets, skipping noise; keeps partial packets between feeds."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._buffer = bytearray()
        self._clock = clock
        self._last_feed = clock()

    def feed(self, data: bytes) -> list[Packet]:
        """Add received bytes; return the complete packets now available."""
        now = self._clock()
        if self._buffer and now - self._last_feed > STALE_S:
            self._buffer.clear()
        self._last_feed = now
        self._buffer.extend(data)
        packets: list[Packet] = []
        while True:
            start = self._buffer.find(HEADER)
            if start < 0:
                del self._buffer[:-1 if self._buffer.endswith(b"\xff") else len(self._buffer)]
                return packets
            del self._buffer[:start]
            if len(self._buffer) < 4:
                return packets
            if self._buffer[2] == 0xFF or self._buffer[3] < 2:
                del self._buffer[:1]  # not a packet start (0xFF 0xFF 0xFF ...) or bad length
                continue
            size = self._buffer[3] + 4
            if len(self._buffer) < size:
                return packets
            raw = bytes(self._buffer[:size])
            del self._buffer[:size]
            packets.append(Packet(raw[2], raw[4], raw[5:-1], raw, checksum(raw[2:-1]) == raw[-1]))
