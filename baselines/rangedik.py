"""RangedIK (PyPI ``relaxed-ik-core``, module ``relaxed_ik_lib``): the real-time motion
synthesis of RelaxedIK / RangedIK (Rakita et al.; Wang et al., ICRA 2023), tracked from the
start pose onto the touch pose (``scheme`` track, the default) or walked back from the touch
pose (walk, :mod:`ikbench.schemes.walk`).

The wheel (relaxed-ik-core 0.1.4, Rust) holds two interfaces in one shared library:

- the Python class ``relaxed_ik_lib.RelaxedIK(settings_path)`` with ``solve(position_m,
  quaternion_wxyz) -> (q, "Success" | "NotConverged" | "Failed")`` (PANOC's own
  convergence), ``forward(q) -> (position_m, quaternion_wxyz)`` and ``current_goal``; its
  ``solve`` sets no tolerance (all zero: the full 6-D pose is matched) and it has no reset;
- the C functions of the repository's ``src/relaxed_ik_wrapper.rs`` (what its
  ``wrappers/python_wrapper.py`` loads with ctypes): ``relaxed_ik_new(settings_path)``,
  ``solve_position(handle, position_m, 3, quaternion_xyzw, 4, tolerances, 6) -> q``,
  ``reset(handle, q, dof)`` and ``relaxed_ik_free``. Only these take RangedIK's
  tolerances: (x, y, z, rx, ry, rz), position [m] along the goal frame's axes and rotation
  [rad] about them (the components of the scaled axis of goal^-1 * end frame). Note the
  quaternion orders differ: x, y, z, w here, w, x, y, z in the Python class.

This adapter solves through the C functions (ctypes on the same file) and checks every
result with the Python class's ``forward`` (the library's own FK).

**Settings** are generated per robot into a temporary folder: the chain's URDF text
(:func:`ikbench.schemes.chain.chain_urdf_text`) as ``configs/urdfs/robot.urdf`` and
``settings.yaml`` with ``urdf: robot.urdf``, ``base_links: [<base link>]``, ``ee_links:
[<end frame>]`` (or a fixed child frame whose z-axis is the pointing axis, when that is not
the end frame's z) and ``starting_config`` (the chain's limits' midpoint, clipped; every
trajectory resets to its own start). The library reads the URDF from ``<current working
directory>/configs/urdfs/<urdf>``, so the process changes into the folder while the solver
is built (untimed, in ``prepare``; not thread-safe) and its start-up messages on stdout are
silenced. Its URDF model takes joint axes along +-x, +-y or +-z only: other robots are
refused before any solve.

**Objectives** (weights fixed in the library's ``ObjectiveMaster::relaxed_ik``, none
settable through the wheel): end-frame position per goal-frame axis (50 each) and rotation
per axis (10 each), each a "groove" loss, or, where a tolerance is set, a flat-bottomed loss
free within +-tolerance; a soft joint-limit loss per joint (0.1; the optimiser, PANOC,
also keeps the joints within the URDF limits as a box constraint); minimal joint velocity
(0.7), acceleration (0.5) and jerk (0.3) against the last three solutions (its warm start and
smoothness memory); manipulability (1.0); self-collision between the chain's joint-to-joint
segments as 5 cm capsules (0.01, radius fixed in the library; this version has no obstacle
objective, so tasks with obstacles are solved without them and ``compare`` judges the
collisions). Each ``solve_position`` call is one real-time step: PANOC from the last
solution, at most 100 iterations, tolerance 5e-4.

**Goals per step** (the track, :mod:`ikbench.schemes.track`): the goal point, and
the rotation nearest the pointing frame's whose z-axis is the scheduled pointing direction,
with tolerances (0, 0, 0, tilt, tilt, roll): position exact, the roll about the pointing axis
free (``roll_tolerance`` 180 deg), the tilt ``tilt_tolerance`` (default 0); without pointing
in the task, every rotation tolerance is 180 deg (position only). One call rarely reaches the
goal point (its smoothness objectives hold it back): the step repeats ``solve_position`` on
the same goals, up to ``calls`` times, until the position error by ``forward`` is within
``tolerance`` and either the pointing is within 1e-3 rad of its goal or the last call moved
no joint more than ``stall`` (:func:`ikbench.schemes.diffik.settle`). A step counts
as converged when its position error is within ``tolerance``. Between steps the library keeps
its own state (its last three solutions); a trajectory starts with ``reset(q_start)`` (the
walk: ``reset(q_touch)``), and on the track each step first resets to its warm start moved
``posture_seed`` (default 0.3) of the way toward the posture pose (start to touch pose,
linearly), which the velocity objective then pulls toward: RangedIK has no posture objective,
and without it (``posture_seed`` 0) nothing brings the arm onto the touch pose before the last
segment (on the Panda lines every last segment jumped, 2 to 6 times the allowed step; with 0.2
to 0.5 all seven meet the speed limit). Nothing bounds a step's joint change (the smoothness
objectives are soft). ``iterations`` counts ``solve_position`` calls.

Each ``solve_position`` result is a 7-double array the library allocates and never frees
(its C interface has no free function for results): 56 bytes per call.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
import weakref
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.urdf_model import with_fixed_frame
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals, element_path
from ikbench.schemes.diffik import settle
from ikbench.schemes.geometry import (
    angle_between_rad,
    closest_rotation_with_axis,
    frame_with_z_on,
    quaternion_xyzw,
)
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.track import SCHEME_HELP, SCHEMES, track
from ikbench.schemes.walk import PointResult, walk_back

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: The fixed frame added after the end frame when the pointing axis is not its z-axis.
POINTING_LINK = "ikbench_pointing"
#: Below this [rad] the pointing counts as on its goal (the stop rule's angle tolerance).
POINTING_EPS = 1e-3
_Z = np.array([0.0, 0.0, 1.0])
_SOLVERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class RangedIKSettings:
    """Settings of RangedIK's track and walk (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    calls: int = option(30, flag="rangedik-calls",
                        help="at most this many solve_position calls (real-time steps) per "
                        "waypoint")
    tolerance: float = option(1e-3, flag="rangedik-tolerance", unit="m",
                              help="a waypoint is converged when the end point is within this "
                              "of its goal point (the library's forward kinematics)")
    stall: float = option(1e-4, flag="rangedik-stall", unit="rad, m",
                          help="stop calling once the position is within the tolerance and "
                          "the last call moved no joint more than this")
    roll_tolerance: float = option(180.0, flag="rangedik-roll-tolerance", unit="deg",
                                   help="RangedIK's rotation tolerance about the pointing axis "
                                   "(180: the roll is free)")
    tilt_tolerance: float = option(0.0, flag="rangedik-tilt-tolerance", unit="deg",
                                   help="RangedIK's rotation tolerance about the two axes "
                                   "across the pointing axis (0: the scheduled direction is "
                                   "matched)")
    posture_seed: float = option(0.3, flag="rangedik-posture-seed",
                                 help="each step first resets the library to its warm start "
                                 "moved this fraction toward the step's posture pose (start to "
                                 "touch pose, linearly); 0: the library's own state")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_positive(self, "calls", integer=True)
        check_positive(self, "tolerance", "stall")
        self.calls = int(self.calls)
        for name, flag in (("roll_tolerance", "roll"), ("tilt_tolerance", "tilt")):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 <= value <= 180):
                raise InputError(f"--rangedik-{flag}-tolerance: {value!r} must be in "
                                 "[0, 180] deg")
        if not (isinstance(self.posture_seed, (int, float)) and 0 <= self.posture_seed <= 1):
            raise InputError(f"--rangedik-posture-seed: {self.posture_seed!r} must be in [0, 1]")

    def tolerances(self, pointing: bool) -> np.ndarray:
        """(6,) RangedIK's tolerances (x, y, z [m], rx, ry, rz [rad]) in the goal frame,
        whose z-axis is the pointing axis; every rotation free without pointing."""
        if not pointing:
            return np.array([0.0, 0.0, 0.0, np.pi, np.pi, np.pi])
        tilt, roll = np.radians(self.tilt_tolerance), np.radians(self.roll_tolerance)
        return np.array([0.0, 0.0, 0.0, tilt, tilt, roll])


