"""Single-pose IK of ours-lm compiled with numba: one target a call with little Python in
between, restarts and a wall-clock deadline inside the compiled loop, or many targets over
threads.

The method is :func:`.single_pose.solve_poses`' (the numpy reference) for one target: a
projected Levenberg-Marquardt loop on ``r = [e_point / tol_mm, e_rot / tol_deg]`` (position
error [mm] and the SO(3) log of R_goal^T R [deg], as :func:`.frames.errors_from_frames`; the
position only for ``kind="position"``) with its exact Jacobian, ``(J^T J + lambda (diag(J^T
J) + eps I)) dq = -J^T r`` (by Cholesky), the step scaled to at most ``max_step`` and moved
into the limits (a revolute joint by whole turns where that brings it within them, the same
frame; else clipped: :func:`.single_pose_kernels.into_limits`; a joint pinned on a limit
that the step pushes out is left out of the system and the step solved again:
:func:`.single_pose_kernels.pinned`), accepted when |r|^2 drops
(lambda / 3, at least 1e-9) or rejected (lambda * 4). Success: both errors below ``stop`` x
the tolerances.

Restarts: the caller passes the starts ``initials`` (A, dof) [pose units], the protocol's
seeded sequence (:func:`random_initials`); attempt 1 runs from row 0, and an attempt that is
stuck (lambda above :data:`.single_pose.STALLED`, ``restart_after`` iterations since its
start without success, or, ``abandon = (t, h)``, |r| still above h after t iterations: far
off, it would rarely succeed) restarts from the next row; the last row's attempt runs until
it stalls. A call ends at success, a stalled last attempt, ``max_iterations`` (all attempts
together) or the deadline, ``budget_s`` after the call entered the compiled code: the
monotonic clock is read before every iteration (:func:`.single_pose_kernels.monotonic_s`,
~30 ns). With every setting the same and the rows the reference's random draws, the loop is
:func:`.single_pose.solve_poses` step for step (its ``restarts`` = A - 1).

The defaults differ from :func:`.single_pose.solve_poses`' where measurements said so
(:data:`RESTART_AFTER`, :data:`MAX_STEP`, :data:`DAMPING`, :data:`ABANDON`); ``abandon=(0,
0.0)`` turns the early restart off, as the reference has none. ``crawl`` (off by default, as
the reference has none; on in ``ikbench ik``'s deterministic table) kicks an attempt that
crawls (:data:`.single_pose_kernels.KICK_SEED`).

Per call (:meth:`SinglePoseLM.solve`): four arrays for numba to type (~0.1 us each: the
chain, limits and settings travel as one packed array, :func:`.compiled_chain.pack`), the
scratch allocated once inside the kernel (:mod:`.single_pose_kernels`). :meth:`SinglePoseLM.
solve_batch` runs numba threads (``prange``, GIL released) that each take the next target
from an atomic counter when done with one, each target with its own deadline. numba is the
core dependency; the first use compiles the kernels (~25 s on a 2-core machine: the loop's
helpers are inlined into it, which halved an iteration's time), numba caches them
(``__pycache__``). :meth:`SinglePoseLM.warm_up` loads every layout before timed calls;
:func:`loaded_on_first_use` and :func:`load_layout` load one as a call first needs it (the
first answer of :func:`ikbench.solve_pose`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numba
import numpy as np

from ikbench.core.compiled import compiled_only as _compiled_only
from ikbench.core.errors import InputError
from ikbench.methods.ours_lm import single_pose_kernels as kernels
from ikbench.methods.ours_lm.compiled_chain import WIDTH, Chain, pack
from ikbench.methods.ours_lm.compiling import say_if_compiling

if TYPE_CHECKING:
    import numpy.typing as npt

    from ikbench.core.robot import Robot

KINDS = ("pose", "position")
#: Defaults chosen on Panda, UR5, xArm7 and the Fetch arm from random starts. First tuned on
#: seeds 1 and 2 (seed 1 is the benchmark's); checked again by the committed script
#: benchmarks/tune_ours_lm_single_pose.py on seeds 101 and 102, which no benchmark or test
#: uses: of its grid (restart_after 8..20 x max_step 30..120 x damping 1e-3..0.1 x the early
#: restart on or off), these solve every target with the fewest LM iterations per target
#: (the criterion: machine-independent). The early restart: |r| > 100 after 6 iterations
#: (e.g. 100 mm or 50 deg off).
RESTART_AFTER, MAX_STEP, DAMPING, ABANDON = 14, 90.0, 0.1, (6, 100.0)
#: The wall-clock budget of one target [s] (TRAC-IK's default timeout).
BUDGET_S = 0.005


class PoseIK(NamedTuple):
    """One target's answer (:meth:`SinglePoseLM.solve`).

    Attributes:
        pose: (dof,) the last pose [pose units], within the limits.
        success: both errors fell below ``stop`` x the tolerances.
        attempts: starts used (rows of ``initials``).
        iterations: LM iterations, all attempts together.
        position_error_mm, rotation_error_deg: the pose's errors (rotation: nan for
            ``kind="position"``).
    """

    pose: np.ndarray
    success: bool
    attempts: int
    iterations: int
    position_error_mm: float
    rotation_error_deg: float


@dataclass
class BatchPoseIK:
    """B targets' answers (:meth:`SinglePoseLM.solve_batch`): the fields of :class:`PoseIK`
    as arrays, poses (B, dof) [pose units] and the others (B,)."""

    poses: np.ndarray
    success: np.ndarray
    attempts: np.ndarray
    iterations: np.ndarray
    position_error_mm: np.ndarray
    rotation_error_deg: np.ndarray


class SinglePoseLM:
    """ours-lm's single-pose IK of one robot, compiled (see the module docstring).

    Args:
        robot: the robot (its chain, pose units and limits).
        kind: ``"pose"`` (point and rotation) or ``"position"`` (the point only).
        tolerance: (position [mm], rotation [deg]): the residual's scale.
        stop: success when both errors are below ``stop`` x ``tolerance``.
        max_iterations: LM iterations of one call at most (all attempts together).
        restart_after: iterations after a (re)start without success before the next row.
        max_step: the largest joint step of one iteration [pose units].
        damping: lambda at every (re)start.
        abandon: (t, h): an attempt whose |r| (errors in tolerances) is above h after t
            iterations restarts; t = 0: never.
        crawl: (window, ratio, kick): an attempt whose |r|^2 is above ``ratio`` x its value
            ``window`` iterations before is kicked, every joint by up to ``kick`` x
            ``max_step`` (:data:`.single_pose_kernels.KICK_SEED`); window 0: never (the
            default).
    """

    def __init__(self, robot: Robot, kind: str = "pose",
                 tolerance: tuple[float, float] = (1.0, 0.5), stop: float = 1e-3,
                 max_iterations: int = 100_000, restart_after: int = RESTART_AFTER,
                 max_step: float = MAX_STEP, damping: float = DAMPING,
                 abandon: tuple[int, float] = ABANDON,
                 crawl: tuple[int, float, float] = (0, 0.0, 0.0)) -> None:
        if kind not in KINDS:
            raise InputError(f"kind: {kind!r} is not one of {', '.join(KINDS)}")
        numbers = {"tolerance": min(tolerance), "stop": stop, "max_step": max_step,
                   "damping": damping, "max_iterations": max_iterations,
                   "restart_after": restart_after}
        for name, value in numbers.items():
            if not value > 0:
                raise InputError(f"{name}: {value!r} must be > 0")
        if len(abandon) != 2 or int(abandon[0]) != abandon[0] or min(abandon) < 0:
            raise InputError(f"abandon: {abandon!r} must be (iterations >= 0, |r| >= 0)")
        if len(crawl) != 3 or int(crawl[0]) != crawl[0] or min(crawl) < 0:
            raise InputError(f"crawl: {crawl!r} must be (iterations >= 0, ratio >= 0, "
                             "kick >= 0)")
        self.robot, self.kind, self.dof = robot, kind, robot.dof
        settings = np.zeros((1, WIDTH))
        settings[0, :13] = (tolerance[0], tolerance[1], stop, max_iterations, restart_after,
                            kind == "position", max_step, damping, abandon[0], abandon[1],
                            *crawl)
        #: (dof + 2, WIDTH) the chain and limits (:func:`.compiled_chain.pack`), settings.
        self.spec = np.vstack([pack(Chain(robot), robot.lower, robot.upper), settings])
        self._identity = np.eye(3)

    def solve(self, target: npt.ArrayLike, rotation: npt.ArrayLike | None,
              initials: npt.ArrayLike, budget_s: float = BUDGET_S) -> PoseIK:
        """Solve one target from the starts ``initials``.

        Args:
            target: the goal point (3,) [mm] in the base frame, or the goal end frame
                T_base_end (4, 4) [m] (then ``rotation`` is None).
            rotation: (3, 3) the goal rotation; None with a frame, or for
                ``kind="position"``.
            initials: (A, dof) starts [pose units], tried in order.
            budget_s: wall-clock budget [s] (``inf``: none).

        Float64 C-ordered arrays pass as they are; others are copied first.
        """
        target, starts = _f64(target), _f64(initials)
        if starts.ndim != 2:
            starts = starts.reshape(-1, self.dof)
        if target.ndim == 2:
            return PoseIK(*kernels.solve_frame(self.spec, target, starts, float(budget_s)))
        if rotation is None or self.kind == "position":
            if self.kind == "pose":
                raise InputError("a point target needs its rotation (3, 3), or pass T (4, 4)")
            rotation = self._identity
        return PoseIK(*kernels.solve_point(self.spec, target, _f64(rotation), starts,
                                           float(budget_s)))

    def solve_batch(self, targets: npt.ArrayLike, rotations: npt.ArrayLike | None,
                    initials: npt.ArrayLike, budget_s: float = BUDGET_S,
                    threads: int | None = None) -> BatchPoseIK:
        """Solve B targets on ``threads`` numba threads (None: all), each with its own
        ``budget_s`` [s] from when its thread starts it.

        Args:
            targets: (B, 3) goal points [mm], or (B, 4, 4) goal frames [m] (``rotations``
                None).
            rotations: (B, 3, 3), or None (frames, or ``kind="position"``).
            initials: (B, A, dof) each target's starts [pose units].
        """
        points, rot = self._goals(np.asarray(targets, dtype=float), rotations)
        b = len(points)
        starts = np.array(initials, dtype=float, order="C", copy=True)  # writeable
        if starts.ndim != 3 or starts.shape[0] != b or starts.shape[2] != self.dof \
                or starts.shape[1] < 1:
            raise InputError(f"initials: shape {starts.shape} is not ({b}, A, {self.dof})")
        out = BatchPoseIK(np.empty((b, self.dof)), np.zeros(b, dtype=np.bool_),
                          np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.int64),
                          np.empty(b), np.empty(b))
        if b == 0:
            return out
        count = max(1, min(threads or max_threads(), max_threads(), b))
        previous = numba.get_num_threads()
        numba.set_num_threads(count)
        try:
            kernels.solve_many(self.spec, points, rot, starts, float(budget_s), out.poses,
                               out.success, out.attempts, out.iterations,
                               out.position_error_mm, out.rotation_error_deg, count)
        finally:
            numba.set_num_threads(previous)
        return out

    def _goals(self, targets: np.ndarray, rotations: npt.ArrayLike | None
               ) -> tuple[np.ndarray, np.ndarray]:
        """(points (B, 3) [mm], rotations (B, 3, 3)) of points or frames."""
        if targets.ndim == 3:  # frames T (B, 4, 4) [m]
            if targets.shape[1:] != (4, 4):
                raise InputError(f"targets: frames must be (B, 4, 4), not {targets.shape}")
            return (np.ascontiguousarray(targets[:, :3, 3] * 1000.0),
                    np.ascontiguousarray(targets[:, :3, :3]))
        points = np.array(targets, order="C", copy=True).reshape(-1, 3)  # writeable
        if rotations is None or self.kind == "position":
            if self.kind == "pose":
                raise InputError("point targets need their rotations (B, 3, 3), or pass "
                                 "frames (B, 4, 4)")
            # a writeable copy: one target's read-only broadcast view would be a second
            # argument layout, compiled again inside a timed call
            return points, np.array(np.broadcast_to(self._identity, (len(points), 3, 3)),
                                    order="C", copy=True)
        return points, np.array(rotations, dtype=float, order="C", copy=True).reshape(
            len(points), 3, 3)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) every kernel and every layout of
        :func:`.single_pose_kernels.solve_views` a timed call can meet, outside any timed
        region (:meth:`.pose_solver.OursLMSolver.prepare`). :func:`ikbench.solve_pose` skips
        this: it loads one layout when a call first needs it (:func:`load_layout`)."""
        say_if_compiling(kernels)
        pose = np.clip(np.zeros(self.dof), self.robot.sample_lower, self.robot.sample_upper)
        T = self.robot.fk_transform(pose)[0]
        self.solve(T[:3, 3] * 1000.0, np.ascontiguousarray(T[:3, :3]), pose[None], 0.0)
        self.solve(T, None, pose[None], 0.0)
        # solve_views (ikbench ik's adapter): the frame's column views and C-ordered copies
        for point in (T[:3, 3], np.ascontiguousarray(T[:3, 3])):
            for rotation in (T[:3, :3], np.ascontiguousarray(T[:3, :3])):
                kernels.solve_views(self.spec, point, rotation, pose[None], 0.0)
        for threads in (1, 2):
            self.solve_batch(T[None], None, pose[None, None], 0.0, threads)


