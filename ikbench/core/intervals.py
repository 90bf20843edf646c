"""Confidence intervals, rank agreement and paired verdicts for finite samples.

Each statistic is ``scipy.stats``'s; this module fixes the conventions ikbench prints with:

- :func:`wilson`: the Wilson score interval of a success rate (``binomtest(...)
  .proportion_ci(method="wilson")``; good at 0 % and 100 %, where the normal approximation
  gives an empty or negative interval);
- :func:`bootstrap_quantiles`: percentile-bootstrap intervals of quantiles (p50, p99) of a
  sample (``scipy.stats.bootstrap``), seeded so the same sample always gives the same interval;
- :func:`overlap` / :func:`clearly_above`: how two intervals compare (a lead counts only when
  the intervals are disjoint);
- :func:`kendall_tau`: agreement of two rankings of the same items (``scipy.stats.kendalltau``);
- :func:`paired_verdict`: two methods measured on the same items (trajectories, targets): the
  sign test's counts and p (``binomtest``), the Wilcoxon signed-rank p, a seeded bootstrap
  interval of the paired median difference, and "tie" unless both the interval excludes 0 and
  the sign test is significant at :data:`ALPHA`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.stats import binomtest, bootstrap, kendalltau, norm, wilcoxon

#: z of a two-sided 95 % interval.
Z95 = 1.959963984540054
#: Bootstrap resamples (percentile intervals).
RESAMPLES = 2000
#: Significance level of :func:`paired_verdict` (two-sided).
ALPHA = 0.05
#: Paired differences no larger than this are ties of the pair (not counted as higher/lower).
PAIR_TIE = 1e-12


def wilson(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval (low, high) of ``successes`` out of ``trials``, as fractions
    in [0, 1]; (nan, nan) without trials. ``z`` sets the coverage (default 95 %)."""
    if trials <= 0:
        return float("nan"), float("nan")
    level = 2.0 * float(norm.cdf(z)) - 1.0
    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=level,
                                                              method="wilson")
    # exact at the ends (the formula gives 1 - 1e-16 at 100 %)
    low = 0.0 if successes == 0 else max(0.0, float(ci.low))
    high = 1.0 if successes == trials else min(1.0, float(ci.high))
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
    out = np.empty((len(qs), 3))
    out[:, 0] = np.quantile(x, qs)
    if len(x) == 1 or np.all(x == x[0]):  # no spread: scipy refuses a degenerate sample
        out[:, 1] = out[:, 2] = out[:, 0]
        return out
    batch = max(1, 2_000_000 // len(x))  # bounded memory: resample in batches
    for i, q in enumerate(qs):
        result = bootstrap((x,), lambda s, axis, q=q: np.quantile(s, q, axis=axis),
                           n_resamples=resamples, confidence_level=level,
                           method="percentile", vectorized=True, batch=batch,
                           rng=np.random.default_rng(seed))
        out[i, 1] = result.confidence_interval.low
        out[i, 2] = result.confidence_interval.high
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
    items = [m for m in first if m in second]
    if len(items) < 2:
        return float("nan")
    tau = kendalltau([first.index(m) for m in items], [second.index(m) for m in items])
    return float(tau.statistic)


def paired_verdict(a: npt.ArrayLike, b: npt.ArrayLike, names: tuple[str, str],
                   higher_is_better: bool = True, seed: int = 0, resamples: int = RESAMPLES,
                   fmt: str = ".3g") -> dict[str, Any]:
    """Compare two methods measured on the same items (``a[i]`` and ``b[i]`` the same
    trajectory or target; pairs with a NaN are dropped).

    Returns a dict: ``n`` pairs, ``higher`` / ``lower`` / ``equal`` (a above b, below, within
    :data:`PAIR_TIE`), ``sign_p`` (two-sided sign test on the unequal pairs, ``binomtest``),
    ``wilcoxon_p`` (signed-rank; NaN when every pair is equal), ``median_diff`` (median of
    a - b) and its seeded percentile-bootstrap 1 - :data:`ALPHA` interval ``diff_low`` /
    ``diff_high``,
    ``verdict`` ("tie", "a better", "b better"; "better" by ``higher_is_better``: a tie unless
    the interval excludes 0 and the sign test is below :data:`ALPHA`), ``winner`` (the better
    name or None) and ``text``, a sentence such as "ours-lm is higher than sequential-ik on 5 of
    7 (sign test p = 0.45; paired median difference +0.0021, 95 % CI -0.001 to 0.004): a tie".
    """
    x = np.asarray(a, dtype=float).ravel()
    y = np.asarray(b, dtype=float).ravel()
    if x.shape != y.shape:
        raise ValueError(f"paired_verdict: {len(x)} values of {names[0]} against {len(y)} of "
                         f"{names[1]}; the pairs must be the same items")
    keep = np.isfinite(x) & np.isfinite(y)
    d = x[keep] - y[keep]
    n = len(d)
    higher, lower = int(np.sum(d > PAIR_TIE)), int(np.sum(d < -PAIR_TIE))
    equal = n - higher - lower
    sign_p = float(binomtest(higher, higher + lower).pvalue) if higher + lower else 1.0
    if higher + lower:
        wilcoxon_p = float(wilcoxon(d[np.abs(d) > PAIR_TIE]).pvalue)
    else:
        wilcoxon_p = float("nan")
    median = float(np.median(d)) if n else float("nan")
    if n >= 2 and not np.all(d == d[0]):
        ci = bootstrap((d,), lambda s, axis: np.median(s, axis=axis), n_resamples=resamples,
                       confidence_level=1.0 - ALPHA, method="percentile", vectorized=True,
                       rng=np.random.default_rng(seed)).confidence_interval
        low, high = float(ci.low), float(ci.high)
    else:
        low = high = median
    shown = n >= 1 and (low > 0 or high < 0) and sign_p < ALPHA
    if not shown:
        verdict, winner = "tie", None
    else:
        a_better = (median > 0) == higher_is_better
        verdict = "a better" if a_better else "b better"
        winner = names[0] if a_better else names[1]
    counts = f"on {higher} of {n}" + (f" ({equal} equal)" if equal else "")
    text = (f"{names[0]} is higher than {names[1]} {counts} (sign test p = {sign_p:.2g}; "
            f"paired median difference {median:+{fmt}}, 95 % CI {low:{fmt}} to {high:{fmt}})")
    text += ": a tie" if winner is None else f": {winner} is better"
    return {"n": n, "higher": higher, "lower": lower, "equal": equal, "sign_p": sign_p,
            "wilcoxon_p": wilcoxon_p, "median_diff": median, "diff_low": low,
            "diff_high": high, "verdict": verdict, "winner": winner, "text": text}
