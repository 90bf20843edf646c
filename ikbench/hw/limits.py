"""The joint limits ``--timing topp`` plans within, for any robot (see
:mod:`ikbench.core.timing_limits`): a robot with servos (NICO) uses its motor table, any other
its URDF and limits file; ``--max-velocity`` / ``--max-acceleration`` override them."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ikbench.core.timing import Limits
from ikbench.core.timing_limits import parse_limit_option, urdf_limits, with_overrides
from ikbench.hw.motors import MotorConfig, load_motor_config

if TYPE_CHECKING:
    from ikbench.core.robot import Robot


def motor_limits(config: MotorConfig) -> Limits:
    """Limits of a motor table [motor deg/s, motor deg/s^2]."""
    return Limits(config.max_speed_deg_s, config.max_acceleration_deg_s2,
                  f"{Path(config.source).name} (max_speed_deg_s, max_acceleration_deg_s2)")


def timing_limits(robot: Robot, config: MotorConfig | None = None, max_velocity: str | None = None,
                  max_acceleration: str | None = None) -> Limits:
    """The robot's limits [pose units/s, /s^2].

    Args:
        robot: the robot.
        config: its motor table (default: the robot's, when its config names one).
        max_velocity: ``--max-velocity`` (one value or one per joint), overriding.
        max_acceleration: ``--max-acceleration``, overriding.
    """
    velocity = parse_limit_option(max_velocity, robot.dof, "max_velocity")
    acceleration = parse_limit_option(max_acceleration, robot.dof, "max_acceleration")
    if config is None and robot.config.hardware:
        config = load_motor_config(None, robot)
    limits = motor_limits(config) if config is not None else urdf_limits(robot, velocity)
    return with_overrides(limits, velocity, acceleration)
