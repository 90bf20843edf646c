"""EAIK (``pip install eaik``): analytic IK by subproblem decomposition, every branch at once.

EAIK (Ostermeier, Külz, Althoff, "Automatic Geometric Decomposition for Analytical Inverse
Kinematics", IEEE RA-L 2025) solves a 6R arm whose axes decompose into the Paden-Kahan-style
subproblems of IK-Geo (spherical wrist, three parallel axes, intersecting pairs, ...) in closed
form and returns all its solutions. ``ikbench ik`` uses it as the analytic limit: the robot's
chain is given to EAIK as its joint axes ``H`` (N, 3) and the offsets between them ``P``
(N+1, 3) at the zero configuration, in the chain's base frame, from Pinocchio
(``eaik.IK_HP.HPRobot(H, P)``'s construction, ``eaik.pybindings.EAIK.Robot(H^T, P^T, R6T, [],
True)``, with the end frame's rotation at the zero configuration as ``R6T``, so EAIK takes a
target frame as it is; on UR5 and UR10 its answers are bit-identical to HPRobot's on the target
rotated by ``R_end(0)^T``, 500 targets each). A chain EAIK cannot decompose (most 7-DoF arms
unless a joint is locked, prismatic joints) is refused when it is prepared, with EAIK's
reason, and its rows fail saying so.

Of the solutions (``IKSolution.Q``, the exact ones; ``is_LS`` marks least-squares answers to
unreachable targets), each joint of each is taken at its representative ``Q + 2 pi k`` within
that joint's limits nearest the initial configuration (:func:`in_limit_turns`: a joint of
UR5's +-360 deg has two representatives of every angle, one of [0, 360] deg or [-350, 10] deg
may have its only one a turn away); a solution is dropped only when some joint has no value
within its limits. The one nearest the initial configuration (row 0 of the protocol) is the
answer: one call, no restarts, deterministic. :meth:`EaikSolver.branches`
gives the whole set within the limits. The library is imported inside functions only.

Per call the glue is what the protocol needs and no more. ``ikbench ik`` times
:meth:`EaikSolver.prepared_call`: the target is made the 4x4 frame EAIK takes (and row 0 a
float64 copy) before the clock, as for EAIK's bare call (:meth:`EaikSolver.bare_call`, timed
beside it, interleaved); the timed call is EAIK's ``calculate_IK``, the reads of its ``Q`` and
``is_LS`` and one compiled pass over those arrays as EAIK returns them (no copy, no
conversion), called at its compiled entry point since its argument types are EAIK's and the
solver's own (:func:`branch_entry`). :meth:`EaikSolver.solve_within` (any caller) copies the
target into the solver's reused work buffer on the call, through numba's dispatchers, which
check the arrays given. The specialisations are loaded in ``prepare``; an argument of another
layout converts instead of compiling on the clock; the kernels keep the GIL (releasing and
taking it back is a measurable share of so short a call).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ikbench.core.compiled import compiled_only
from ikbench.methods.registry import Adapter
from ikbench.schemes.single_pose import PoseOut, PoseSolver

#: Pinocchio's revolute joints with a fixed axis (their shortname -> the axis in the joint).
_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0),
         "JointModelRZ": (0.0, 0.0, 1.0), "JointModelRUBX": (1.0, 0.0, 0.0),
         "JointModelRUBY": (0.0, 1.0, 0.0), "JointModelRUBZ": (0.0, 0.0, 1.0)}


def chain_axes(model, data, frame_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chain at its zero configuration as EAIK takes it: ``H`` (N, 3) unit joint axes,
    ``P`` (N+1, 3) offsets [m] (base to joint 1, joint to joint, last joint to the end frame),
    both in the base frame, and the end frame's rotation (3, 3) there. ValueError for a joint
    that is not revolute."""
    import pinocchio as pin

    pin.framesForwardKinematics(model, data, pin.neutral(model))
    axes, origins = [], []
    for i in range(1, model.njoints):
        joint = model.joints[i]
        name = joint.shortname()
        if name in _AXES:
            axis = np.asarray(_AXES[name])
        elif name in ("JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
            axis = np.asarray(joint.extract().axis, dtype=float)
        else:
            raise ValueError(f"joint {model.names[i]} is {name}: EAIK takes revolute joints only")
        axes.append(data.oMi[i].rotation @ axis)
        origins.append(data.oMi[i].translation.copy())
    end = data.oMf[frame_id]
    offsets = [origins[0], *np.diff(origins, axis=0), end.translation - origins[-1]]
    return np.array(axes), np.array(offsets), end.rotation.copy()


def in_limit_turns(Q: np.ndarray, lower: np.ndarray, upper: np.ndarray, near: np.ndarray,
                   revolute: np.ndarray | None = None, tol: float = 1e-9
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Each revolute joint of the solutions ``Q`` (S, dof) [rad] at its value ``Q + 2 pi k``
    within ``[lower, upper]`` (widened by ``tol``) nearest ``near`` (dof,) [rad]; joints are
    independent, so each row is its branch's configuration within the limits nearest
    ``near``. A joint without limits (infinite, a continuous joint) takes the value nearest
    ``near``; a prismatic one (``revolute`` False) stays as it is. Returns the moved
    solutions (S, dof) and a mask (S,): True where every joint has a value within its
    limits."""
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    near = np.broadcast_to(np.asarray(near, dtype=float), Q.shape)
    turn = 2 * math.pi
    with np.errstate(invalid="ignore"):
        k_low = np.ceil((lower - tol - Q) / turn)  # -inf without a lower limit
        k_high = np.floor((upper + tol - Q) / turn)
        k = np.clip(np.round((near - Q) / turn), k_low, k_high)  # |Q + 2 pi k - near| is convex
    moved = Q + turn * k
    if revolute is not None:
        fixed = ~np.asarray(revolute, dtype=bool)
        moved = np.where(fixed, Q, moved)
        k_low = np.where(fixed, np.where((Q >= lower - tol) & (Q <= upper + tol), 0, 1), k_low)
        k_high = np.where(fixed, 0, k_high)
    return moved, np.all(k_low <= k_high, axis=1)


#: The solver's work buffer (float64): the 4x4 target frame EAIK is given (C order), then
#: per joint the limits widened by the tolerance, then two scratch rows of ``_SCRATCH`` (per
#: solution: the squares, within the limits).
_FRAME, _SCRATCH = 16, 32


def _kernel():
    """The compiled bodies (numba, cached; compiled on first use): the branch pass of
    :func:`nearest_in_limits` and the copy of a call's target into the work buffer
    (``[T (16) | lower - tol (dof) | upper + tol (dof) | scratch]``)."""
    global _NEAREST
    if _NEAREST is None:
        from numba import njit

        @njit(cache=True)
        def nearest(Q, drop, work, near, out):  # pragma: no cover - compiled
            # joint by joint over the solutions (EAIK's Q is column-major: each joint's values
            # are contiguous, so the loop vectorises), the squares summed in joint order as
            # the norm's; a solution with a joint without a value within its limits is out
            turn = 2 * math.pi
            dof, S = out.shape[0], Q.shape[0]
            low, high, scratch = _FRAME, _FRAME + dof, _FRAME + 2 * dof
            if S <= _SCRATCH:  # the scratch rows of the work buffer
                squares = work[scratch:scratch + S]
                inside = work[scratch + _SCRATCH:scratch + _SCRATCH + S]
            else:
                squares, inside = np.empty(S), np.empty(S)
            for s in range(S):
                squares[s] = 0.0
                inside[s] = 0.0 if drop[s] else 1.0
            for j in range(dof):
                lower, upper, to = work[low + j], work[high + j], near[j]
                for s in range(S):
                    q = Q[s, j]
                    k_low = np.ceil((lower - q) / turn)  # -inf without a lower limit
                    k_high = np.floor((upper - q) / turn)
                    k = min(max(np.rint((to - q) / turn), k_low), k_high)
                    gap = q + turn * k - to
                    squares[s] += gap * gap
                    inside[s] = inside[s] if k_low <= k_high else 0.0
            found, pick, best = 0, -1, math.inf
            for s in range(S):
                if inside[s] != 0.0:
                    found += 1
                    distance = math.sqrt(squares[s])
                    if distance < best:  # the first of equals, as argmin
                        best, pick = distance, s
            if pick >= 0:
                for j in range(dof):
                    q, to = Q[pick, j], near[j]
                    k_low = np.ceil((work[low + j] - q) / turn)
                    k_high = np.floor((work[high + j] - q) / turn)
                    out[j] = q + turn * min(max(np.rint((to - q) / turn), k_low), k_high)
            return found

        @njit(cache=True)
        def frame(T, rotation, point_m):  # pragma: no cover - compiled
            # T: the frame's 16 values, C order (the work buffer's first or a frame's own)
            if rotation.shape != (3, 3) or point_m.shape != (3,):
                raise ValueError("expected a (3, 3) rotation and a (3,) point")
            for i in range(3):
                for j in range(3):
                    T[4 * i + j] = rotation[i, j]
                T[4 * i + 3] = point_m[i]

        _NEAREST = nearest, frame
    return _NEAREST


_NEAREST = None


def work_buffer(lower: np.ndarray, upper: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """A work buffer of the compiled pass (see :data:`_FRAME`): the identity frame, the limits
    widened by ``tol`` (the same floating-point operations as :func:`in_limit_turns`'
    ``lower - tol - Q``, evaluated left to right), the scratch rows."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    return np.concatenate([np.eye(4).ravel(), lower - tol, upper + tol,
                           np.zeros(2 * _SCRATCH)])


