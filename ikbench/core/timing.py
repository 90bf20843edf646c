"""Timing along a path: when each solved pose is reached (``--timing constant|min-jerk|topp``).

A trajectory is a path (the solved poses, (n+1, dof) in pose units: motor degrees for NICO)
plus a timing. Retiming never changes the poses, only the time each is reached:

- ``constant`` (the paper's): n segments of T/n each, a constant joint speed inside each
  segment (linear interpolation between poses). The fingertip starts and stops abruptly.
- ``min-jerk``: the fingertip's arc length along the path follows the minimum-jerk profile
  ``L * (10 tau^3 - 15 tau^4 + 6 tau^5)``, tau = t/T (Flash & Hogan 1985): a bell-shaped
  fingertip speed, zero at both ends (L: the fingertip's arc length along the motion).
- ``topp``: the time-optimal timing within per-joint velocity and acceleration limits
  (TOPP-RA, the ``toppra`` package; :mod:`ikbench.core.timing_topp`), from rest to rest.

Between the solved poses ``min-jerk`` and ``topp`` move along a cubic spline (not-a-knot)
through the poses, parametrised by the fingertip's cumulative chord length
(:func:`path_parameter`): it passes through every solved pose, and is twice differentiable
so that velocities and accelerations exist. :func:`fingertip_deviation_mm` measures how far
the fingertip on it strays from the solved path (the polyline through the solved fingertip
points).

Example::

    timed = retime(robot, poses_motor_deg, "min-jerk", duration_s=2.0)
    timed.times_s            # (n+1,) when each pose is reached [s]
    q, qd, qdd = timed.sample(np.linspace(0, timed.duration_s, 500))
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.core.robot import unwrap_continuous
from ikbench.core.timed_path import (  # noqa: F401  (re-exported: the timing API)
    INTERPOLATION,
    MIN_PARAMETER_FRACTION,
    Limits,
    Sampler,
    TimedPath,
    path_parameter,
    spline,
)
from ikbench.core.timing_topp import topp

if TYPE_CHECKING:

    from ikbench.core.robot import Robot

#: ``--timing`` values -> what they do.
TIMINGS = {
    "constant": "n segments of T/n, constant joint speed in each (the paper's; default)",
    "min-jerk": "fingertip arc length on the minimum-jerk profile over T (bell-shaped speed)",
    "topp": "time-optimal within the joints' velocity and acceleration limits (TOPP-RA)",
}
DEFAULT_TIMING = "constant"
#: Points per segment at which min-jerk measures the fingertip's arc length along the spline.
ARC_SAMPLES = 16
def check_timing(name: str) -> str:
    """``name`` if it is a timing of :data:`TIMINGS`, else InputError naming the allowed ones."""
    if name not in TIMINGS:
        raise InputError(f"timing: {name!r}; allowed: {', '.join(TIMINGS)}")
    return name


def retime(robot: Robot, poses: npt.ArrayLike, timing: str, *,
           duration_s: float = DEFAULT_DURATION_S, limits: Limits | None = None,
           tip_mm: npt.ArrayLike | None = None) -> TimedPath:
    """Time a path.

    Args:
        robot: the robot (FK for the fingertip's arc length).
        poses: (n+1, dof) solved poses [pose units].
        timing: one of :data:`TIMINGS`.
        duration_s: T [s] for ``constant`` and ``min-jerk`` (``topp`` finds its own).
        limits: joint limits for ``topp`` (required there).
        tip_mm: (n+1, 3) fingertip points [mm] of ``poses`` (default: FK).

    Raises:
        InputError: a bad timing, duration or path; ``topp`` without limits or toppra.
    """
    check_timing(timing)
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or len(poses) < 2 or not np.all(np.isfinite(poses)):
        raise InputError(f"a timing needs (n+1, dof) finite poses with n >= 1, got an array of "
                         f"shape {poses.shape}")
    poses = unwrap_continuous(robot, poses)  # a continuous joint never turns the long way
    if timing != "topp" and not (np.isfinite(duration_s) and duration_s > 0):
        raise InputError(f"duration_s: {duration_s!r}; give a positive number of seconds")
    if timing == "constant":
        return constant(poses, duration_s)
    tip = np.asarray(robot.fk(poses).point_mm if tip_mm is None else tip_mm, dtype=float)
    if timing == "min-jerk":
        return min_jerk(poses, tip, duration_s, robot)
    if limits is None:
        raise InputError("timing: topp needs joint velocity and acceleration limits")
    return topp(poses, tip, limits)


def constant(poses: np.ndarray, duration_s: float) -> TimedPath:
    """The paper's timing: pose i at ``i * T/n``, linear in the joints in between."""
    n = len(poses) - 1
    dt_s = duration_s / n
    times = np.arange(n + 1) * dt_s
    speeds = np.diff(poses, axis=0) / dt_s  # (n, dof)
    velocity = np.zeros_like(poses)
    velocity[1:-1] = (poses[2:] - poses[:-2]) / (2.0 * dt_s)

    def sampler(t):
        k = np.clip(np.floor(t / dt_s).astype(int), 0, n - 1)
        q = poses[k] + speeds[k] * (t - k * dt_s)[:, None]
        return q, speeds[k], np.zeros_like(q)

    return TimedPath("constant", poses, times, velocity, None, None, sampler)


# ----- minimum jerk ----------------------------------------------------------------------------
def min_jerk_profile(tau: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk progress u(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 and its first two
    derivatives in tau, for tau in [0, 1]."""
    tau = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    u = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)
    du = 30.0 * tau ** 2 * (1.0 - tau) ** 2
    ddu = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)
    return u, du, ddu


def min_jerk_inverse(u: npt.ArrayLike) -> np.ndarray:
    """tau in [0, 1] with ``min_jerk_profile(tau)[0] == u`` (bisection to 1e-15)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    low, high = np.zeros_like(u), np.ones_like(u)
    for _ in range(55):
        mid = 0.5 * (low + high)
        below = min_jerk_profile(mid)[0] < u
        low, high = np.where(below, mid, low), np.where(below, high, mid)
    return 0.5 * (low + high)


def min_jerk(poses: np.ndarray, tip_mm: np.ndarray, duration_s: float, robot: Robot
             ) -> TimedPath:
    """The fingertip's arc length along the motion on the minimum-jerk profile over
    ``duration_s``; the joints along :func:`spline`.

    The arc length is that of the fingertip on the spline (FK at :data:`ARC_SAMPLES` points per
    segment), so the fingertip speed is the analytic bell ``L/T * 30 tau^2 (1 - tau)^2``; the
    spline parameter for an arc length is interpolated monotonically (PCHIP) between them.
    """
    from scipy.interpolate import PchipInterpolator

    chord = np.linalg.norm(np.diff(tip_mm, axis=0), axis=1)
    if not chord.sum() > 1e-9:
        raise InputError("timing: min-jerk times the fingertip's path, and the fingertip does "
                         "not move along this trajectory; use constant or topp timing")
    knots = path_parameter(tip_mm)
    path = spline(knots, poses)
    d1, d2 = path.derivative(1), path.derivative(2)
    fractions = np.arange(ARC_SAMPLES) / ARC_SAMPLES
    sigma = np.append((knots[:-1, None] + np.diff(knots)[:, None] * fractions).reshape(-1),
                      knots[-1])
    points = np.asarray(robot.fk(path(sigma)).point_mm, dtype=float)
    arc_mm = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    arc_mm += 1e-9 * sigma  # strictly increasing where the fingertip rests
    length_mm = float(arc_mm[-1])
    law = PchipInterpolator(arc_mm, sigma)  # spline parameter of an arc length
    law1, law2 = law.derivative(1), law.derivative(2)
    times = duration_s * min_jerk_inverse(arc_mm[::ARC_SAMPLES] / length_mm)
    times[0], times[-1] = 0.0, duration_s

    def sampler(t):
        u, du, ddu = min_jerk_profile(t / duration_s)
        a, ad, add = (length_mm * u, length_mm * du / duration_s,
                      length_mm * ddu / duration_s ** 2)  # arc length [mm] and its rates
        a = np.clip(a, 0.0, length_mm)
        s = law(a)
        sd, sdd = law1(a) * ad, law2(a) * ad ** 2 + law1(a) * add
        q1 = d1(s)
        return path(s), q1 * sd[:, None], d2(s) * (sd ** 2)[:, None] + q1 * sdd[:, None]

    q, qd, qdd = sampler(times)
    qd[[0, -1]] = 0.0
    return TimedPath("min-jerk", poses, times, qd, qdd, None, sampler)


# ----- measures --------------------------------------------------------------------------------
def finite_differences(times_s: npt.ArrayLike, poses: npt.ArrayLike
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Velocities (n, dof) and accelerations (n+1, dof) of samples by finite differences.

    Velocity of segment k: ``(q[k+1] - q[k]) / (t[k+1] - t[k])``. Acceleration at sample k:
    ``(v[k] - v[k-1]) / ((dt[k-1] + dt[k]) / 2)``, with the arm at rest before the first and
    after the last sample (``v[-1] = v[n] = 0`` over half a segment), since every timing starts
    and ends at rest. For a motion whose acceleration stays within a limit these stay within
    it too (a divided difference is a weighted mean of the acceleration).
    """
    t, q = np.asarray(times_s, dtype=float), np.asarray(poses, dtype=float)
    dt = np.diff(t)
    v = np.diff(q, axis=0) / dt[:, None]
    padded = np.vstack([np.zeros_like(v[:1]), v, np.zeros_like(v[:1])])
    half = np.concatenate([[dt[0]], dt[:-1] + dt[1:], [dt[-1]]]) / 2.0
    return v, np.diff(padded, axis=0) / half[:, None]


def limit_use(times_s: npt.ArrayLike, poses: npt.ArrayLike, limits: Limits
              ) -> tuple[np.ndarray, np.ndarray]:
    """(dof,) peak |velocity| / limit and (dof,) peak |acceleration| / limit of samples, by
    :func:`finite_differences` (1.0: at the limit)."""
    v, a = finite_differences(times_s, poses)
    return (np.abs(v).max(axis=0) / limits.velocity,
            np.abs(a).max(axis=0) / limits.acceleration)


def constant_duration_within(poses: npt.ArrayLike, limits: Limits) -> float:
    """The shortest T [s] whose ``constant`` timing keeps :func:`finite_differences` within
    ``limits`` (the fair comparison for ``topp``: the same limits, the same measure)."""
    q = np.asarray(poses, dtype=float)
    n, step = len(q) - 1, np.abs(np.diff(q, axis=0))
    # v = step n/T; a = |second difference| n^2/T^2 inside, 2 step n^2/T^2 at both ends
    second = np.vstack([2 * step[:1], np.abs(np.diff(q, 2, axis=0)), 2 * step[-1:]])
    by_speed = n * (step / limits.velocity).max()
    by_acceleration = n * np.sqrt((second / limits.acceleration).max())
    return float(max(by_speed, by_acceleration))


def fingertip_deviation_mm(robot: Robot, samples: npt.ArrayLike, solved_tip_mm: np.ndarray
                           ) -> float:
    """Largest distance [mm] of the fingertip at ``samples`` (m, dof) [pose units] from the
    solved path: the polyline through ``solved_tip_mm`` (n+1, 3)."""
    points = np.asarray(robot.fk(np.asarray(samples, dtype=float)).point_mm, dtype=float)
    a, b = np.asarray(solved_tip_mm[:-1], float), np.asarray(solved_tip_mm[1:], float)
    ab = b - a  # (n, 3)
    worst = 0.0
    for start in range(0, len(points), 512):  # (chunk, n) distances to every segment
        p = points[start:start + 512, None, :]
        denominator = np.maximum((ab ** 2).sum(-1), 1e-300)
        u = np.clip(((p - a) * ab).sum(-1) / denominator, 0.0, 1.0)
        distance = np.linalg.norm(p - (a + u[..., None] * ab), axis=-1).min(axis=1)
        worst = max(worst, float(distance.max()))
    return worst
