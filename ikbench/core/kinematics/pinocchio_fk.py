"""FK through Pinocchio (float64, numpy), and the robot's Pinocchio model for IK and Jacobians.

The model holds only the robot's chain: every other movable joint of the URDF is locked at 0,
the config's locked joints at their values (``pinocchio.buildReducedModel``), continuous
joints are read as revolute joints with unbounded limits (one coordinate each, so
nq = nv = dof), and the chain's base link is the
model's world frame (positions and world-aligned Jacobians are in the base frame).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ikbench.core.kinematics.robot_like import RobotLike

#: Limit [rad] given to continuous joints in the model (Pinocchio needs finite numbers).
CONTINUOUS_LIMIT_RAD = 1e6


def chain_urdf_xml(robot: RobotLike) -> str:
    """The robot's URDF text, written from its model (``Robot.urdf_model``), with its
    collision elements and its continuous joints made revolute with wide limits."""
    return robot.urdf_model.to_xml(continuous_limit=CONTINUOUS_LIMIT_RAD)


def link_frame_id(model: Any, name: str) -> int:
    """The id of link ``name``'s frame in ``model``: its ``BODY`` frame when there is one, else
    the one frame of that name. A URDF may give a fixed joint and its child link one name (z1's
    ``gripperStator``); Pinocchio then holds two frames of it, and ``getFrameId(name)`` raises
    "Several frames match the filter"."""
    import pinocchio as pin

    if model.existFrame(name, pin.FrameType.BODY):
        return int(model.getFrameId(name, pin.FrameType.BODY))
    return int(model.getFrameId(name))


def build_chain_model(robot: RobotLike) -> Any:
    """The Pinocchio model of ``robot``'s chain (see the module docstring)."""
    return build_chain_model_with_geometry(robot, with_collision=False)[0]


def build_chain_model_with_geometry(robot: RobotLike, with_collision: bool = True
                                    ) -> tuple[Any, Any | None]:
    """(model, collision GeometryModel or None) of ``robot``'s chain: :func:`build_chain_model`
    and, with ``with_collision``, the URDF's ``<collision>`` elements reduced with it (meshes
    found through ``package://`` paths relative to the URDF's folder and its parents)."""
    import pinocchio as pin

    xml = chain_urdf_xml(robot)
    full = pin.buildModelFromXML(xml)
    geometry = None
    if with_collision:
        dirs = [str(p) for p in robot.urdf_path.parents][:8]
        geometry = pin.buildGeomFromUrdfString(full, xml, pin.GeometryType.COLLISION,
                                               package_dirs=dirs)
    keep = set(robot.joint_names)
    lock = [j for j in range(1, full.njoints) if full.names[j] not in keep]
    reference = pin.neutral(full)
    for name, value in robot.locked_urdf.items():  # the config's locked joints, others at 0
        reference[full.idx_qs[full.getJointId(name)]] = value
    model = full
    if lock and geometry is not None:
        model, geometry = pin.buildReducedModel(full, geometry, lock, reference)
    elif lock:
        model = pin.buildReducedModel(full, lock, reference)
    names = tuple(model.names[1:])
    if names != robot.joint_names:
        raise ValueError(f"URDF joint order {names} differs from {robot.joint_names}")
    if not model.existFrame(robot.root_link):
        raise ValueError(f"base link {robot.root_link} is not a frame of the model")
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    T_world_base = data.oMf[link_frame_id(model, robot.root_link)].copy()
    if not T_world_base.isIdentity():
        # the chain's base becomes the world frame: its first joint hangs off the universe
        first = 1
        model.jointPlacements[first] = T_world_base.actInv(model.jointPlacements[first])
        for item in (geometry.geometryObjects if geometry is not None else []):
            if item.parentJoint == 0:
                item.placement = T_world_base.actInv(item.placement)
    return model, geometry


class PinocchioFK:
    """FK through Pinocchio (float64, numpy), plus its model for IK and Jacobians.

    Attributes:
        model: the chain's ``pinocchio.Model`` (world = the robot's base link).
        data: scratch data of ``model``.
        frame_id: the end frame's id.
    """

    def __init__(self, robot: RobotLike) -> None:
        self.robot = robot
        self.model = build_chain_model(robot)
        self.data = self.model.createData()
        self.frame_id = link_frame_id(self.model, robot.end_frame)

    def placement(self, q_rad: np.ndarray) -> Any:
        """The end frame's ``pin.SE3`` in the base frame for one configuration (dof,)."""
        import pinocchio as pin

        pin.framesForwardKinematics(self.model, self.data, q_rad)
        return self.data.oMf[self.frame_id]

    def transforms(self, q_pose: npt.ArrayLike) -> np.ndarray:
        """End-frame transforms (B, 4, 4) [m] for poses (B, dof) [pose units]."""
        q_urdf = self.robot.to_urdf(np.atleast_2d(np.asarray(q_pose, dtype=float)))
        out = np.empty((len(q_urdf), 4, 4))
        for i, q in enumerate(q_urdf):
            out[i] = self.placement(q).homogeneous
        return out

    def __call__(self, q_pose):
        """Return ``(point_m, direction)`` arrays (B, 3) for poses (B, dof) [pose units]."""
        T_base_tip = self.transforms(q_pose)
        return T_base_tip[:, :3, 3], T_base_tip[:, :3, :3] @ self.robot.pointing_axis
