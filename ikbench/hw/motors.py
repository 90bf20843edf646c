"""Motor configuration (one Dynamixel per joint) and motor-degree <-> register conversions.

A motor config file is JSON::

    {"baudrate": 1000000,
     "motors": {"r_shoulder_z": {"id": 21, "model": "MX", "offset_deg": 0.0,
                                 "orientation": "direct", "angle_limit_deg": [-30, 80],
                                 "max_speed_deg_s": 270, "max_acceleration_deg_s2": 1000},
                ...}}

Every joint of the robot needs exactly one entry. Positions follow the MX series in Protocol
1.0: 4096 steps per turn, raw 2048 = 0 deg, ``raw = round(2048 + sign*(deg + offset)*4096/360)``
with sign +1 for ``direct`` and -1 for ``indirect``. Speeds are in units of 0.114 rpm
(0.684 deg/s); raw 0 means "no speed control" (full speed), so a slow segment is sent as 1.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot, load_robot

BAUDRATE = 1_000_000
PROTOCOL_VERSION = 1.0
#: MX-series control table (Protocol 1.0) addresses used here.
ADDR_MODEL_NUMBER = 0
ADDR_CW_ANGLE_LIMIT = 6
ADDR_CCW_ANGLE_LIMIT = 8
ADDR_TORQUE_ENABLE = 24
ADDR_GOAL_POSITION = 30
ADDR_MOVING_SPEED = 32
ADDR_PRESENT_POSITION = 36
POSITION_STEPS = 4096
CENTER_RAW = 2048
RAW_MAX = POSITION_STEPS - 1
DEG_PER_STEP = 360.0 / POSITION_STEPS
#: One moving-speed unit: 0.114 rpm = 0.684 deg/s.
SPEED_UNIT_DEG_S = 0.114 * 360.0 / 60.0
SPEED_RAW_MIN = 1
SPEED_RAW_MAX = 1023
LIMIT_TOLERANCE_DEG = 1e-6
ORIENTATIONS = {"direct": 1, "indirect": -1}
#: Supported models: model number reported at address 0, no-load speed at 12 V [deg/s]
#: (ROBOTIS e-manual). "MX" means "some MX-series motor": no model-number check, and the
#: slowest no-load speed of the family as the default speed limit.
MODELS = {
    "MX-28": (29, 330.0),
    "MX-64": (310, 378.0),
    "MX-106": (320, 270.0),
    "MX": (None, 270.0),
}
#: Keys a config file may have at top level and per motor ("description": free text, ignored).
#: Anything else is refused: a misspelt key (``"offset"``, ``"orientaton"``) would otherwise
#: silently drop the calibration it was meant to give.
CONFIG_KEYS = ("description", "baudrate", "motors")
MOTOR_KEYS = ("id", "model", "offset_deg", "orientation", "angle_limit_deg", "max_speed_deg_s",
              "max_acceleration_deg_s2", "description")
#: Acceleration limit [deg/s^2] a plan is timed within (``--timing topp``) when a motor gives
#: none. An assumption, not a measurement: the MX series' own acceleration profile (Goal
#: Acceleration, address 73, 8.583 deg/s^2 per unit) reaches 2180 deg/s^2 unloaded; about half
#: of it leaves torque for the arm's load and reaches the 270 deg/s speed limit in 0.27 s.
DEFAULT_MAX_ACCELERATION_DEG_S2 = 1000.0


@dataclass(frozen=True)
class Motor:
    """One joint's Dynamixel.

    Attributes:
        joint: joint name.
        id: Dynamixel id (0..252).
        model: one of :data:`MODELS`.
        offset_deg: calibration offset [motor deg], added before the sign.
        orientation: ``"direct"`` or ``"indirect"``.
        lower_deg, upper_deg: angle limits [motor deg]; no goal outside is ever sent.
        max_speed_deg_s: speed limit [deg/s] that plans are checked against.
        max_acceleration_deg_s2: acceleration limit [deg/s^2] that ``--timing topp`` plans
            within (see :data:`DEFAULT_MAX_ACCELERATION_DEG_S2`).
    """

    joint: str
    id: int
    model: str
    offset_deg: float
    orientation: str
    lower_deg: float
    upper_deg: float
    max_speed_deg_s: float
    max_acceleration_deg_s2: float = DEFAULT_MAX_ACCELERATION_DEG_S2

    @property
    def sign(self) -> int:
        """+1 for direct, -1 for indirect orientation."""
        return ORIENTATIONS[self.orientation]

    @property
    def model_number(self) -> int | None:
        """Model number the motor reports at address 0 (None: not checked)."""
        return MODELS[self.model][0]

    def deg_to_raw_unclipped(self, q_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Goal register value(s) for angle(s) [motor deg], rounded, not clipped."""
        steps = self.sign * (np.asarray(q_motor_deg, dtype=float) + self.offset_deg) / DEG_PER_STEP
        return np.rint(CENTER_RAW + steps).astype(np.int64)

    def deg_to_raw(self, q_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Goal register value(s) in 0..4095 (+180 deg maps to 4096, sent as 4095)."""
        return np.clip(self.deg_to_raw_unclipped(q_motor_deg), 0, RAW_MAX)

    def raw_to_deg(self, raw: npt.ArrayLike) -> np.ndarray:
        """Angle(s) [motor deg] of register value(s)."""
        return self.sign * (np.asarray(raw, dtype=float) - CENTER_RAW) * DEG_PER_STEP \
            - self.offset_deg

    @property
    def raw_limits(self) -> tuple[int, int]:
        """(low, high) goal register values of the angle limits."""
        ends = sorted(int(v) for v in self.deg_to_raw([self.lower_deg, self.upper_deg]))
        return ends[0], ends[1]


def _per_motor(field: str) -> property:
    """A read-only property: the motors' ``field`` as an array, one value per motor."""
    return property(lambda self: np.array([getattr(m, field) for m in self.motors]))


@dataclass(frozen=True)
class MotorConfig:
    """The motors of a robot, in the robot's joint order.

    Attributes:
        motors: one :class:`Motor` per joint, in ``joint_names`` order.
        baudrate: bus speed [baud].
        source: the file it was read from.
    """

    motors: tuple[Motor, ...]
    baudrate: int = BAUDRATE
    source: str = "nico_right_arm.dynamixel.json"

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(m.joint for m in self.motors)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(m.id for m in self.motors)

    #: The motors' limits, one per motor (arrays): angles [deg], speed [deg/s], acceleration
    #: [deg/s^2].
    lower_deg = _per_motor("lower_deg")
    upper_deg = _per_motor("upper_deg")
    max_speed_deg_s = _per_motor("max_speed_deg_s")
    max_acceleration_deg_s2 = _per_motor("max_acceleration_deg_s2")

    def label(self, index: int) -> str:
        """``"id 5 (r_elbow_y)"`` for the motor at ``index``."""
        return f"id {self.motors[index].id} ({self.motors[index].joint})"

    def by_id(self, motor_id: int) -> Motor:
        """The motor with Dynamixel id ``motor_id``."""
        for motor in self.motors:
            if motor.id == motor_id:
                return motor
        raise InputError(f"motor id {motor_id} is not in {self.source}; ids: {list(self.ids)}")

    def poses_to_raw(self, poses_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Goal register values (..., dof) for poses (..., dof) [motor deg]."""
        poses = np.asarray(poses_motor_deg, dtype=float)
        return np.stack([m.deg_to_raw(poses[..., i]) for i, m in enumerate(self.motors)], -1)

    def raw_to_poses(self, raw: npt.ArrayLike) -> np.ndarray:
        """Poses (..., dof) [motor deg] for register values (..., dof)."""
        raw = np.asarray(raw)
        return np.stack([m.raw_to_deg(raw[..., i]) for i, m in enumerate(self.motors)], -1)

    def outside_limits(self, poses_motor_deg: npt.ArrayLike) -> np.ndarray:
        """Boolean mask (..., dof): angle outside its motor's angle limits."""
        poses = np.asarray(poses_motor_deg, dtype=float)
        return (poses < self.lower_deg - LIMIT_TOLERANCE_DEG) | (
            poses > self.upper_deg + LIMIT_TOLERANCE_DEG)


def speed_to_raw(speed_deg_s: npt.ArrayLike) -> np.ndarray:
    """Moving-speed register values for speeds [deg/s]: rounded up, clamped to 1..1023.

    Rounded up so that a joint finishes its segment in time (at most one unit, 0.684 deg/s,
    early) instead of falling behind by a little more every segment. Never 0: the MX series
    reads 0 as "full speed", the opposite of a slow segment.
    """
    units = np.abs(np.asarray(speed_deg_s, dtype=float)) / SPEED_UNIT_DEG_S
    raw = np.ceil(units - 1e-9)
    return np.clip(raw, SPEED_RAW_MIN, SPEED_RAW_MAX).astype(np.int64)


def raw_to_speed(raw: npt.ArrayLike) -> np.ndarray:
    """Speeds [deg/s] of moving-speed register values (0 is "full speed": returned as 0)."""
    return np.asarray(raw, dtype=float) * SPEED_UNIT_DEG_S


def default_config_path(robot: Robot | None = None) -> Path:
    """Path of the robot's motor config (its config's ``hardware`` file; NICO's right arm by
    default).

    Raises:
        InputError: the robot names no motor config.
    """
    robot = robot or load_robot()
    name = robot.config.hardware
    if not name:
        raise InputError(f"robot {robot.name} has no motor config (no 'hardware' in its robot "
                         "config); give --motors FILE")
    return Path(str(robot.config.config_path)).parent / name


def load_motor_config(path: str | Path | None = None, robot: Robot | None = None) -> MotorConfig:
    """Read and validate a motor config file (default: the robot's; NICO's right arm).

    Raises:
        InputError: a missing or unreadable file, or an entry naming the bad value and what is
            allowed.
    """
    robot = robot or load_robot()
    path = Path(path) if path is not None else default_config_path(robot)
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"motor config file {str(path)!r} not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"motor config {str(path)!r} is not readable JSON: {exc}") from None
    return parse_motor_config(spec, robot, str(path))


def parse_motor_config(spec: Any, robot: Robot, source: str) -> MotorConfig:
    """Validate a motor config (the parsed JSON); see :func:`load_motor_config`."""
    if not isinstance(spec, dict) or not isinstance(spec.get("motors"), dict):
        raise InputError(f"{source}: needs an object with a \"motors\" object keyed by joint name")
    _check_keys(spec, CONFIG_KEYS, f"{source}: unknown top-level key")
    entries = spec["motors"]
    unknown = [name for name in entries if name not in robot.joint_names]
    missing = [name for name in robot.joint_names if name not in entries]
    if unknown or missing:
        raise InputError(
            f"{source}: motors must be exactly the joints {', '.join(robot.joint_names)}; "
            f"unknown: {unknown or 'none'}, missing: {missing or 'none'}"
        )
    motors = tuple(_parse_motor(name, entries[name], f"{source}: {name}")
                   for name in robot.joint_names)
    ids = [m.id for m in motors]
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise InputError(f"{source}: motor id(s) {duplicates} are used by more than one joint")
    baudrate = spec.get("baudrate", BAUDRATE)
    if not isinstance(baudrate, int) or isinstance(baudrate, bool) or baudrate <= 0:
        raise InputError(f"{source}: baudrate = {baudrate!r}; give a positive integer "
                         f"(NICO: {BAUDRATE})")
    return MotorConfig(motors=motors, baudrate=baudrate, source=source)


def _check_keys(entry: dict, allowed: tuple[str, ...], what: str) -> None:
    """Refuse keys of ``entry`` not in ``allowed``; ``what`` starts the message."""
    import difflib

    for key in entry:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(f"{what} {key!r}{hint}; allowed: {', '.join(allowed)}")


def _number(entry: dict, key: str, where: str, default=None) -> float:
    value = entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where}.{key} = {value!r}; give a finite number")
    return float(value)


def _parse_motor(name: str, entry, where: str) -> Motor:
    if not isinstance(entry, dict):
        raise InputError(f"{where}: expected an object with id, model, offset_deg, orientation, "
                         f"angle_limit_deg")
    _check_keys(entry, MOTOR_KEYS, f"{where}: unknown key")
    motor_id = entry.get("id")
    if isinstance(motor_id, bool) or not isinstance(motor_id, int) or not 0 <= motor_id <= 252:
        raise InputError(f"{where}.id = {motor_id!r}; give an integer Dynamixel id in 0..252")
    model = entry.get("model", "MX")
    if model not in MODELS:
        raise InputError(f"{where}.model = {model!r}; allowed: {', '.join(MODELS)}")
    orientation = entry.get("orientation", "direct")
    if orientation not in ORIENTATIONS:
        raise InputError(f"{where}.orientation = {orientation!r}; allowed: direct, indirect")
    limits = entry.get("angle_limit_deg")
    if not isinstance(limits, list) or len(limits) != 2:
        raise InputError(f"{where}.angle_limit_deg = {limits!r}; give [lower, upper] in motor "
                         f"degrees")
    lower = _number({"angle_limit_deg[0]": limits[0]}, "angle_limit_deg[0]", where)
    upper = _number({"angle_limit_deg[1]": limits[1]}, "angle_limit_deg[1]", where)
    if not lower < upper:
        raise InputError(f"{where}.angle_limit_deg = {limits!r}; lower must be below upper")
    max_speed = _number(entry, "max_speed_deg_s", where, MODELS[model][1])
    top = SPEED_RAW_MAX * SPEED_UNIT_DEG_S
    if not 0 < max_speed <= top:
        raise InputError(f"{where}.max_speed_deg_s = {max_speed:g}; allowed: (0, {top:.1f}] "
                         f"(the moving-speed register's range)")
    max_acceleration = _number(entry, "max_acceleration_deg_s2", where,
                               DEFAULT_MAX_ACCELERATION_DEG_S2)
    if not max_acceleration > 0:
        raise InputError(f"{where}.max_acceleration_deg_s2 = {max_acceleration:g}; give a "
                         "positive number")
    motor = Motor(name, motor_id, model, _number(entry, "offset_deg", where, 0.0), orientation,
                  lower, upper, max_speed, max_acceleration)
    for limit in (lower, upper):
        raw = int(motor.deg_to_raw_unclipped(limit))
        if not 0 <= raw <= POSITION_STEPS:
            raise InputError(
                f"{where}: angle limit {limit:g} deg maps to raw {raw}, outside the encoder "
                f"range 0..{RAW_MAX}; narrow angle_limit_deg or change offset_deg"
            )
    return motor