class _Opt(ctypes.Structure):
    _fields_ = [("data", ctypes.POINTER(ctypes.c_double)), ("length", ctypes.c_int)]


_DOUBLES = ctypes.POINTER(ctypes.c_double)


def c_library() -> Any:
    """The wheel's shared library as ctypes sees it, with the C functions' signatures."""
    import relaxed_ik_lib

    lib = ctypes.CDLL(relaxed_ik_lib.relaxed_ik_lib.__file__)
    lib.relaxed_ik_new.restype = ctypes.c_void_p
    lib.relaxed_ik_new.argtypes = [ctypes.c_char_p]
    lib.relaxed_ik_free.argtypes = [ctypes.c_void_p]
    lib.reset.argtypes = [ctypes.c_void_p, _DOUBLES, ctypes.c_int]
    lib.solve_position.argtypes = [ctypes.c_void_p, _DOUBLES, ctypes.c_int, _DOUBLES,
                                   ctypes.c_int, _DOUBLES, ctypes.c_int]
    lib.solve_position.restype = _Opt
    return lib


def _doubles(values: Any) -> tuple[np.ndarray, Any]:
    array = np.ascontiguousarray(values, dtype=np.float64)
    return array, array.ctypes.data_as(_DOUBLES)


@contextlib.contextmanager
def _quiet_in(folder: Path) -> Iterator[None]:
    """Run in ``folder`` with file descriptor 1 (the library's println) sent to /dev/null."""
    cwd = os.getcwd()
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        try:
            os.chdir(folder)
            yield
        finally:
            os.chdir(cwd)
            os.dup2(saved, 1)
            os.close(saved)


