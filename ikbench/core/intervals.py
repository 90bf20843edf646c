"""Confidence intervals and rank agreement for finite samples (``ikbench recommend``).

- :func:`wilson`: the Wilson score interval of a success rate (good at 0 % and 100 %, where
  the normal approximation gives an empty or negative interval);
- :func:`bootstrap_quantiles`: percentile-bootstrap intervals of quantiles (p50, p99) of a
  sample, seeded so the same sample always gives the same interval;
- :func:`overlap` / :func:`clearly_above`: how two intervals compare (a lead counts only when
  the intervals are disjoint);
- :func:`kendall_tau`: agreement of two rankings of the same items.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: z of a two-sided 95 % interval.
Z95 = 1.959963984540054
#: Bootstrap resamples (percentile intervals).
RESAMPLES = 2000


def wilson(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval (low, high) of ``successes`` out of ``trials``, as fractions
    in [0, 1]; (nan, nan) without trials."""
    if trials <= 0:
        return float("nan"), float("nan")
    p = successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z * np.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials)) / (1 + z2 / trials)
    # exact at the ends (the formula gives 1 - 1e-16 at 100 %)
    low = 0.0 if successes == 0 else max(0.0, float(centre - half))
    high = 1.0 if successes == trials else min(1.0, float(centre + half))
    return low, high


def bootstrap_quantiles(sample: np.ndarray, quantiles: Sequence[float], seed: int = 0,
                        resamples: int = RESAMPLES, level: float = 0.95) -> np.ndarray:
    """Percentile-bootstrap intervals of the ``quantiles`` (each in [0, 1]) of ``sample``.

    Args:
        sample: (n,) values (NaN dropped).
        quantiles: (q,) which quantiles, e.g. (0.5, 0.99).
        seed: the resampling generator's seed (the same sample gives the same interval).
        resamples: bootstrap resamples.
        level: the interval's coverage.

    Returns:
        (q, 3): each quantile's estimate on the sample, its interval's low and high; NaN for an
        empty sample.
    """
    x = np.asarray(sample, dtype=float)
    x = x[np.isfinite(x)]
    qs = np.asarray(quantiles, dtype=float)
    if not len(x):
        return np.full((len(qs), 3), np.nan)
    rng = np.random.default_rng(seed)
    out = np.empty((len(qs), 3))
    out[:, 0] = np.quantile(x, qs)
    tail = (1.0 - level) / 2.0
    chunk = max(1, 2_000_000 // len(x))  # bounded memory: resample in chunks
    stats = []
    for start in range(0, resamples, chunk):
        draws = rng.integers(0, len(x), (min(chunk, resamples - start), len(x)))
        stats.append(np.quantile(x[draws], qs, axis=1).T)  # (chunk, q)
    stats = np.concatenate(stats)
    out[:, 1] = np.quantile(stats, tail, axis=0)
    out[:, 2] = np.quantile(stats, 1.0 - tail, axis=0)
    return out


def overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """True when the intervals ``a`` = (low, high) and ``b`` share a point."""
    return a[0] <= b[1] and b[0] <= a[1]


def clearly_above(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """True when the interval ``a`` lies wholly above ``b`` (a lead outside the intervals)."""
    return a[0] > b[1]


def kendall_tau(first: Sequence[str], second: Sequence[str]) -> float:
    """Kendall's tau-b between two rankings (best first) of the same items: 1 the same
    order, -1 the reverse; NaN with fewer than two items."""
    from scipy.stats import kendalltau

    items = [m for m in first if m in second]
    if len(items) < 2:
        return float("nan")
    tau = kendalltau([first.index(m) for m in items], [second.index(m) for m in items])
    return float(tau.statistic)
