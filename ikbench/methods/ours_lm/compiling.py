"""Saying, once per process, that ours-lm's numba kernels are about to compile.

Imported by the modules that hold kernels (:data:`.devices.COMPILED_MODULES`); it imports
none of ikbench's own modules, so those modules sit above it and below
:mod:`.devices`, which names them.
"""

from __future__ import annotations

import functools
import sys
from types import ModuleType

#: Said once per process before ours-lm's kernels compile (numba's cache holds none of them).
COMPILING = ("compiling ours-lm's kernels once for this machine (minutes on 2 busy cores; later "
             "runs load numba's cache; `ikbench warmup` does it ahead, with progress)")


def say_if_compiling(module: ModuleType) -> bool:
    """Print :data:`COMPILING` on stderr (once per process) when the kernels of ``module``
    (one of :data:`.devices.COMPILED_MODULES`, with the ikbench modules it imports) are about to
    compile: none of them is loaded in this process, and numba's on-disk cache holds a fresh
    index for none of them (an index is written by one numba version and stamped with its
    source file's time and size; a missing or stale one means compiling). A first run on
    this machine, or after a numba upgrade; a source edit that recompiles one file is not
    announced. True when it printed."""
    from numba.core.dispatcher import Dispatcher

    modules = [module] + [v for v in vars(module).values() if isinstance(v, ModuleType)
                          and v.__name__.startswith("ikbench.")]
    kernels = [v for m in modules for v in vars(m).values() if isinstance(v, Dispatcher)
               and v.targetoptions.get("inline") != "always"]
    if not kernels or any(k.signatures or _cached(k) for k in kernels):
        return False
    _say_compiling()
    return True


@functools.cache
def _say_compiling() -> None:
    print(COMPILING, file=sys.stderr, flush=True)


def _cached(dispatcher) -> bool:
    """True when numba's cache index holds a fresh entry for ``dispatcher``."""
    cache = getattr(dispatcher, "_cache", None)
    index = getattr(cache, "_cache_file", None)
    try:
        return bool(index._load_index()) if index is not None else False
    except Exception:  # an unreadable index is recompiled by numba too
        return False
