"""Legibility, predictability and smoothness of a fingertip motion over a goal set.

The observer model is Dragan, Lee and Srinivasa, "Legibility and Predictability of Robot
Motion", HRI 2013. An observer who sees the motion so far, from the start S to the current
fingertip point Q, infers the goal G of a set of goals::

    P(G | xi_S->Q) = exp(-C(xi_S->Q) - V_G(Q)) / exp(-V_G(S)) * P(G) / Z

with a uniform prior P(G) = 1/K over the K goals. C is Dragan's sum of squared velocities,
in the motion's normalised time tau = t/T: ``C[xi] = integral_0^1 |dxi/dtau|^2 dtau / s^2``,
discretised on the trajectory's times as ``sum_j |P_j+1 - P_j|^2 / (tau_j+1 - tau_j) / s^2``
(n equal steps: n times Dragan's sum of squared steps), with s a length scale (the observer's
rationality; default the smallest distance between two goals of the set). Its optimum from Q,
reached at tau, to G in the time left is the straight line at constant speed, so::

    V_G(Q, tau) = |G - Q|^2 / ((1 - tau) s^2),      V_G(S) = |G - S|^2 / s^2

(with equal steps, Dragan's ``|G - Q_i|^2 / (n - i)`` for the i-th of n steps, times n).
C(xi_S->Q) is the same for every goal and cancels in Z, so::

    log P(G | xi_S->Q) = (|G - S|^2 - |G - Q|^2 / (1 - tau)) / s^2 + log P(G) - log Z

At the end (tau = 1) the goal the motion reached (within :data:`NEAR_GOAL_MM`) takes all the
probability; a goal the straight line at constant speed heads to keeps P(G) >= its prior's
share, since C + V_G(Q) >= V_G(S) for every other goal. The *pointing* observer
reads the forefinger's ray instead: with theta_G the angle between the pointing axis and the
direction from the fingertip to G, ``P(G | ray) ∝ exp(-theta_G^2 / (2 sigma^2)) P(G)``,
sigma = :data:`POINTING_SIGMA_DEG` (theta_G = 0 within :data:`NEAR_GOAL_MM` of G).

The legibility of either observer is Dragan's weighted integral with f(t) = T - t::

    legibility = integral_0^T P(G* | t) f(t) dt / integral_0^T f(t) dt

(G* the true goal; trapezoid rule on the trajectory's times). Predictability is
``exp(-(C(xi) - C(xi*)))`` with C in units of the straight line's cost: ``C(xi) =
sum_i |P_i+1 - P_i|^2 / dtau_i / |P_n - P_0|^2``, dtau_i = (t_i+1 - t_i)/T, so the straight
line at constant speed, C(xi*) = 1, gives 1 and any other path less (Cauchy-Schwarz).
Smoothness: the fingertip's dimensionless jerk ``(T^5 / L^2) integral |x'''(t)|^2 dt``
(L the fingertip's arc length; 720 for a minimum-jerk straight line) and the peak joint jerk
[pose units / s^3], by finite differences (``numpy.gradient``: second order inside, one-sided
at the ends; no rest assumed outside [0, T]) on the times given.

Times: the functions take the trajectory's times ``times_s`` (n+1,); a study's trajectory CSVs
are timed ``constant`` (n segments of T/n, :func:`constant_times_s`). Lengths in mm, angles in
degrees, times in s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.targets import Targets

#: The pointing observer's angular spread sigma [deg] (about a goal's angular spacing seen
#: from NICO's start point; a setting, not a measurement).
POINTING_SIGMA_DEG = 10.0
#: Within this distance [mm] of a goal the ray points at it (its direction is undefined there).
NEAR_GOAL_MM = 1.0
#: P(true goal) above this is "inferred" (the times of first settled inference).
THRESHOLD = 0.5
#: The columns :func:`legibility_metrics` returns, in order.
LEGIBILITY_COLUMNS = ["position_legibility", "position_inferred_s", "position_final_p",
                      "pointing_legibility", "pointing_inferred_s", "pointing_final_p",
                      "predictability", "dimensionless_jerk", "peak_joint_jerk_deg_s3",
                      "position_legibility_unscaled"]


def constant_times_s(points: int, duration_s: float) -> np.ndarray:
    """(points,) times [s] of n = points - 1 segments of T/n each (the ``constant`` timing)."""
    return np.linspace(0.0, float(duration_s), int(points))


def length_scale_mm(goals_mm: npt.ArrayLike) -> float:
    """The default s [mm]: the smallest distance between two goals (1 mm for one goal)."""
    goals = np.asarray(goals_mm, dtype=float).reshape(-1, 3)
    if len(goals) < 2:
        return 1.0
    gaps = np.linalg.norm(goals[:, None] - goals[None], axis=-1)
    gaps = gaps[~np.eye(len(goals), dtype=bool)]
    smallest = float(gaps.min())
    return smallest if smallest > 0 else 1.0


def _normalise(logits: np.ndarray, prior: npt.ArrayLike | None) -> np.ndarray:
    k = logits.shape[1]
    log_prior = np.log(np.full(k, 1.0 / k) if prior is None
                       else np.asarray(prior, dtype=float) / np.sum(prior))
    z = logits + log_prior
    z = z - z.max(axis=1, keepdims=True)
    p = np.exp(z)
    return p / p.sum(axis=1, keepdims=True)


def position_probabilities(points_mm: npt.ArrayLike, goals_mm: npt.ArrayLike,
                           times_s: npt.ArrayLike, scale_mm: float | None = None,
                           prior: npt.ArrayLike | None = None,
                           time_scaled: bool = True) -> np.ndarray:
    """P(G | xi_S->P_i) (n+1, K) of the position observer for fingertip points (n+1, 3) [mm]
    reached at times (n+1,) [s] and goals (K, 3) [mm]; ``scale_mm`` s (default
    :func:`length_scale_mm`), ``prior`` (K,) (default uniform). ``time_scaled=False`` drops
    the modelling choice of dividing V_G(Q) by the time left (1 - tau): V_G(Q) = |G - Q|^2 /
    s^2, the observer reading distance alone (the ``position_legibility_unscaled`` column)."""
    points = np.asarray(points_mm, dtype=float)
    goals = np.asarray(goals_mm, dtype=float).reshape(-1, 3)
    t = np.asarray(times_s, dtype=float)
    s = length_scale_mm(goals) if scale_mm is None else float(scale_mm)
    left = (t[-1] - t) / (t[-1] - t[0])  # (n+1,) 1 - tau, the time left
    if not time_scaled:
        left = np.ones_like(left)  # V_G(Q) unscaled: no point is "out of time"
    v_start = np.sum((goals - points[0]) ** 2, axis=1)  # (K,) s^2 V_G(S)
    gap = np.sum((goals[None] - points[:, None]) ** 2, axis=2)  # (n+1, K) |G - Q|^2
    with np.errstate(divide="ignore", invalid="ignore"):
        v_here = gap / left[:, None]
    # no time left: the goal reached costs nothing more, the others cannot be reached
    done = left <= 0.0
    v_here[done] = np.where(gap[done] <= NEAR_GOAL_MM ** 2, 0.0, np.inf)
    logits = (v_start[None] - v_here) / s ** 2
    if np.any(np.all(np.isinf(logits), axis=1)):  # the end reaches no goal: the last finite
        last = np.flatnonzero(np.any(np.isfinite(logits), axis=1))[-1]
        logits[np.all(np.isinf(logits), axis=1)] = logits[last]
    return _normalise(logits, prior)


def pointing_angles_deg(points_mm: npt.ArrayLike, directions: npt.ArrayLike,
                        goals_mm: npt.ArrayLike) -> np.ndarray:
    """(n+1, K) angle [deg] between each pointing axis (n+1, 3) and the direction from its
    fingertip point (n+1, 3) [mm] to each goal (K, 3); 0 within :data:`NEAR_GOAL_MM`."""
    points = np.asarray(points_mm, dtype=float)
    d = np.asarray(directions, dtype=float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    to_goal = np.asarray(goals_mm, dtype=float).reshape(-1, 3)[None] - points[:, None]
    cross = np.linalg.norm(np.cross(d[:, None], to_goal), axis=2)
    dot = np.sum(d[:, None] * to_goal, axis=2)
    angles = np.degrees(np.arctan2(cross, dot))
    return np.where(np.linalg.norm(to_goal, axis=2) < NEAR_GOAL_MM, 0.0, angles)


def pointing_probabilities(points_mm: npt.ArrayLike, directions: npt.ArrayLike,
                           goals_mm: npt.ArrayLike, sigma_deg: float = POINTING_SIGMA_DEG,
                           prior: npt.ArrayLike | None = None) -> np.ndarray:
    """P(G | ray_i) (n+1, K) of the pointing observer: exp(-theta^2 / (2 sigma^2)) P(G)."""
    theta = pointing_angles_deg(points_mm, directions, goals_mm)
    return _normalise(-theta ** 2 / (2.0 * float(sigma_deg) ** 2), prior)


def weighted_legibility(p_true: npt.ArrayLike, times_s: npt.ArrayLike) -> float:
    """Dragan's integral of P(G* | t) (n+1,) with f(t) = T - t over the times (n+1,) [s],
    over the integral of f (trapezoid rule on both)."""
    p = np.asarray(p_true, dtype=float)
    t = np.asarray(times_s, dtype=float)
    f = t[-1] - t
    return float(_trapezoid(p * f, t) / _trapezoid(f, t))


def inferred_time_s(p_true: npt.ArrayLike, times_s: npt.ArrayLike,
                    threshold: float = THRESHOLD) -> float:
    """The first time [s] from which P(G*) stays above ``threshold`` to the end; NaN if the
    last value is not above it."""
    above = np.asarray(p_true, dtype=float) > threshold
    if not above[-1]:
        return float("nan")
    below = np.flatnonzero(~above)
    first = 0 if below.size == 0 else int(below[-1]) + 1
    return float(np.asarray(times_s, dtype=float)[first])


def path_cost(points_mm: npt.ArrayLike, times_s: npt.ArrayLike) -> float:
    """C(xi) = sum |dP_i|^2 / dtau_i over |P_n - P_0|^2 (1 for a straight line at constant
    speed; inf when the motion ends where it starts but moves)."""
    points = np.asarray(points_mm, dtype=float)
    t = np.asarray(times_s, dtype=float)
    dtau = np.diff(t) / (t[-1] - t[0])
    energy = float(np.sum(np.sum(np.diff(points, axis=0) ** 2, axis=1) / dtau))
    chord = float(np.sum((points[-1] - points[0]) ** 2))
    if chord == 0.0:
        return 1.0 if energy == 0.0 else float("inf")
    return energy / chord


def predictability(points_mm: npt.ArrayLike, times_s: npt.ArrayLike) -> float:
    """exp(-(C(xi) - C(xi*))) with C(xi*) = 1 (:func:`path_cost`): 1 = perfectly predictable."""
    return float(np.exp(-(path_cost(points_mm, times_s) - 1.0)))


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    """The trapezoid rule (numpy 1.26 has no ``numpy.trapezoid``)."""
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2.0)


def _third_derivative(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = values
    for _ in range(3):
        out = np.gradient(out, t, axis=0)
    return out


def dimensionless_jerk(points_mm: npt.ArrayLike, times_s: npt.ArrayLike) -> float:
    """(T^5 / L^2) integral |x'''|^2 dt of the fingertip points (n+1, 3) [mm] (L: arc
    length); NaN for fewer than 4 points or no motion."""
    points = np.asarray(points_mm, dtype=float)
    t = np.asarray(times_s, dtype=float)
    length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    if len(points) < 4 or length == 0.0:
        return float("nan")
    jerk = _third_derivative(points, t)
    duration = t[-1] - t[0]
    return float(duration ** 5 / length ** 2 * _trapezoid(np.sum(jerk ** 2, axis=1), t))


def peak_joint_jerk(poses: npt.ArrayLike, times_s: npt.ArrayLike) -> float:
    """The largest |q'''| [pose units / s^3] over the poses (n+1, dof) and joints."""
    poses = np.asarray(poses, dtype=float)
    if len(poses) < 4:
        return float("nan")
    return float(np.abs(_third_derivative(poses, np.asarray(times_s, dtype=float))).max())


def position_legibility(points_mm: npt.ArrayLike, goals_mm: npt.ArrayLike, true_goal: int,
                        times_s: npt.ArrayLike, scale_mm: float | None = None,
                        time_scaled: bool = True) -> float:
    """Dragan's legibility of the fingertip path for goal ``true_goal`` (an index of goals);
    ``time_scaled``: :func:`position_probabilities`'."""
    p = position_probabilities(points_mm, goals_mm, times_s, scale_mm,
                               time_scaled=time_scaled)[:, true_goal]
    return weighted_legibility(p, times_s)


