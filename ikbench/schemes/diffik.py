"""The differential-IK scheme pink and mink share (one QP per step, per goal point).

Per goal point, from the warm start, repeat until the position error is below ``tolerance``
[m] and the pointing error below ``tolerance`` [rad], or ``max_steps`` steps:

1. measure the pointing frame P (the end frame turned so that its z-axis is the pointing
   axis, :func:`ikbench.schemes.geometry.frame_with_z_on`) and the errors;
2. set the frame task's target: the goal point, and the rotation nearest P's whose z-axis is
   the goal direction (so the roll error is 0 and the orientation cost ``[w, w, 0]`` on P's
   body twist frees the roll); for 6-D goals the goal rotation itself, cost ``[w, w, w]``;
3. one QP: ``v = solve_ik(configuration, tasks, dt, damping, limits)``, q <- q + v dt.

That is the walk's solve. The tracking scheme (:mod:`ikbench.schemes.track`) shares the
rest of this module: the frame task's target at step i (:func:`track_target_rotation`: the scheduled
pointing direction, roll free, or none), the errors (:func:`track_errors`), the stop rule
(:func:`settle`: position within the tolerance and the last QP step stalled, since the
scheduled pointing may be out of reach), the posture task's per-joint weights
(:func:`posture_weights`: every pose unit costs alike) and the speed limits as a QP box
(``Goals.max_step``, :class:`SpeedBox`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.methods.options import check_positive, flag_of
from ikbench.schemes.chain import Chain, Goals
from ikbench.schemes.geometry import (
    angle_between_rad,
    closest_rotation_with_axis,
    rotation_angle_rad,
)
from ikbench.schemes.method import ChainResult, shared_option
from ikbench.schemes.walk import PointResult, walk_back

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.schemes.track import TrackPlan

Z = np.array([0.0, 0.0, 1.0])
#: The options of the scheme, alike in pink and mink (``--<library>-<field>``,
#: :func:`qp_option`): pink's defaults and words (mink's few differences are in its settings).
QP_OPTIONS: dict[str, dict[str, Any]] = {
    "dt": {"default": 1.0, "unit": "s", "help": "integration step of the QP velocity (1 with "
           "gain 1: a full Gauss-Newton step)"},
    "damping": {"default": 1e-6, "help": "Tikhonov damping of the QP (solve_ik's damping)"},
    "position_cost": {"default": 1.0, "unit": "1/m", "help": "FrameTask position cost"},
    "orientation_cost": {"default": 0.1, "unit": "1/rad", "help": "FrameTask orientation cost "
                         "on the pointing axis's tilt (roll free)"},
    "limit_gain": {"default": 0.5, "help": "ConfigurationLimit gain in (0, 1]"},
    "qp_solver": {"default": "daqp", "help": "qpsolvers backend"},
    "tolerance": {"default": 1e-6, "unit": "m, rad",
                  "help": "stop a point when position and pointing errors are below"},
    "max_steps": {"default": 100, "help": "QP steps per goal point at most"},
    "track_position_cost": {"default": 1000.0, "unit": "1/m", "help": "scheme track: "
                            "FrameTask position cost (the goal point is the hard goal; the "
                            "pointing and posture costs are small against it)"},
    "posture_cost": {"default": 0.01, "unit": "1/rad", "help": "scheme track: PostureTask "
                     "cost towards the start-to-touch posture (per pose unit: a motor degree "
                     "for NICO)"},
    "speed_fraction": {"default": 0.95, "help": "scheme track: each step moves every joint by "
                       "at most this fraction of the contract's speed-limit step and keeps the "
                       "touch pose within reach at that speed (a QP box constraint); 0: no "
                       "box"},
    "stall": {"default": 1e-4, "unit": "rad, m", "help": "scheme track: a step ends once the "
              "position is within the tolerance and the last QP step moved no joint more "
              "than this"},
}


def qp_option(library: str, name: str, **changes: Any) -> Any:
    """The settings field ``name`` of :data:`QP_OPTIONS` as ``--<library>-<name>``
    (``changes``: another default or help for this library)."""
    return shared_option(QP_OPTIONS, library, name, **changes)


def check_qp_settings(settings: Any) -> None:
    """InputError naming the method's flag when an option of :data:`QP_OPTIONS` is out of
    range or its ``qp_solver`` is not installed; ``max_steps`` becomes an int."""
    check_positive(settings, "dt", "position_cost", "track_position_cost", "limit_gain",
                   "tolerance", "stall")
    check_positive(settings, "max_steps", integer=True)
    if (settings.limit_gain > 1 or settings.damping < 0 or settings.orientation_cost < 0
            or settings.posture_cost < 0 or not 0 <= settings.speed_fraction <= 1):
        flag = {name: flag_of(settings, name) for name in QP_OPTIONS}
        raise InputError(f"{flag['limit_gain']} must be in (0, 1], {flag['speed_fraction']} "
                         f"in [0, 1], {flag['damping']}, {flag['orientation_cost']} and "
                         f"{flag['posture_cost']} >= 0")
    settings.max_steps = int(settings.max_steps)
    check_qp_solver(settings, "qp_solver")


def check_qp_solver(settings: object, field_name: str) -> None:
    """InputError naming the flag when the qpsolvers backend is not installed."""
    import qpsolvers

    value = getattr(settings, field_name)
    if value not in qpsolvers.available_solvers:

        raise InputError(f"{flag_of(settings, field_name)}: {value!r} is not an installed "
                         f"qpsolvers backend; installed: {', '.join(qpsolvers.available_solvers)}")


def target_rotation(goals: Goals, i: int, R_P: np.ndarray, R_EP: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) the frame task asks of P for goal ``i`` (see the module doc)."""
    if goals.rotations is not None:
        return goals.rotations[i] @ R_EP
    return closest_rotation_with_axis(R_P, Z, goals.directions[i])