def random_initials(robot: Robot, shape: tuple[int, ...], seed: int | np.random.Generator
                    ) -> np.ndarray:
    """Starts (*shape, dof) [pose units] drawn uniformly within the limits (continuous
    joints: +-180 deg), seeded: e.g. ``(A,)`` for :meth:`SinglePoseLM.solve`, ``(B, A)``
    for :meth:`SinglePoseLM.solve_batch`."""
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.sample_lower, robot.sample_upper, (*shape, robot.dof))


#: :func:`ikbench.core.compiled.compiled_only`, one dispatcher per kernel: the specialisations
#: ``kernel`` has compiled (or loaded) when first asked; TypeError for any other argument types
#: instead of a compile inside a timed call, so the caller's layout checks (~0.3 us a call,
#: :func:`ikbench.methods.ours_lm.pose_solver._f64`) run only on that rare path.
compiled_only = functools.cache(_compiled_only)


@functools.cache
def loaded_on_first_use(kernel: Any) -> Any:
    """A dispatcher of ``kernel``'s function holding no specialisation yet, compiling none by
    itself (TypeError for argument types it lacks, as :func:`compiled_only`'s):
    :func:`load_layout` loads one into it when a call first needs it. The first call of
    :func:`ikbench.solve_pose` loads one layout of :func:`.single_pose_kernels.solve_views`
    instead of the ~11 specialisations :meth:`SinglePoseLM.warm_up` and :func:`compiled_only`
    load (~0.1 s each from numba's cache on a 2-core machine)."""
    dispatcher = numba.njit(cache=True, nogil=True)(kernel.py_func)
    # what disable_compile() sets; it refuses a dispatcher holding no specialisation yet
    dispatcher._can_compile = False  # type: ignore[attr-defined]
    return dispatcher


