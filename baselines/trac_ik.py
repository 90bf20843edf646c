"""TRAC-IK (PyPI ``pytracik``): one exact 6-D IK per goal point, warm-started: tracked from the
start pose onto the touch pose (``scheme`` track, the default) or walked back from the touch
pose (walk, :mod:`ikbench.schemes.walk`).

pytracik 0.0.3 ships only its compiled binding (module ``pytracik``; the ``trac_ik`` Python
wrapper of its README is not in the wheel; source: github.com/chenhaox/pytracik
``src/pytracik.cpp``). The calls:

- ``pytracik.TRAC_IK(base_link, end_frame, urdf_text, timeout_s, eps, SolveType)``: KDL chain
  from the URDF, solver;
- ``pytracik.set_joint_limits(solver, lower, upper)``: the chain's limits. Needed: its URDF
  parser stores limits in single precision (pi becomes 3.1415927 > pi), which would let
  solutions leave the limits by ~1e-7 rad. Continuous joints get +-FLT_MAX, which TRAC-IK
  reads as "continuous";
- ``pytracik.ik(solver, seed, x, y, z, qx, qy, qz, qw)`` -> ``[rc, q...]`` (rc >= 0: solved);
- ``pytracik.fk(solver, q)`` -> 4x4 end frame in the base frame.

Pointing goals with an exact-pose solver: the binding calls ``CartToJnt`` without TRAC-IK's
tolerance twist (which could free the roll), so every solve asks for a full rotation. Goal i
asks for the warm start's end-frame rotation tilted by the smallest angle that puts the pointing
axis on the goal direction (the roll carried over from the previous pose). When TRAC-IK finds
no solution for that roll, the roll is swept about the goal direction (+-1, +-2, ... deg up to
+-60 deg by default) and the first success kept; near the start of some NICO lines only a few
degrees of roll are reachable. A point with no solution keeps its warm start and counts as not
converged. 6-D goal frames are solved as given. A returned solution counts as solved only when
``pytracik.fk`` puts it within the tolerance asked: TRAC-IK bounds every component of the
pose-error twist by ``eps`` in its own frame, so position [m] and rotation angle [rad] within
sqrt(3) eps (:data:`FK_CHECK`).

The track (:mod:`ikbench.schemes.track`): row 0 is the start pose, row n the touch pose;
step i asks for the plan's point and scheduled pointing direction, the rotation built as above
but its roll ramped onto the touch pose's (:mod:`ikbench.schemes.exact_pose`) rather
than carried over, so the last segment does not spin the wrist onto the touch pose. When
the task asks no pointing, position only is impossible with an exact-pose solver: the step asks
for the task's own goal direction (not judged; roll swept as above) and, when none of those
rotations is solved, for the warm start's rotation itself. TRAC-IK has no posture term: its
redundancy resolution is SolveType ``Distance`` (default here; the solution nearest the seed
among those found within the timeout), and the seed of step i is the warm start moved
``posture_seed`` of the way toward the plan's posture pose (start to touch pose, linearly),
the only way to steer it toward the touch pose. Nothing bounds a step's joint change: on NICO
the first steps, where the pointing turns onto the line, move the wrist several times faster
than its speed limit allows (docs/baselines.md).

Not deterministic: each ``CartToJnt`` races a KDL Newton thread and an NLopt thread against a
wall-clock timeout with random restarts and returns the best solution found when the race
ends, so identical inputs can give slightly different joints (about 1 solve in 200 here).
``iterations`` counts ``pytracik.ik`` calls (TRAC-IK reports no iteration count).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.chatter import quiet
from ikbench.methods.base import Capabilities
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals, chain_of
from ikbench.schemes.exact_pose import (
    check_roll_settings,
    roll_max_option,
    roll_step_option,
    rolls_rad,
    solve_exact_poses,
)
from ikbench.schemes.geometry import quaternion_xyzw, rotation_angle_rad
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.single_pose import PoseOut, PoseSolver
from ikbench.schemes.track import SCHEME_HELP, SCHEMES

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

SOLVE_TYPES = ("Speed", "Distance", "Manip1", "Manip2")
#: What TRAC-IK takes as the limits of a continuous joint (it tests against FLT_MAX).
CONTINUOUS = float(np.finfo(np.float32).max)
#: A solution counts as solved when its FK position error [m] and rotation error [rad] are
#: both within this many times ``eps``: TRAC-IK bounds every component of the error twist by
#: eps in its own frame, so both norms are within sqrt(3) eps in any frame.
FK_CHECK = float(np.sqrt(3.0))
_SOLVERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class TracIKSettings:
    """Settings of TRAC-IK's track and walk (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    timeout: float = option(0.005, flag="tracik-timeout", unit="s",
                            help="TRAC-IK's time limit per solve")
    eps: float = option(5e-7, flag="tracik-eps", unit="m, rad",
                        help="stop when every component of the pose-error twist is below")
    solve_type: str = option("Distance", flag="tracik-solve-type", choices=SOLVE_TYPES,
                             help="TRAC-IK's SolveType: Distance returns the solution nearest "
                             "the seed found within the timeout, Speed the first one, Manip1 / "
                             "Manip2 the most manipulable one")
    roll_step: float = roll_step_option("tracik")
    roll_max: float = roll_max_option("tracik")
    posture_seed: float = option(0.5, flag="tracik-posture-seed",
                                 help="scheme track: TRAC-IK's seed (the pose its Distance "
                                 "mode returns the solution nearest to) is the warm start "
                                 "moved this fraction toward the step's posture pose (start "
                                 "to touch pose, linearly); 0: the warm start")

    def __post_init__(self):
        check_positive(self, "timeout", "eps")
        check_choice(self, "scheme", SCHEMES)
        check_choice(self, "solve_type", SOLVE_TYPES)
        check_roll_settings(self)

    def rolls_rad(self) -> list[float]:
        """0, +step, -step, +2 step, ... up to +-roll_max [rad]."""
        return rolls_rad(self.roll_step, self.roll_max)


