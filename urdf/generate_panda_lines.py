"""Write panda_lines.targets.json: a start pose and seven touch poses of the Panda, all drawn
at random (seeded), whose straight lines the comparison's methods track.

Run: ``.venv/bin/python urdf/generate_panda_lines.py`` (rewrites urdf/panda_lines.targets.json;
``tests/test_panda_lines.py`` checks that it reproduces the committed file).

- **Start pose**: the first pose drawn by ``numpy.random.default_rng(SEED)`` uniformly within
  the middle half of every joint's range whose hand is in front of the robot and above a
  table (x 300..600 mm, |y| <= 200 mm, z 300..600 mm in panda_link0's frame) pointing down
  (the approach axis within 45 deg of -z).
- **Touch poses**: drawn by ``numpy.random.default_rng(SEED + 1)`` uniformly within
  :data:`REACH_DEG` of the start pose on every joint (and within the limits: a touch pose on
  the start pose's IK branch, which a line can join without a flip), kept by the Panda's
  ``[batch]`` filter (:class:`ikbench.studies.batch.WorkspaceFilter` of ``urdf/panda.toml``:
  the hand at least 50 mm above the table, at least 100 mm below the start point, pointing
  within 30 deg of the line), in order, while the line is reachable: every one of its n + 1
  points (n = :data:`STEPS`) has a position IK solution within 1 mm
  (:func:`ikbench.methods.ours_lm.single_pose.solve_poses`, seeded from the joint-space
  interpolation of the two poses, random restarts). The first :data:`COUNT` such lines are
  kept.

Poses are rounded to 0.01 deg (the file's precision); the checks above are made on the
rounded poses.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "panda_lines.targets.json"
SEED = 2026
COUNT = 7
STEPS = 50
#: Touch-pose candidates drawn at most.
CANDIDATES = 100_000
#: Touch poses lie within this of the start pose on every joint [deg].
REACH_DEG = 45.0


def start_pose(robot, rng: np.random.Generator) -> np.ndarray:
    """The first draw within the middle half of the ranges that meets the start criteria."""
    lo, hi = robot.sample_lower, robot.sample_upper
    mid, half = (lo + hi) / 2, (hi - lo) / 4
    while True:
        poses = np.round(rng.uniform(mid - half, mid + half, (256, robot.dof)), 2)
        fk = robot.fk(poses)
        p, d = fk.point_mm, fk.direction
        ok = ((300 <= p[:, 0]) & (p[:, 0] <= 600) & (np.abs(p[:, 1]) <= 200)
              & (300 <= p[:, 2]) & (p[:, 2] <= 600) & (-d[:, 2] >= np.cos(np.radians(45))))
        if ok.any():
            return poses[int(np.argmax(ok))]


def reachable(robot, start: np.ndarray, touch: np.ndarray) -> bool:
    """Every point of the straight line from FK(start) to FK(touch) has a position IK
    solution within 1 mm."""
    from ikbench.methods.ours_lm.single_pose import solve_poses

    fk = robot.fk(np.stack([start, touch])).point_mm
    s = np.linspace(0.0, 1.0, STEPS + 1)[:, None]
    points = fk[0] + s * (fk[1] - fk[0])
    initial = start + s * (touch - start)
    out = solve_poses(robot, points, np.broadcast_to(np.eye(3), (STEPS + 1, 3, 3)), initial,
                      tolerance=(1.0, 1.0), position_only=True, max_iterations=400,
                      restarts=10, restart_after=25, seed=SEED)
    return bool(np.all(out.converged))


def panda_lines() -> dict:
    """The targets document (see the module docstring)."""
    from ikbench.core.robot import load_robot
    from ikbench.studies.batch import WorkspaceFilter

    robot = load_robot("panda")
    start = start_pose(robot, np.random.default_rng(SEED))
    lo = np.maximum(robot.sample_lower, start - REACH_DEG)
    hi = np.minimum(robot.sample_upper, start + REACH_DEG)
    candidates = np.round(np.random.default_rng(SEED + 1).uniform(
        lo, hi, (CANDIDATES, robot.dof)), 2)
    fk = robot.fk(candidates)
    keep = WorkspaceFilter.of(robot).accept(fk.point_mm, fk.direction,
                                            robot.fk(start).point_mm[0])
    touch: dict[str, list[float]] = {}
    for pose in candidates[keep]:
        if not reachable(robot, start, pose):
            continue
        touch[str(len(touch) + 1)] = [float(v) for v in pose]
        if len(touch) == COUNT:
            break
    if len(touch) < COUNT:
        raise RuntimeError(f"only {len(touch)} lines of {CANDIDATES} draws kept; draw more")
    return {
        "description": (f"Panda: {COUNT} straight lines from a random start pose to random touch "
                        f"poses within {REACH_DEG:g} deg of it on every joint (seed {SEED}), kept "
                        "by panda.toml's [batch] filter and checked reachable point by point; "
                        "written by urdf/generate_panda_lines.py, joint degrees."),
        "joint_names": list(robot.joint_names),
        "start_pose": [float(v) for v in start],
        "targets": touch,
        "steps": STEPS,
    }


def main() -> None:
    """Write :data:`OUT`."""
    OUT.write_text(json.dumps(panda_lines(), indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
