"""A path and its timing: the types every timing returns, and the spline between poses.

:class:`TimedPath` (the solved poses, the time each is reached, velocities, accelerations, a
sampler between poses) and :class:`Limits` (per-joint velocity and acceleration limits), with
the path parameter and spline that ``min-jerk`` and ``topp`` share (:mod:`ikbench.core.timing`,
:mod:`ikbench.core.timing_topp`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

#: Words for the interpolation between solved poses of each timing.
INTERPOLATION = {
    "constant": "linear in the joints between solved poses",
    "min-jerk": "cubic spline (not-a-knot) through the solved poses, parametrised by the "
                "fingertip's cumulative chord length",
    "topp": "cubic spline (not-a-knot) through the solved poses, parametrised by the "
            "fingertip's cumulative chord length",
}
#: A segment's path parameter is at least this fraction of the mean segment's (a segment where
#: the fingertip does not move but the joints do still takes time).
MIN_PARAMETER_FRACTION = 1e-3
#: Below this mean fingertip movement per segment [mm] the fingertip counts as still (a path
#: that turns the hand about the fingertip: its chords are the solver's jitter, and a spline
#: on them overshoots by metres), and the spline is parametrised by the pose index.
STILL_TIP_MM = 0.01

#: t [s] (m,) -> (q, qd, qdd), each (m, dof).
Sampler = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Limits:
    """Per-joint limits a timing respects.

    Attributes:
        velocity: (dof,) speed limits [pose units/s] (motor deg/s for NICO).
        acceleration: (dof,) acceleration limits [pose units/s^2].
        source: where they come from, in words.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    source: str

    def __post_init__(self):
        for name in ("velocity", "acceleration"):
            values = np.asarray(getattr(self, name), dtype=float)
            if values.ndim != 1 or not (np.all(np.isfinite(values)) and np.all(values > 0)):
                raise InputError(f"{name} limits must be positive finite numbers, got "
                                 f"{values.tolist()} ({self.source})")
            object.__setattr__(self, name, values)


@dataclass(frozen=True)
class TimedPath:
    """A path and its timing.

    Attributes:
        timing: one of :data:`TIMINGS`.
        poses: (n+1, dof) the solved poses [pose units], unchanged.
        times_s: (n+1,) the time each pose is reached [s], from 0.
        velocity: (n+1, dof) joint velocities at the poses [pose units/s] (``constant``:
            central differences, zero at both ends, as the ROS export gives them).
        acceleration: (n+1, dof) joint accelerations at the poses [pose units/s^2], or None
            (``constant``: the speed jumps at every pose).
        limits: the limits ``topp`` respected (None for the other timings).
        sampler: t [s] (m,) -> (q (m, dof), qd (m, dof), qdd (m, dof)) between the poses.
    """

    timing: str
    poses: np.ndarray
    times_s: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray | None
    limits: Limits | None
    sampler: Sampler

    @property
    def duration_s(self) -> float:
        """Time of the last pose [s]."""
        return float(self.times_s[-1])

    @property
    def segment_s(self) -> np.ndarray:
        """(n,) duration of each segment [s]."""
        return np.diff(self.times_s)

    @property
    def interpolation(self) -> str:
        """How the motion runs between solved poses, in words."""
        return INTERPOLATION[self.timing]

    def sample(self, times_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd), each (m, dof), at times ``times_s`` (m,) [s], clipped to [0, T]."""
        t = np.clip(np.asarray(times_s, dtype=float), 0.0, self.duration_s)
        return self.sampler(t)

    def index_at(self, t_s: float) -> int:
        """The solved pose nearest in time to ``t_s`` [s] (the last after the end)."""
        k = int(np.searchsorted(self.times_s, t_s))
        if k <= 0:
            return 0
        if k >= len(self.times_s):
            return len(self.times_s) - 1
        return k if self.times_s[k] - t_s < t_s - self.times_s[k - 1] else k - 1


# ----- the path between solved poses ---------------------------------------------------------
def path_parameter(tip_mm: np.ndarray) -> np.ndarray:
    """(n+1,) strictly increasing knots of the spline: the fingertip's cumulative chord length,
    each segment at least :data:`MIN_PARAMETER_FRACTION` of the mean, in units of the mean
    segment (0 ... n: TOPP-RA's solver fails on some paths in mm); the pose index when the
    fingertip stays still (mean segment below :data:`STILL_TIP_MM`)."""
    chord = np.linalg.norm(np.diff(tip_mm, axis=0), axis=1)
    if not chord.mean() >= STILL_TIP_MM:
        chord = np.ones_like(chord)
    chord = np.maximum(chord, MIN_PARAMETER_FRACTION * chord.mean())
    return np.concatenate([[0.0], np.cumsum(chord / chord.mean())])


def spline(knots: np.ndarray, poses: np.ndarray) -> CubicSpline:
    """The cubic spline (not-a-knot) through ``poses`` at ``knots`` (scipy CubicSpline)."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(knots, poses, bc_type="not-a-knot", axis=0)