def nearest_in_limits(Q: np.ndarray, drop: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                      near: np.ndarray, out: np.ndarray, tol: float = 1e-9) -> int:
    """The answer of :meth:`EaikSolver.solve` without an array per call: of the solutions
    ``Q`` (S, dof) [rad] not marked in ``drop`` (S,) (bool), each revolute joint at its value
    within the limits nearest ``near`` (dof,) (exactly :func:`in_limit_turns`), the one
    nearest ``near`` (norm over the joints; the first of equals) is written into ``out``
    (dof,); returns how many lie within the limits (0: ``out`` untouched)."""
    near = np.ascontiguousarray(near, dtype=float)
    return int(_kernel()[0](Q, drop, work_buffer(lower, upper, tol), near, out))


def branch_entry(nearest, dof: int):
    """The branch pass's compiled entry point for EAIK's arrays (``Q`` (S, dof) float64,
    column-major and read-only; ``is_LS`` (S,) bool), a work buffer, the configuration to be
    nearest and an answer (float64, C order; made by :meth:`EaikSolver.prepared_call`): the
    call without numba's type dispatch (a share of so short a call). Those types
    are EAIK's for every S (Eigen's column-major matrices; S <= 1 is contiguous both ways),
    checked here on EAIK's own kind of arrays; ``nearest`` (the dispatcher) itself where the
    check fails."""
    import numba

    Q = np.zeros((3, dof), order="F")
    drop = np.zeros(3, dtype=bool)
    Q.flags.writeable = drop.flags.writeable = False
    work = work_buffer(np.zeros(dof), np.zeros(dof))
    signature = tuple(numba.typeof(a) for a in (Q, drop, work, np.zeros(dof), np.zeros(dof)))
    compiled = nearest.overloads.get(signature)
    return nearest if compiled is None else compiled.entry_point


