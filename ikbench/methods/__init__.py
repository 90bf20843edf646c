"""Trajectory methods, registered by name.

A method turns a :class:`ikbench.task.Task` into a :class:`Solution` (n+1 poses in motor
degrees). Modules in this package and in the ``baselines`` package register themselves with
:func:`register` when imported; :func:`get_method` finds them all. A method class has:

- ``name`` and ``description`` (one line, shown in ``--help``);
- ``add_arguments(group)``: its CLI options (defaults None, so unset options keep the
  method's own defaults);
- ``from_args(args)``: build it from the parsed CLI namespace;
- ``solve(robot, task, progress=None) -> Solution``; optionally ``solve_many(robot, tasks,
  progress=None)`` for batched methods (default: one ``solve`` per task).
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field

import numpy as np

from ikbench.errors import InputError

_REGISTRY: dict[str, type] = {}
_PACKAGES = ("ikbench.methods", "baselines")


@dataclass
class Solution:
    """A method's result for one task.

    Attributes:
        poses_deg: (n+1, dof) poses [motor deg].
        iterations: optimiser iterations (total IK iterations for sequential IK).
        duration_s: wall time of the solve [s].
        loss: final loss in the paper's units (cm, motor deg), or None if the method has none.
        converged: whether the method's own stopping criterion was met (not the cap).
        info: extra method-specific figures (written to details.csv).
    """

    poses_deg: np.ndarray
    iterations: int
    duration_s: float
    loss: float | None
    converged: bool = True
    info: dict = field(default_factory=dict)


class Method:
    """Base class with the default CLI plumbing; subclasses set name/description/solve."""

    name = ""
    description = ""
    #: option name (argparse dest) -> constructor keyword
    options: dict[str, str] = {}

    @classmethod
    def add_arguments(cls, group) -> None:
        """Add this method's CLI options to an argparse group (defaults must be None)."""

    @classmethod
    def from_args(cls, args) -> Method:
        kwargs = {kw: getattr(args, dest) for dest, kw in cls.options.items()
                  if getattr(args, dest, None) is not None}
        return cls(**kwargs)

    def solve(self, robot, task, progress=None) -> Solution:  # pragma: no cover - abstract
        raise NotImplementedError

    def solve_many(self, robot, tasks, progress=None) -> list[Solution]:
        """Solve every task; batched methods override this."""
        solutions = []
        for k, task in enumerate(tasks):
            if progress:
                progress.start(task, k, len(tasks))
            solutions.append(self.solve(robot, task, progress))
            if progress:
                progress.done(task, solutions[-1])
        return solutions


def register(cls):
    """Class decorator: make a method available by its ``name``."""
    _REGISTRY[cls.name] = cls
    return cls


def _discover() -> None:
    for package_name in _PACKAGES:
        try:
            package = importlib.import_module(package_name)
        except ImportError:
            continue
        for info in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package_name}.{info.name}")


def available_methods() -> dict[str, type]:
    """name -> method class, for every registered method."""
    _discover()
    return dict(sorted(_REGISTRY.items()))


def get_method(name: str) -> type:
    """The method class called ``name``; InputError naming the valid ones otherwise."""
    methods = available_methods()
    if name not in methods:
        raise InputError(f"--method: unknown method {name!r}; available: {', '.join(methods)}")
    return methods[name]
