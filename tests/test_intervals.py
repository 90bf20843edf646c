"""``ikbench.core.intervals``: scipy.stats's Wilson interval against the closed form and the
committed power study's intervals, the bootstrap's seeding, and :func:`paired_verdict`'s
counts, test and tie rule on made-up pairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.core.intervals import Z95, bootstrap_quantiles, paired_verdict, wilson

ROOT = Path(__file__).resolve().parents[1]


def _closed_form(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    p, z2 = k / n, z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * np.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return max(0.0, centre - half), min(1.0, centre + half)


@pytest.mark.parametrize("k,n", [(1, 10), (3, 7), (50, 100), (123, 300), (999, 1000)])
def test_wilson_is_the_closed_form(k, n):
    assert wilson(k, n) == pytest.approx(_closed_form(k, n), abs=1e-12)


def test_wilson_is_exact_at_the_ends_and_nan_without_trials():
    assert wilson(0, 20)[0] == 0.0 and wilson(20, 20)[1] == 1.0
    assert all(np.isnan(wilson(0, 0)))


def test_the_committed_power_intervals_are_recomputed():
    paths = sorted((ROOT / "results/experiment/power").glob("*/power.csv"))
    if not paths:
        pytest.skip("no committed power study")
    for path in paths:
        for _, row in pd.read_csv(path).iterrows():
            low, high = wilson(int(row["rejections"]), int(row["repetitions"]))
            assert (low, high) == pytest.approx((row["power_ci_low"], row["power_ci_high"]),
                                                abs=1e-12), path


def test_bootstrap_of_a_constant_sample_is_the_constant():
    out = bootstrap_quantiles(np.full(10, 2.5), (0.5, 0.99))
    assert np.all(out == 2.5)
    assert np.all(np.isnan(bootstrap_quantiles(np.array([np.nan]), (0.5,))))


def test_paired_verdict_calls_a_small_sample_a_tie():
    # 5 of 7 higher: the sign test's p is 0.45, so no difference is shown
    a = np.array([1.0, 1.1, 1.2, 1.3, 1.4, 0.9, 0.8])
    b = np.array([0.9, 1.0, 1.1, 1.2, 1.3, 1.0, 0.9])
    v = paired_verdict(a, b, ("x", "y"))
    assert (v["higher"], v["lower"], v["n"]) == (5, 2, 7)
    assert v["sign_p"] == pytest.approx(0.453125)
    assert v["verdict"] == "tie" and v["winner"] is None
    assert "on 5 of 7" in v["text"] and v["text"].endswith("a tie")


def test_paired_verdict_shows_a_consistent_lead_and_respects_the_direction():
    rng = np.random.default_rng(0)
    b = rng.normal(size=20)
    a = b + 0.5 + 0.01 * rng.normal(size=20)
    v = paired_verdict(a, b, ("x", "y"))
    assert v["higher"] == 20 and v["sign_p"] < 1e-5 and v["diff_low"] > 0.4
    assert v["winner"] == "x" and v["verdict"] == "a better"
    assert paired_verdict(a, b, ("x", "y"), higher_is_better=False)["winner"] == "y"
    # seeded: the same pairs give the same interval
    assert paired_verdict(a, b, ("x", "y"))["diff_low"] == v["diff_low"]


def test_paired_verdict_counts_equal_pairs_and_refuses_unpaired_lengths():
    v = paired_verdict([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], ("x", "y"))
    assert v["equal"] == 3 and v["verdict"] == "tie" and "(3 equal)" in v["text"]
    with pytest.raises(ValueError, match="same items"):
        paired_verdict([1.0, 2.0], [1.0], ("x", "y"))