def check_axes(chain: Chain) -> None:
    """InputError unless every chain joint turns or slides along +-x, +-y or +-z (the only
    axes RangedIK's URDF model takes)."""
    for name, _, _ in element_path(chain):
        if name not in chain.joint_names:
            continue
        axis = np.asarray(chain.urdf.joint(name).axis, dtype=float)
        text = " ".join(f"{v:g}" for v in axis)
        if np.count_nonzero(axis) != 1 or abs(float(np.max(np.abs(axis)))) != 1.0:
            raise InputError(f"--method rangedik: joint {name!r} has axis {text!r}; RangedIK's "
                             "URDF model takes joint axes along +-x, +-y or +-z only")


def settings_urdf(chain: Chain) -> tuple[str, str]:
    """(URDF text, end link) RangedIK loads: the chain's URDF, plus the fixed frame
    :data:`POINTING_LINK` on the end frame when the pointing axis is not its z-axis."""
    R_EP = frame_with_z_on(chain.pointing_axis)
    if np.allclose(R_EP, np.eye(3)):
        return chain.urdf_text, chain.end_frame
    return with_fixed_frame(chain.urdf_text, POINTING_LINK, chain.end_frame, R_EP), POINTING_LINK


class Solver:
    """One RangedIK solver for a chain: the C handle (solves) and the Python object (its FK).

    Args:
        chain: the robot's chain (URDF units).
    """

    def __init__(self, chain: Chain) -> None:
        import relaxed_ik_lib

        check_axes(chain)
        self.dof = chain.dof
        self.lib = c_library()
        urdf_text, end_link = settings_urdf(chain)
        start = chain.clip(np.where(np.isfinite(chain.lower) & np.isfinite(chain.upper),
                                    0.5 * (chain.lower + chain.upper), 0.0))
        with tempfile.TemporaryDirectory(prefix="ikbench-rangedik-") as name:
            folder = Path(name)
            (folder / "configs" / "urdfs").mkdir(parents=True)
            (folder / "configs" / "urdfs" / "robot.urdf").write_text(urdf_text)
            settings = folder / "settings.yaml"
            settings.write_text(
                "urdf: robot.urdf\nlink_radius: 0.05\n"
                f"base_links:\n  - {chain.base_link}\nee_links:\n  - {end_link}\n"
                f"starting_config: [{', '.join(repr(float(v)) for v in start)}]\n")
            with _quiet_in(folder):
                self.handle = self.lib.relaxed_ik_new(str(settings).encode())
                self.python = relaxed_ik_lib.RelaxedIK(str(settings))
        weakref.finalize(self, self.lib.relaxed_ik_free, self.handle)

    def reset(self, q: np.ndarray) -> None:
        """Set the library's state (its solution and the three before) to ``q`` (dof,)."""
        array, pointer = _doubles(q)
        self.lib.reset(self.handle, pointer, self.dof)

    def solve(self, point_m: np.ndarray, rotation: np.ndarray, tolerances: np.ndarray
              ) -> np.ndarray:
        """One ``solve_position`` call (one real-time step); (dof,) joint values."""
        point, p_point = _doubles(point_m)
        quaternion, p_quaternion = _doubles(quaternion_xyzw(rotation))
        tol, p_tol = _doubles(tolerances)
        out = self.lib.solve_position(self.handle, p_point, 3, p_quaternion, 4, p_tol, 6)
        return np.array(out.data[:out.length], dtype=float)

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) [m], rotation (3, 3)) of the pointing frame by the library's FK."""
        from scipy.spatial.transform import Rotation

        position, wxyz = self.python.forward(np.ascontiguousarray(q, dtype=float))
        w, x, y, z = (float(v) for v in wxyz)
        return np.asarray(position, dtype=float), Rotation.from_quat([x, y, z, w]).as_matrix()


