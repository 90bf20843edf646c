"""CppFlow's validity of a Cartesian path solution, collisions included.

From jstmn/cppflow (``scripts/evaluate.py::CONSTRAINTS``, the same numbers as
``cppflow/config.py`` at the paper's commit 2b6ad30; checked in ``Plan.is_valid``): a
trajectory is valid when, at every waypoint, the position error is below 0.1 mm, the rotation
error below 0.1 deg, every revolute joint changes by less than 7 deg and every prismatic joint
by less than 20 mm between consecutive waypoints (changes wrapped to [-180, 180) deg), and every
pose lies within the joint limits (jrl's, which bound continuous joints to [-180, 180] deg).

CppFlow also requires no self-collision and no collision with the problem's obstacles
(``self_collision``, ``env_collision``; checked by :mod:`ikbench.core.collision` on the robot's
collision model: jstmn/jrl's capsules for Panda and Fetch, which CppFlow's optimiser uses;
CppFlow's final check uses the makers' meshes through Klampt, which the capsules enclose, so
the capsule check is the stricter one), and, where the problem gives an initial
configuration, the first pose within 0.2 of it (``initial_configuration``: the Euclidean norm
of the difference in URDF units, rad and m; CppFlow's
``SUCCESS_THRESHOLD_initial_q_norm_dist``). A robot without a collision model cannot be
checked for collisions; its rows say so (``collision_model`` = ``none``). CppFlow measures
rotation errors
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
#: Largest distance of the first pose from a given initial configuration (rad, m), strict.
MAX_INITIAL_DISTANCE = 0.2
SOURCE = ("jstmn/cppflow scripts/evaluate.py CONSTRAINTS (= cppflow/config.py at 2b6ad30) and "
          "cppflow/data_types.py Plan.is_valid_ (collisions, initial configuration)")


def validity_failures(metrics: dict) -> list[str]:
    """Names of the criteria a trajectory fails (empty: valid), from :func:`frame_metrics`'s
    figures: ``position``, ``rotation``, ``joint_change``, ``prismatic_change``, ``limits``,
    ``self_collision``, ``env_collision``, ``initial_configuration`` (the last three only
    when the figures hold them)."""
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
    if metrics.get("self_collisions", 0) > 0:
        failed.append("self_collision")
    if metrics.get("env_collisions", 0) > 0:
        failed.append("env_collision")
    initial = metrics.get("initial_configuration_distance", math.nan)
    if not math.isnan(initial) and not initial < MAX_INITIAL_DISTANCE:
        failed.append("initial_configuration")
    return failed


def describe() -> str:
    """The criteria in one sentence (reports)."""
    return (f"position error < {MAX_POSITION_ERROR_MM:g} mm and rotation error < "
            f"{MAX_ROTATION_ERROR_DEG:g} deg at every waypoint, joint changes between waypoints "
            f"< {MAX_JOINT_CHANGE_DEG:g} deg (revolute, wrapped) and < {MAX_JOINT_CHANGE_MM:g} "
            "mm (prismatic), every pose within the limits (continuous joints within "
            "[-180, 180] deg), no self-collision and no collision with the obstacles (the "
            "robot's collision model), the first pose within "
            f"{MAX_INITIAL_DISTANCE:g} (rad, m) of a given initial configuration")
