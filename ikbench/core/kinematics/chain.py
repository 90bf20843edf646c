"""Vectorised FK and analytic Jacobians of a serial chain in numpy (many poses at once).

Built from the robot's Pinocchio model (joint placements, axes, end frame), then pure numpy:
one pass over the joints for all M poses. For a revolute joint with world axis w through o,
dP/dq = w x (P - o) and dv/dq = w x v; for a prismatic joint dP/dq = w and dv/dq = 0; times
dq/dp, the URDF units per pose unit (motor map scale x pi/180, or 1/1000 m per mm).
``pinocchio_kinematics`` is the per-pose reference it is tested against.

One chain, three loops. :class:`ChainKinematics` is where the chain's constants are read from
the Pinocchio model, once per robot (``robot.chain_kinematics()``, cached): the joint
placements (``rotations``, ``translations``), ``axes``, their cross-product matrices
``skews``, ``prismatic``, the end frame (``tip_rotation``, ``tip_translation``, ``tip_axis``)
and ``urdf_per_unit``. Its twins take these arrays from it and read nothing else of the
model: :class:`~ikbench.core.kinematics.chain_torch.TorchChainKinematics` (torch, any device
and dtype, for ours-lm's torch backend) and :class:`ikbench.methods.ours_lm.compiled.Chain`
(numba). numpy and torch share the pass over the joints (:func:`joint_product`): it needs
only ``@``, ``+``, ``*`` and indexing, which both read alike, and each library hands it its
own rotation about a joint axis (the sines and cosines are the part that differs: numpy
functions turn a CUDA tensor into an error or a host copy, torch functions take no ndarray).
numba compiles neither torch nor the batched ``(M, 3, 3) @ (3, 3)`` products used here (its
matmul takes 1-D and 2-D arrays), so the compiled loop is written per pose in scalars. The
loops are kept equal by tests: ``tests/test_ours_lm_torch.py`` (torch = numpy to 1e-12 on
revolute, prismatic, continuous and unaligned axes) and ``tests/test_ours_lm_compiled.py``
(numba = numpy).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, Protocol, TypeAlias

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import SolverError
from ikbench.core.kinematics.pinocchio_fk import PinocchioFK
from ikbench.core.kinematics.robot_like import RobotLike


class ChainRobot(RobotLike, Protocol):
    """What the chain reads of a robot: :class:`RobotLike` and its Pinocchio backend."""

    def pinocchio_fk(self) -> PinocchioFK:
        """The Pinocchio FK backend (cached)."""
        ...


#: (point or position (M, 3), direction (M, 3) or rotation (M, 3, 3), and their Jacobians
#: (M, 3, dof), or None without them)
Frames: TypeAlias = tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]

_REVOLUTE = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0),
             "JointModelRZ": (0.0, 0.0, 1.0)}
_PRISMATIC = {"JointModelPX": (1.0, 0.0, 0.0), "JointModelPY": (0.0, 1.0, 0.0),
              "JointModelPZ": (0.0, 0.0, 1.0)}


def joint_axis(joint: Any, name: str) -> tuple[np.ndarray, bool]:
    """(unit axis (3,) in the joint frame, prismatic?) of a Pinocchio joint model."""
    short = joint.shortname()
    if short in _REVOLUTE:
        return np.array(_REVOLUTE[short]), False
    if short in _PRISMATIC:
        return np.array(_PRISMATIC[short]), True
    if short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.array(joint.extract().axis, dtype=float)
        return axis / np.linalg.norm(axis), short == "JointModelPrismaticUnaligned"
    raise SolverError(f"the chain kinematics handles revolute and prismatic joints; {name} "
                      f"is {short}")


def cross_matrices(axes: npt.ArrayLike) -> np.ndarray:
    """Cross-product matrices [a]_x (k, 3, 3) of vectors (k, 3): [a]_x v = a x v."""
    a = np.asarray(axes, dtype=float).reshape(-1, 3)
    skew = np.zeros((len(a), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
    skew -= skew.transpose(0, 2, 1)
    return skew


def joint_product(rot: Any, pos: Any, q: Any, chain: Any, turn: Callable[[int, Any], Any]
                  ) -> Iterator[tuple[Any, Any, Any]]:
    """The pass over a chain's joints, on numpy arrays or torch tensors alike: from the frame
    ``rot`` (M, 3, 3), ``pos`` (M, 3) [m], through each joint j's placement
    (``chain.rotations[j]``, ``chain.translations[j]``) and its motion by ``q[:, j]`` [rad, m]:
    along ``chain.axes[j]`` for a prismatic joint (``chain.prismatic[j]``), else the rotation
    ``turn(j, q[:, j])`` (M, 3, 3) about it. Yields each joint's frame after its motion:
    (rotation (M, 3, 3), origin (M, 3) [m], axis in the base frame (M, 3))."""
    for j in range(len(chain.axes)):
        pos = pos + rot @ chain.translations[j]
        rot = rot @ chain.rotations[j]
        axis = chain.axes[j]
        if chain.prismatic[j]:
            pos = pos + (rot @ axis) * q[:, j, None]
        else:
            rot = rot @ turn(j, q[:, j])
        yield rot, pos, rot @ axis


def axis_rotation(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rotations (M, 3, 3) about a unit axis by angles (M,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle_rad)[:, None, None], np.cos(angle_rad)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


class ChainKinematics:
    """Vectorised FK and analytic Jacobians of the robot's chain.

    Call with poses (M, dof) [pose units]; returns the end point [m] (M, 3), the pointing
    direction (M, 3) and their Jacobians d/d(pose unit) (M, 3, dof); :meth:`transforms` gives
    the full end-frame rotation too.

    Its attributes are the chain's constants, read from the Pinocchio model here and only
    here; the torch and numba twins take them from this object (module docstring).
    """

    def __init__(self, robot: ChainRobot) -> None:
        pfk = robot.pinocchio_fk()
        model = pfk.model
        self.dof = robot.dof
        self.rotations: list[np.ndarray] = []
        self.translations: list[np.ndarray] = []
        self.axes: list[np.ndarray] = []
        joint_is_prismatic: list[bool] = []
        for j in range(1, model.njoints):
            if model.parents[j] != j - 1:
                raise SolverError(f"a serial chain is needed; joint {model.names[j]} hangs off "
                                  f"joint {model.names[model.parents[j]]}")
            axis, prismatic = joint_axis(model.joints[j], model.names[j])
            self.axes.append(axis)
            joint_is_prismatic.append(prismatic)
            self.rotations.append(np.array(model.jointPlacements[j].rotation))
            self.translations.append(np.array(model.jointPlacements[j].translation))
        frame = model.frames[pfk.frame_id]
        if frame.parentJoint != model.njoints - 1:
            raise SolverError(f"end frame {robot.end_frame} is not on the last joint")
        self.tip_rotation = np.array(frame.placement.rotation)
        self.tip_translation = np.array(frame.placement.translation)
        self.tip_axis = self.tip_rotation @ robot.pointing_axis
        self.prismatic = np.array(joint_is_prismatic)
        #: [a]_x (dof, 3, 3) of each joint axis (joint frame), for Rodrigues' formula
        self.skews = cross_matrices(self.axes)
        #: URDF units [rad or m] per pose unit, per joint
        self.urdf_per_unit = robot.to_urdf(np.ones(self.dof)) - robot.to_urdf(np.zeros(self.dof))
        self.robot = robot

    def transforms(self, poses: npt.ArrayLike
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position_m (M, 3), rotation (M, 3, 3), axes_world (M, dof, 3),
        origins_m (M, dof, 3)) of the end frame and the joints, for poses (M, dof)."""
        rotations, origins, axes_world = self.joint_frames(poses)
        rot, pos = rotations[:, -1], origins[:, -1]
        point = pos + rot @ self.tip_translation
        return point, rot @ self.tip_rotation, axes_world, origins

    def joint_frames(self, poses: npt.ArrayLike
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rotations (M, dof, 3, 3), origins_m (M, dof, 3), axes_world (M, dof, 3)): every
        joint's frame (after its motion) in the base frame, for poses (M, dof)."""
        q = self.robot.to_urdf(np.asarray(poses, dtype=float))
        m = len(q)
        rotations, origins, axes_world = zip(*joint_product(
            np.broadcast_to(np.eye(3), (m, 3, 3)), np.zeros((m, 3)), q, self,
            lambda j, angle: axis_rotation(self.axes[j], angle)), strict=True)
        return np.stack(rotations, 1), np.stack(origins, 1), np.stack(axes_world, 1)

    def __call__(self, poses: npt.ArrayLike, jacobian: bool = True) -> Frames:
        """FK (and Jacobians) of poses (M, dof) [pose units].

        Returns:
            (point_m (M, 3), direction (M, 3), J_point (M, 3, dof) [m / pose unit] or None,
            J_direction (M, 3, dof) [1 / pose unit] or None).
        """
        point, rotation, w, o = self.transforms(poses)
        direction = rotation @ self.robot.pointing_axis
        if not jacobian:
            return point, direction, None, None
        scale = self.urdf_per_unit[None, :, None]
        revolute = ~self.prismatic[None, :, None]
        j_point = np.where(revolute, np.cross(w, point[:, None, :] - o), w) * scale
        j_dir = np.where(revolute, np.cross(w, direction[:, None, :]), 0.0) * scale
        return point, direction, j_point.transpose(0, 2, 1), j_dir.transpose(0, 2, 1)


    def frames(self, poses: npt.ArrayLike, jacobian: bool = True) -> Frames:
        """End-frame poses (and Jacobians) of poses (M, dof) [pose units].

        A second formulation of the chain, built for few poses at a time (the start search of
        pose paths calls it once per waypoint): every joint's local 4 x 4 transform is made
        for all joints at once, leaving one product per joint.

        Returns:
            (point_m (M, 3), rotation (M, 3, 3), J_point (M, 3, dof) [m / pose unit] or None,
            J_angular (M, 3, dof) [rad / pose unit], world-aligned, or None).
        """
        if not hasattr(self, "_placements"):
            self._prepare_frames()
        q = self.robot.to_urdf(np.asarray(poses, dtype=float))
        revolute = ~self.prismatic
        s, c = np.sin(q * revolute)[..., None, None], np.cos(q * revolute)[..., None, None]
        local = np.zeros((len(q), self.dof, 4, 4))
        local[..., :3, :3] = np.eye(3) + s * self._skew + (1.0 - c) * self._skew2
        local[..., :3, 3] = (q * self.prismatic)[..., None] * self._axes
        local[..., 3, 3] = 1.0
        local = self._placements @ local
        chain = np.empty_like(local)
        chain[:, 0] = current = local[:, 0]
        for j in range(1, self.dof):
            chain[:, j] = current = current @ local[:, j]
        end = current @ self._tip
        point, rotation = end[:, :3, 3], end[:, :3, :3]
        if not jacobian:
            return point, rotation, None, None
        w = np.einsum("mjab,jb->maj", chain[..., :3, :3], self._axes)       # (M, 3, dof)
        d = point[:, :, None] - chain[..., :3, 3].transpose(0, 2, 1)       # P - o_j
        cross = w[:, [1, 2, 0]] * d[:, [2, 0, 1]] - w[:, [2, 0, 1]] * d[:, [1, 2, 0]]
        scale = self.urdf_per_unit
        j_point = np.where(revolute, cross, w) * scale
        return point, rotation, j_point, w * (revolute * scale)

    def _prepare_frames(self) -> None:
        """Constant 4 x 4 placements, axes and their cross-product matrices (for frames)."""
        self._placements = np.zeros((self.dof, 4, 4))
        self._placements[:, :3, :3] = self.rotations
        self._placements[:, :3, 3] = self.translations
        self._placements[:, 3, 3] = 1.0
        self._axes = np.array(self.axes, dtype=float)
        self._skew = self.skews
        self._skew2 = self._skew @ self._skew
        self._tip = np.eye(4)
        self._tip[:3, :3], self._tip[:3, 3] = self.tip_rotation, self.tip_translation


