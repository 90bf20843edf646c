"""Batched, differentiable FK through pytorch-kinematics (torch), float32 or float64."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pytorch_kinematics as pk
    import torch
    from torch import Tensor

from ikbench.core.kinematics.robot_like import RobotLike


def _float64_transform(origin):
    """URDF origin -> float64 Transform3d (pytorch-kinematics rounds rpy to float32)."""
    import pytorch_kinematics.transforms as tf
    import torch

    if origin is None:
        return tf.Transform3d(dtype=torch.float64)
    rpy = torch.tensor(origin.rpy, dtype=torch.float64)
    pos = torch.tensor(origin.xyz, dtype=torch.float64)
    return tf.Transform3d(rot=tf.quaternion_from_euler(rpy, "sxyz"), pos=pos, dtype=torch.float64)


def build_chain_float64(urdf_bytes: bytes, end_frame: str, root_frame: str = ""
                        ) -> pk.SerialChain:
    """``pk.build_serial_chain_from_urdf`` with its constant transforms exact in float64.

    pytorch-kinematics (0.10) converts every URDF ``rpy`` and joint axis through a float32
    tensor, which moves the NICO fingertip by ~4e-8 m (an unaligned axis: ~3e-9 m more). After
    the normal build, each joint offset and axis is recomputed in float64 from the URDF and the
    serial chain (``root_frame`` -> ``end_frame``; "" is
    the URDF's root) is built in float64; ``TorchFK`` then casts it to the dtype asked for.
    """
    import pytorch_kinematics as pk
    import pytorch_kinematics.urdf as pk_urdf
    import torch

    tree = pk.build_chain_from_urdf(urdf_bytes)
    joints = {j.name: j for j in pk_urdf.URDF.from_xml_string(urdf_bytes).joints}
    stack = [tree._root]
    while stack:
        frame = stack.pop()
        joint = joints.get(frame.joint.name)
        if joint is not None and frame.joint.offset is not None:
            frame.joint.offset = _float64_transform(joint.origin)
        if joint is not None and joint.axis is not None:
            axis = torch.tensor(joint.axis, dtype=torch.float64)
            frame.joint.axis = axis / axis.norm()
        if frame.link.offset is not None:
            frame.link.offset = frame.link.offset.to(device="cpu", dtype=torch.float64)
        stack.extend(frame.children)
    return pk.SerialChain(tree, end_frame, root_frame, dtype=torch.float64)


class TorchFK:
    """Batched, differentiable FK of the robot's chain through pytorch-kinematics.

    Args:
        robot: the :class:`ikbench.core.robot.Robot`.
        dtype: torch dtype (float32 or float64).
        device: torch device.
    """

    def __init__(self, robot: RobotLike, dtype: torch.dtype | None = None,
                 device: str = "cpu") -> None:
        import torch

        self.robot = robot
        self.dtype = dtype or torch.float32
        self.device = device
        chain = build_chain_float64(robot.urdf_model.to_xml(collisions=False).encode(),
                                    robot.end_frame, robot.root_link)
        names = tuple(chain.get_joint_parameter_names())
        free = tuple(n for n in names if n not in robot.locked_urdf)
        if free != robot.joint_names:
            raise ValueError(f"URDF joint order {free} differs from {robot.joint_names}")
        self.chain = chain.to(dtype=self.dtype, device=device)
        # locked joints: their value is inserted into the chain's joint vector
        self._columns = [names.index(n) for n in robot.joint_names]
        self._locked = (torch.tensor([robot.locked_urdf.get(n, 0.0) for n in names],
                                     dtype=self.dtype, device=device)
                        if robot.locked_urdf else None)
        self.pointing_axis = torch.as_tensor(robot.pointing_axis, dtype=self.dtype,
                                             device=device)

    def transform(self, q_pose: Tensor) -> Tensor:
        """End-frame homogeneous transforms (B, 4, 4) [m] for poses (B, dof) [pose units]."""
        q_urdf = self.robot.to_urdf(q_pose)
        if self._locked is not None:
            full = self._locked.expand(q_urdf.shape[0], -1).clone()
            full[:, self._columns] = q_urdf
            q_urdf = full
        return self.chain.forward_kinematics(q_urdf).get_matrix()

    def __call__(self, q_pose):
        """Return ``(point_m, direction)`` tensors (B, 3) for poses (B, dof) [pose units]."""
        T_base_tip = self.transform(q_pose)
        return T_base_tip[:, :3, 3], T_base_tip[:, :3, :3] @ self.pointing_axis
