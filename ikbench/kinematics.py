"""Forward-kinematics backends behind one small interface.

Each backend is called with poses in motor degrees, shape (B, dof), and returns
``(point_m, direction)``: the end-frame origin [m] and its z-axis (unit pointing direction),
both (B, 3), in the robot's root frame.
"""

from __future__ import annotations

import numpy as np


def _float64_transform(origin):
    """URDF origin -> float64 Transform3d (pytorch-kinematics rounds rpy to float32)."""
    import pytorch_kinematics.transforms as tf
    import torch

    if origin is None:
        return tf.Transform3d(dtype=torch.float64)
    rpy = torch.tensor(origin.rpy, dtype=torch.float64)
    pos = torch.tensor(origin.xyz, dtype=torch.float64)
    return tf.Transform3d(rot=tf.quaternion_from_euler(rpy, "sxyz"), pos=pos, dtype=torch.float64)


def _build_chain_float64(urdf_bytes: bytes, end_frame: str):
    """``pk.build_serial_chain_from_urdf`` with its constant transforms exact in float64.

    pytorch-kinematics (0.10) converts every URDF ``rpy`` through a float32 tensor, which moves
    the NICO fingertip by ~4e-8 m. After the normal build, each joint offset is recomputed in
    float64 from the URDF origin and the serial chain is built in float64; ``TorchFK`` then casts
    it to the dtype asked for.
    """
    import pytorch_kinematics as pk
    import pytorch_kinematics.urdf as pk_urdf
    import torch

    tree = pk.build_chain_from_urdf(urdf_bytes)
    origins = {j.name: j.origin for j in pk_urdf.URDF.from_xml_string(urdf_bytes).joints}
    stack = [tree._root]
    while stack:
        frame = stack.pop()
        if frame.joint.name in origins and frame.joint.offset is not None:
            frame.joint.offset = _float64_transform(origins[frame.joint.name])
        if frame.link.offset is not None:
            frame.link.offset = frame.link.offset.to(device="cpu", dtype=torch.float64)
        stack.extend(frame.children)
    return pk.SerialChain(tree, end_frame, "", dtype=torch.float64)


class TorchFK:
    """Batched, differentiable FK through pytorch-kinematics.

    Args:
        robot: the :class:`ikbench.robot.Robot`.
        dtype: torch dtype (float32 or float64).
        device: torch device.
    """

    def __init__(self, robot, dtype=None, device: str = "cpu"):
        import torch

        self.robot = robot
        self.dtype = dtype or torch.float32
        self.device = device
        chain = _build_chain_float64(robot.urdf_path.read_bytes(), robot.end_frame)
        names = tuple(chain.get_joint_parameter_names())
        if names != robot.joint_names:
            raise ValueError(f"URDF joint order {names} differs from {robot.joint_names}")
        self.chain = chain.to(dtype=self.dtype, device=device)

    def transform(self, q_motor_deg):
        """End-frame homogeneous transforms (B, 4, 4) for poses (B, dof) [motor deg]."""
        q_rad = self.robot.motor_to_joint_rad(q_motor_deg)
        return self.chain.forward_kinematics(q_rad).get_matrix()

    def __call__(self, q_motor_deg):
        """Return ``(point_m, direction)`` tensors (B, 3) for poses (B, dof) [motor deg]."""
        T_base_tip = self.transform(q_motor_deg)
        return T_base_tip[:, :3, 3], T_base_tip[:, :3, 2]


class PinocchioFK:
    """FK through Pinocchio (float64, numpy), plus access to its model for IK and Jacobians."""

    def __init__(self, robot):
        import pinocchio as pin

        self.robot = robot
        self.model = pin.buildModelFromUrdf(str(robot.urdf_path))
        names = tuple(self.model.names[1:])
        if names != robot.joint_names:
            raise ValueError(f"URDF joint order {names} differs from {robot.joint_names}")
        self.data = self.model.createData()
        self.frame_id = self.model.getFrameId(robot.end_frame)

    def placement(self, q_rad: np.ndarray):
        """The end frame's ``pin.SE3`` for one configuration (dof,) [rad]."""
        import pinocchio as pin

        pin.framesForwardKinematics(self.model, self.data, q_rad)
        return self.data.oMf[self.frame_id]

    def __call__(self, q_motor_deg):
        """Return ``(point_m, direction)`` arrays (B, 3) for poses (B, dof) [motor deg]."""
        q_rad = self.robot.motor_to_joint_rad(np.atleast_2d(np.asarray(q_motor_deg, float)))
        point_m = np.empty((len(q_rad), 3))
        direction = np.empty((len(q_rad), 3))
        for i, q in enumerate(q_rad):
            T_base_tip = self.placement(q)
            point_m[i] = T_base_tip.translation
            direction[i] = T_base_tip.rotation[:, 2]
        return point_m, direction
