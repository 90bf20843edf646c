"""TRAC-IK (PyPI ``pytracik``): one exact 6-D IK per goal point, warm-started, walked back from
the touch pose.

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
converged. 6-D goal frames are solved as given.

Not deterministic: each ``CartToJnt`` races a KDL Newton thread and an NLopt thread against a
wall-clock timeout with random restarts and returns the best solution found when the race
ends, so identical inputs can give slightly different joints (about 1 solve in 200 here).
``iterations`` counts ``pytracik.ik`` calls (TRAC-IK reports no iteration count).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from baselines._chain import Chain, Goals
from baselines._geometry import closest_rotation_with_axis, quaternion_xyzw, rotation_about
from baselines._method import ChainResult, LibraryMethod
from baselines._walk import PointResult, walk_back
from ikbench.core.errors import InputError
from ikbench.methods.base import check_choice, check_positive, option

SOLVE_TYPES = ("Speed", "Distance", "Manip1", "Manip2")
#: What TRAC-IK takes as the limits of a continuous joint (it tests against FLT_MAX).
CONTINUOUS = float(np.finfo(np.float32).max)
_SOLVERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class TracIKSettings:
    """Settings of the TRAC-IK walk (see the module docstring)."""

    timeout: float = option(0.005, flag="tracik-timeout", unit="s",
                            help="TRAC-IK's time limit per solve")
    eps: float = option(5e-7, flag="tracik-eps", unit="m, rad",
                        help="stop when every component of the pose-error twist is below")
    solve_type: str = option("Speed", flag="tracik-solve-type", choices=SOLVE_TYPES,
                             help="TRAC-IK's SolveType: Speed returns the first solution; the "
                             "others use the whole timeout")
    roll_step: float = option(1.0, flag="tracik-roll-step", unit="deg",
                              help="roll sweep step when a point has no solution")
    roll_max: float = option(60.0, flag="tracik-roll-max", unit="deg",
                             help="largest roll change tried (0: no sweep)")

    def __post_init__(self):
        check_positive(self, "timeout", "eps", "roll_step")
        check_choice(self, "solve_type", SOLVE_TYPES)
        if not 0 <= self.roll_max <= 180:
            raise InputError(f"--tracik-roll-max: {self.roll_max!r} must be in [0, 180] deg")

    def rolls_rad(self) -> list[float]:
        """0, +step, -step, +2 step, ... up to +-roll_max [rad]."""
        count = int(np.floor(self.roll_max / self.roll_step + 1e-9))
        rolls = [0.0]
        for k in range(1, count + 1):
            rolls += [np.radians(k * self.roll_step), -np.radians(k * self.roll_step)]
        return rolls


def tracik_solver(chain: Chain, settings: TracIKSettings):
    """The TRAC-IK solver of ``chain`` (cached per chain and timeout, eps, solve type)."""
    key = (settings.timeout, settings.eps, settings.solve_type)
    cached = _SOLVERS.setdefault(chain, {})
    if key in cached:
        return cached[key]
    import pytracik

    solver = pytracik.TRAC_IK(chain.base_link, chain.end_frame, chain.urdf_text,
                              float(settings.timeout), float(settings.eps),
                              getattr(pytracik.SolveType, settings.solve_type))
    if pytracik.get_num_joints(solver) != chain.dof:
        raise ValueError(f"TRAC-IK's chain {chain.base_link} -> {chain.end_frame} has "
                         f"{pytracik.get_num_joints(solver)} joints, the robot {chain.dof}")
    lower = np.where(np.isfinite(chain.lower), chain.lower, -CONTINUOUS)
    upper = np.where(np.isfinite(chain.upper), chain.upper, CONTINUOUS)
    pytracik.set_joint_limits(solver, [float(v) for v in lower], [float(v) for v in upper])
    cached[key] = solver
    return solver


def solve_chain(chain: Chain, goals: Goals, settings: TracIKSettings) -> ChainResult:
    """The TRAC-IK walk in URDF units (see the module docstring)."""
    import pytracik

    solver = tracik_solver(chain, settings)
    rolls = settings.rolls_rad()
    swept = []

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        if goals.rotations is not None:
            candidates = [goals.rotations[i]]
        else:
            R_warm = np.asarray(pytracik.fk(solver, q_warm))[:3, :3]
            tilted = closest_rotation_with_axis(R_warm, chain.pointing_axis,
                                                goals.directions[i])
            candidates = [rotation_about(goals.directions[i], r) @ tilted for r in rolls]
        x, y, z = (float(v) for v in goals.points_m[i])
        for k, rotation in enumerate(candidates):
            out = pytracik.ik(solver, np.ascontiguousarray(q_warm, dtype=float), x, y, z,
                              *quaternion_xyzw(rotation))
            if out[0] >= 0:
                if k:
                    swept.append(i)
                return PointResult(np.asarray(out[1:], dtype=float), k + 1, True)
        return PointResult(q_warm, len(candidates), False)

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, points_roll_swept=len(swept),
                                 solve_type=settings.solve_type,
                                 iterations_are="pytracik.ik calls (TRAC-IK reports no "
                                 "iteration count)")


class TracIK(LibraryMethod):
    """TRAC-IK per point (exact 6-D, roll carried over), walked back from the touch pose."""

    name = "trac-ik"
    description = ("library: TRAC-IK (pytracik) per point, the roll carried over from the "
                   "previous pose, warm-started, walked back from the touch pose; not "
                   "bit-deterministic (threads race a timeout)")
    library = "pytracik"
    Settings = TracIKSettings
    supports_frames = True

    def prepare(self, robot) -> None:
        """Untimed: KDL parses the URDF, TRAC-IK builds its solvers."""
        from baselines._chain import chain_of

        tracik_solver(chain_of(robot), self.settings)

    def solve_chain(self, robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)