def tracik_solver(chain: Chain, settings: TracIKSettings) -> Any:
    """The TRAC-IK solver of ``chain`` (cached per chain and timeout, eps, solve type)."""
    key = (settings.timeout, settings.eps, settings.solve_type)
    cached = _SOLVERS.setdefault(chain, {})
    if key in cached:
        return cached[key]
    import pytracik

    with quiet("trac-ik"):  # KDL prints on stdout ("The root link %s has an inertia ...")
        solver = pytracik.TRAC_IK(chain.base_link, chain.end_frame, chain.urdf_text,
                                  float(settings.timeout), float(settings.eps),
                                  getattr(pytracik.SolveType, settings.solve_type))
    if pytracik.get_num_joints(solver) != chain.dof:
        raise ValueError(f"TRAC-IK's chain {chain.base_link} -> {chain.end_frame} has "
                         f"{pytracik.get_num_joints(solver)} joints, the robot {chain.dof}")
    set_limits(solver, chain.lower, chain.upper)
    cached[key] = solver
    return solver


def set_limits(solver: Any, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:
    """TRAC-IK's joint limits [rad, m]; infinite ones (continuous joints) as +-FLT_MAX."""
    import pytracik

    lower = np.where(np.isfinite(lower), lower, -CONTINUOUS)
    upper = np.where(np.isfinite(upper), upper, CONTINUOUS)
    pytracik.set_joint_limits(solver, [float(v) for v in lower], [float(v) for v in upper])


def solve_chain(chain: Chain, goals: Goals, settings: TracIKSettings) -> ChainResult:
    """TRAC-IK in URDF units: the tracking scheme when ``goals.track`` is set, else the walk
    (see the module docstring)."""
    import pytracik

    solver = tracik_solver(chain, settings)

    def solve(seed: np.ndarray, point: np.ndarray, rotation: np.ndarray
              ) -> tuple[np.ndarray, bool] | None:
        x, y, z = (float(v) for v in point)
        out = pytracik.ik(solver, np.ascontiguousarray(seed, dtype=float), x, y, z,
                          *quaternion_xyzw(rotation))
        if out[0] < 0:
            return None
        q = np.asarray(out[1:], dtype=float)
        return q, pose_error(solver, q, point, rotation) <= FK_CHECK * settings.eps

    def end_rotation(q: np.ndarray) -> np.ndarray:
        return np.asarray(pytracik.fk(solver, np.ascontiguousarray(q, dtype=float)))[:3, :3]

    walk, info = solve_exact_poses(chain, goals, solve, end_rotation, settings.rolls_rad(),
                                   settings.posture_seed)
    return ChainResult.from_walk(walk, points_roll_swept=info["points_roll_swept"],
                                 points_fk_off=info["points_fk_off"],
                                 solve_type=settings.solve_type, scheme=info["scheme"],
                                 iterations_are="pytracik.ik calls (TRAC-IK reports no "
                                 "iteration count)")


def pose_error(solver: Any, q: npt.ArrayLike, point: npt.ArrayLike, rotation: np.ndarray
               ) -> float:
    """The larger of the position error [m] and the rotation error [rad] of ``q`` against the
    pose (``point``, ``rotation``), by ``pytracik.fk``."""
    import pytracik

    T = np.asarray(pytracik.fk(solver, np.ascontiguousarray(q, dtype=float)))
    return max(float(np.linalg.norm(T[:3, 3] - np.asarray(point, dtype=float))),
               rotation_angle_rad(T[:3, :3], rotation))


class TracIK(LibraryMethod):
    """TRAC-IK per point (exact 6-D; the roll ramped onto the touch pose's on the track,
    carried over on the walk), tracked from the start pose onto the touch pose (scheme track)
    or walked back from the touch pose (walk)."""

    name = "trac-ik"
    description = ("library: TRAC-IK (pytracik) per point, exact 6-D poses whose roll is "
                   "ramped onto the touch pose's, SolveType Distance, tracked from the start "
                   "pose onto the touch pose (--scheme walk: back from it, the roll carried "
                   "over); not bit-deterministic (threads race a timeout)")
    library = "pytracik"
    Settings = TracIKSettings
    capabilities = Capabilities(needs_touch_pose=True, frames=True)

    def prepare(self, robot: Robot) -> None:
        """Untimed: KDL parses the URDF, TRAC-IK builds its solvers."""

        tracik_solver(chain_of(robot), self.settings)

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)


