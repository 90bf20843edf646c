"""Time-optimal timing within joint velocity and acceleration limits (TOPP-RA, ``toppra``).

The path is :func:`ikbench.core.timed_path.spline` (a cubic spline through the solved poses over
the fingertip's cumulative chord length s). TOPP-RA (Pham & Pham 2018) finds the fastest
path speed s_dot(s) from rest to rest such that at every grid point

    |q'(s) s_dot| <= v_max   and   |q'(s) s_ddot + q''(s) s_dot^2| <= a_max   (per joint).

The grid holds every solved pose and :data:`GRID_PER_SEGMENT` - 1 points between consecutive
ones; between grid points s_ddot is constant (toppra's ``ParametrizeConstAccel``), so the time
of each grid interval is ``2 ds / (s_dot[k] + s_dot[k+1])``. TOPP-RA checks the limits only at
grid points, so it is given the limits times :data:`LIMIT_MARGIN`, the motion is then checked
at :data:`CHECKS_PER_INTERVAL` points inside every grid interval, and intervals where it
exceeds a stated limit are halved and the path solved again (at most :data:`REFINEMENTS`
times).
"""

from __future__ import annotations

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.timed_path import Limits, TimedPath, path_parameter, spline

#: Grid points per segment between solved poses (the solved poses are grid points).
GRID_PER_SEGMENT = 8
#: Points inside each grid interval where the limits are checked after a solve.
CHECKS_PER_INTERVAL = 4
#: The most rounds of halving the grid intervals where a limit is exceeded.
REFINEMENTS = 6
#: Fraction of the stated limits TOPP-RA is given.
LIMIT_MARGIN = 0.995
INSTALL = "pip install 'ikbench[timing]' (the toppra package)"


def toppra_available() -> bool:
    """Whether the ``toppra`` package can be imported."""
    try:
        import toppra  # noqa: F401
    except ImportError:
        return False
    return True


def topp(poses: np.ndarray, tip_mm: np.ndarray, limits: Limits) -> TimedPath:
    """The time-optimal timing of ``poses`` (n+1, dof) within ``limits``, from rest to rest.

    Raises:
        InputError: toppra is missing, the limits do not match the joints, or TOPP-RA fails.
    """
    try:
        import toppra
        import toppra.algorithm
        import toppra.constraint
    except ImportError:
        raise InputError(f"timing: topp needs toppra, which is not installed: {INSTALL}"
                         ) from None
    dof = poses.shape[1]
    if limits.velocity.shape != (dof,) or limits.acceleration.shape != (dof,):
        raise InputError(f"topp: limits for {len(limits.velocity)} joints, the path has {dof}")
    knots = path_parameter(tip_mm)
    path = spline(knots, poses)
    geometric = toppra.SplineInterpolator(knots, poses, bc_type="not-a-knot")
    _quiet(toppra)
    grid = _grid(knots)
    for refinement in range(REFINEMENTS + 1):
        sd = _solve(toppra, geometric, grid, limits)
        over = _over_limit(path, grid, sd, limits)
        if not over.any() or refinement == REFINEMENTS:  # keep the grid ``sd`` was solved on
            break
        grid = np.sort(np.concatenate([grid, 0.5 * (grid[:-1] + grid[1:])[over]]))
    return _timed(poses, path, grid, np.searchsorted(grid, knots), sd, limits)


def _solve(toppra, geometric, grid: np.ndarray, limits: Limits) -> np.ndarray:
    """TOPP-RA's path speeds s_dot (N,) at the grid points, from rest to rest."""
    constraints = [
        toppra.constraint.JointVelocityConstraint(limits.velocity * LIMIT_MARGIN),
        toppra.constraint.JointAccelerationConstraint(
            limits.acceleration * LIMIT_MARGIN,
            discretization_scheme=toppra.constraint.DiscretizationType.Interpolation),
    ]
    instance = toppra.algorithm.TOPPRA(constraints, geometric, gridpoints=grid,
                                       solver_wrapper="seidel")
    instance.compute_parameterization(0.0, 0.0)
    data = instance.problem_data
    if data.return_code != toppra.algorithm.ParameterizationReturnCode.Ok:
        raise InputError(f"topp: TOPP-RA found no timing for this path ({data.return_code}); "
                         f"check the limits ({limits.source})")
    return np.maximum(np.asarray(data.sd_vec, dtype=float).reshape(-1), 0.0)


def _over_limit(path, grid, sd, limits: Limits) -> np.ndarray:
    """(N-1,) grid intervals inside which a joint exceeds a stated limit."""
    ds = np.diff(grid)
    u = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    fractions = np.arange(1, CHECKS_PER_INTERVAL + 1) / (CHECKS_PER_INTERVAL + 1)
    s = grid[:-1, None] + ds[:, None] * fractions  # (N-1, C)
    x = np.maximum(sd[:-1, None] ** 2 + 2.0 * u[:, None] * (s - grid[:-1, None]), 0.0)
    q1, q2 = path(s, 1), path(s, 2)  # (N-1, C, dof)
    velocity = np.abs(q1) * np.sqrt(x)[..., None] / limits.velocity
    acceleration = np.abs(q1 * u[:, None, None] + q2 * x[..., None]) / limits.acceleration
    return (np.maximum(velocity, acceleration) > 1.0).any(axis=(1, 2))


def _grid(knots: np.ndarray) -> np.ndarray:
    """Every knot and ``GRID_PER_SEGMENT - 1`` evenly spaced points between neighbours."""
    fractions = np.arange(GRID_PER_SEGMENT) / GRID_PER_SEGMENT
    inner = (knots[:-1, None] + np.diff(knots)[:, None] * fractions).reshape(-1)
    return np.append(inner, knots[-1])


def _timed(poses, path, grid, knots, sd, limits: Limits) -> TimedPath:
    """The TimedPath of path speeds ``sd`` (s_dot at the grid points, constant s_ddot
    between them)."""
    ds = np.diff(grid)
    speed_sum = sd[:-1] + sd[1:]
    if np.any(speed_sum <= 0):
        raise InputError("topp: TOPP-RA stopped the path in the middle; check the limits "
                         f"({limits.source})")
    dt = 2.0 * ds / speed_sum
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    u = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)  # s_ddot in each interval
    d1, d2 = path.derivative(1), path.derivative(2)

    def sampler(t):
        k = np.clip(np.searchsorted(t_grid, t, side="right") - 1, 0, len(ds) - 1)
        tau = np.clip(t - t_grid[k], 0.0, dt[k])
        s_dot = np.maximum(sd[k] + u[k] * tau, 0.0)
        s = np.minimum(grid[k] + sd[k] * tau + 0.5 * u[k] * tau ** 2, grid[k + 1])
        q1 = d1(s)
        return path(s), q1 * s_dot[:, None], d2(s) * (s_dot ** 2)[:, None] + q1 * u[k][:, None]

    q1, s_dot = d1(grid[knots]), sd[knots]
    # the acceleration at a knot: of the interval that starts there (the last: that ends there)
    u_knot = u[np.minimum(knots, len(ds) - 1)]
    acceleration = d2(grid[knots]) * (s_dot ** 2)[:, None] + q1 * u_knot[:, None]
    return TimedPath("topp", poses, t_grid[knots], q1 * s_dot[:, None], acceleration, limits,
                     sampler)


def _quiet(toppra) -> None:
    """toppra logs every solve at INFO and failures at WARNING; ikbench reports its own."""
    import logging

    logging.getLogger("toppra").setLevel(logging.ERROR)
