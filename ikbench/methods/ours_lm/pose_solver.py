"""ours-lm's single-pose IK under the protocol of ``ikbench ik`` (ikbench's own method, not a
library: its adapter sits beside the interface, :mod:`ikbench.schemes.single_pose`).

ours-lm restarts by itself: :meth:`OursLMSolver.solve_within` takes the target's whole
sequence of initial configurations [pose units] and the budget. With numba (a core
dependency, where it imports) it runs the compiled single-pose LM
(:class:`ikbench.methods.ours_lm.single_pose_compiled.SinglePoseLM`): the restarts from the
rows in order and the wall-clock deadline are inside its compiled loop, one target per call
from Python, and :meth:`OursLMSolver.solve_batch` solves every target over numba threads,
each with its own budget. :meth:`OursLMSolver.solve_within` is one compiled call
(:func:`.single_pose_kernels.solve_views`): the goal's conversion to [mm] and its copies
run inside it, on the clock as the other libraries' conversions run inside theirs, with no
per-call Python arrays (UR5: ~12 -> ~10 us per call). Without numba it runs the numpy reference,
:func:`ikbench.methods.ours_lm.single_pose.solve_poses`, one target per call: an attempt from
row a stops after :data:`RESTART_AFTER` iterations without success (the last row's after
:data:`~ikbench.schemes.single_pose.MAX_STEPS`), and the next row starts while the
budget lasts (checked between attempts: numpy cannot stop inside one); its batch is one numpy
call without a deadline. :meth:`OursLMSolver.runtime` says which ran.

One descent (``--attempts 1``: one row) stops after
:data:`~ikbench.schemes.single_pose.MAX_STEPS` iterations, as the other methods'
descents do.
"""

from __future__ import annotations

import importlib
import math
import time
from typing import Any

import numpy as np

from ikbench.methods.ours_lm.devices import (
    numba_threads,
    numba_unavailable,
    numpy_fallback,
)
from ikbench.methods.ours_lm.single_pose import solve_poses
from ikbench.schemes.single_pose import MAX_STEPS, BatchOut, PoseOut, PoseSolver

#: Iterations of one attempt before the next row (the numpy reference's ``restart_after``).
RESTART_AFTER = 15
#: The numpy batch: LM iterations per target in all (restarts included).
BATCH_MAX_ITERATIONS = 1500
#: The deterministic table's solver (K rows, no clock): lambda at each start and the crawl
#: check (window, ratio, kick: :data:`.single_pose_kernels.KICK_SEED`): an attempt whose |r|^2
#: has not halved in 10 iterations moves every joint by a uniform draw in +-2 x max_step
#: (+-180 deg), into its limits, within the attempt's iterations. Measured by
#: ``benchmarks/tune_ours_lm_single_pose.py --rows`` on seeds 101 and 102 (no benchmark's or
#: test's): of its grid, these solve every target with the fewest LM iterations; without the
#: kick, attempts from every row of some targets stay in a saddle (the UR10's stretched
#: elbow, where J^T J cannot see that bending helps) or crawl out of their 100 iterations.
ROWS_DAMPING, ROWS_CRAWL = 0.3, (10, 0.5, 2.0)


def compiled_available() -> bool:
    """True when numba imports (the compiled solver runs); else the numpy reference runs and
    one line on stderr says so (:func:`~ikbench.methods.ours_lm.devices.numpy_fallback`)."""
    if numba_unavailable() is None:
        return True
    numpy_fallback()
    return False


