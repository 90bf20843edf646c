"""The servo bus as the executor sees it: dynamixel-sdk (Protocol 1.0) calls whose failures
raise :class:`CommunicationError` naming the motor, the operation and what went wrong."""

from __future__ import annotations

import numpy as np

from ikbench.core.errors import HardwareError
from ikbench.hw.motors import (
    ADDR_GOAL_POSITION,
    ADDR_PRESENT_POSITION,
    ADDR_TORQUE_ENABLE,
    MODELS,
    MotorConfig,
)
from ikbench.hw.protocol import describe_error


class CommunicationError(HardwareError):
    """No, late or corrupted status packet, an error bit set, or a port failure."""

    def __init__(self, message: str, timeout: bool = False):
        super().__init__(message)
        self.timeout = timeout


def describe_sdk_exception(exc: Exception) -> tuple[bool, str]:
    """(whether it is a port failure, words for it) for an exception raised inside
    dynamixel-sdk or pyserial.

    The SDK flushes the port with ``termios.tcflush`` before every instruction; when the port
    goes away (USB adapter unplugged, an emulator's pty closed) that raises ``termios.error``,
    which is not an OSError. Anything else the SDK raises is named by its type.
    """
    termios_error: type[Exception] | tuple[()]
    try:
        import termios

        termios_error = termios.error
    except ImportError:  # not on POSIX: no termios
        termios_error = ()
    import serial

    if isinstance(exc, termios_error) and len(exc.args) == 2:
        return True, f"{exc.args[1]} (errno {exc.args[0]})"
    if isinstance(exc, (OSError, termios_error, serial.SerialException)):
        return True, str(exc)
    return False, f"dynamixel-sdk raised {type(exc).__name__}: {exc}"


#: The least wait [ms] for a status packet from a port the in-process emulator serves. The SDK
#: waits two USB latency timers plus the transfer (about 34 ms at 1 Mbaud), which a real servo
#: meets; the emulator's thread can miss it while the client's thread spins on the same
#: interpreter on a loaded machine. Real ports keep the SDK's wait.
EMULATED_STATUS_TIMEOUT_MS = 500.0


def _port_handler(sdk, port_name: str):
    """dynamixel-sdk's PortHandler for ``port_name``; for an emulated port (see
    :data:`ikbench.hw.emulator.SERVED_PORTS`) one whose status wait is at least
    :data:`EMULATED_STATUS_TIMEOUT_MS`."""
    from ikbench.hw.emulator import SERVED_PORTS

    if port_name not in SERVED_PORTS:
        return sdk.PortHandler(port_name)

    class EmulatedPortHandler(sdk.PortHandler):
        def setPacketTimeout(self, packet_length):  # noqa: N802 (the SDK's name)
            super().setPacketTimeout(packet_length)
            wait_ms = float(getattr(self, "packet_timeout"))  # noqa: B009 (untyped SDK)
            setattr(self, "packet_timeout", max(wait_ms, EMULATED_STATUS_TIMEOUT_MS))  # noqa: B010

    return EmulatedPortHandler(port_name)


