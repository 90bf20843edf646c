"""The names of the paper's loss terms and the weights the objectives use by default.

Plain data, shared by the losses (:mod:`ikbench.core.losses`, which re-exports every name
here) and the tasks (:mod:`ikbench.core.task`, whose ``default_weights`` start from them), so
neither of those modules imports the other for its constants.
"""

from __future__ import annotations

TERMS = ("L0", "L1", "L2", "L3", "L4", "L5", "L6")
#: The paper's weights c0..c6.
PAPER_WEIGHTS = {"L0": 1.0, "L1": 50.0, "L2": 5.0, "L3": 100.0, "L4": 10.0, "L5": 200.0,
                 "L6": 1.0}
PAPER_WEIGHTS_TEXT = "the paper's c0=1,c1=50,c2=5,c3=100,c4=10,c5=200,c6=1"
TERM_DESCRIPTIONS = {
    "L0": "line points", "L1": "pointing direction", "L2": "start pose", "L3": "end pose",
    "L4": "start point", "L5": "end point", "L6": "smoothness",
}

#: Weights of the 6-D pose-path objective (tasks with goal frames), in its own units: L0 =
#: mean squared position error [mm^2], L1 = mean squared rotation error (SO(3) log map, the
#: three components) [deg^2], L6 = mean squared joint step [deg^2, mm^2 for prismatic joints];
#: the other terms do not apply. Equal position and rotation weights match CppFlow's equal
#: thresholds (0.1 mm, 0.1 deg); the small smoothness weight picks the smooth solution among
#: the arm's redundant ones while moving the pose errors by far less than the thresholds.
FRAME_WEIGHTS = {"L0": 1.0, "L1": 1.0, "L2": 0.0, "L3": 0.0, "L4": 0.0, "L5": 0.0,
                 "L6": 0.001}
FRAME_TERM_DESCRIPTIONS = {"L0": "position [mm^2]", "L1": "rotation [deg^2]",
                           "L6": "smoothness [deg^2]"}