class EaikSolver(PoseSolver):
    """``ikbench ik``: EAIK's analytic IK, the branch nearest the initial configuration (see
    the module docstring)."""

    rank = 5
    name, library, modules = "eaik", "eaik", ("eaik",)
    kinds = ("pose",)
    analytic = True
    restarts_itself = True  # one call answers from row 0; no restarts to make
    iterations_are = "solutions (all branches, within the limits)"
    attempt_bound = "closed form"

    def prepare(self) -> None:
        from eaik.pybindings.EAIK import Robot as EaikRobot

        fk = self.robot.pinocchio_fk()
        H, P, self.R_end0 = chain_axes(fk.model, fk.model.createData(), fk.frame_id)
        try:  # HPRobot(H, P)'s own construction, with the end frame's zero rotation as R6T
            self.eaik = EaikRobot(H.T, P.T, self.R_end0, [], True)
        except RuntimeError as exc:  # EAIK's own refusal (e.g. more than 6 joints)
            raise ValueError(f"EAIK cannot solve this {len(H)}-joint chain: {exc}") from None
        if not self.eaik.has_known_decomposition():
            raise ValueError(f"EAIK knows no decomposition of this {len(H)}-joint chain "
                             f"({self.eaik.get_kinematic_family()}); 7-DoF arms need a joint "
                             "locked")
        self.lower, self.upper = self.chain.lower, self.chain.upper
        self._dof = len(self.lower)
        self._work = work_buffer(self.lower, self.upper)  # reused by every call
        self._T = self._work[:_FRAME].reshape(4, 4)  # the frame EAIK is given: a view of it
        self._ik = self.eaik.calculate_IK
        nearest, frame = _kernel()
        # compile (or load numba's cache) here, untimed, for the arrays a call passes: EAIK's
        # answer (read-only, column-major) to the end frame at the zero configuration and to
        # one out of reach (least-squares answers), the target given as arrays and as views
        # of a frame
        T0 = np.eye(4)
        T0[:3, :3], T0[:3, 3] = self.R_end0, P.sum(axis=0)
        far = T0.copy()
        far[:3, 3] *= 1e3
        self._nearest, self._frame_into, self._branch_pass = nearest, frame, nearest
        for T in (T0, far):
            self.solve(np.zeros(self._dof), T[:3, 3].copy(), T[:3, :3].copy())
            self.solve(np.zeros(self._dof), T[:3, 3], T[:3, :3])
            self._solve_converted(np.zeros(self._dof), T[:3, 3], T[:3, :3])
        for rows in (1, 3):  # EAIK's Q of one solution reads as C-ordered, of more as F
            Q = np.zeros((rows, self._dof), order="F")
            drop = np.zeros(rows, dtype=bool)
            Q.flags.writeable = drop.flags.writeable = False
            nearest(Q, drop, self._work.copy(), np.zeros(self._dof), np.empty(self._dof))
        # from here on a call of another layout or dtype converts instead of compiling on
        # the clock (:meth:`solve`)
        self._nearest = compiled_only(nearest)
        self._frame_into = compiled_only(frame)
        self._branch_pass = branch_entry(self._nearest, self._dof)

    def _frame(self, point_m: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """The target as EAIK takes it (see the module docstring), in the reused buffer."""
        self._frame_into(self._work, np.ascontiguousarray(rotation, dtype=float),
                         np.ascontiguousarray(point_m, dtype=float))
        return self._T

    def solutions(self, point_m: np.ndarray, rotation: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """EAIK's answers to one frame, as EAIK gives them (in (-pi, pi]): the exact ones
        (S, dof) [rad] and the least-squares ones (``is_LS``: the frame is not reached)."""
        solution = self._ik(self._frame(point_m, rotation))
        Q = np.asarray(solution.Q, dtype=float).reshape(-1, len(self.lower))
        ls = np.asarray(solution.is_LS, dtype=bool) if len(Q) else np.zeros(0, dtype=bool)
        return Q[~ls], Q[ls]

    def branches(self, point_m: np.ndarray, rotation: np.ndarray,
                 near: np.ndarray | None = None, tol: float = 1e-9) -> np.ndarray:
        """Every exact solution within the limits (widened by ``tol`` [rad]) (S, dof) [rad],
        each joint at its value within its limits nearest ``near`` (default the middle of
        the limits; see :func:`in_limit_turns`)."""
        Q = self.solutions(point_m, rotation)[0]
        if not len(Q):
            return Q
        finite = np.isfinite(self.lower) & np.isfinite(self.upper)
        middle = np.where(finite, (np.where(finite, self.lower, 0.0)
                                   + np.where(finite, self.upper, 0.0)) / 2, 0.0)
        ref = middle if near is None else np.asarray(near, dtype=float)
        moved, inside = in_limit_turns(Q, self.lower, self.upper, ref, tol=tol)
        return moved[inside]

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        """The branch within the limits nearest ``q_init``: what :meth:`branches` and an
        argmin give, in one compiled pass (:func:`nearest_in_limits`) over EAIK's arrays as
        it returns them (no copies)."""
        return self.solve_within(np.asarray(q_init, dtype=float)[None], point_m, rotation,
                                 math.inf)

    def solve_within(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                     budget_s: float) -> PoseOut:
        """:meth:`solve` from row 0 of ``initials`` (closed form: one call, no budget): the
        target copied into the work buffer and row 0 passed to the branch pass through numba's
        dispatchers, which check their types (another layout or dtype converts,
        :meth:`solve`)."""
        try:
            self._frame_into(self._work, rotation, point_m)  # the target, as EAIK takes it
            solution = self._ik(self._T)
            q = np.empty(self._dof)
            found = self._nearest(solution.Q, solution.is_LS, self._work, initials[0], q)
        except TypeError:  # an argument of another layout or dtype: float64 copies
            return self._solve_converted(initials[0], point_m, rotation)
        if found:
            return _new_tuple(PoseOut, (q, found, True, 1))
        # unreachable, or only outside the limits: EAIK says no
        return PoseOut(np.asarray(initials[0], dtype=float), 0, False)

    def prepared_call(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                      budget_s: float) -> Callable[[], PoseOut]:
        """:meth:`solve_within` with its inputs in EAIK's form made in advance (see
        :meth:`PoseSolver.prepared_call`): the target frame as a 4x4 array of its own, as
        :meth:`bare_call` gives it to EAIK, and row 0 as a float64 copy; the call is EAIK's
        ``calculate_IK``, the reads of its ``Q`` and ``is_LS`` and the branch pass at its
        compiled entry point (:func:`branch_entry`; the types are the ones it was compiled for,
        made here), writing the answer into an array made here too: the call is one solve
        (called again, it answers again into the same array)."""
        T = self._frame(point_m, rotation).copy()
        near = np.array(np.asarray(initials, dtype=float)[0], dtype=float)  # C order, own
        if near.shape != (self._dof,):
            raise ValueError(f"expected starts (A, {self._dof}), got {np.shape(initials)}")
        ik, branch_pass, work, q, new = self._ik, self._branch_pass, self._work, \
            np.empty(self._dof), _new_tuple

        def call() -> PoseOut:
            solution = ik(T)
            found = branch_pass(solution.Q, solution.is_LS, work, near, q)
            if found:
                return new(PoseOut, (q, found, True, 1))
            # unreachable, or only outside the limits: EAIK says no
            return PoseOut(near.copy(), 0, False)

        return call

    def _solve_converted(self, q_init, point_m, rotation) -> PoseOut:
        """:meth:`solve` of inputs converted to C-ordered float64 first (never a compile)."""
        f64 = np.ascontiguousarray
        self._frame_into(self._work, f64(rotation, dtype=float), f64(point_m, dtype=float))
        solution = self._ik(self._T)
        Q = np.asarray(solution.Q, dtype=float).reshape(-1, self._dof).copy()
        drop = np.array(solution.is_LS, dtype=bool).reshape(len(Q))
        q = np.empty(self._dof)
        near = f64(q_init, dtype=float)
        found = self._nearest(Q, drop, self._work, near, q) if len(Q) else 0
        if not found:
            return PoseOut(np.asarray(q_init, dtype=float), 0, False)
        return PoseOut(q, found, True)

    def bare_call(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray
                  ) -> Callable[[], object]:
        """EAIK's own ``calculate_IK(T)`` on the target frame assembled in advance (see
        :meth:`PoseSolver.bare_call`)."""
        T, ik = self._frame(point_m, rotation).copy(), self._ik
        return lambda: ik(T)


_new_tuple = tuple.__new__  # PoseOut without its Python __new__ (~0.07 us a call)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="eaik", requires=("eaik",), solvers=(EaikSolver,), rank=140)
