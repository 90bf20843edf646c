"""ikbench: generate robot-arm trajectories of a required shape and compare kinematics methods.

Poses are in motor degrees, reports in millimetres and degrees. Start with
:func:`load_robot` and :func:`load_targets`.
"""

__version__ = "0.1.0"

from ikbench.errors import IkbenchError, InputError  # noqa: E402
from ikbench.robot import Robot, load_robot  # noqa: E402
from ikbench.targets import Targets, load_targets  # noqa: E402

__all__ = ["IkbenchError", "InputError", "Robot", "Targets", "load_robot", "load_targets"]
