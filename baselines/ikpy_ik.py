"""ikpy (PyPI ``ikpy``): sequential IK per goal point, tracked from the start pose onto the
touch pose (``scheme`` track, the default) or walked back from the touch pose (walk, the
paper's own baseline, ``ikpy-walk``).

The paper's authors generated their Table 2 trajectories with ikpy (andylucny/nico2,
``generate-ikpy/generate-ikpy.py``): starting at the touch pose, one
``Chain.inverse_kinematics_frame(target=frame, initial_position=previous)`` per goal point,
where ``frame`` is a 4x4 target whose translation is the goal point and whose z-axis is the
(negated) line direction. They passed no ``orientation_mode``, and ikpy then fits the position
only (``ikpy.inverse_kinematics.inverse_kinematic_optimization`` builds its residual from
``target_frame[:3, 3]`` alone): the rotation in the frame is ignored. ``ikpy-walk`` is exactly
that (scheme walk, orientation position).

Orientation modes (``--ikpy-orientation``):

- ``pointing`` (default of ``ikpy``): ikpy's single-axis mode, ``orientation_mode="X" | "Y" |
  "Z"`` on the end frame's pointing axis (a negative axis gets the negated direction); ikpy
  minimises ``[p - p_goal, c (axis - d)]`` (c: ikpy's ``ORIENTATION_COEFF``), roll free. Only
  coordinate pointing axes are possible;
- ``position`` (default of ``ikpy-walk``): the authors' call, position only (a target rotation
  is still built the way they built it, and ignored by ikpy as it was for them).

Tasks with 6-D goal frames use ``orientation_mode="all"`` (``[p - p_goal, R - R_goal]``).

The track (:mod:`ikbench.schemes.track`): row 0 is the start pose, row n the touch pose;
step i asks for the plan's point and scheduled pointing direction (position only when the task asks
no pointing), from the pose before. ikpy has no posture term; two things make the poses
playable:

- speed bounds: ikpy passes each link's ``bounds`` to ``scipy.optimize.least_squares``, and
  for step i they are narrowed to ``max_speed_use`` of the joints' speed limit per segment
  around the pose before, and to what can still land on the touch pose in the steps left
  (|q_i - q_touch| <= (n - i) max step); a step they keep from its goals ends as close as
  the bounds allow (not solved);
- the orientation weight: ``ORIENTATION_COEFF`` (a module constant of ikpy, 1: a unit-vector
  error weighs like metres) is set to ``orientation_coeff`` during the track's calls, so a
  step its bounds keep from meeting both goals gives up pointing before position.

A point counts as solved only when ``chain.forward_kinematics`` of ikpy's answer is within
``position_tolerance`` of the goal point and, where pointing (or a frame) is asked, within
``pointing_tolerance`` of the goal direction (rotation); ikpy itself reports no success.

The chain: ``ikpy.chain.Chain.from_urdf_file`` on the chain's URDF text with
``base_elements`` = the explicit link / joint path from the base link to the end frame, cut
after the end frame's joint, then rebuilt with ``ikpy.chain.Chain(links, active_links_mask)``
active exactly on the robot's joints, each link's ``bounds`` set to the chain's limits. ikpy
passes the bounds to ``scipy.optimize.least_squares`` (method "trf", strictly feasible
iterates), so every solution is within the limits; a warm start on a limit is first nudged
1e-3 rad inside (``strictly_inside_bounds``). ikpy returns joint values only: no iteration
count (``iterations`` counts ikpy calls) and no success flag (checked by FK, above).
"""

from __future__ import annotations

import io
import warnings
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.methods.base import Capabilities
from ikbench.methods.options import check_choice, check_fraction, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals, chain_of, element_path
from ikbench.schemes.geometry import angle_between_rad, rotation_angle_rad
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.single_pose import PoseOut, PoseSolver
from ikbench.schemes.track import SCHEME_HELP, SCHEMES, speed_box, track
from ikbench.schemes.walk import PointResult, walk_back

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

ORIENTATIONS = ("position", "pointing")
#: The narrowest bounds [rad, m] given to ikpy (scipy's least_squares needs lower < upper).
MIN_WIDTH = 1e-9
_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


