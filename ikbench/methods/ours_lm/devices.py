"""Which solver ``ours-lm`` runs: numpy, numba (compiled), or the torch backend on a device.

``--device`` None (the default) runs on the CPU in float64: ``--lm-backend numpy`` is the
numpy solver (the reference; LAPACK), ``numba`` the same loop compiled (:mod:`.compiled`;
numba is a core dependency), ``auto`` (default) numba when it imports and the settings allow
it, else numpy (:func:`cpu_backend`), said once on stderr (:func:`numpy_fallback`).
``cpu``, ``cuda`` or ``cuda:N`` runs the torch backend
(:mod:`.torch_backend`) there, in ``--dtype`` float64 (default) or float32. Checked when the
settings are made, so a bad choice fails before any work with one line; torch and numba are
imported only when they run.
"""

from __future__ import annotations

import functools
import importlib.util
import re
import sys
from typing import TYPE_CHECKING, Protocol

from ikbench.core.errors import InputError
from ikbench.core.provenance import cpu_model

if TYPE_CHECKING:
    import torch

DTYPES = ("float64", "float32")
BACKENDS = ("auto", "numpy", "numba")
#: How to get numba back (a core dependency since 0.3.0; ``[fast]`` is kept as an alias).
FAST_EXTRA = "pip install -c constraints.txt -e ."
_DEVICE = re.compile(r"^(cpu|cuda(:\d+)?)$")


class BackendSettings(Protocol):
    """The fields of ours-lm's settings (:class:`.settings.LMSettings`) that choose and check
    its solver here (a protocol: this module sits below the settings that import it)."""

    backend: str
    kinematics: str
    linear_solver: str
    dtype: str
    device: str | None
    threads: int | None


def check_device(device: str | None) -> str | None:
    """``device`` if it names a usable torch device (None: the numpy solver).

    Raises:
        InputError: not ``cpu``, ``cuda`` or ``cuda:N``; CUDA asked for where torch has none;
            a CUDA index beyond the devices present.
    """
    if device is None:
        return None
    text = str(device).strip().lower()
    if not _DEVICE.match(text):
        raise InputError(f"--device: {device!r} is not cpu, cuda or cuda:N (N a GPU index); "
                         "leave it out for the numpy solver")
    if text.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise InputError(f"--device {text}: CUDA is not available here (torch "
                             f"{torch.__version__}, {_cuda_build(torch)}); use --device cpu, "
                             "or leave --device out for the numpy solver")
        index = int(text.partition(":")[2] or 0)
        count = torch.cuda.device_count()
        if index >= count:
            raise InputError(f"--device {text}: this machine has {count} CUDA device(s), "
                             f"cuda:0..cuda:{count - 1}")
    return text


def _cuda_build(torch) -> str:
    cuda = getattr(torch.version, "cuda", None)
    return f"built for CUDA {cuda}, no GPU found" if cuda else "a CPU-only build"


def check_backend(settings: BackendSettings) -> None:
    """InputError for settings the chosen solver cannot honour (one line naming the flag)."""
    if settings.dtype not in DTYPES:
        raise InputError(f"--dtype: {settings.dtype!r} is not one of {', '.join(DTYPES)}")
    _check_cpu_backend(settings)
    if settings.device is None:
        if settings.dtype != "float64":
            raise InputError(f"--dtype {settings.dtype}: the numpy solver (no --device) "
                             "computes in float64; add --device cpu or --device cuda for the "
                             "torch backend")
        return
    if settings.kinematics != "numpy":
        raise InputError(f"--lm-kinematics {settings.kinematics}: the torch backend (--device "
                         f"{settings.device}) has its own chain kinematics; leave "
                         "--lm-kinematics out")


def torch_dtype(name: str) -> torch.dtype:
    """``"float32"`` -> ``torch.float32``."""
    import torch

    return {"float32": torch.float32, "float64": torch.float64}[name]


def device_name(device: str) -> str:
    """A readable name of a torch device: the GPU's model, or the CPU's."""
    if device.startswith("cuda"):
        import torch

        return torch.cuda.get_device_name(torch.device(device))

    return cpu_model()


def numba_installed() -> bool:
    """True when numba is installed (found, not imported here)."""
    try:
        return importlib.util.find_spec("numba") is not None
    except (ImportError, ValueError):  # ValueError: sys.modules["numba"] is None
        return False


@functools.cache
def numba_unavailable() -> str | None:
    """Why numba cannot run here (``"numba is not installed"``, or the import's error), or
    None when it imports. Imported once per process, only when ours-lm asks."""
    if not numba_installed():
        return "numba is not installed"
    try:
        import numba  # noqa: F401
    except Exception as error:  # an ImportError, or a broken llvmlite/numpy pairing
        return f"{type(error).__name__}: {error}".splitlines()[0]
    return None


@functools.cache
def numpy_fallback() -> str:
    """The line, said once per process on stderr, that ours-lm runs its numpy reference
    because numba cannot import (and why); returned for the leaderboards' headers."""
    line = (f"ours-lm runs its numpy reference, not the compiled solver: numba cannot import "
            f"({numba_unavailable()}); {FAST_EXTRA}")
    print(line, file=sys.stderr, flush=True)
    return line


def numba_threads() -> int:
    """The threads numba runs on at most (``NUMBA_NUM_THREADS``; all cores by default),
    without importing numba."""
    import os

    value = os.environ.get("NUMBA_NUM_THREADS", "")
    return int(value) if value.isdigit() and int(value) > 0 else (os.cpu_count() or 1)


def torch_threads() -> int:
    """torch's intra-op threads (imports torch: only for the torch backend)."""
    import torch

    return torch.get_num_threads()


def cpu_backend(settings: BackendSettings) -> str:
    """The CPU solver the settings run: ``"numpy"`` or ``"numba"`` (``--device`` None).

    ``auto``: numba when the settings are the compiled loop's (chain kinematics ``numpy``,
    linear solver ``banded``) and it imports, else numpy; numpy because numba cannot import
    is said once on stderr (:func:`numpy_fallback`).
    """
    if settings.backend != "auto":
        return settings.backend
    if settings.kinematics == "numpy" and settings.linear_solver == "banded":
        if numba_unavailable() is None:
            return "numba"
        numpy_fallback()
    return "numpy"


def _check_cpu_backend(settings: BackendSettings) -> None:
    if settings.backend not in BACKENDS:
        raise InputError(f"--lm-backend: {settings.backend!r} is not one of "
                         f"{', '.join(BACKENDS)}")
    threads = settings.threads
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int)
                                or threads < 1):
        raise InputError(f"--lm-threads: {threads!r} must be an integer >= 1")
    if settings.backend != "numba":
        return
    if settings.device is not None:
        raise InputError(f"--lm-backend numba: runs on the CPU; leave out --device "
                         f"{settings.device} (the torch backend), or --lm-backend")
    for flag, value, wanted in (("--lm-kinematics", settings.kinematics, "numpy"),
                                ("--lm-linear-solver", settings.linear_solver, "banded")):
        if value != wanted:
            raise InputError(f"{flag} {value}: the numba backend has its own compiled "
                             f"{wanted} loop; leave {flag} out, or use --lm-backend numpy")
    if not numba_installed():
        raise InputError(f"--lm-backend numba: numba is not installed; {FAST_EXTRA}, or "
                         "use --lm-backend numpy")
