"""The method registry: built-in methods listed explicitly, third-party ones by entry point.

A method whose library is missing never breaks another: each entry names the Python modules
it needs (``requires``); when one is not installed the method is listed as unavailable with
the reason and the extra to install, and its module is not imported. A module that fails to
import for another reason (a bug, a broken install) is listed as ``failed to import: <error>``:
the two are told apart, so tests skip only the first. Nothing is imported until
a method is asked for (``ikbench fk`` imports no method at all).

Third parties register methods in the entry-point group ``ikbench.methods``::

    [project.entry-points."ikbench.methods"]
    my-method = "my_package.my_module:MyMethod"
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass
from importlib import metadata
from typing import TYPE_CHECKING, TypeVar

from ikbench.core.errors import InputError

if TYPE_CHECKING:  # the registry holds method classes; base.Method asks it for alternatives
    from ikbench.methods.base import Method

#: A method class (:func:`register` returns the class it is given).
M = TypeVar("M", bound="Method")

ENTRY_POINT_GROUP = "ikbench.methods"
LIBS_EXTRA = "pip install 'ikbench[libs]'"


@dataclass(frozen=True)
class Entry:
    """Where a method lives and what it needs.

    Attributes:
        name: registry name.
        target: ``"module:Class"``.
        requires: import names that must be installed.
        install: how to install them (shown when one is missing).
    """

    name: str
    target: str
    requires: tuple[str, ...] = ()
    install: str = LIBS_EXTRA


#: The built-in methods, in listing order.
BUILTIN = (
    Entry("ours", "ikbench.methods.ours:Ours", ("torch", "pytorch_kinematics")),
    Entry("ours-lm", "ikbench.methods.ours_lm:OursLM", ("scipy", "pinocchio")),
    Entry("ours-exact", "ikbench.methods.ours_exact:OursExact", ("scipy", "pinocchio")),
    Entry("sequential-ik", "ikbench.baselines.sequential_ik:SequentialIK", ("pinocchio",)),
    Entry("sequential-ik-walk", "ikbench.baselines.sequential_ik:SequentialIKWalk", ("pinocchio",)),
    # other kinematics libraries (baselines/, installed with the [libs] extra)
    Entry("ikpy", "ikbench.baselines.libraries.ikpy_ik:IkpyIK", ("ikpy",)),
    Entry("ikpy-walk", "ikbench.baselines.libraries.ikpy_ik:IkpyWalk", ("ikpy",)),
    Entry("pink", "ikbench.baselines.libraries.pink_ik:PinkIK", ("pink", "qpsolvers", "daqp")),
    Entry("trac-ik", "ikbench.baselines.libraries.trac_ik:TracIK", ("pytracik",)),
    Entry("rtb-lm", "ikbench.baselines.libraries.rtb:RtbLM", ("roboticstoolbox",)),
    Entry("mink", "ikbench.baselines.libraries.mink_ik:MinkIK",
          ("mink", "mujoco", "qpsolvers", "daqp")),
    Entry("drake-ik", "ikbench.baselines.libraries.drake_ik:DrakeIK", ("pydrake",)),
    Entry("drake-trajopt", "ikbench.baselines.libraries.drake_trajopt:DrakeTrajopt",
          ("pydrake",)),
    Entry("pyroki", "ikbench.baselines.libraries.pyroki_trajopt:PyrokiTrajopt",
          ("pyroki", "jax", "jaxls")),
    Entry("rangedik", "ikbench.baselines.libraries.rangedik:RangedIK", ("relaxed_ik_lib",)),
    Entry("placo", "ikbench.baselines.libraries.placo_ik:Placo", ("placo",)),
)


@dataclass
class MethodStatus:
    """A registered method: its class when available, else why not."""

    name: str
    cls: type[Method] | None
    reason: str = ""
    source: str = "built-in"

    @property
    def available(self) -> bool:
        return self.cls is not None


_STATUS: dict[str, MethodStatus] | None = None


def _entries() -> list[tuple[Entry, str]]:
    entries = [(e, "built-in") for e in BUILTIN]
    names = {e.name for e in BUILTIN}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in names:
            continue
        dist = ep.dist.name if ep.dist else "an installed package"
        entries.append((Entry(ep.name, ep.value, (), f"from {dist}"), f"entry point of {dist}"))
        names.add(ep.name)
    return entries


def _load(entry: Entry, source: str) -> MethodStatus:
    missing = [m for m in entry.requires if importlib.util.find_spec(m) is None]
    if missing:
        return MethodStatus(entry.name, None, f"needs {', '.join(missing)} ({entry.install})",
                            source)
    module_name, _, class_name = entry.target.partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except Exception as exc:  # a broken or incomplete module must not break the others
        return MethodStatus(entry.name, None,
                            f"failed to import: {type(exc).__name__}: {exc}", source)
    return MethodStatus(entry.name, cls, "", source)


def method_status() -> dict[str, MethodStatus]:
    """name -> :class:`MethodStatus` of every registered method (built-ins first)."""
    global _STATUS
    if _STATUS is None:
        _STATUS = {entry.name: _load(entry, source) for entry, source in _entries()}
    return _STATUS


def available_methods() -> dict[str, type[Method]]:
    """name -> method class, for every method that can run here (registry order)."""
    return {name: s.cls for name, s in method_status().items() if s.cls is not None}


def get_method(name: str) -> type[Method]:
    """The method class called ``name``; InputError naming the valid ones otherwise."""
    status = method_status()
    cls = status[name].cls if name in status else None
    if cls is not None:
        return cls
    if name in status:
        raise InputError(f"method: {name} is not available here: {status[name].reason}")
    raise InputError(f"method: unknown method {name!r}; available: "
                     f"{', '.join(available_methods())} (ikbench methods lists them all)")


def register(cls: type[M]) -> type[M]:
    """Class decorator kept for methods defined in scripts and notebooks: makes ``cls``
    available by its ``name`` for this process (packages use the entry-point group)."""
    method_status()[cls.name] = MethodStatus(cls.name, cls, "", "registered at run time")
    return cls