def pinocchio_frames(robot: ChainRobot, poses: npt.ArrayLike, jacobian: bool = True) -> Frames:
    """The reference of :meth:`ChainKinematics.frames`: Pinocchio per pose."""
    import pinocchio as pin

    pfk = robot.pinocchio_fk()
    model, data, fid = pfk.model, pfk.data, pfk.frame_id
    q_urdf = robot.to_urdf(np.atleast_2d(np.asarray(poses, dtype=float)))
    m, dof = q_urdf.shape
    point, rotation = np.empty((m, 3)), np.empty((m, 3, 3))
    j_point, j_angular = np.empty((m, 3, dof)), np.empty((m, 3, dof))
    scale = robot.to_urdf(np.ones(dof)) - robot.to_urdf(np.zeros(dof))
    for i, q in enumerate(q_urdf):
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        point[i] = data.oMf[fid].translation
        rotation[i] = data.oMf[fid].rotation
        j_point[i], j_angular[i] = jac[:3] * scale, jac[3:] * scale
    if not jacobian:
        return point, rotation, None, None
    return point, rotation, j_point, j_angular


def pinocchio_kinematics(robot: ChainRobot, poses: npt.ArrayLike, jacobian: bool = True) -> Frames:
    """The reference of :class:`ChainKinematics`: Pinocchio per pose (LOCAL_WORLD_ALIGNED)."""
    import pinocchio as pin

    pfk = robot.pinocchio_fk()
    model, data, fid = pfk.model, pfk.data, pfk.frame_id
    q_urdf = robot.to_urdf(np.atleast_2d(np.asarray(poses, dtype=float)))
    m, dof = q_urdf.shape
    point, direction = np.empty((m, 3)), np.empty((m, 3))
    j_point, j_dir = np.empty((m, 3, dof)), np.empty((m, 3, dof))
    scale = robot.to_urdf(np.ones(dof)) - robot.to_urdf(np.zeros(dof))
    for i, q in enumerate(q_urdf):
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        placement = data.oMf[fid]
        point[i] = placement.translation
        direction[i] = placement.rotation @ robot.pointing_axis
        j_point[i] = jac[:3] * scale
        j_dir[i] = np.cross(jac[3:].T, direction[i]).T * scale
    if not jacobian:
        return point, direction, None, None
    return point, direction, j_point, j_dir
