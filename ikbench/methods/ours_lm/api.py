"""``ikbench.solve_pose``: ours-lm's single-pose IK of one goal frame, as a library call.

The call ``ikbench ik`` times (:meth:`.pose_solver.OursLMSolver.solve_within`), without the
benchmark around it: the compiled solver of a robot is built on the first call for that
robot, kind and tolerance, and kept
(:meth:`.pose_solver.OursLMSolver.prepare_first_call`): a call loads from numba's cache only
the kernel layout its arrays need, on its first use (compiled where the cache holds none),
instead of every layout the benchmark's timed calls can meet; every later call is one
compiled call (the goal's conversion to [mm] inside it), with the answers of the benchmark's
solver bit for bit.
"""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError

if TYPE_CHECKING:
    import numpy.typing as npt

    from ikbench.core.robot import Robot

#: Robot -> {(kind, tolerance): prepared OursLMSolver}; dropped with the robot.
_SOLVERS: weakref.WeakKeyDictionary[Any, dict[tuple, Any]] = weakref.WeakKeyDictionary()
#: The last (robot, kind, tolerance, solver) asked for: a repeated call finds its solver by
#: identity (~0.05 us; the weak dictionary's look-up costs ~0.3 us). Holds one robot.
_LAST: list[Any] = [None, None, None, None]


def solve_pose(robot: Robot, T: npt.ArrayLike, q0: npt.ArrayLike, *,
               kind: str = "pose", tolerance: tuple[float, float] = (1.0, 0.5),
               budget_s: float = math.inf) -> tuple[np.ndarray, bool]:
    """Solve one goal end frame by ours-lm's Levenberg-Marquardt from ``q0``.

    Args:
        robot: the robot (:func:`ikbench.load_robot`).
        T: the goal end frame T_base_end (4, 4): rotation and translation [m], in the
            robot's base frame.
        q0: the initial configuration (dof,) in the robot's pose units (joint degrees,
            prismatic joints in mm; motor degrees for NICO), or several (A, dof) tried in
            order until one succeeds (each attempt at most 100 LM iterations; a crawling
            one kicked, as ``ikbench ik --attempts A``).
        kind: ``"pose"`` (point and rotation) or ``"position"`` (the point only).
        tolerance: (position [mm], rotation [deg]) the success tolerance.
        budget_s: wall-clock budget [s] (``inf``, the default: none; with a budget and
            several rows, the budgeted restarts of ``ikbench ik --attempts auto``).

    Returns:
        (q, success): the answer configuration (dof,) [pose units], within the joint limits,
        and whether both errors are below 1e-3 x ``tolerance`` (far inside the judge's
        tolerance; a failed answer is the last attempt's pose).

    The first call for a robot builds its solver and loads the one kernel layout it needs
    from numba's cache (compiled once per machine: ``ikbench warmup``); later ones cost
    the kernel's time and ~1 us besides (``benchmarks/ours_lm_empty_call.py``).
    """
    last = _LAST
    if last[0] is robot and last[1] == kind and (
            last[2] is tolerance or (tolerance.__class__ is tuple and last[2] == tolerance)):
        solver = last[3]
    else:
        solver = _solver(robot, kind, tolerance)
    if T.__class__ is not np.ndarray:
        T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise InputError(f"T: shape {T.shape} is not (4, 4)")
    starts = q0 if q0.__class__ is np.ndarray else np.asarray(q0, dtype=float)
    if starts.ndim == 1:
        starts = starts[None]
    try:
        out = solver.solve_within(starts, T[:3, 3], T[:3, :3], budget_s)
    except ValueError:  # the kernel's shape check, named as the caller passed it
        raise InputError(f"q0: shape {np.shape(q0)} is not ({robot.dof},) or (A >= 1, "
                         f"{robot.dof})") from None
    return out.q, bool(out.ok)


def _solver(robot: Robot, kind: str, tolerance: tuple[float, float]) -> Any:
    """The robot's prepared solver for ``kind`` and ``tolerance`` (built on first use),
    remembered as the last one asked for."""
    per_robot = _SOLVERS.get(robot)
    if per_robot is None:
        per_robot = _SOLVERS[robot] = {}
    key = (kind, tuple(float(t) for t in tolerance))
    solver = per_robot.get(key)
    if solver is None:
        solver = per_robot[key] = _build(robot, kind, key[1])
    _LAST[:] = [robot, kind, tolerance if tolerance.__class__ is tuple else key[1], solver]
    return solver


def _build(robot: Robot, kind: str, tolerance: tuple[float, ...]) -> Any:
    """A :class:`.pose_solver.OursLMSolver` set up for first use (its layouts loaded as calls
    need them; bad settings: InputError)."""
    from ikbench.methods.ours_lm.pose_solver import OursLMSolver

    if kind not in ("pose", "position"):
        raise InputError(f"kind: {kind!r} is not one of pose, position")
    if len(tolerance) != 2 or not min(tolerance) > 0:
        raise InputError(f"tolerance: {tolerance!r} must be (mm > 0, deg > 0)")
    solver = OursLMSolver(robot, kind, tolerance)
    solver.prepare_first_call()
    return solver