ORIENTATION_HELP = ("position (the paper authors' call: a target frame without "
                    "orientation_mode, which fits the position only) or pointing (ikpy's "
                    "orientation_mode on the pointing axis, roll free)")


@dataclass
class IkpySettings:
    """Settings of ikpy's track and walk (see the module docstring).

    Attributes:
        scheme: ``"track"`` (from the start pose onto the touch pose) or ``"walk"`` (back
            from the touch pose, the authors' scheme).
        orientation: ``"pointing"`` (ikpy's axis mode) or ``"position"`` (the authors' call).
        position_tolerance: a point counts as solved when its FK end point is this close to
            the goal point [mm] ...
        pointing_tolerance: ... and, where pointing is asked, its pointing axis this close to
            the goal direction [deg].
    """

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    orientation: str = option("pointing", flag="ikpy-orientation", choices=ORIENTATIONS,
                              help=ORIENTATION_HELP)
    position_tolerance: float = option(0.1, flag="ikpy-position-tolerance", unit="mm",
                                       help="a point counts as solved when FK puts its end "
                                       "point within this of the goal point")
    pointing_tolerance: float = option(0.1, flag="ikpy-pointing-tolerance", unit="deg",
                                       help="... and, where pointing is asked, its pointing "
                                       "axis within this of the goal direction")
    orientation_coeff: float = option(0.02, flag="ikpy-orientation-coeff", unit="m",
                                      help="scheme track: ikpy's weight of the pointing-axis "
                                      "residual against the position residual "
                                      "(ORIENTATION_COEFF, 1 in ikpy): a step its bounds keep "
                                      "from meeting both gives up the pointing first")
    max_speed_use: float = option(0.95, flag="ikpy-max-speed-use", unit="of the limit",
                                  help="scheme track: ikpy's bounds of a step are narrowed to "
                                  "this fraction of the joints' speed limits around the pose "
                                  "before, and to what can still land on the touch pose in "
                                  "time (0: the joint limits only)")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_choice(self, "orientation", ORIENTATIONS)
        check_positive(self, "position_tolerance", "pointing_tolerance", "orientation_coeff")
        check_fraction(self, "max_speed_use")


