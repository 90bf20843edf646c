"""Adapters and their discovery: what each library (or ikbench itself) brings, found by scanning.

An :class:`Adapter` is one library's whole contribution: its name, the Python modules it needs,
its trajectory methods (:class:`~ikbench.methods.base.Method` subclasses) and its single-pose
solvers (:class:`~ikbench.schemes.single_pose.PoseSolver` subclasses, ``ikbench ik``). Each
module of ``ikbench.methods`` (ikbench's own methods) and of ``ikbench.baselines`` (the
checkout's ``baselines/`` folder: one module or package per library) that exports a module
attribute ``ADAPTER`` is found by a scan of those two packages; there is no list of names to
keep. Those modules import their library inside functions only, so scanning them never needs
the library.

A method whose library is missing never breaks another: when a module of ``requires`` is not
installed the adapter's methods and solvers are listed as unavailable with the reason and the
extra to install. A module that fails to import for another reason (a bug, a broken install) is
listed as ``failed to import: <error>``: the two are told apart, so tests skip only the first.
Nothing is scanned until a method is asked for (``ikbench fk`` imports no method at all).

Third parties add adapters in the entry-point group ``ikbench.methods``; the value names an
:class:`Adapter`, a module that exports ``ADAPTER``, or (the older form) a single method class::

    [project.entry-points."ikbench.methods"]
    my-library = "my_package.my_module:ADAPTER"
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import metadata
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypeVar

from ikbench.core.errors import InputError
from ikbench.methods.base import Method, use_catalogue

if TYPE_CHECKING:
    from ikbench.schemes.single_pose import PoseSolver

#: A method class (:func:`register` returns the class it is given).
M = TypeVar("M", bound="Method")

ENTRY_POINT_GROUP = "ikbench.methods"
LIBS_EXTRA = "pip install 'ikbench[libs]'"
#: The packages scanned for modules that export ``ADAPTER``: ikbench's own methods, then the
#: libraries of ``baselines/``.
SCANNED_PACKAGES = ("ikbench.methods", "ikbench.baselines")
#: The rank of an adapter that gives none (after every built-in one).
DEFAULT_RANK = 1000


@dataclass(frozen=True)
class Adapter:
    """What one library (or one of ikbench's own method families) brings.

    Attributes:
        library: the library's name as its users know it (``"ikbench"`` for its own methods).
        requires: import names that must be installed for its methods and solvers to run.
        methods: its trajectory methods, in listing order.
        solvers: its single-pose solvers (``ikbench ik``); each sets its own ``rank``.
        install: how to install what it requires (shown when one is missing).
        rank: listing order of its methods among the adapters' (lower first).
    """

    library: str
    requires: tuple[str, ...] = ()
    methods: tuple[type[Method], ...] = ()
    solvers: tuple[type[PoseSolver], ...] = ()
    install: str = LIBS_EXTRA
    rank: int = DEFAULT_RANK

    def missing(self) -> list[str]:
        """The modules of ``requires`` that are not installed (nothing is imported)."""
        return [m for m in self.requires if importlib.util.find_spec(m) is None]


@dataclass
class MethodStatus:
    """A registered method (or single-pose solver): its class when available, else why not."""

    name: str
    cls: Any
    reason: str = ""
    source: str = "built-in"

    @property
    def available(self) -> bool:
        return self.cls is not None


@dataclass
class _Found:
    adapter: Adapter | None
    source: str
    where: str
    error: str = ""


_FOUND: list[_Found] | None = None
_STATUS: dict[str, MethodStatus] | None = None
_SOLVERS: dict[str, MethodStatus] | None = None


def _import_error(exc: BaseException) -> str:
    return f"failed to import: {type(exc).__name__}: {exc}"


def _scan_package(package: str) -> list[_Found]:
    found = []
    root = importlib.import_module(package)
    for info in pkgutil.iter_modules(root.__path__, f"{package}."):
        if info.name.rpartition(".")[2].startswith("_"):
            continue
        try:
            module = importlib.import_module(info.name)
        except Exception as exc:  # a broken module must not break the others
            found.append(_Found(None, "built-in", info.name, _import_error(exc)))
            continue
        adapter = getattr(module, "ADAPTER", None)
        if isinstance(adapter, Adapter):
            found.append(_Found(adapter, "built-in", info.name))
    return found


def _as_adapter(obj: Any, dist: str) -> Adapter | None:
    """An entry point's object as an adapter: an Adapter, a module exporting one, a method
    class or a single-pose solver class."""
    if isinstance(obj, ModuleType):
        obj = getattr(obj, "ADAPTER", None)
    if isinstance(obj, Adapter):
        return obj
    if isinstance(obj, type) and hasattr(obj, "solve_within"):  # a PoseSolver
        return Adapter(library=dist, solvers=(obj,), install=f"from {dist}")
    if isinstance(obj, type) and hasattr(obj, "solve"):
        return Adapter(library=dist, methods=(obj,), install=f"from {dist}")
    return None


def _scan_entry_points() -> list[_Found]:
    found = []
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist.name if ep.dist else "an installed package"
        source = f"entry point of {dist}"
        try:
            adapter = _as_adapter(ep.load(), dist)
        except Exception as exc:  # a broken plugin must not break the others
            found.append(_Found(None, source, ep.name, _import_error(exc)))
            continue
        if adapter is None:
            found.append(_Found(None, source, ep.name,
                                f"failed to import: {ep.value} is not an ikbench adapter"))
        else:
            found.append(_Found(adapter, source, ep.name))
    return found


def adapters() -> list[Adapter]:
    """Every adapter found (built-in ones by rank, then the entry points' by rank)."""
    return [f.adapter for f in _found() if f.adapter is not None]


def _found() -> list[_Found]:
    global _FOUND
    if _FOUND is None:
        builtin = [f for package in SCANNED_PACKAGES for f in _scan_package(package)]
        builtin.sort(key=lambda f: (f.adapter.rank if f.adapter else DEFAULT_RANK, f.where))
        plugins = _scan_entry_points()
        plugins.sort(key=lambda f: (f.adapter.rank if f.adapter else DEFAULT_RANK, f.where))
        _FOUND = builtin + plugins
    return _FOUND


def _statuses(kind: str) -> dict[str, MethodStatus]:
    rows: dict[str, MethodStatus] = {}
    for found in _found():
        if found.adapter is None:
            name = found.where.rpartition(".")[2]
            if kind == "methods":
                rows.setdefault(name, MethodStatus(name, None, found.error, found.source))
            continue
        adapter = found.adapter
        missing = adapter.missing()
        classes = adapter.methods if kind == "methods" else adapter.solvers
        for cls in classes:
            needs = missing or ([m for m in getattr(cls, "modules", ())
                                 if importlib.util.find_spec(m) is None]
                                if kind == "solvers" else [])
            reason = f"needs {', '.join(needs)} ({adapter.install})" if needs else ""
            rows.setdefault(cls.name, MethodStatus(cls.name, None if needs else cls, reason,
                                                   found.source))
    if kind == "solvers":  # the solvers' own order (their rank), ties by name
        ranked = sorted(rows.values(), key=lambda s: (_solver_rank(s, _found()), s.name))
        rows = {s.name: s for s in ranked}
    return rows


def _solver_rank(status: MethodStatus, found: list[_Found]) -> int:
    for f in found:
        for cls in f.adapter.solvers if f.adapter else ():
            if cls.name == status.name:
                return int(getattr(cls, "rank", DEFAULT_RANK))
    return DEFAULT_RANK


def method_status() -> dict[str, MethodStatus]:
    """name -> :class:`MethodStatus` of every trajectory method (built-ins first)."""
    global _STATUS
    if _STATUS is None:
        _STATUS = _statuses("methods")
    return _STATUS


def solver_status() -> dict[str, MethodStatus]:
    """name -> :class:`MethodStatus` of every single-pose solver (``ikbench ik``), in the
    solvers' rank order."""
    global _SOLVERS
    if _SOLVERS is None:
        _SOLVERS = _statuses("solvers")
    return _SOLVERS


def available_methods() -> dict[str, type[Method]]:
    """name -> method class, for every method that can run here (registry order)."""
    return {name: s.cls for name, s in method_status().items() if s.cls is not None}


def available_solvers() -> dict[str, type[PoseSolver]]:
    """name -> single-pose solver class, for every solver that can run here (rank order)."""
    return {name: s.cls for name, s in solver_status().items() if s.cls is not None}


# base.Method.check_tasks names the methods that can do what another cannot from this catalogue
use_catalogue(lambda: available_methods())


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


def register_solver(cls: type[PoseSolver]) -> type[PoseSolver]:
    """The same for a single-pose solver defined in a script (``ikbench ik`` finds it)."""
    solver_status()[cls.name] = MethodStatus(cls.name, cls, "", "registered at run time")
    return cls


def refresh() -> None:
    """Forget what was found (tests that install an entry point scan again)."""
    global _FOUND, _STATUS, _SOLVERS
    _FOUND = _STATUS = _SOLVERS = None


def parse_names(text: str | Sequence[str] | None, *, solvers: bool = False,
                installed: bool = True, accepts: Callable[[Any], str] | None = None,
                default: Callable[[], list[str]] | None = None,
                option: str = "--methods") -> list[str]:
    """The one parser of a ``--methods`` value: ``"ours-lm,ikpy"`` (or a list) -> names.

    Every study that takes method names calls this with its own rule; the splitting,
    de-duplication and the wording of every refusal are the same everywhere.

    Args:
        text: comma-separated names, a sequence of names, or None (then ``default()``).
        solvers: names of single-pose solvers (``ikbench ik``) instead of trajectory methods.
        installed: each must be available here; False accepts any registered name (``compare``
            reports the missing ones as rows).
        accepts: the study's own rule: the reason an available class cannot take part (an
            empty string when it can), e.g. "cannot follow goal frames ...".
        default: the names when ``text`` is None.
        option: the option named in the messages.

    Raises:
        InputError: no name, an unknown name, one not installed (when ``installed``), or one
            ``accepts`` refuses; the message lists what is allowed.
    """
    table = solver_status() if solvers else method_status()
    if text is None and default is not None:
        return default()
    items = text if isinstance(text, (list, tuple)) else str(text).split(",")
    names = list(dict.fromkeys(str(s).strip() for s in items if str(s).strip()))
    allowed = (f"available: {', '.join(n for n, s in table.items() if s.available)}"
               if installed else f"registered: {', '.join(table)}")
    if not names:
        raise InputError(f"{option}: {text!r} names no method; {allowed}")
    unknown = [n for n in names if n not in table]
    if unknown:
        noun = "single-pose IK method" if solvers else "method"
        raise InputError(f"{option}: unknown {noun}{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(map(repr, unknown))}; {allowed} "
                         "(ikbench methods lists them all)")
    for name in names:
        status = table[name]
        if status.cls is None:
            if installed:
                raise InputError(f"{option}: {name} is not available here: {status.reason}")
            continue
        why = accepts(status.cls) if accepts is not None else ""
        if why:
            raise InputError(f"{option}: {name} {why}")
    return names