class Bus:
    """dynamixel-sdk port + Protocol 1.0 packet handler; failures raise CommunicationError.

    Attributes:
        last_goal_raw: motor index -> goal position register value of the last goal sent to
            it successfully (by :meth:`write_goal` or :meth:`sync_write`).
    """

    def __init__(self, port_name: str, config: MotorConfig):
        try:
            import dynamixel_sdk as sdk
        except ImportError:
            raise HardwareError("playing on servos needs dynamixel-sdk, which is not "
                                "installed: pip install 'ikbench[hw]'") from None

        self.sdk, self.config, self.name = sdk, config, port_name
        self.port = _port_handler(sdk, port_name)
        self.handler = sdk.PacketHandler(1.0)
        self.last_goal_raw: dict[int, int] = {}

    def open(self) -> None:
        """Open the port at the config's baud rate.

        Raises:
            HardwareError: the port cannot be opened or the baud rate is not supported.
        """
        try:
            ok = self.port.setBaudRate(self.config.baudrate)  # opens the port
        except Exception as exc:  # whatever pyserial or termios raise: say so
            raise HardwareError(f"cannot open port {self.name!r}: "
                                f"{describe_sdk_exception(exc)[1]}") from None
        if not ok:
            raise HardwareError(f"baudrate {self.config.baudrate} in {self.config.source} is not "
                                f"supported by dynamixel-sdk; NICO uses 1000000")

    def close(self) -> None:
        """Close the port; a port that already failed is given up without a further error
        (the failure that matters has been reported)."""
        try:
            if self.port.is_open:
                self.port.closePort()
        except Exception:  # closing a dead port: nothing left to do
            pass

    def _call(self, what: str, index: int | None, function, *args):
        label = "the bus" if index is None else f"motor {self.config.label(index)}"
        try:
            *values, result, error = function(self.port, *args)
        except Exception as exc:  # termios.error, OSError, serial, SDK bugs
            self.port.is_using = False  # the SDK leaves it set when it raises mid-packet
            port_failed, reason = describe_sdk_exception(exc)
            where = f"port {self.name!r} failed: " if port_failed else ""
            raise CommunicationError(f"{what} on {label}: {where}{reason}") from None
        if result != self.sdk.COMM_SUCCESS:
            raise CommunicationError(f"{what} on {label}: {self._describe(result)}",
                                     timeout=result == self.sdk.COMM_RX_TIMEOUT)
        if error:
            raise CommunicationError(f"{what}: {label} reports error "
                                     f"{describe_error(error)} (status error byte 0x{error:02x})")
        return values[0] if values else None

    def _describe(self, result: int) -> str:
        sdk = self.sdk
        return {sdk.COMM_RX_TIMEOUT: "no status packet (timeout)",
                sdk.COMM_RX_CORRUPT: "corrupted status packet (bad checksum or length)",
                sdk.COMM_TX_FAIL: "could not send the instruction packet",
                sdk.COMM_PORT_BUSY: "port busy"}.get(result, self.handler.getTxRxResult(result))

    def ping(self) -> dict[int, int]:
        """Ping every motor; return id -> model number. Names all missing ids at once."""
        models, missing = {}, []
        for index, motor in enumerate(self.config.motors):
            try:
                models[motor.id] = self._call("ping", index, self.handler.ping, motor.id)
            except CommunicationError as exc:
                if not exc.timeout:
                    raise
                missing.append(self.config.label(index))
        if missing:
            raise CommunicationError(
                f"no answer from motor(s) {', '.join(missing)} on {self.name} at "
                f"{self.config.baudrate} baud; check power, cables and the ids in "
                f"{self.config.source}")
        for index, motor in enumerate(self.config.motors):
            if motor.model_number not in (None, models[motor.id]):
                names = {number: name for name, (number, _) in MODELS.items()}
                raise HardwareError(
                    f"motor {self.config.label(index)} reports model number {models[motor.id]} "
                    f"({names.get(models[motor.id], 'unknown')}) but {self.config.source} says "
                    f"{motor.model}")
        return models

    def read_present_raw(self, index: int) -> int:
        return self._call("read present position", index, self.handler.read2ByteTxRx,
                          self.config.motors[index].id, ADDR_PRESENT_POSITION)

    def read_all_raw(self) -> np.ndarray:
        """(dof,) present positions (register values): one READ per motor."""
        return np.array([self.read_present_raw(i) for i in range(len(self.config.motors))])

    def write_goal(self, index: int, goal_raw: int, speed_raw: int) -> None:
        """WRITE goal position and moving speed of one motor, with its status checked."""
        self._check_goal(index, goal_raw)
        data = list(int(goal_raw).to_bytes(2, "little") + int(speed_raw).to_bytes(2, "little"))
        self._call("write goal position", index, self.handler.writeTxRx,
                   self.config.motors[index].id, ADDR_GOAL_POSITION, 4, data)
        self.last_goal_raw[index] = int(goal_raw)

    def enable_torque(self, index: int) -> None:
        self._call("enable torque", index, self.handler.write1ByteTxRx,
                   self.config.motors[index].id, ADDR_TORQUE_ENABLE, 1)

    def sync_write(self, goals_raw: dict[int, int], speeds_raw: dict[int, int]) -> None:
        """One SYNC WRITE at address 30: goal position + moving speed for the given indices."""
        group = self.sdk.GroupSyncWrite(self.port, self.handler, ADDR_GOAL_POSITION, 4)
        for index, goal in goals_raw.items():
            self._check_goal(index, goal)
            data = int(goal).to_bytes(2, "little") + int(speeds_raw[index]).to_bytes(2, "little")
            group.addParam(self.config.motors[index].id, list(data))
        self._call("sync write", None, lambda port: (group.txPacket(), 0))
        self.last_goal_raw.update({index: int(goal) for index, goal in goals_raw.items()})

    def _check_goal(self, index: int, goal_raw: int) -> None:
        low, high = self.config.motors[index].raw_limits
        if not low <= goal_raw <= high:  # the plan is checked first; this is a last guard
            raise HardwareError(f"refusing goal {goal_raw} for motor {self.config.label(index)}: "
                                f"outside its limits [{low}, {high}]")
