"""Forward-kinematics backends behind one small interface.

Each backend is called with poses in pose units (motor degrees for NICO), shape (B, dof),
and returns ``(point_m, direction)``: the end-frame origin [m] and its pointing axis (unit),
both (B, 3), in the robot's base frame.

- :class:`~ikbench.core.kinematics.torch_fk.TorchFK`: pytorch-kinematics, batched and
  differentiable (float32/float64, any torch device);
- :class:`~ikbench.core.kinematics.pinocchio_fk.PinocchioFK`: Pinocchio, float64, one pose
  at a time, plus the model for IK and Jacobians;
- :class:`~ikbench.core.kinematics.chain.ChainKinematics`: vectorised numpy chain with
  analytic Jacobians (what ``ours-lm`` and the batch sampler use).

Import the submodules directly; this package imports nothing heavy.
"""
