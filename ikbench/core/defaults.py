"""The defaults that several layers share, each defined once here.

This module imports nothing, so the command line can take its defaults from it at ``--help``
time without loading numpy or a kinematics library. It is the one module outside
``ikbench/methods`` and ``baselines/`` that names methods: the rest of core, runtime, render,
studies and cli take the names from here or from a method's class
(``tests/test_architecture.py``).
"""

#: The robot every command and function uses when none is named (NICO's right arm).
DEFAULT_ROBOT = "nico_right_arm"
#: Default duration T of a movement [s] (the paper's): the time of a trajectory CSV's last
#: row, the contract's speed limits, the motion plans of ``ikbench plan`` / ``execute``.
DEFAULT_DURATION_S = 2.0

# ----- defaults that name a method ---------------------------------------------------------
#: The paper's method (Adam on the paper's loss): what ``ikbench run``, ``letters`` and
#: ``ablate`` solve with when no method is named.
DEFAULT_METHOD = "ours"
#: The method the others are measured against: ``compare``'s time ratios (``--reference``)
#: and its weight sweep, the README's leaderboard; the designer's fallback.
REFERENCE_METHOD = "ours-lm"
#: The method ``ikbench design`` re-solves with when none is named (the path and the fixed
#: poses exact, warm-started).
DESIGN_METHOD = "ours-exact"
#: The method whose trajectories the pointing experiment plays by default (ikbench experiment
#: design --method): the line held exactly, as the paper's stimuli.
EXPERIMENT_METHOD = "ours-exact"
#: The method ``ikbench robot init`` checks its default targets with (the line and the fixed
#: poses held exactly: a target it solves is feasible under the task contract).
TARGET_CHECK_METHOD = "ours-exact"
#: ``ikbench ik``'s judge: an answer succeeds within these of its target by default [mm], [deg]
#: (``--tolerance-mm``, ``--tolerance-deg``); the ground truth's margins are multiples of them.
JUDGE_TOLERANCE_MM, JUDGE_TOLERANCE_DEG = 1.0, 0.5
#: ``ikbench compare``'s methods when none are named.
COMPARE_METHODS = ("ours-lm", "ours-exact", "sequential-ik")
#: ``ikbench bench``'s methods when none are named.
BENCH_METHODS = ("ours", "ours-lm")
#: The trajectory optimisers that meet the contract exactly: the ``exact-benchmark`` study of
#: ``ikbench reproduce --all`` times these (``results/exact_benchmark/``).
EXACT_BENCHMARK_METHODS = ("ours-lm", "ours-exact", "drake-trajopt", "pyroki")
#: The learned-start study's methods (``results/learned/``): ikbench's compiled LM and the
#: library LM the issue names beside it (issue 61).
LEARNED_STUDY_METHODS = ("ours-lm", "rtb-lm")
#: The methods the learned-trajectory study runs from their usual and from a trajectory
#: model's start (``ikbench/studies/learned_trajectory.py``): the two with warm starts.
LEARNED_TRAJECTORY_METHODS = ("ours-lm", "ours-exact")
#: The backend a method's published figures ran on: a leaderboard whose run used another
#: says so above its table (``Method.runtime()["backend"]``; issue 50).
PUBLISHED_BACKENDS = {"ours-lm": "numba"}
