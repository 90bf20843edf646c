"""Drake (``pip install drake``): ``drake-ik`` (InverseKinematics per point, :mod:`.ik`),
``drake-trajopt`` (KinematicTrajectoryOptimization of the whole path, :mod:`.trajopt`) and the
single-pose solver of ``ikbench ik``; what they share (the plant, the solver choice) is in
:mod:`.common`. pydrake is imported inside their functions only."""

from ikbench.baselines.drake.ik import DrakeIK, DrakeSolver
from ikbench.baselines.drake.trajopt import DrakeTrajopt
from ikbench.methods.registry import Adapter

#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="drake", requires=("pydrake",),
                  methods=(DrakeIK, DrakeTrajopt), solvers=(DrakeSolver,), rank=100)
