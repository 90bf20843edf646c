"""numba dispatchers that never compile inside a timed call (numba is imported when used).

:func:`compiled_only` is shared by ikbench's compiled solvers and by the library adapters whose
glue is compiled (eaik's branch pass): a timed call of an argument type the warm-up did not
load raises TypeError, and the caller converts its arguments instead.
"""

from __future__ import annotations

from typing import Any


def compiled_only(kernel: Any) -> Any:
    """A dispatcher of ``kernel``'s function that runs the specialisations ``kernel`` has
    compiled (or loaded) when asked, and raises TypeError for any other argument types instead
    of compiling one inside a timed call (``kernel`` itself keeps compiling for its other
    callers)."""
    import numba

    # the kernel's own options (nopython, nogil, ...), so that its cached code is what loads
    dispatcher = numba.jit(cache=True, **kernel.targetoptions)(kernel.py_func)
    for signature in kernel.signatures:
        dispatcher.compile(signature)  # loaded from numba's cache, which kernel has filled
    dispatcher.disable_compile()
    return dispatcher
