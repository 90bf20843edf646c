"""Tracking and walking with a library that solves exact 6-D poses (TRAC-IK, roboticstoolbox's
``ik_LM``): what pointing goals become for such a solver, shared by those methods.

A pointing goal fixes one axis of the end frame, not its roll; an exact-pose solver needs a
whole rotation. Goal i asks for the warm start's end-frame rotation tilted by the smallest angle
that puts the pointing axis on the goal direction (the walk: the roll carried over from the pose
before; the track: then ramped, below).
When the solver finds no solution for that roll, the roll is swept about the goal direction
(+-step, +-2 step, ... up to +-max, :func:`rolls_rad`) and the first success kept. A point with
no solution keeps its warm start and counts as not converged. 6-D goal frames are solved as
given.

The track (:mod:`ikbench.schemes.track`): step i asks for the plan's point and
scheduled pointing direction (the plan already turns the pointing from the start pose's own over
the unjudged first steps and onto the touch pose's over the last ones); when the task asks no
pointing, the step asks for the task's own goal direction (not judged; roll swept as above) and,
when none of those rotations is solved, for the warm start's rotation itself. The roll is not
carried over but ramped onto the touch pose's (:func:`ramped_roll`): step i turns the warm
start's tilted rotation about the pointing axis by the roll still between it and the touch
pose's rotation (tilted onto the same direction) divided by the steps left, n - i, so the roll
arrives at the touch pose's by step n - 1 in equal parts and the last segment does not spin the
wrist onto it. The seed of step i is the warm start moved ``posture_seed`` of the way toward the
plan's posture pose (start to touch pose, linearly): an exact-pose solver has no posture term.
Each point is still one library call per rotation tried; ikbench only picks the rotations and
the seed. The walk (:mod:`ikbench.schemes.walk`) seeds each point with the pose after
it and carries the roll over.

A library that can leave the roll free itself (roboticstoolbox's ``ik_LM`` with a mask: the
``solve_free`` argument) is asked each pointing goal once, roll free, with the warm start's
tilted rotation as the hint, no sweep and no ramp. On the track its seed is then the warm
start moved toward the posture pose by a fraction that is 0 over the unjudged first steps
(i < ``judged_from``, where the pointing turns) and rises linearly to ``posture_seed`` over
the next 2 ``judged_from`` steps (:func:`delayed_seed_fraction`): a solver without a posture
term that settles near its seed is pulled onto the touch pose gradually, and not while the
turn already takes the wrist's allowed step.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.options import check_fraction, check_positive, flag_of, option
from ikbench.schemes.chain import Chain, Goals
from ikbench.schemes.geometry import (
    closest_rotation_with_axis,
    roll_between_rad,
    rotation_about,
)
from ikbench.schemes.track import track
from ikbench.schemes.walk import PointResult, Walk, walk_back

#: ``solve(seed, point, rotation)``: seed (dof,) [rad, m], goal point (3,) [m], goal rotation
#: (3, 3) -> (q (dof,), holds) when the library returns a solution (``holds``: its FK is
#: within the library's tolerance), None when it finds none.
PoseIK = Callable[[np.ndarray, np.ndarray, np.ndarray], "tuple[np.ndarray, bool] | None"]


def roll_step_option(prefix: str) -> Any:
    """The settings field ``roll_step`` [deg], flag ``--{prefix}-roll-step``."""
    return option(1.0, flag=f"{prefix}-roll-step", unit="deg",
                  help="roll sweep step when a point has no solution")


def roll_max_option(prefix: str) -> Any:
    """The settings field ``roll_max`` [deg], flag ``--{prefix}-roll-max``."""
    return option(60.0, flag=f"{prefix}-roll-max", unit="deg",
                  help="largest roll change tried (0: no sweep)")


def check_roll_settings(settings: Any) -> None:
    """InputError naming the flag for a bad ``roll_step``, ``roll_max`` [deg] or
    ``posture_seed`` of an exact-pose method's settings."""
    check_positive(settings, "roll_step")
    check_fraction(settings, "posture_seed")
    if not 0 <= settings.roll_max <= 180:
        raise InputError(f"{flag_of(settings, 'roll_max')}: {settings.roll_max!r} must be in "
                         "[0, 180] deg")


def rolls_rad(step_deg: float, max_deg: float) -> list[float]:
    """0, +step, -step, +2 step, ... up to +-max_deg [rad]."""
    count = int(np.floor(max_deg / step_deg + 1e-9))
    rolls = [0.0]
    for k in range(1, count + 1):
        rolls += [np.radians(k * step_deg), -np.radians(k * step_deg)]
    return rolls


def ramped_roll(tilted: np.ndarray, touch: np.ndarray, axis_local: np.ndarray,
                steps_left: int) -> np.ndarray:
    """``tilted`` (3, 3) turned about its local ``axis_local`` (3,) by 1 / ``steps_left`` of the
    roll between it and ``touch`` (3, 3; its ``axis_local`` along the same direction): the
    track's goal rotation (see the module docstring). ``steps_left`` >= 1; 1 gives ``touch``'s
    rotation."""
    angle = roll_between_rad(tilted, touch, axis_local) / max(int(steps_left), 1)
    return tilted @ rotation_about(axis_local, angle)