def errors(goals: Goals, i: int, p_P: npt.ArrayLike, R_P: np.ndarray, R_EP: np.ndarray
           ) -> tuple[float, float]:
    """(position error [m], orientation error [rad]) of P at (p_P (3,), R_P (3, 3)): the angle
    between its z-axis and the goal direction, or to the goal rotation for 6-D goals."""
    position = float(np.linalg.norm(np.asarray(p_P) - goals.points_m[i]))
    if goals.rotations is not None:
        return position, rotation_angle_rad(R_P, goals.rotations[i] @ R_EP)
    return position, angle_between_rad(np.asarray(R_P) @ Z, goals.directions[i])


def orientation_costs(goals: Goals, cost: float) -> list[float]:
    """Per-axis orientation cost of P's frame task: the roll (z) free unless 6-D goals."""
    return [cost, cost, cost if goals.rotations is not None else 0.0]


def converge(measure: Callable[[], tuple[float, float]], step: Callable[[], None],
             tolerance: float, max_steps: int) -> tuple[int, bool]:
    """Take ``step()`` until both errors of ``measure()`` are below ``tolerance`` or
    ``max_steps`` steps; return (steps taken, converged)."""
    steps = 0
    while True:
        position, angle = measure()
        if position < tolerance and angle < tolerance:
            return steps, True
        if steps >= max_steps:
            return steps, False
        step()
        steps += 1


# --- the tracking scheme (ikbench.schemes.track): one solve per step from the start pose
# -


def track_target_rotation(plan: TrackPlan, i: int, R_P: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) the frame task asks of P at step ``i`` of a
    :class:`ikbench.schemes.track.TrackPlan`: the rotation nearest P's whose z-axis is the
    scheduled direction (roll kept), or P's own rotation when the plan asks no pointing."""
    if plan.directions is None:
        return np.asarray(R_P, dtype=float)
    return closest_rotation_with_axis(R_P, Z, plan.directions[i])


def track_errors(plan: TrackPlan, i: int, p_P: npt.ArrayLike, R_P: np.ndarray
                 ) -> tuple[float, float]:
    """(position error [m], pointing error [rad]) of P at step ``i`` of a plan; the pointing
    error is 0 when the plan asks no pointing."""
    position = float(np.linalg.norm(np.asarray(p_P) - plan.points_m[i]))
    if plan.directions is None:
        return position, 0.0
    return position, angle_between_rad(np.asarray(R_P)[:, 2], plan.directions[i])


def track_orientation_costs(plan: TrackPlan, cost: float) -> list[float]:
    """P's orientation cost on a tracking step: ``[w, w, 0]`` (roll free), all 0 when the plan
    asks no pointing (position only)."""
    return [0.0, 0.0, 0.0] if plan.directions is None else [cost, cost, 0.0]


