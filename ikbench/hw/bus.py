"""The servo bus as the executor sees it: dynamixel-sdk (Protocol 1.0) calls whose failures
raise :class:`CommunicationError` naming the motor, the operation and what went wrong."""

from __future__ import annotations

import numpy as np

from ikbench.errors import HardwareError
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


class Bus:
    """dynamixel-sdk port + Protocol 1.0 packet handler; failures raise CommunicationError."""

    def __init__(self, port_name: str, config: MotorConfig):
        import dynamixel_sdk as sdk

        self.sdk, self.config, self.name = sdk, config, port_name
        self.port = sdk.PortHandler(port_name)
        self.handler = sdk.PacketHandler(1.0)

    def open(self) -> None:
        import serial

        try:
            ok = self.port.setBaudRate(self.config.baudrate)  # opens the port
        except (OSError, serial.SerialException) as exc:
            raise HardwareError(f"cannot open port {self.name!r}: {exc}") from None
        if not ok:
            raise HardwareError(f"baudrate {self.config.baudrate} in {self.config.source} is not "
                                f"supported by dynamixel-sdk; NICO uses 1000000")

    def close(self) -> None:
        if self.port.is_open:
            self.port.closePort()

    def _call(self, what: str, index: int | None, function, *args):
        import serial

        label = "the bus" if index is None else f"motor {self.config.label(index)}"
        try:
            *values, result, error = function(self.port, *args)
        except (OSError, serial.SerialException) as exc:
            self.port.is_using = False
            raise CommunicationError(f"{what} on {label}: port {self.name!r} failed: {exc}") \
                from None
        if result != self.sdk.COMM_SUCCESS:
            raise CommunicationError(f"{what} on {label}: {self._describe(result)}",
                                     timeout=result == self.sdk.COMM_RX_TIMEOUT)
        if error:
            raise CommunicationError(f"{what}: motor {self.config.label(index)} reports error "
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

    def _check_goal(self, index: int, goal_raw: int) -> None:
        low, high = self.config.motors[index].raw_limits
        if not low <= goal_raw <= high:  # the plan is checked first; this is a last guard
            raise HardwareError(f"refusing goal {goal_raw} for motor {self.config.label(index)}: "
                                f"outside its limits [{low}, {high}]")
