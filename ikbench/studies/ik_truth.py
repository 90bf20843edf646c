"""Ground truth of ``ikbench ik``: every analytic branch of each target, and silent failures.

**Branches.** Where an analytic solver can take the robot (a single-pose solver whose class
says ``analytic``: EAIK on the 6R arms it decomposes), each target's full solution set within
the joint limits is computed once (:func:`solution_sets`) and stored beside the targets
(``branches.csv``). A numerical solver lands on one of those branches; the branch nearest the
initial configuration (row 0 of the target's sequence) is the one that keeps a tracked motion
continuous. A successful answer that lies on one of the branches (within
:data:`SAME_BRANCH_DEG`, whole turns aside) gets two columns (:func:`branch_columns`):
``on_nearest_branch`` (it is the configuration nearest the initial one: the same branch a
whole turn away is not) and
``branch_excess_deg``: its joint distance from the initial configuration minus that nearest
branch's [deg, the Euclidean norm over the joints in pose units], 0 when it is on it. A
success on none of the branches has NaN in both; the report's share on the nearest branch is
of all the method's successes, such a one counted as not on it.

**Stress** (:func:`stress`): how near a singularity and a joint limit each target's
configuration is. **Unreachable targets** (:func:`unreachable_mix`): frames beyond a reach
bound no configuration leaves (:func:`reach_bound_m`, :func:`unreachable_targets`), and, where
an analytic solver takes the robot, half of them (rounded down) at a reachable position with
an orientation the solver proves impossible there (:func:`orientation_impossible`). The report
(:mod:`ikbench.render.ik_report`) sets the library's own verdicts against the judge's (silent
failures), bins success and time by stress, and times the giving up on unreachable targets.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.defaults import JUDGE_TOLERANCE_DEG, JUDGE_TOLERANCE_MM
from ikbench.methods.registry import available_solvers

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.schemes.single_pose import PoseSolver

#: An answer lies on a branch when every joint is within this of it, whole turns aside [deg].
SAME_BRANCH_DEG = 1.0


def analytic_solver(robot: Robot) -> PoseSolver | None:
    """The first installed analytic solver that can take ``robot``, prepared; None if none."""
    for cls in available_solvers().values():
        if not getattr(cls, "analytic", False):
            continue
        solver = cls(robot)
        try:
            solver.prepare()
        except Exception:  # it refuses this robot (its rows say why): no ground truth here
            continue
        return solver
    return None


def solution_sets(solver: PoseSolver, robot: Robot, T_target: np.ndarray,
                  q_init: np.ndarray) -> list[np.ndarray]:
    """Each target's solutions within the limits (S_k, dof) [pose units], every joint moved by
    whole turns toward that target's initial configuration ``q_init`` (B, dof) [pose units]
    where the limits allow."""
    sets = []
    for T, q0 in zip(T_target, q_init):
        found = solver.branches(T[:3, 3], T[:3, :3], robot.to_urdf(q0))  # type: ignore[attr-defined]
        sets.append(robot.from_urdf(found) if len(found) else np.zeros((0, robot.dof)))
    return sets


def _turn_units(robot: Robot) -> np.ndarray:
    """One whole turn of each joint in pose units (0 for a prismatic joint)."""
    return np.abs(robot.from_urdf(np.full(robot.dof, 2 * math.pi)) - robot.from_urdf(
        np.zeros(robot.dof)))


def branch_columns(robot: Robot, sets: list[np.ndarray], q_init: np.ndarray,
                   poses: np.ndarray, success: np.ndarray) -> dict[str, np.ndarray]:
    """``on_nearest_branch`` and ``branch_excess_deg`` of B answers ``poses`` (B, dof) [pose
    units] to the targets of ``sets`` (see the module docstring); NaN where the answer failed,
    the target has no branch, or the answer lies on none of them."""
    turn = _turn_units(robot)
    on_nearest = np.full(len(poses), np.nan)
    excess = np.full(len(poses), np.nan)
    for k, (found, q0, q) in enumerate(zip(sets, q_init, poses)):
        if not success[k] or not len(found):
            continue
        gap = found - q
        gap = np.where(turn > 0, gap - turn * np.round(gap / np.where(turn > 0, turn, 1)), gap)
        lies = np.abs(gap).max(axis=1) <= SAME_BRANCH_DEG
        if not lies.any():
            continue
        nearest = int(np.argmin(np.linalg.norm(found - q0, axis=1)))
        on_nearest[k] = float(np.abs(found[nearest] - q).max() <= SAME_BRANCH_DEG)
        excess[k] = max(0.0, float(np.linalg.norm(q - q0) - np.linalg.norm(found[nearest] - q0)))
    return {"on_nearest_branch": on_nearest, "branch_excess_deg": excess}


def stress(robot: Robot, q_target: np.ndarray) -> dict[str, np.ndarray]:
    """What makes a target hard, from the configuration it was sampled from (B, dof) [pose
    units]: ``sigma_min``, the smallest singular value of the end frame's 6 x dof Jacobian
    (Pinocchio, LOCAL_WORLD_ALIGNED; translation rows in m, rotation rows in rad, per rad or m
    of joint motion: near 0 at a singularity), and ``limit_margin_deg``, the smallest
    distance of a joint from its limits [pose units: deg, mm for prismatic joints]."""
    import pinocchio as pin

    fk = robot.pinocchio_fk()
    data = fk.model.createData()
    sigma = np.empty(len(q_target))
    for k, q in enumerate(robot.to_urdf(np.atleast_2d(q_target))):
        pin.computeJointJacobians(fk.model, data, q)
        pin.updateFramePlacements(fk.model, data)
        J = pin.getFrameJacobian(fk.model, data, fk.frame_id, pin.LOCAL_WORLD_ALIGNED)
        sigma[k] = np.linalg.svd(J, compute_uv=False).min()
    margin = np.minimum(q_target - robot.lower, robot.upper - q_target).min(axis=1)
    return {"sigma_min": sigma, "limit_margin_deg": margin}


def reach_bound_m(robot: Robot) -> tuple[np.ndarray, float]:
    """A sphere no end-frame position can leave: its centre, the first joint's origin at the
    zero configuration [m, base frame], and its radius, the sum of the distances between
    consecutive joint origins and from the last one to the end frame [m] (the triangle
    inequality: every joint moves the points after it rigidly about an axis through its
    origin, so their distances to that origin never change)."""
    import pinocchio as pin

    fk = robot.pinocchio_fk()
    data = fk.model.createData()
    pin.framesForwardKinematics(fk.model, data, pin.neutral(fk.model))
    origins = [data.oMi[i].translation.copy() for i in range(1, fk.model.njoints)]
    points = [*origins, data.oMf[fk.frame_id].translation.copy()]
    radius = float(sum(np.linalg.norm(b - a) for a, b in zip(points, points[1:])))
    return origins[0], radius


#: Unreachable targets lie this far beyond the reach bound (times its radius) at least.
BEYOND_REACH = 1.1


def unreachable_targets(robot: Robot, T_reachable: np.ndarray, rng: np.random.Generator
                        ) -> np.ndarray:
    """Frames (B, 4, 4) [m] no configuration reaches: each of ``T_reachable``'s rotations at a
    position pushed along the ray from the reach bound's centre to between
    :data:`BEYOND_REACH` and twice the bound's radius (:func:`reach_bound_m`)."""
    centre, radius = reach_bound_m(robot)
    out = np.array(T_reachable, dtype=float, copy=True)
    ray = out[:, :3, 3] - centre
    norm = np.linalg.norm(ray, axis=1, keepdims=True)
    ray = np.where(norm > 1e-9, ray / np.maximum(norm, 1e-12), np.array([1.0, 0.0, 0.0]))
    distance = radius * rng.uniform(BEYOND_REACH, 2.0, (len(out), 1))
    out[:, :3, 3] = centre + ray * distance
    return out