@dataclass
class IkpyWalkSettings(IkpySettings):
    """:class:`IkpySettings` with the authors' defaults: the walk back from the touch pose,
    position only (``ikpy-walk``)."""

    scheme: str = option("walk", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    orientation: str = option("position", flag="ikpy-orientation", choices=ORIENTATIONS,
                              help=ORIENTATION_HELP)


def authors_rotation(direction: npt.ArrayLike) -> np.ndarray:
    """The target rotation the authors built (their ``rotation_from_z``): z on ``direction``,
    x = up x z with up = +y (+x when z is parallel to +-y). ikpy ignores it in position mode."""
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    up = np.array([0.0, 1.0, 0.0])
    if np.isclose(abs(z @ up), 1.0):
        up = np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def ikpy_chain(chain: Chain) -> tuple[Any, np.ndarray]:
    """The ikpy chain of ``chain`` and the indices of its active links (cached per chain)."""
    if chain in _CHAINS:
        return _CHAINS[chain]
    import ikpy.chain

    path = element_path(chain)
    elements = [chain.base_link]
    for joint, _, child in path:
        elements += [joint, child]
    with warnings.catch_warnings():  # it warns about the fixed links of its default mask
        warnings.simplefilter("ignore")
        full = ikpy.chain.Chain.from_urdf_file(io.StringIO(chain.urdf_text),
                                               base_elements=elements, name=chain.end_frame)
        names = [link.name for link in full.links]
        links = full.links[:names.index(path[-1][0]) + 1]  # nothing below the end frame
        mask = [link.name in chain.joint_names for link in links]
        for link, is_active in zip(links, mask):
            if is_active:
                k = chain.joint_names.index(link.name)
                link.bounds = (float(chain.lower[k]), float(chain.upper[k]))
        ik_chain = ikpy.chain.Chain(links, active_links_mask=mask, name=chain.end_frame)
    active = np.flatnonzero(mask)
    if [links[k].name for k in active] != list(chain.joint_names):
        raise ValueError(f"ikpy's chain {names} does not hold the joints {chain.joint_names}")
    _CHAINS[chain] = (ik_chain, active)
    return _CHAINS[chain]


def axis_mode(chain: Chain) -> tuple[str, float]:
    """ikpy's ``orientation_mode`` for the pointing axis and its sign; InputError if the axis
    is not a coordinate axis of the end frame."""
    k = int(np.argmax(np.abs(chain.pointing_axis)))
    if not np.isclose(abs(chain.pointing_axis[k]), 1.0):
        raise InputError(f"--ikpy-orientation pointing: ikpy points a coordinate axis of the "
                         f"end frame; the robot's pointing axis {tuple(chain.pointing_axis)} "
                         "is none (use --ikpy-orientation position)")
    return "XYZ"[k], float(np.sign(chain.pointing_axis[k]))


@contextmanager
def orientation_coeff(value: float) -> Iterator[None]:
    """ikpy's weight of the orientation residual against the position residual [m]
    (``ikpy.inverse_kinematics.ORIENTATION_COEFF``, 1 in ikpy) set to ``value`` for the
    calls inside, and restored after."""
    import ikpy.inverse_kinematics as ikpy_ik

    before = ikpy_ik.ORIENTATION_COEFF
    ikpy_ik.ORIENTATION_COEFF = float(value)
    try:
        yield
    finally:
        ikpy_ik.ORIENTATION_COEFF = before


def solve_chain(chain: Chain, goals: Goals, settings: IkpySettings,
                max_step: np.ndarray | None = None) -> ChainResult:
    """ikpy in URDF units: the tracking scheme when ``goals.track`` is set, else the walk
    (see the module docstring). ``max_step`` (dof,): the track's largest joint change per
    step [rad, m] (its speed bound), or None."""
    ik_chain, active = ikpy_chain(chain)
    pointing = settings.orientation == "pointing"
    mode, sign = axis_mode(chain) if pointing else (None, 1.0)
    if goals.rotations is not None:
        mode = "all"
    plan = goals.track
    position_tol = settings.position_tolerance / 1000.0
    pointing_tol = np.radians(settings.pointing_tolerance)

    def solve(q_warm: np.ndarray, point, direction, rotation, mode) -> tuple[np.ndarray, bool]:
        """One ikpy call; its solution (dof,) and whether FK puts it within the tolerances
        of what it was asked (position; pointing axis or frame where asked)."""
        frame = np.eye(4)
        frame[:3, 3] = point
        if rotation is not None:
            frame[:3, :3] = rotation
        elif direction is not None:
            frame[:3, :3] = authors_rotation(-direction)  # as the authors built it
            if mode is not None:
                frame[:3, "XYZ".index(mode)] = sign * direction
        start = np.zeros(len(ik_chain.links))
        start[active] = q_warm
        kwargs = {} if mode is None else {"orientation_mode": mode}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = np.asarray(ik_chain.inverse_kinematics_frame(
                target=frame, initial_position=start, **kwargs), dtype=float)
            reached = ik_chain.forward_kinematics(full)
        ok = float(np.linalg.norm(reached[:3, 3] - point)) <= position_tol
        if mode == "all":
            ok = ok and rotation_angle_rad(reached[:3, :3], rotation) <= pointing_tol
        elif mode is not None:
            ok = ok and angle_between_rad(reached[:3, :3] @ chain.pointing_axis,
                                          direction) <= pointing_tol
        return full[active], ok

    def walk_point(i: int, q_warm: np.ndarray) -> PointResult:
        rotation = None if goals.rotations is None else goals.rotations[i]
        q, ok = solve(q_warm, goals.points_m[i], goals.directions[i], rotation, mode)
        return PointResult(q, 1, ok)

    links = [ik_chain.links[k] for k in active]
    bounds = [link.bounds for link in links]
    step = None if plan is None or settings.max_speed_use == 0 else max_step

    def track_point(i: int, q_warm: np.ndarray) -> PointResult:
        direction = None if plan.directions is None else plan.directions[i]
        if step is not None:  # ikpy's bounds: the speed limit and the landing, too
            low, high = speed_box(q_warm, plan.q_touch, len(plan) - 1 - i,
                                  settings.max_speed_use * step, chain.lower, chain.upper)
            low = np.minimum(low, high - MIN_WIDTH)  # least_squares wants low < high
            for link, a, b in zip(links, low, high):
                link.bounds = (float(a), float(b))
        try:
            with orientation_coeff(settings.orientation_coeff):
                q, ok = solve(q_warm, plan.points_m[i], direction, None,
                              mode if direction is not None else None)
        finally:
            for link, bound in zip(links, bounds):
                link.bounds = bound
        return PointResult(q, 1, ok)

    walk = track(track_point, chain, plan) if plan is not None else \
        walk_back(walk_point, chain, goals)
    return ChainResult.from_walk(walk, orientation_mode=mode or "none (position only)",
                                 scheme="track" if plan is not None else "walk",
                                 iterations_are="ikpy calls (ikpy reports no iteration count)")


class IkpyIK(LibraryMethod):
    """ikpy's ``inverse_kinematics_frame`` per point: tracked from the start pose onto the
    touch pose, pointing (scheme track, the default), or walked back (walk)."""

    name = "ikpy"
    description = ("library: ikpy inverse_kinematics_frame per point, tracked from the start "
                   "pose onto the touch pose, pointing axis (orientation_mode) "
                   "(--scheme walk --ikpy-orientation position: the authors' call)")
    library = "ikpy"
    Settings = IkpySettings
    capabilities = Capabilities(needs_touch_pose=True, frames=True)
    #: untimed: parse the URDF and build ikpy's chain (sympy-compiled link matrices)
    chain_model = staticmethod(ikpy_chain)

    def check_robot(self, robot: Robot) -> None:
        """Pointing mode needs a coordinate pointing axis (ikpy's X / Y / Z modes)."""
        if self.settings.orientation == "pointing":
            axis_mode(chain_of(robot))

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings,
                           goals.max_step if goals.track is not None else None)


