"""Where a study's work runs: in this process, or as tasks on a Ray cluster.

An executor has one job: ``map(fn, items)`` yields ``fn(item)`` for every item, **in the
order of the items**, as they become available. ``fn`` must be picklable (a module-level
function, which Ray ships by reference, or a ``functools.partial`` of one), and so must the
items and results. Studies split their work into independent parts (:func:`split`), map a
function over the parts and put the results together in order, so the numbers and files do
not depend on the executor.

- ``local``: one part after another in this process (``workers`` = 1: a study solves its
  whole batch in one call, as it always did).
- ``ray``: each part a Ray task (1 CPU, or 1 GPU for a study on a CUDA device), at most
  ``2 x workers`` in flight. Without an address a private local Ray is started with every
  core of this machine; ``--ray-address HOST:PORT`` (or ``auto``: the cluster this machine
  belongs to) joins a running cluster, whose nodes must have ikbench installed (docs/scale.md).
  Ray is imported only here, only when asked for: ``pip install 'ikbench[scale]'``.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import logging
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, Any

from ikbench.core.errors import IkbenchError, InputError

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

EXECUTORS = ("local", "ray")
SCALE_EXTRA = "pip install 'ikbench[scale]'"


def check_executor(name: str, address: str | None = None) -> str:
    """Validate ``--executor`` / ``--ray-address`` before any work (no heavy imports).

    Raises:
        InputError: an unknown executor, an address without ``--executor ray``, or Ray
            asked for but not installed.
    """
    if name not in EXECUTORS:
        raise InputError(f"--executor: {name!r} is not one of {', '.join(EXECUTORS)}")
    if address is not None and name != "ray":
        raise InputError(f"--ray-address {address}: give --executor ray with it")
    if name == "ray" and importlib.util.find_spec("ray") is None:
        raise InputError(f"--executor ray: Ray is not installed; {SCALE_EXTRA}")
    return name


def split(count: int, parts: int) -> list[range]:
    """``count`` items in at most ``parts`` contiguous ranges of nearly equal size, in order
    (none empty; one range for ``parts`` <= 1)."""
    parts = max(1, min(parts, count))
    bounds = [count * k // parts for k in range(parts + 1)]
    return [range(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def portable_robot(robot: Robot) -> Robot:
    """The robot without its caches (kinematics, models), to send to another process."""
    return dataclasses.replace(robot, _cache={})


class LocalExecutor:
    """Runs every item in this process, in order."""

    name = "local"
    workers = 1
    address = None

    def map(self, fn: Callable, items: Iterable, gpus: float = 0.0) -> Iterator:
        """``fn(item)`` for each item, in order (``gpus`` is ignored)."""
        for item in items:
            yield fn(item)

    def describe(self) -> dict:
        """What ran the work (recorded with results)."""
        return {"executor": self.name, "workers": self.workers}


class RayExecutor:
    """Runs every item as a Ray task; results come back in the order of the items.

    Args:
        address: a running cluster (``HOST:PORT``, ``ray://HOST:PORT`` or ``auto``); None
            starts a private local Ray (or reuses the one this process already started).
    """

    name = "ray"

    def __init__(self, address: str | None = None):
        ray = _import_ray()
        self.address = address
        if not ray.is_initialized():
            try:
                ray.init(address=address or "local", include_dashboard=False,
                         logging_level=logging.WARNING)
            except (ConnectionError, ValueError, RuntimeError) as exc:
                where = address or "a local Ray"
                raise InputError(f"--ray-address: cannot start or reach {where}: "
                                 f"{' '.join(str(exc).split())}") from None
        resources = ray.cluster_resources()
        self.workers = max(1, int(resources.get("CPU", 1)))
        self.gpus = int(resources.get("GPU", 0))

    def map(self, fn: Callable, items: Iterable, gpus: float = 0.0) -> Iterator:
        """``fn(item)`` for each item as Ray tasks (1 CPU, or ``gpus`` GPUs each), in order.

        Raises:
            IkbenchError: the one a task raised (other Ray failures propagate).
        """
        ray = _import_ray()
        options: dict[str, Any] = {"num_gpus": gpus} if gpus else {"num_cpus": 1}
        remote = ray.remote(_apply).options(max_retries=0, **options)
        pending: deque = deque()
        source = iter(items)
        window = 2 * (max(1, self.gpus) if gpus else self.workers)
        try:
            for item in source:
                pending.append(remote.remote(fn, item))
                if len(pending) >= window:
                    break
            while pending:
                result = _get(ray, pending.popleft())
                for item in source:
                    pending.append(remote.remote(fn, item))
                    break
                yield result
        finally:
            for ref in pending:  # Ctrl-C or an error: stop what is still queued
                ray.cancel(ref, force=True)

    def describe(self) -> dict:
        """What ran the work (recorded with results)."""
        ray = _import_ray()
        return {"executor": self.name, "address": self.address or "local",
                "workers": self.workers, "gpus": self.gpus, "nodes": len(ray.nodes())}


Executor = LocalExecutor | RayExecutor


def get_executor(name: str = "local", address: str | None = None) -> Executor:
    """The executor called ``name`` (``local`` or ``ray``), see the module docstring."""
    check_executor(name, address)
    return RayExecutor(address) if name == "ray" else LocalExecutor()


def _apply(fn: Callable, item):
    """``fn(item)``: the one remote function (so any picklable callable can be mapped)."""
    return fn(item)


def _import_ray():
    try:
        import ray
    except ImportError:
        raise InputError(f"--executor ray: Ray is not installed; {SCALE_EXTRA}") from None
    return ray


def _get(ray, ref):
    """``ray.get(ref)``, re-raising an ikbench error of the task as itself."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = getattr(exc, "cause", None)
        if isinstance(cause, IkbenchError):
            raise cause from None
        raise