def pointing_legibility(points_mm: npt.ArrayLike, directions: npt.ArrayLike,
                        goals_mm: npt.ArrayLike, true_goal: int, times_s: npt.ArrayLike,
                        sigma_deg: float = POINTING_SIGMA_DEG) -> float:
    """The pointing observer's legibility for goal ``true_goal`` (an index of goals)."""
    p = pointing_probabilities(points_mm, directions, goals_mm, sigma_deg)[:, true_goal]
    return weighted_legibility(p, times_s)


def legibility_metrics(points_mm: npt.ArrayLike, directions: npt.ArrayLike,
                       poses: npt.ArrayLike, goals_mm: npt.ArrayLike, true_goal: int,
                       times_s: npt.ArrayLike) -> dict[str, float]:
    """The :data:`LEGIBILITY_COLUMNS` of one motion: fingertip points (n+1, 3) [mm], pointing
    axes (n+1, 3), poses (n+1, dof), goals (K, 3) [mm], the true goal's index, times (n+1,)
    [s]. ``*_inferred_s``: :func:`inferred_time_s`; ``*_final_p``: P(G*) at the end;
    ``position_legibility_unscaled``: the position observer without the time-left scaling of
    V_G (``time_scaled=False``), to show how much a verdict rests on that choice."""
    position = position_probabilities(points_mm, goals_mm, times_s)[:, true_goal]
    pointing = pointing_probabilities(points_mm, directions, goals_mm)[:, true_goal]
    return {"position_legibility": weighted_legibility(position, times_s),
            "position_inferred_s": inferred_time_s(position, times_s),
            "position_final_p": float(position[-1]),
            "pointing_legibility": weighted_legibility(pointing, times_s),
            "pointing_inferred_s": inferred_time_s(pointing, times_s),
            "pointing_final_p": float(pointing[-1]),
            "predictability": predictability(points_mm, times_s),
            "dimensionless_jerk": dimensionless_jerk(points_mm, times_s),
            "peak_joint_jerk_deg_s3": peak_joint_jerk(poses, times_s),
            "position_legibility_unscaled": weighted_legibility(
                position_probabilities(points_mm, goals_mm, times_s,
                                       time_scaled=False)[:, true_goal], times_s)}


