"""What the FK backends read of a robot, as a Protocol (:class:`ikbench.core.robot.Robot` is one).

The backends sit below the robot that builds them (``Robot.torch_fk()``, ``pinocchio_fk()``,
``chain_kinematics()``), so they name the robot by this structural type rather than importing
its module: the arrow runs one way only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ikbench.core.urdf_model import UrdfModel


class RobotLike(Protocol):
    """A serial chain of a URDF with its pose units (see :class:`ikbench.core.robot.Robot`)."""

    @property
    def dof(self) -> int:
        """Number of movable joints of the chain."""
        ...

    @property
    def urdf_path(self) -> Path:
        """Path of the URDF (SI units)."""
        ...

    @property
    def end_frame(self) -> str:
        """The link whose origin is the end point and whose ``pointing_axis`` points."""
        ...

    @property
    def root_link(self) -> str:
        """The chain's base link; positions are in its frame."""
        ...

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The chain's movable joints, base to end, in pose order."""
        ...

    @property
    def pointing_axis(self) -> np.ndarray:
        """(3,) unit axis of the end frame that "points"."""
        ...

    @property
    def locked_urdf(self) -> dict:
        """Joints of the chain held fixed, name -> value [rad or m]."""
        ...

    @property
    def urdf_model(self) -> UrdfModel:
        """The URDF as read when the robot was loaded."""
        ...

    def to_urdf(self, q: Any) -> Any:
        """Poses [pose units] -> URDF joint values [rad, m]; arrays or tensors (..., dof)."""
        ...
