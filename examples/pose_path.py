"""A pose path: a CppFlow problem (the end frame's position and orientation along a path),
solved by ours-lm and judged by CppFlow's validity criteria.

Shows ``ikbench.run(..., problem=NAME)`` on ``fetch_arm__hello`` (the Fetch arm writing
"hello", shipped with ikbench from jstmn/cppflow's benchmark) and the criteria a valid
trajectory meets at every waypoint (``ikbench.core.validity``): position error < 0.1 mm,
rotation error < 0.1 deg, joint changes < 7 deg between waypoints, within the joint limits
(ikbench has no collision model, so CppFlow's collision checks are left out).

Run:  python examples/pose_path.py [PROBLEM]     (about 20 s on 2 busy cores; ikbench cartesian
--help lists the problems)
"""

import sys

import ikbench
from ikbench.core.validity import describe

problem = sys.argv[1] if len(sys.argv) > 1 else "fetch_arm__hello"
table = ikbench.run("ours-lm", problem=problem, output=None, progress=False)
row = table.iloc[0]
print(f"{row['trajectory']}: position error max {row['position_error_max_mm']:.2g} mm, "
      f"rotation error max {row['rotation_error_max_deg']:.2g} deg, largest joint change "
      f"{row['max_joint_change_deg']:.2f} deg, {row['iterations']} iterations in "
      f"{row['duration_s']:.2f} s")
print(f"valid by CppFlow's criteria: {bool(row['valid'])} ({describe()})")