@functools.cache
def view_layouts() -> frozenset[tuple[Any, ...]]:
    """The argument types of :func:`.single_pose_kernels.solve_views` that
    :meth:`SinglePoseLM.warm_up` compiles (the goal frame's column views and C-ordered copies
    of the point and rotation; the packed spec and the starts C-ordered, the budget a float),
    as numba types them."""
    T = np.eye(4)
    spec, starts = numba.typeof(np.zeros((3, WIDTH))), numba.typeof(np.zeros((1, 1)))
    return frozenset((spec, numba.typeof(point), numba.typeof(rotation), starts, numba.float64)
                     for point in (T[:3, 3], np.ascontiguousarray(T[:3, 3]))
                     for rotation in (T[:3, :3], np.ascontiguousarray(T[:3, :3])))


def numba_target_without_scipy_linalg() -> None:
    """Import numba's array maths (``numba.np.arraymath``, imported when the CPU target first
    loads any kernel, cached or not) without the ``import scipy.linalg.cython_blas`` its
    module-level BLAS probe runs (~0.3 s on a quiet 2-core machine, most of scipy.linalg's
    import): the probe only sets whether ``np.dot``-like overloads may lower to BLAS, and
    every BLAS or LAPACK lowering calls numba's ``ensure_blas``/``ensure_lapack`` again (then
    scipy.linalg imports), while a kernel loaded from the cache fetches its BLAS pointers
    from scipy when it first calls one. The probe's other half, numba's check that scipy's
    BLAS integer width is the one numba was built for, still runs (it reads
    ``scipy.__config__`` only). ours-lm's single-pose kernels use no BLAS (their Cholesky is
    written out in :mod:`.single_pose_kernels`). Nothing happens when numba's array maths is
    already imported, or scipy is not installed (the probe's answer is then False)."""
    import importlib.util
    import sys

    if "numba.np.arraymath" in sys.modules or importlib.util.find_spec("scipy") is None:
        return
    from numba.np import linalg

    probe = linalg.ensure_blas
    linalg.ensure_blas = linalg._check_lapack_int_width
    try:
        arraymath = importlib.import_module("numba.np.arraymath")
    finally:
        linalg.ensure_blas = probe
    arraymath.ensure_blas = probe  # type: ignore[attr-defined]  # the name it imported


