"""The robot model: URDF + end frame + motor<->joint map + motor ranges, with FK backends.

Poses at every interface are in **motor degrees** (what NICO reports), in the order of
``Robot.joint_names``. The URDF speaks radians; :meth:`Robot.motor_to_joint_rad` maps between.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ikbench.errors import InputError

URDF_DIR = Path(__file__).resolve().parents[1] / "urdf"
DEFAULT_ROBOT = "nico_right_arm"
DEG2RAD = math.pi / 180.0
#: Tolerance [motor deg] when checking that a pose lies within the motor ranges.
RANGE_TOLERANCE_DEG = 1e-6


class FKResult(NamedTuple):
    """Fingertip point [mm] and unit pointing direction (end frame z-axis), both (B, 3)."""

    point_mm: np.ndarray
    direction: np.ndarray


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial arm described by a URDF and a motor calibration file.

    Attributes:
        name: robot name (the calibration file's stem).
        urdf_path: path of the URDF (SI units).
        end_frame: name of the frame whose origin is the fingertip and whose z-axis points.
        root_link: name of the URDF root link (the torso base for NICO).
        joint_names: actuated joint names, in pose order.
        scale: (dof,) joint_deg = scale * motor_deg + offset_deg.
        offset_deg: (dof,) see ``scale``.
        lower_motor_deg: (dof,) lower motor limits [motor deg].
        upper_motor_deg: (dof,) upper motor limits [motor deg].
    """

    name: str
    urdf_path: Path
    end_frame: str
    root_link: str
    joint_names: tuple[str, ...]
    scale: np.ndarray
    offset_deg: np.ndarray
    lower_motor_deg: np.ndarray
    upper_motor_deg: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def dof(self) -> int:
        """Number of actuated joints."""
        return len(self.joint_names)

    # ----- motor <-> joint map -------------------------------------------------------------
    def motor_to_joint_rad(self, q_motor_deg):
        """Map motor degrees to URDF joint radians; numpy arrays or torch tensors (..., dof)."""
        scale, offset = self._map_constants(q_motor_deg)
        return (q_motor_deg * scale + offset) * DEG2RAD

    def joint_rad_to_motor_deg(self, q_rad):
        """Inverse of :meth:`motor_to_joint_rad`."""
        scale, offset = self._map_constants(q_rad)
        return (q_rad / DEG2RAD - offset) / scale

    def _map_constants(self, like):
        if isinstance(like, np.ndarray) or np.isscalar(like):
            return self.scale, self.offset_deg
        import torch

        key = ("map", like.dtype, like.device)
        if key not in self._cache:
            self._cache[key] = (
                torch.as_tensor(self.scale, dtype=like.dtype, device=like.device),
                torch.as_tensor(self.offset_deg, dtype=like.dtype, device=like.device),
            )
        return self._cache[key]

    # ----- validation -------------------------------------------------------------------------
    def check_pose(self, pose_motor_deg, what: str = "pose") -> np.ndarray:
        """Validate one pose (length, finite, within the motor ranges); return it as float64.

        Raises:
            InputError: naming the bad entry and the allowed values.
        """
        try:
            pose = np.asarray(pose_motor_deg, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                f"{what}: {pose_motor_deg!r} is not a list of {self.dof} numbers "
                f"(motor degrees, order {', '.join(self.joint_names)})"
            ) from None
        if pose.shape != (self.dof,):
            raise InputError(
                f"{what}: expected {self.dof} angles ({', '.join(self.joint_names)}), "
                f"got {pose.size}"
            )
        for name, value, lo, hi in zip(
            self.joint_names, pose, self.lower_motor_deg, self.upper_motor_deg
        ):
            if not math.isfinite(value):
                raise InputError(f"{what}: {name} = {value} is not a finite number")
            if value < lo - RANGE_TOLERANCE_DEG or value > hi + RANGE_TOLERANCE_DEG:
                raise InputError(
                    f"{what}: {name} = {value:g} motor deg is outside its range [{lo:g}, {hi:g}]"
                )
        return pose

    def within_limits(self, poses_motor_deg, tol_deg: float = RANGE_TOLERANCE_DEG) -> bool:
        """True when every pose in (..., dof) lies within the motor ranges (+- ``tol_deg``)."""
        poses = np.asarray(poses_motor_deg, dtype=float)
        return bool(
            np.all(poses >= self.lower_motor_deg - tol_deg)
            and np.all(poses <= self.upper_motor_deg + tol_deg)
        )

    # ----- kinematics -------------------------------------------------------------------------
    def torch_fk(self, dtype=None, device: str = "cpu"):
        """The pytorch-kinematics FK backend (cached per dtype/device); see :class:`TorchFK`."""
        import torch

        from ikbench.kinematics import TorchFK

        dtype = dtype or torch.float32
        key = ("torch_fk", dtype, str(device))
        if key not in self._cache:
            self._cache[key] = TorchFK(self, dtype=dtype, device=device)
        return self._cache[key]

    def pinocchio_fk(self):
        """The Pinocchio FK backend (cached); see :class:`PinocchioFK`."""
        from ikbench.kinematics import PinocchioFK

        if "pin_fk" not in self._cache:
            self._cache["pin_fk"] = PinocchioFK(self)
        return self._cache["pin_fk"]

    def fk(self, q_motor_deg, backend: str = "pinocchio") -> FKResult:
        """Fingertip point [mm] and pointing direction for poses (dof,) or (B, dof) [motor deg].

        Args:
            q_motor_deg: pose(s) in motor degrees.
            backend: ``"pinocchio"`` or ``"torch"`` (pytorch-kinematics, float64).

        Returns:
            FKResult with arrays of shape (B, 3) (B = 1 for a single pose).
        """
        q = np.atleast_2d(np.asarray(q_motor_deg, dtype=float))
        if backend == "pinocchio":
            point_m, direction = self.pinocchio_fk()(q)
        elif backend == "torch":
            import torch

            fk = self.torch_fk(dtype=torch.float64)
            with torch.no_grad():
                point_m, direction = fk(torch.as_tensor(q, dtype=torch.float64))
            point_m, direction = point_m.numpy(), direction.numpy()
        else:
            raise InputError(f"backend {backend!r} is unknown; choose one of: pinocchio, torch")
        return FKResult(point_m * 1000.0, direction)


@functools.lru_cache(maxsize=8)
def load_robot(name_or_path: str | Path = DEFAULT_ROBOT) -> Robot:
    """Load a robot from its motor calibration file.

    Args:
        name_or_path: a robot name under ``urdf/`` (``"nico_right_arm"``) or the path of a
            ``*.motors.json`` calibration file that names its URDF.
    """
    path = Path(name_or_path)
    if path.suffix != ".json":
        path = URDF_DIR / f"{name_or_path}.motors.json"
    if not path.is_file():
        raise InputError(f"robot calibration file {str(path)!r} not found")
    spec = json.loads(path.read_text())
    joints = spec["joints"]
    return Robot(
        name=path.name.removesuffix(".motors.json"),
        urdf_path=(path.parent / spec["urdf"]).resolve(),
        end_frame=spec["end_frame"],
        root_link=spec["root_link"],
        joint_names=tuple(j["name"] for j in joints),
        scale=np.array([j["scale"] for j in joints], dtype=float),
        offset_deg=np.array([j["offset_deg"] for j in joints], dtype=float),
        lower_motor_deg=np.array([j["lower_motor_deg"] for j in joints], dtype=float),
        upper_motor_deg=np.array([j["upper_motor_deg"] for j in joints], dtype=float),
    )