def settle(measure: Callable[[], tuple[float, float]], step: Callable[[], float],
           tolerance: float, stall: float, max_steps: int,
           infeasible: type[Exception] | tuple[type[Exception], ...] = ()) -> tuple[int, bool]:
    """Take ``step()`` (one QP; it returns the largest joint change it made [rad, m]) until
    the position error of ``measure()`` is below ``tolerance`` and either the pointing error
    is below ``tolerance`` too or the last step moved no joint by more than ``stall`` (the
    weighted optimum is reached: the scheduled pointing may be slightly out of reach), or
    until the last step moved no joint more than ``stall`` and did not halve the position
    error (stuck: a constraint holds the point off its goal), or ``max_steps`` steps; return
    (steps taken, position error below ``tolerance``), or (0, False) when a step raised
    ``infeasible`` (a QP that a collision constraint makes infeasible)."""
    steps, moved, before = 0, np.inf, np.inf
    while True:
        position, angle = measure()
        stalled = moved <= stall
        if position < tolerance and (angle < tolerance or stalled):
            return steps, True
        if steps >= max_steps or (stalled and position > 0.5 * before):
            return steps, position < tolerance
        try:
            moved, before = float(step()), position
        except infeasible:
            return 0, False
        steps += 1


def posture_weights(robot: Robot) -> np.ndarray:
    """(dof,) per-joint factors of the posture cost so that one pose unit of every joint costs
    the same as a URDF degree (or mm) of a joint mapped 1 : 1 (NICO: a motor degree; its wrist
    and finger motors turn their joints only 0.5 and 0.22 URDF degrees per motor degree, and
    the speed limits are per motor degree)."""
    dof = len(robot.joint_names)
    per_unit = np.abs(robot.to_urdf(np.ones(dof)) - robot.to_urdf(np.zeros(dof)))
    unit = np.where(np.asarray(robot.prismatic, dtype=bool), 1e-3, np.pi / 180.0)
    return unit / per_unit


def solve_clear(i: int, q_warm: np.ndarray, run: Callable[[int, np.ndarray, bool], PointResult],
                penetrating: Callable[[np.ndarray], bool], infeasible: type[Exception],
                entered: list[int]) -> PointResult:
    """A walk's point ``i`` with collision avoidance (``run(i, q_warm, avoiding)``): the
    avoidance cannot lead out of an obstacle, so a warm start that overlaps one (the walk's
    first, the home pose, may) is first solved without it (``i`` goes to ``entered``) and,
    if that pose is clear, solved with it from there; a QP the avoidance makes infeasible
    (``infeasible`` raised) leaves the point unsolved at its warm start."""
    spent = 0
    if penetrating(q_warm):
        q_free, spent, _ = run(i, q_warm, False)
        entered.append(i)
        if not penetrating(q_free):  # else: stay, not deeper inside
            q_warm = q_free
    try:
        q, steps, ok = run(i, q_warm, True)
    except infeasible:  # the avoidance's QP is infeasible here
        q, steps, ok = q_warm, 0, False
    return PointResult(q, spent + steps, ok)


def walk_clear(run: Callable[[int, np.ndarray, bool], PointResult],
               penetrating: Callable[[np.ndarray], bool] | None, infeasible: type[Exception],
               chain: Chain, goals: Goals, **info: object) -> ChainResult:
    """A QP library's walk back from the touch pose, point ``i`` solved by ``run(i, q_warm,
    avoiding)``: without obstacles (``penetrating`` None) plainly, else by
    :func:`solve_clear`; the result's info gets ``info`` and, with obstacles, the count of
    the points whose warm start was inside one (``started_inside_points``)."""
    entered: list[int] = []

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        if penetrating is None:
            return run(i, q_warm, False)
        return solve_clear(i, q_warm, run, penetrating, infeasible, entered)

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, **info,
                                 **({} if penetrating is None else
                                    {"started_inside_points": len(entered)}))