def goal_points_mm(robot: Robot, targets: Targets) -> tuple[list[str], np.ndarray]:
    """A goal set: the targets' ids and their touch poses' fingertip points (K, 3) [mm]
    (FK of the touch poses; NICO's default targets give the seven touch points)."""
    ids = targets.ids
    poses = np.stack([targets.touch_poses[i] for i in ids])
    return ids, robot.fk(poses).point_mm


def true_goal_index(goals_mm: np.ndarray, end_point_mm: npt.ArrayLike
                    ) -> tuple[np.ndarray, int]:
    """(goals, index of the true goal): the goal nearest the task's end point when within
    :data:`NEAR_GOAL_MM`, else the goals with the end point appended as the true goal."""
    end = np.asarray(end_point_mm, dtype=float)
    goals = np.asarray(goals_mm, dtype=float).reshape(-1, 3)
    gaps = np.linalg.norm(goals - end, axis=1)
    if gaps.size and gaps.min() <= NEAR_GOAL_MM:
        return goals, int(np.argmin(gaps))
    return np.vstack([goals, end]), len(goals)


# ----- ikbench's extension (not the paper's method): a legibility term to optimise ----------

def legibility_term_weights(points: int, weight: float) -> np.ndarray:
    """(n+1,) w_i = W f_i / sum_j f_j with Dragan's f_i = 1 - tau_i = 1 - i/n (the
    ``constant`` timing): the weights of :func:`legibility_term` (early poses weigh most)."""
    f = 1.0 - np.linspace(0.0, 1.0, int(points))
    return float(weight) * f / f.sum()


def legibility_term(p_true: npt.ArrayLike, weight: float) -> float:
    """ikbench's legibility term (ours-exact's ``--exact-legibility-weight``; not the paper's
    method): ``W sum_i f_i (1 - P_i(G*))^2 / sum_i f_i`` over the n+1 poses of a motion with
    the ``constant`` timing, f_i = 1 - i/n, P_i(G*) the pointing observer's probability of the
    true goal at pose i (:func:`pointing_probabilities`). 0 when the finger points at the true
    goal alone all along; at most W."""
    p = np.asarray(p_true, dtype=float)
    return float(np.sum(legibility_term_weights(len(p), weight) * (1.0 - p) ** 2))