class OursLMSolver(PoseSolver):
    """ours-lm's projected LM on ``[e_point / tol_mm, e_rot / tol_deg]`` (see the module
    docstring)."""

    rank = 10
    name, library, modules = "ours-lm", "ikbench", ()
    restarts_itself = True
    batched = True
    pose_units = True
    iterations_are = "LM iterations (all attempts)"
    attempt_bound = (f"errors below 1e-3 of the tolerances; a fixed count of rows: each "
                     f"attempt at most {MAX_STEPS} LM iterations (K x {MAX_STEPS} in all), "
                     "one crawling 10 iterations re-drawn near its pose (ROWS_CRAWL); "
                     "the budgeted table: the next row after RESTART_AFTER (14) iterations "
                     "without success or when far off (ABANDON)")

    #: The compiled solvers (:meth:`prepare`; None: the numpy reference runs).
    compiled: Any = None
    descent: Any = None
    #: True after :meth:`prepare_first_call`: layouts are loaded on first use.
    _lazy = False

    def prepare(self) -> None:
        """Build (and compile or load) the compiled solver when numba is installed: every
        kernel layout the timed calls can meet is loaded here, so no timed call loads or
        compiles one (``ikbench ik`` times calls after this)."""
        self._build(warm=True)

    def prepare_first_call(self) -> None:
        """The cheaper set-up of :func:`ikbench.solve_pose` and of the first-call column
        (:mod:`ikbench.studies.first_call`): the compiled solvers built, no kernel loaded; a
        call loads (from numba's cache: compiles where it holds none) only the layout of
        :func:`.single_pose_kernels.solve_views` its arrays need, one that :meth:`prepare`
        would have loaded (:func:`.single_pose_compiled.load_layout`), on its first use
        (UR5, warm cache: one of ~11 specialisations). The answers are :meth:`prepare`'s, bit
        for bit: the same compiled code runs. Not for timed calls: a call meeting a layout
        the first time waits for its load."""
        self._build(warm=False)

    def _build(self, warm: bool) -> None:
        self.compiled = None
        self._lazy = False
        if compiled_available():
            module = importlib.import_module("ikbench.methods.ours_lm.single_pose_compiled")
            SinglePoseLM = module.SinglePoseLM  # noqa: N806
            self._module = module
            self._views_any = module.kernels.solve_views
            self._identity = np.eye(3)
            self.compiled = SinglePoseLM(self.robot, self.kind, self.tolerance)
            self.descent = SinglePoseLM(self.robot, self.kind, self.tolerance,
                                        max_iterations=MAX_STEPS)
            self.rows: dict[int, Any] = {}
            if warm:
                self.compiled.warm_up()
                self.descent.warm_up()
                self._views = module.compiled_only(self._views_any)
            else:  # each layout loaded on its first call (_load_views)
                module.say_if_compiling(module.kernels)
                self._views = module.loaded_on_first_use(self._views_any)
                self._lazy = True

    def runtime(self) -> dict[str, Any]:
        """The solver that runs: compiled (numba) or the numpy reference."""
        return {"backend": "numba" if getattr(self, "compiled", None) else "numpy"}

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        """One descent from ``q_init`` [pose units] (:data:`MAX_STEPS` iterations at most)."""
        return self.solve_within(np.asarray(q_init, dtype=float)[None], point_m, rotation,
                                 float("inf"))

    def solve_within(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                     budget_s: float) -> PoseOut:
        """From the rows of ``initials`` (A, dof) [pose units] in order until success, the
        last row or the budget [s] (see the module docstring)."""
        compiled = self.compiled
        if compiled is not None:
            # One compiled call does the rest (the goal to [mm], its copies, the checks, the
            # restarts): no Python copies or checks per call.
            # _solver_for inlined (a Python call less: ~0.08 us of an empty call)
            rows = len(initials)
            if rows == 1:
                solver = self.descent
            elif budget_s < math.inf:
                solver = compiled
            else:
                solver = self.rows.get(rows) or self._rows_solver(rows)
            if rotation is None:  # kind "position": the rotation is not read
                rotation = self._identity
            # tuple.__new__: PoseOut(*...) costs ~0.07 us more per call
            try:  # the arrays as they come: a layout compiled at warm-up runs
                return _new_tuple(PoseOut, self._views(solver.spec, point_m, rotation,
                                                       initials, budget_s))
            except TypeError:  # another layout or dtype: float64 copies, never a compile
                if self._lazy:  # prepare_first_call: a layout not loaded yet, or copies
                    return _new_tuple(PoseOut, self._load_views(
                        solver.spec, point_m, rotation, initials, budget_s))
                return _new_tuple(PoseOut, self._views_any(
                    solver.spec, _f64(point_m), _f64(rotation), _f64(initials),
                    float(budget_s)))
        point_mm = np.asarray(point_m, dtype=float) * 1000.0
        deadline = time.perf_counter() + budget_s
        goal_R = np.asarray(rotation, dtype=float)[None]
        iterations = 0
        for a in range(len(initials)):
            last = a + 1 == len(initials)
            out = solve_poses(self.robot, point_mm[None], goal_R, initials[a:a + 1],
                              self.tolerance, position_only=self.kind == "position",
                              max_iterations=MAX_STEPS if last else RESTART_AFTER)
            iterations += int(out.iterations[0])
            if out.converged[0] or last or time.perf_counter() >= deadline:
                break
        return PoseOut(out.poses[0], iterations, bool(out.converged[0]), a + 1)

    def _load_views(self, spec: np.ndarray, point_m: Any, rotation: Any, initials: Any,
                    budget_s: float) -> tuple:
        """:meth:`prepare_first_call`'s first call with a layout: the arrays as they come
        when :meth:`prepare` would have loaded their layout, else their float64 copies (as
        :meth:`prepare`'s path copies them), that layout loaded into ``self._views`` first."""
        load = self._module.load_layout
        args = (spec, point_m, rotation, initials, budget_s)
        if not load(self._views, args):
            args = (spec, _f64(point_m), _f64(rotation), _f64(initials), float(budget_s))
            if not load(self._views, args):  # not reached: copies have a loaded layout
                return self._views_any(*args)
        return self._views(*args)

    def _solver_for(self, rows: int, budget_s: float) -> Any:
        """The compiled solver of ``rows`` starts within ``budget_s`` [s]: one descent for one
        row, the tuned restarts under a budget, else the fixed-count rule's
        (:meth:`_rows_solver`). :meth:`solve_within` and :meth:`solve_batch` both ask here, so
        the batched column runs the per-call table's solver and settings."""
        if rows == 1:
            return self.descent
        if budget_s < math.inf:  # the budgeted protocol: its tuned restarts
            return self.compiled
        # K rows, no clock: each a descent of MAX_STEPS, as the other methods'
        return self.rows.get(rows) or self._rows_solver(rows)

    def _rows_solver(self, rows: int) -> Any:
        """The compiled solver of a fixed count of rows without a budget (the deterministic
        table): an attempt gives way after :data:`MAX_STEPS` iterations without success, no
        early abandon, a crawling attempt kicked (:data:`ROWS_CRAWL`), :data:`MAX_STEPS` x
        ``rows`` iterations in all (built once per count, the same compiled kernel)."""
        if rows not in self.rows:
            kernels = importlib.import_module("ikbench.methods.ours_lm.single_pose_compiled")
            SinglePoseLM = kernels.SinglePoseLM  # noqa: N806
            self.rows[rows] = SinglePoseLM(self.robot, self.kind, self.tolerance,
                                           max_iterations=MAX_STEPS * rows,
                                           restart_after=MAX_STEPS, abandon=(0, 0.0),
                                           damping=ROWS_DAMPING, crawl=ROWS_CRAWL)
        return self.rows[rows]

    def solve_batch(self, initials: np.ndarray, points_m: np.ndarray, rotations: np.ndarray,
                    budget_s: float, threads: int | None = None) -> BatchOut:
        """Every target in one call: compiled over ``threads`` numba threads, each target with
        its own budget and the solver :meth:`solve_within` runs for the same rows and budget
        (:meth:`_solver_for`: under a fixed count of rows the crawl kick too, so each target's
        answer is the per-call one), or (numpy) one batch without a deadline on one thread."""
        points_mm = np.asarray(points_m, dtype=float) * 1000.0
        if self.compiled is not None:
            solver = self._solver_for(initials.shape[1], budget_s)
            out = solver.solve_batch(points_mm, rotations, initials, budget_s, threads)
            count = max(1, min(threads or numba_threads(), numba_threads(), len(points_mm)))
            return BatchOut(out.poses, out.attempts, count)
        rows = initials.shape[1]
        out = solve_poses(self.robot, points_mm, rotations, initials[:, 0], self.tolerance,
                          position_only=self.kind == "position",
                          max_iterations=BATCH_MAX_ITERATIONS, restarts=rows - 1,
                          restart_after=RESTART_AFTER)
        return BatchOut(out.poses, out.restarts + 1, 1)


def _f64(array: Any) -> np.ndarray:
    """``array`` itself when it is a writeable float64 ndarray (any layout: the kernel copies
    what it reads; Fortran-ordered ones excepted), else a C-ordered float64 copy (read-only arrays
    too: numba would compile them as another argument type, inside a timed call). On the clock
    three times a call: the dtype compared by identity and the flags read once (~0.1 us
    each, from ~0.17)."""
    if array.__class__ is np.ndarray and array.dtype is _FLOAT64:
        flags = array.flags
        if flags.writeable and (flags.c_contiguous or not flags.f_contiguous):
            return array
    return np.ascontiguousarray(array, dtype=float)


_FLOAT64 = np.dtype(np.float64)
_new_tuple = tuple.__new__