class WarmStart:
    """Where each step of a track starts: the step before moved on by the last segment's
    motion (a constant-speed warm start), kept in the step's :class:`SpeedBox` (whose step it
    sets) and clipped by ``clip`` to the joint limits; not moved on where ``moving_on`` is
    False (with obstacles: avoidance acts on QP steps only, and a warm start moved on without
    it may start inside an obstacle)."""

    def __init__(self, box: SpeedBox | None, clip: Callable[[np.ndarray], np.ndarray],
                 moving_on: bool) -> None:
        self.box, self.clip, self.moving_on = box, clip, moving_on
        self.previous: np.ndarray | None = None

    def __call__(self, i: int, q_warm: np.ndarray) -> np.ndarray:
        """The start (dof,) [rad, m] of step ``i`` from the step before, ``q_warm``."""
        q0 = q_warm
        if self.box is not None:
            self.box.set_step(i, q_warm)
        if self.previous is not None and self.moving_on:
            q0 = q_warm + (q_warm - self.previous)
            q0 = self.clip(self.box.clip(q0) if self.box is not None else q0)
        self.previous = q_warm
        return q0


class SpeedBox:
    """The joint box a tracking step may move in: the speed limit as a QP constraint.

    At step i every joint stays within ``step`` of the previous step's value and within
    ``(n - i) step`` of the touch pose (so the touch pose stays reachable at that speed: the
    arm lands on it without a jump); where the two do not meet (the previous step already
    lies too far) the second wins. :meth:`inequalities` gives the box as ``G dq <= h`` on a
    QP step dq from q, widened where it would ask more than a configuration limit of gain
    ``gain`` lets one QP step do near a joint limit (the two stay compatible).

    Args:
        step: (dof,) the largest change per segment [rad, m] (the contract's times the
            adapter's ``speed_fraction``).
        q_touch: (dof,) the touch pose (row n).
        n: the number of segments.
        lower, upper: (dof,) the joint limits [rad, m].
        gain: the configuration limit's gain.
    """

    @classmethod
    def of(cls, plan: TrackPlan, step: np.ndarray | None, fraction: float,
           lower: npt.ArrayLike, upper: npt.ArrayLike, gain: float) -> SpeedBox | None:
        """The box of a track whose contract allows ``step`` (dof,) per segment [rad, m],
        taken at ``fraction`` of it; None without a step or with ``fraction`` 0."""
        if step is None or fraction <= 0:
            return None
        return cls(fraction * step, plan.q_touch, len(plan) - 1, lower, upper, gain)

    def __init__(self, step: npt.ArrayLike, q_touch: npt.ArrayLike, n: int,
                 lower: npt.ArrayLike, upper: npt.ArrayLike, gain: float) -> None:
        self.step = np.asarray(step, dtype=float)
        self.q_touch = np.asarray(q_touch, dtype=float)
        self.n = int(n)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.gain = float(gain)
        self.lo = self.lower.copy()
        self.hi = self.upper.copy()

    def set_step(self, i: int, q_previous: npt.ArrayLike) -> None:
        """Set the box of step ``i`` after the previous step's pose ``q_previous`` (dof,)."""
        q_previous = np.asarray(q_previous, dtype=float)
        reach = (self.n - i) * self.step
        near_lo, near_hi = self.q_touch - reach, self.q_touch + reach
        lo = np.maximum(q_previous - self.step, near_lo)
        hi = np.minimum(q_previous + self.step, near_hi)
        apart = lo > hi
        land = np.clip(q_previous, near_lo, near_hi)
        self.lo = np.clip(np.where(apart, land, lo), self.lower, self.upper)
        self.hi = np.clip(np.where(apart, land, hi), self.lower, self.upper)

    def clip(self, q: npt.ArrayLike) -> np.ndarray:
        """``q`` (dof,) clipped into the current box."""
        return np.clip(q, self.lo, self.hi)

    def inequalities(self, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(G (k, dof), h (k,)): ``lo - q <= dq <= hi - q`` as ``G dq <= h``, the rows with
        an infinite bound (continuous joints) left out; k = 0 when no row is left."""
        q = np.asarray(q, dtype=float)
        lo = np.minimum(self.lo, q + self.gain * (self.upper - q))
        hi = np.maximum(self.hi, q + self.gain * (self.lower - q))
        eye = np.eye(len(q))
        G, h = np.vstack([eye, -eye]), np.concatenate([hi - q, q - lo])
        finite = np.isfinite(h)
        return G[finite], h[finite]
