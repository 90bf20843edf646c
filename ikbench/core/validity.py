"""CppFlow's validity of a Cartesian path solution, without its collision checks.

From jstmn/cppflow (``scripts/evaluate.py::CONSTRAINTS``, the same numbers as
``cppflow/config.py`` at the paper's commit 2b6ad30; checked in ``Plan.is_valid``): a
trajectory is valid when, at every waypoint, the position error is below 0.1 mm, the rotation
error below 0.1 deg, every revolute joint changes by less than 7 deg and every prismatic joint
by less than 20 mm between consecutive waypoints (changes wrapped to [-180, 180) deg), and every
pose lies within the joint limits (jrl's, which bound continuous joints to [-180, 180] deg).

CppFlow also requires no self-collision (and no collision with obstacles); ikbench has no
collision model, so those two criteria are not checked here. CppFlow measures rotation errors
as 2 acos(<q_FK, q_goal>) with the dot product clamped to 1 - 1e-7, in float32, which cannot
report less than about 0.05 deg; ikbench uses the exact geodesic angle (SO(3) log map).
"""

from __future__ import annotations

import math

#: Largest position error [mm] (CppFlow: 0.01 cm), strict.
MAX_POSITION_ERROR_MM = 0.1
#: Largest rotation error [deg], strict.
MAX_ROTATION_ERROR_DEG = 0.1
#: Largest change of a revolute joint between waypoints [deg] ("mjac"), strict.
MAX_JOINT_CHANGE_DEG = 7.0
#: Largest change of a prismatic joint between waypoints [mm] (CppFlow: 2 cm), strict.
MAX_JOINT_CHANGE_MM = 20.0
SOURCE = ("jstmn/cppflow scripts/evaluate.py CONSTRAINTS (= cppflow/config.py at 2b6ad30), "
          "collision checks left out")


def validity_failures(metrics: dict) -> list[str]:
    """Names of the criteria a trajectory fails (empty: valid), from :func:`frame_metrics`'s
    figures: ``position``, ``rotation``, ``joint_change``, ``prismatic_change``, ``limits``."""
    failed = []
    if not metrics["position_error_max_mm"] < MAX_POSITION_ERROR_MM:
        failed.append("position")
    if not metrics["rotation_error_max_deg"] < MAX_ROTATION_ERROR_DEG:
        failed.append("rotation")
    if not metrics["max_joint_change_deg"] < MAX_JOINT_CHANGE_DEG:
        failed.append("joint_change")
    prismatic = metrics.get("max_joint_change_mm", math.nan)
    if not math.isnan(prismatic) and not prismatic < MAX_JOINT_CHANGE_MM:
        failed.append("prismatic_change")
    if not metrics["within_limits"]:
        failed.append("limits")
    return failed


def describe() -> str:
    """The criteria in one sentence (reports)."""
    return (f"position error < {MAX_POSITION_ERROR_MM:g} mm and rotation error < "
            f"{MAX_ROTATION_ERROR_DEG:g} deg at every waypoint, joint changes between waypoints "
            f"< {MAX_JOINT_CHANGE_DEG:g} deg (revolute, wrapped) and < {MAX_JOINT_CHANGE_MM:g} "
            "mm (prismatic), every pose within the limits (continuous joints within "
            "[-180, 180] deg); no collision checks")
