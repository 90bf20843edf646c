"""What the baseline adapters share: the chain in URDF units, the tracking and walking
schemes, differential IK, collision helpers, single-pose solvers; not methods themselves."""