def load_layout(dispatcher: Any, args: tuple[Any, ...]) -> bool:
    """Load into ``dispatcher`` (:func:`loaded_on_first_use`) the specialisation of ``args``'
    types when it is one of :func:`view_layouts` (from numba's cache, which any warm-up of
    ours-lm fills; compiled where the cache holds none, as a warm-up would); False, loading
    nothing, for any other types. True when ``dispatcher`` can now run ``args``."""
    signature = tuple(numba.typeof(arg) for arg in args)
    if signature not in view_layouts():
        return False
    if signature not in dispatcher.overloads:
        numba_target_without_scipy_linalg()
        dispatcher._can_compile = True
        try:
            dispatcher.compile(signature)
        finally:
            dispatcher._can_compile = False
    return True


def max_threads() -> int:
    """The most threads numba runs (``NUMBA_NUM_THREADS``, by default the cores)."""
    return int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]


def _f64(array: npt.ArrayLike) -> np.ndarray:
    """``array`` itself when it is a writeable C-ordered float64 ndarray (no copy), else a
    copy (read-only arrays too: numba compiles them as another argument layout)."""
    if type(array) is np.ndarray and array.dtype == np.float64 and array.flags.c_contiguous \
            and array.flags.writeable:
        return array
    return np.ascontiguousarray(array, dtype=float)