def delayed_seed_fraction(i: int, judged_from: int, top: float) -> float:
    """The roll-free track's seed fraction toward the posture pose at step ``i``: 0 before
    ``judged_from``, then rising linearly to ``top`` over 2 ``judged_from`` steps (see the
    module docstring)."""
    ramp = 2 * max(int(judged_from), 1)
    return float(top * np.clip((i - judged_from) / ramp, 0.0, 1.0))


def solve_exact_poses(chain: Chain, goals: Goals, solve: PoseIK,
                      end_rotation: Callable[[np.ndarray], np.ndarray], rolls: list[float],
                      posture_seed: float, solve_free: PoseIK | None = None
                      ) -> tuple[Walk, dict[str, object]]:
    """Track (``goals.track`` set) or walk the goals with ``solve`` (see the module docstring).

    Args:
        chain: the chain (limits, pointing axis).
        goals: the goals in URDF units.
        solve: the library's IK of one pose (:data:`PoseIK`).
        end_rotation: the end frame's rotation (3, 3) of a configuration (dof,), by the
            library's own FK.
        rolls: the roll angles [rad] tried in order (:func:`rolls_rad`).
        posture_seed: the track's seed moves this fraction from the warm start toward the
            plan's posture pose (with ``solve_free``: the top of :func:`delayed_seed_fraction`).
        solve_free: the library's IK of a pointing goal with the roll about the pointing axis
            left free (:data:`PoseIK`; the rotation's roll is only a hint), or None: then
            pointing goals are solved with it, once each (see the module docstring).

    Returns:
        (the walk, figures for details: points whose roll was swept, points whose solution
        missed the library's tolerance by FK, the scheme).
    """
    plan = goals.track
    swept, off = [], []
    touch_rotation = None if plan is None else end_rotation(plan.q_touch)

    def solve_pose(i: int, seed: np.ndarray, point: np.ndarray,
                   candidates: list[np.ndarray], q_warm: np.ndarray) -> PointResult:
        """The first candidate rotation solved at ``point`` from ``seed``; none: q_warm."""
        for k, rotation in enumerate(candidates):
            out = solve(seed, point, rotation)
            if out is not None:
                q, holds = out
                if k:
                    swept.append(i)
                if not holds:
                    off.append(i)
                return PointResult(q, k + 1, holds)
        return PointResult(q_warm, len(candidates), False)

    def pointing_candidates(q_warm: np.ndarray, direction: np.ndarray,
                            steps_left: int = 0) -> list[np.ndarray]:
        """The warm start's rotation tilted onto ``direction`` (its roll ramped onto the touch
        pose's with ``steps_left`` > 0, :func:`ramped_roll`), then rolled about it."""
        axis = chain.pointing_axis
        tilted = closest_rotation_with_axis(end_rotation(q_warm), axis, direction)
        if steps_left > 0:
            assert touch_rotation is not None
            tilted = ramped_roll(tilted, closest_rotation_with_axis(touch_rotation, axis,
                                                                    direction), axis, steps_left)
        return [rotation_about(direction, r) @ tilted for r in rolls]

    def solve_roll_free(i: int, seed: np.ndarray, point: np.ndarray, direction: np.ndarray,
                        q_warm: np.ndarray) -> PointResult:
        """One ``solve_free`` call, the warm start's rotation tilted onto ``direction`` as the
        hint; none: q_warm."""
        assert solve_free is not None
        hint = closest_rotation_with_axis(end_rotation(q_warm), chain.pointing_axis, direction)
        out = solve_free(seed, point, hint)
        if out is None:
            return PointResult(q_warm, 1, False)
        if not out[1]:
            off.append(i)
        return PointResult(out[0], 1, out[1])

    def walk_point(i: int, q_warm: np.ndarray) -> PointResult:
        if goals.rotations is None and solve_free is not None:
            return solve_roll_free(i, q_warm, goals.points_m[i], goals.directions[i], q_warm)
        candidates = ([goals.rotations[i]] if goals.rotations is not None
                      else pointing_candidates(q_warm, goals.directions[i]))
        return solve_pose(i, q_warm, goals.points_m[i], candidates, q_warm)

    def track_point(i: int, q_warm: np.ndarray) -> PointResult:
        assert plan is not None
        if solve_free is not None and plan.directions is not None:
            fraction = delayed_seed_fraction(i, plan.judged_from, posture_seed)
            seed = chain.clip(q_warm + fraction * (plan.posture[i] - q_warm))
            return solve_roll_free(i, seed, plan.points_m[i], plan.directions[i], q_warm)
        candidates = pointing_candidates(q_warm, goals.directions[i] if plan.directions is None
                                         else plan.directions[i], len(plan) - 1 - i)
        if plan.directions is None:  # no pointing asked: else the warm start's rotation
            candidates.append(end_rotation(q_warm))
        seed = chain.clip(q_warm + posture_seed * (plan.posture[i] - q_warm))
        return solve_pose(i, seed, plan.points_m[i], candidates, q_warm)

    walk = track(track_point, chain, plan) if plan is not None else \
        walk_back(walk_point, chain, goals)
    return walk, {"points_roll_swept": len(swept), "points_fk_off": len(off),
                  "scheme": "track" if plan is not None else "walk"}