def rangedik_solver(chain: Chain) -> Solver:
    """The chain's :class:`Solver` (built once per chain)."""
    if chain not in _SOLVERS:
        _SOLVERS[chain] = Solver(chain)
    return _SOLVERS[chain]


def solve_chain(chain: Chain, goals: Goals, settings: RangedIKSettings) -> ChainResult:
    """RangedIK in URDF units: the tracking scheme when ``goals.track`` is set, else the
    walk (see the module docstring)."""
    solver = rangedik_solver(chain)
    plan = goals.track
    directions = goals.directions if plan is None else plan.directions
    tolerances = settings.tolerances(directions is not None)

    def solve_point(i: int, q_warm: np.ndarray, point: np.ndarray,
                    posture: np.ndarray | None) -> PointResult:
        if posture is not None and settings.posture_seed > 0:
            solver.reset(chain.clip(q_warm + settings.posture_seed * (posture - q_warm)))
        state = {"q": q_warm}

        def measure() -> tuple[float, float]:
            position, R_P = solver.forward(state["q"])
            error = float(np.linalg.norm(position - point))
            if directions is None:
                return error, 0.0
            return error, angle_between_rad(R_P[:, 2], directions[i])

        def step() -> float:
            _, R_P = solver.forward(state["q"])
            rotation = (R_P if directions is None
                        else closest_rotation_with_axis(R_P, _Z, directions[i]))
            q = solver.solve(point, rotation, tolerances)
            moved = float(np.max(np.abs(q - state["q"])))
            state["q"] = q
            return moved

        calls, ok = settle(measure, step, settings.tolerance, settings.stall, settings.calls)
        return PointResult(state["q"], calls, ok)

    if plan is not None:
        solver.reset(plan.q_start)
        walk = track(lambda i, q: solve_point(i, q, plan.points_m[i], plan.posture[i]),
                     chain, plan)
    else:
        assert goals.q_touch is not None  # the walk starts at the touch pose (check_tasks)
        solver.reset(goals.q_touch)
        walk = walk_back(lambda i, q: solve_point(i, q, goals.points_m[i], None), chain, goals)
    return ChainResult.from_walk(walk, scheme="track" if plan is not None else "walk",
                                 iterations_are="solve_position calls (one real-time step "
                                 "each)")


class RangedIK(LibraryMethod):
    """RangedIK per waypoint (position exact, roll free by its tolerances, smoothness
    objectives on), tracked from the start pose onto the touch pose (or walked back from
    the touch pose: ``--scheme walk``)."""

    name = "rangedik"
    description = ("library: RangedIK / RelaxedIK (relaxed-ik-core) per waypoint, position "
                   "goal with the roll about the pointing axis free through its tolerances, "
                   "its smoothness, joint-limit and self-collision objectives on, several "
                   "real-time steps per waypoint, tracked from the start pose onto the touch "
                   "pose (--scheme walk: back from it)")
    library = "relaxed-ik-core"
    Settings = RangedIKSettings
    chain_check = staticmethod(check_axes)  # InputError for axes not along x, y or z
    chain_model = staticmethod(rangedik_solver)  # untimed: write the settings, load them

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="relaxed-ik-core", requires=("relaxed_ik_lib",),
                  methods=(RangedIK,), solvers=(), rank=120)
