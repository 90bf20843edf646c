"""Up-front budgets: sizes that allocate are refused before the work starts.

A count, a rate or a grid that would need more memory than is available is refused with the
estimate and the most that fits (``rate_hz: 36,000,001 points need about 134 GiB of memory;
8 GiB are available here: at most 1,073,741 points``). Messages name the field; the CLI names
its option instead.
"""

from __future__ import annotations

from ikbench.core.errors import InputError

#: Share of the memory available now that one command may plan to use.
MEMORY_SHARE = 0.5


def available_memory_bytes() -> int:
    """Memory available now [bytes] (Linux: MemAvailable; elsewhere assumed 4 GiB)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 4 * 2**30


def check_memory(field: str, amount: int, what: str, bytes_each: float) -> None:
    """InputError when ``amount`` ``what`` (``"points"``) of ``bytes_each`` would need more
    than :data:`MEMORY_SHARE` of the available memory; the message gives the estimate and the
    most that fit. ``field`` names the value (the CLI maps it to its option)."""
    need = amount * bytes_each
    budget = MEMORY_SHARE * available_memory_bytes()
    if need > budget:
        most = int(budget // bytes_each)
        raise InputError(f"{field}: {amount:,} {what} need about {_bytes(need)} of memory; "
                         f"{_bytes(budget / MEMORY_SHARE)} are available here: at most "
                         f"{most:,} {what}")


def _bytes(amount: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if amount >= size:
            return f"{amount / size:.3g} {unit}"
    return f"{amount / 1024:.3g} KiB"
