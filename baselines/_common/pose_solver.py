"""What every single-pose solver of ``ikbench ik`` shares: the answer, the base class, the
library tolerance and the QP-step loop (the solvers are listed in
:mod:`ikbench.baselines._common.single_pose`; a library module may define its own, as
:mod:`ikbench.baselines.libraries.placo_ik` does).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np

from ikbench.baselines._common.chain import chain_of

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: The libraries' own stopping tolerance [m, rad] (far below the study's mm and degrees).
LIBRARY_TOLERANCE = 1e-6
#: Iterations (QP steps, DLS steps) per solve at most.
MAX_STEPS = 100


class PoseOut(NamedTuple):
    """One library answer: q (dof,) [rad, m], iterations (what they count:
    ``iterations_are``), ok (the library's own success claim; None when it makes none)."""

    q: np.ndarray
    iterations: int
    ok: bool | None


class PoseSolver:
    """One library's single-pose IK (see :mod:`ikbench.baselines._common.single_pose`).

    Class attributes:
        name: the method's name (as in ``ikbench methods``).
        library: PyPI distribution whose version is recorded.
        modules: modules that must be importable.
        kinds: the target kinds it takes (``pose``, ``position``).
        deterministic: same input, same answer.
        batched: solves all targets in one call (:meth:`solve_batch`) instead of one at a time.
        iterations_are: what ``iterations`` counts.
    """

    name: ClassVar[str] = ""
    library: ClassVar[str] = ""
    modules: ClassVar[tuple[str, ...]] = ()
    kinds: ClassVar[tuple[str, ...]] = ("pose", "position")
    deterministic: ClassVar[bool] = True
    batched: ClassVar[bool] = False
    iterations_are: ClassVar[str] = "iterations"

    def __init__(self, robot: Robot, kind: str = "pose") -> None:
        self.robot = robot
        self.kind = kind
        self.chain = chain_of(robot)

    @classmethod
    def available(cls) -> bool:
        """True when every module it needs can be imported (nothing is imported here)."""
        return all(importlib.util.find_spec(m) is not None for m in cls.modules)

    def prepare(self) -> None:
        """Untimed set-up (models, compilation)."""

    def solve(self, q_init: np.ndarray, point_m: np.ndarray,
              rotation: np.ndarray) -> PoseOut:  # pragma: no cover - interface
        raise NotImplementedError


def converge(measure: Callable[[], tuple[float, float]], step: Callable[[], object]
             ) -> tuple[int, bool]:
    """QP steps until both errors of ``measure()`` (position [m], angle [rad]) are below
    :data:`LIBRARY_TOLERANCE`, at most :data:`MAX_STEPS`; (steps taken, converged)."""
    for steps in range(MAX_STEPS + 1):
        position, angle = measure()
        if position < LIBRARY_TOLERANCE and angle < LIBRARY_TOLERANCE:
            return steps, True
        if steps < MAX_STEPS:
            step()
    return MAX_STEPS, False