#: ``unreachable_kind`` of a target: reachable, beyond the reach bound, or an orientation the
#: analytic solver proves impossible at a reachable position.
REACHABLE, BEYOND_REACH_KIND, ORIENTATION_KIND = "", "beyond_reach", "orientation_impossible"
#: Random orientations drawn per orientation-impossible target at most.
ORIENTATION_DRAWS = 100
#: An orientation counts as impossible only with this margin, in judge tolerances: nothing
#: comes within this many times the judge's tolerances of the frame (see
#: :func:`orientation_impossible`).
MARGIN_TOLERANCES = 3.0
#: Damped least-squares iterations of the numerical check from each least-squares answer.
NEARBY_ITERATIONS = 60


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation (3, 3) uniform over SO(3): a unit quaternion from four normal draws."""
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _perturbations(step_m: float, step_rad: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """A fixed set of (offset [m] (3,), rotation (3, 3)) steps: every position offset of
    {-1, 0, 1}^3 x ``step_m`` combined with no rotation and with a rotation by ``step_rad``
    about each axis either way (27 x 7 = 189, the first the identity)."""
    import pinocchio as pin

    offsets = [np.array([i, j, k], dtype=float) * step_m
               for i in (0, -1, 1) for j in (0, -1, 1) for k in (0, -1, 1)]
    turns = [np.eye(3)] + [pin.exp3(sign * step_rad * np.eye(3)[axis])
                           for axis in range(3) for sign in (-1.0, 1.0)]
    return [(offset, turn) for turn in turns for offset in offsets]


def _nearest_miss(solver: PoseSolver, point_m: np.ndarray, rotation: np.ndarray,
                  starts: np.ndarray, tolerance: tuple[float, float]) -> float:
    """The smallest miss of the frame, ``max(mm / tolerance_mm, deg / tolerance_deg)``, that
    damped least squares (Pinocchio, the error weighted by the tolerances, each step kept
    within the limits) reaches from each of ``starts`` (S, dof) [rad]; inf without starts."""
    import pinocchio as pin

    fk = solver.robot.pinocchio_fk()
    data = fk.model.createData()
    scale = np.r_[np.full(3, 1000.0 / tolerance[0]), np.full(3, math.degrees(1.0) / tolerance[1])]
    lower, upper = solver.lower, solver.upper  # type: ignore[attr-defined]
    target = pin.SE3(rotation, np.asarray(point_m, dtype=float))
    best = math.inf
    for q in np.atleast_2d(starts):
        q = np.clip(np.asarray(q, dtype=float), lower, upper)
        for _ in range(NEARBY_ITERATIONS + 1):
            pin.framesForwardKinematics(fk.model, data, q)
            M = data.oMf[fk.frame_id]
            miss_mm = 1000.0 * float(np.linalg.norm(M.translation - target.translation))
            miss_deg = math.degrees(float(np.linalg.norm(pin.log3(M.rotation.T @ rotation))))
            best = min(best, max(miss_mm / tolerance[0], miss_deg / tolerance[1]))
            # the error in the world-aligned frame: position gap and the rotation's log
            err = np.r_[target.translation - M.translation, pin.log3(rotation @ M.rotation.T)]
            J = pin.computeFrameJacobian(fk.model, data, q, fk.frame_id,
                                         pin.LOCAL_WORLD_ALIGNED)
            Js, es = J * scale[:, None], err * scale
            dq = np.linalg.solve(Js.T @ Js + 1e-6 * np.eye(len(q)), Js.T @ es)
            q = np.clip(q + dq, lower, upper)
    return best


def orientation_impossible(solver: PoseSolver, point_m: np.ndarray, rotation: np.ndarray,
                           tolerance: tuple[float, float] = (JUDGE_TOLERANCE_MM,
                                                             JUDGE_TOLERANCE_DEG)) -> bool:
    """True when no configuration within the limits comes near the frame, with a margin of
    :data:`MARGIN_TOLERANCES` times the judge's ``tolerance`` (mm, deg). Two checks, both
    must hold:

    (a) the analytic ``solver`` has no exact solution (``is_LS`` False) with every joint
        within its limits widened by the margin [deg] (any whole turn,
        :func:`ikbench.baselines.eaik_ik.in_limit_turns`), for the frame nor for any of a
        fixed set of frames around it (:func:`_perturbations`: the position moved by the
        margin [mm] along each axis and diagonal, the rotation turned by the margin [deg]
        about each axis): a frame the judge would accept an answer for lies within one
        tolerance of the frame, so within the grid's spacing of one of these;
    (b) damped least squares within the limits, from each of the solver's least-squares
        answers to the frame (they are near the nearest pose, not on it: a frame just beyond
        a workspace boundary is missed by them by more than by the boundary's pose), misses
        by more than the margin (:func:`_nearest_miss`).

    The EAIK enumeration is exact; the margin covers the boundary between its frames and
    numerical solvers that stop within a tolerance of the frame."""
    step_m = MARGIN_TOLERANCES * tolerance[0] / 1000.0
    step_rad = math.radians(MARGIN_TOLERANCES * tolerance[1])
    widen = math.radians(MARGIN_TOLERANCES * tolerance[1])
    point_m = np.asarray(point_m, dtype=float)
    for offset, turn in _perturbations(step_m, step_rad):
        if len(solver.branches(point_m + offset, rotation @ turn,  # type: ignore[attr-defined]
                               tol=widen)):
            return False
    starts = solver.solutions(point_m, rotation)[1]  # type: ignore[attr-defined]
    return _nearest_miss(solver, point_m, rotation, starts, tolerance) > MARGIN_TOLERANCES


def unreachable_mix(robot: Robot, T_reachable: np.ndarray, rng: np.random.Generator,
                    solver: PoseSolver | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The unreachable targets of ``--unreachable`` (B, 4, 4) [m] made from B reachable ones,
    and each one's kind (B,) (:data:`BEYOND_REACH_KIND`, :data:`ORIENTATION_KIND`).

    Without an analytic ``solver`` every one is beyond the reach bound
    (:func:`unreachable_targets`, the same draws as before). With one, the first ``B // 2``
    (half, rounded down) get a reachable position (target k's, then, draw after draw, the
    next target's: some positions admit every orientation) and a random orientation
    (uniform, from ``rng``) that the solver proves impossible there
    (:func:`orientation_impossible`), drawn up to :data:`ORIENTATION_DRAWS` times each; a
    target that finds none within its draws falls back to beyond the reach bound (said on
    stderr). The rest are beyond the reach bound, drawn from ``rng`` after the
    orientations."""
    out = np.array(T_reachable, dtype=float, copy=True)
    kinds = np.full(len(out), BEYOND_REACH_KIND, dtype=object)
    wanted = len(out) // 2 if solver is not None else 0
    for k in range(wanted):
        for draw in range(ORIENTATION_DRAWS):
            point = T_reachable[(k + draw) % len(out), :3, 3]  # a position no orientation
            rotation = _random_rotation(rng)                   # misses moves to the next
            if solver is not None and orientation_impossible(solver, point, rotation):
                out[k, :3, :3], out[k, :3, 3], kinds[k] = rotation, point, ORIENTATION_KIND
                break
    far = kinds == BEYOND_REACH_KIND
    missing = int(far[:wanted].sum())
    if missing:
        import sys

        print(f"ikbench ik: {missing} of {wanted} orientation-impossible targets not found in "
              f"{ORIENTATION_DRAWS} draws each; beyond the reach bound instead", file=sys.stderr)
    if far.any():
        out[far] = unreachable_targets(robot, T_reachable[far], rng)
    return out, kinds