#: Single-pose IK: TRAC-IK's eps and SolveType (trac_ik_lib's defaults; its default timeout,
#: 5 ms, is the protocol's default budget), and its timeout when the budget is unbounded.
POSE_EPS, POSE_SOLVE_TYPE, POSE_UNBOUNDED_TIMEOUT_S = 1e-5, "Speed", 1.0


class TracIKSolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`):
    ``ik(solver, seed, x, y, z, qx, qy, qz, qw)`` from the first initial configuration, with
    the budget as TRAC-IK's timeout (its own random restarts within it: it restarts itself,
    from its own draws; the sequence's further rows are not used), eps 1e-5, Speed. Poses
    only: the binding cannot free the rotation (no tolerance twist)."""

    rank = 30
    name, library, modules = "trac-ik", "pytracik", ("pytracik",)
    kinds = ("pose",)
    deterministic = False
    restarts_itself = True
    one_descent = False
    iterations_are = "pytracik.ik calls (TRAC-IK reports no iteration count)"
    attempt_bound = ("its timeout, the budget, under every rule (its own random restarts "
                     "within it)")

    def prepare(self) -> None:
        timeout = self.budget_s if np.isfinite(self.budget_s) else POSE_UNBOUNDED_TIMEOUT_S
        self.solver = tracik_solver(self.chain, TracIKSettings(
            timeout=timeout, eps=POSE_EPS, solve_type=POSE_SOLVE_TYPE))

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        import pytracik

        x, y, z = (float(v) for v in point_m)
        out = pytracik.ik(self.solver, np.ascontiguousarray(q_init, dtype=float), x, y, z,
                          *quaternion_xyzw(rotation))
        ok = out[0] >= 0
        return PoseOut(np.asarray(out[1:], dtype=float) if ok else np.asarray(q_init), 1, ok)

    def bare_call(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray
                  ) -> Callable[[], object]:
        """The bare ``pytracik.ik(solver, seed, x, y, z, qx, qy, qz, qw)`` of :meth:`solve`, its
        arguments converted in advance (see :meth:`PoseSolver.bare_call`)."""
        import pytracik

        ik, solver = pytracik.ik, self.solver
        seed = np.ascontiguousarray(q_init, dtype=float)
        x, y, z = (float(v) for v in point_m)
        quaternion = tuple(float(v) for v in quaternion_xyzw(rotation))
        return lambda: ik(solver, seed, x, y, z, *quaternion)

    def solve_within(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                     budget_s: float) -> PoseOut:
        """The first row, TRAC-IK's timeout the budget (set in :meth:`prepare`: ``budget_s``
        must be the solver's)."""
        if budget_s != self.budget_s:
            raise ValueError(f"TRAC-IK's timeout is the budget it was built with, "
                             f"{self.budget_s} s, not {budget_s} s")
        return self.solve(initials[0], point_m, rotation)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="pytracik", requires=("pytracik",),
                  methods=(TracIK,), solvers=(TracIKSolver,), rank=70)
