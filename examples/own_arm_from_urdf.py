"""Your own arm from a URDF: load it by file and end link, and draw a straight line with it.

Shows ``ikbench.load_robot(URDF, end_frame=...)`` (any serial chain; poses in joint degrees,
mm for prismatic joints), ``ikbench.line_task`` (a straight line from FK(start pose) to
FK(end pose), n segments), solving it with ``ours-lm`` directly (``Method.solve``) and judging
the trajectory with ``ikbench.trajectory_metrics``. A bare URDF names no pointing axis, so the
pointing term is switched off (weights ``c1=0``) and the line weighted up (``c0=100``).

Run:  python examples/own_arm_from_urdf.py [URDF END_LINK]     (about 3 s)
(default: the Panda URDF shipped with ikbench and its link ``panda_hand``, as a user's own
file would be given.)
"""

import sys

import numpy as np

import ikbench
from ikbench.core.robot import robots_dir

urdf, end_link = sys.argv[1:3] if len(sys.argv) >= 3 else (robots_dir() / "panda.urdf",
                                                             "panda_hand")
robot = ikbench.load_robot(urdf, end_frame=end_link)
print(f"{robot.name}: {robot.dof} joints {', '.join(robot.joint_names)}")

# a start pose in the middle of the joint ranges, and an end pose 25 % of the way to the
# upper limits: a line between the two end points that the arm can follow
middle = (robot.sample_lower + robot.sample_upper) / 2
start = middle
end = middle + 0.25 * (robot.sample_upper - middle)
task = ikbench.line_task(robot, start, end, steps=20, name="my-line")
first_mm, last_mm = np.round(task.goal.points_mm[[0, -1]], 1)
print(f"line from {first_mm} to {last_mm} mm (base frame)")

solver = ikbench.get_method("ours-lm")(weights="c0=100,c1=0")
solution = solver.solve(robot, task)
metrics = ikbench.trajectory_metrics(robot, task, solution.poses)
print(f"solved in {solution.iterations} iterations, {solution.duration_s * 1000:.1f} ms: "
      f"line distance mean {metrics['line_distance_mean_mm']:.4f} mm, end point error "
      f"{metrics['end_point_error_mm']:.4f} mm, largest joint step "
      f"{metrics['max_joint_step_deg']:.2f} deg, within limits: "
      f"{robot.within_limits(solution.poses)}")