class IkpyWalk(IkpyIK):
    """The paper authors' ikpy baseline: walked back from the touch pose, position only."""

    name = "ikpy-walk"
    description = ("library: ikpy inverse_kinematics_frame per point, the authors' walk back "
                   "from the touch pose (the start pose is free), position only (their call)")
    Settings = IkpyWalkSettings


class IkpySolver(PoseSolver):
    """Single-pose IK (``ikbench ik``, :mod:`ikbench.schemes.single_pose`):
    ``Chain.inverse_kinematics_frame`` (scipy least squares within the bounds),
    ``orientation_mode="all"`` for poses, None (position only) for points."""

    rank = 100
    name, library, modules = "ikpy", "ikpy", ("ikpy",)
    iterations_are = "ikpy calls (ikpy reports no iteration count)"
    attempt_bound = "scipy least_squares' own limits"
    #: benchmarks/determinism_check.py: the same successes, and answers within 1e-9 rad (not
    #: to the bit: scipy's least squares calls LAPACK), under OpenBLAS' other kernels.
    stable_across_machines = True
    #: A start on a bound is moved this far inside (scipy's trf wants strictly feasible).
    INSIDE = 1e-3

    def prepare(self) -> None:
        self.ik_chain, self.active = ikpy_chain(self.chain)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = rotation, point_m
        start = np.zeros(len(self.ik_chain.links))
        start[self.active] = np.clip(q_init, self.chain.lower + self.INSIDE,
                                     self.chain.upper - self.INSIDE)
        kwargs = {"orientation_mode": "all"} if self.kind == "pose" else {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = np.asarray(self.ik_chain.inverse_kinematics_frame(
                target=frame, initial_position=start, **kwargs), dtype=float)
        return PoseOut(full[self.active], 1, None)

    def bare_call(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray):
        """The bare ``chain.inverse_kinematics_frame(target, initial_position, ...)`` of
        :meth:`solve` (inside its warnings filter), frame and start built in advance (see
        :meth:`PoseSolver.bare_call`)."""
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = rotation, point_m
        start = np.zeros(len(self.ik_chain.links))
        start[self.active] = np.clip(q_init, self.chain.lower + self.INSIDE,
                                     self.chain.upper - self.INSIDE)
        kwargs = {"orientation_mode": "all"} if self.kind == "pose" else {}
        ik = self.ik_chain.inverse_kinematics_frame

        def call():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return ik(target=frame, initial_position=start, **kwargs)
        return call


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="ikpy", requires=("ikpy",),
                  methods=(IkpyIK, IkpyWalk), solvers=(IkpySolver,), rank=50)
