"""Vectorised FK and analytic Jacobians of a serial chain in torch, on any device.

The torch twin of :class:`~ikbench.core.kinematics.chain.ChainKinematics`: the same joint
placements, axes, their cross-product matrices and end frame, taken as they are from the numpy
chain (which alone reads them from the robot's Pinocchio model) and cast once to this dtype
and device; then the same operations in the same order, as tensors. For a revolute joint with
world axis w through o, dP/dq = w x (P - o) and dv/dq = w x v; for a prismatic joint
dP/dq = w and dv/dq = 0; times dq/dp, the URDF units per pose unit. In float64 its outputs
equal the numpy chain's to about 1e-15 (``tests/test_ours_lm_torch.py`` holds them to 1e-12).

The pass over the joints is the numpy chain's,
:func:`~ikbench.core.kinematics.chain.joint_product` (only ``@``, ``+``, ``*`` and indexing,
alike on tensors), given the rotation about each joint axis in torch operations on the
tensors' device (:func:`_rotation`); the chain module's docstring names the third twin,
numba's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ikbench.core.kinematics.chain import joint_product

if TYPE_CHECKING:
    import torch
    from torch import Tensor

    from ikbench.core.robot import Robot


def torch_chain_kinematics(robot: Robot, dtype: torch.dtype | None = None,
                           device: str | torch.device = "cpu") -> TorchChainKinematics:
    """The robot's :class:`TorchChainKinematics` for ``dtype`` / ``device`` (cached)."""
    import torch

    dtype = dtype or torch.float64
    key = ("chain_torch", dtype, str(torch.device(device)))
    cache = robot._cache
    if key not in cache:
        cache[key] = TorchChainKinematics(robot, dtype=dtype, device=device)
    return cache[key]


class TorchChainKinematics:
    """FK and Jacobians of the robot's chain for many poses at once, in torch.

    Args:
        robot: the :class:`ikbench.core.robot.Robot`.
        dtype: torch float dtype (default float64).
        device: torch device (``"cpu"``, ``"cuda"``, ``"cuda:1"``, ...).

    Call with poses (M, dof) [pose units]; returns the end point [m] (M, 3), the pointing
    direction (M, 3) and their Jacobians d/d(pose unit) (M, 3, dof), all tensors.
    """

    def __init__(self, robot: Robot, dtype: torch.dtype | None = None,
                 device: str | torch.device = "cpu") -> None:
        import torch

        chain = robot.chain_kinematics()
        self.robot = robot
        self.dof = chain.dof
        self.dtype = dtype or torch.float64
        self.device = torch.device(device)

        def tensor(value) -> Any:
            return torch.as_tensor(value, dtype=self.dtype, device=self.device)

        self.rotations = [tensor(r) for r in chain.rotations]        # (3, 3) each
        self.translations = [tensor(t) for t in chain.translations]  # (3,) each [m]
        self.axes = [tensor(a) for a in chain.axes]                  # (3,) unit, joint frame
        self.skews = [tensor(k) for k in chain.skews]                # (3, 3) [a]_x
        self.prismatic = [bool(p) for p in chain.prismatic]
        self.tip_rotation = tensor(chain.tip_rotation)
        self.tip_translation = tensor(chain.tip_translation)
        self.pointing_axis = tensor(robot.pointing_axis)
        self.urdf_per_unit = tensor(chain.urdf_per_unit)             # (dof,)
        self.revolute = torch.as_tensor([not p for p in self.prismatic], device=self.device)

    def transforms(self, poses: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        """(position_m (M, 3), rotation (M, 3, 3), axes_world (M, dof, 3), origins_m
        (M, dof, 3)) of the end frame and the joints, for poses (M, dof) [pose units]."""
        import torch

        q = self.robot.to_urdf(poses)
        m = q.shape[0]
        eye = torch.eye(3, dtype=self.dtype, device=self.device)
        rotations, origins, axes_world = zip(*joint_product(
            eye.expand(m, 3, 3), torch.zeros(m, 3, dtype=self.dtype, device=self.device), q,
            self, lambda j, angle: _rotation(eye, self.skews[j], angle)), strict=True)
        rot, pos = rotations[-1], origins[-1]
        point = pos + rot @ self.tip_translation
        return (point, rot @ self.tip_rotation, torch.stack(axes_world, 1),
                torch.stack(origins, 1))

    def __call__(self, poses, jacobian: bool = True):
        """FK (and Jacobians) of poses (M, dof) [pose units], a tensor of this dtype/device.

        Returns:
            (point_m (M, 3), direction (M, 3), J_point (M, 3, dof) [m / pose unit] or None,
            J_direction (M, 3, dof) [1 / pose unit] or None).
        """
        import torch

        point, rotation, w, o = self.transforms(poses)
        direction = rotation @ self.pointing_axis
        if not jacobian:
            return point, direction, None, None
        scale = self.urdf_per_unit[None, :, None]
        revolute = self.revolute[None, :, None]
        j_point = torch.where(revolute, torch.linalg.cross(w, point[:, None, :] - o), w) * scale
        j_dir = torch.where(revolute, torch.linalg.cross(w, direction[:, None, :].expand_as(w)),
                            torch.zeros((), dtype=self.dtype, device=self.device)) * scale
        return point, direction, j_point.transpose(1, 2), j_dir.transpose(1, 2)


def _rotation(eye: Tensor, skew: Tensor, angle_rad: Tensor) -> Tensor:
    """Rotations (M, 3, 3) about a unit axis (its skew matrix) by angles (M,) (Rodrigues)."""
    s, c = angle_rad.sin()[:, None, None], angle_rad.cos()[:, None, None]
    return eye + s * skew + (1.0 - c) * (skew @ skew)
