"""Power by simulation: how many participants the pointing experiment needs.

A simulator ``simulate(n_participants, seed) -> responses`` (responses.csv columns: e.g. the
lead's simulated observers, or any synthetic generator) is run ``repetitions`` times per
sample size and a test ``test(responses) -> p_value`` applied to each; the power is the share
of p < alpha, with its Wilson interval. :func:`false_positive_rate` runs the same on a null
simulator (no effect put in): it should be near alpha.

Ready-made tests: :func:`h1_test` (GP vs P pooled) and :func:`h2_test` (under I, gaze vs
pointing), each by the participant-level Wilcoxon test (fast) or the GEE Wald test, exactly as
:func:`ikbench.experiment.analysis.contrasts` computes them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.intervals import wilson
from ikbench.experiment.analysis import (
    ALPHA,
    gee_contrast,
    gee_share,
    participant_rates,
    wilcoxon_paired,
)

Simulate = Callable[[int, int], pd.DataFrame]
Test = Callable[[pd.DataFrame], float]
METHODS = ("wilcoxon", "gee")


def _answered(responses: pd.DataFrame) -> pd.DataFrame:
    """Non-practice, answered rows with hit / follows_gaze / follows_either (as the analysis
    defines them)."""
    frame = responses[~responses["practice"].astype(bool) & ~responses["timed_out"].astype(bool)]
    answer = frame["answer_target"].astype(float)
    hit = answer == frame["target"].astype(float)
    gaze = answer == frame["gaze_target"].astype(float)
    return pd.DataFrame({"participant": frame["participant"].astype(str).to_numpy(),
                         "cell": frame["cell"].astype(str).to_numpy(),
                         "hit": hit.to_numpy(), "follows_gaze": gaze.to_numpy(),
                         "follows_either": (hit | gaze).to_numpy()})


def _method(method: str) -> str:
    if method not in METHODS:
        raise InputError(f"power test method {method!r}; allowed: {', '.join(METHODS)}")
    return method


def h1_test(responses: pd.DataFrame, method: str = "wilcoxon",
            wilcoxon: str = "auto") -> float:
    """Two-sided p of H1a pooled: GP's hit rate vs P's (every GP* vs every P* cell).

    Args:
        responses: responses.csv rows (practice and timed-out rows are dropped).
        method: "wilcoxon" (participants' paired rates) or "gee" (GEE logistic Wald test).
        wilcoxon: scipy's Wilcoxon method ("auto": exact permutation with ties at n <= 13,
            slow there; "asymptotic": the normal approximation, fast).
    """
    frame = _answered(responses)
    gp = sorted({c for c in frame["cell"] if c.startswith("GP")})
    p = sorted({c for c in frame["cell"] if c.startswith("P")})
    if _method(method) == "gee":
        return float(gee_contrast(frame, gp, p)["p_value"])
    return float(wilcoxon_paired(participant_rates(frame, gp, "hit"),
                                 participant_rates(frame, p, "hit"), wilcoxon)["p_value"])


def h2_test(responses: pd.DataFrame, method: str = "wilcoxon",
            wilcoxon: str = "auto") -> float:
    """Two-sided p of H2 pooled: under I, follows gaze vs follows pointing.

    Args:
        responses: responses.csv rows (practice and timed-out rows are dropped).
        method: "wilcoxon" (participants' paired rates) or "gee" (the share of gaze-following
            among answers that follow either cue, against 0.5).
        wilcoxon: scipy's Wilcoxon method (see :func:`h1_test`).
    """
    frame = _answered(responses)
    ii = sorted({c for c in frame["cell"] if c.startswith("I")})
    if _method(method) == "gee":
        either = frame[frame["cell"].isin(ii) & frame["follows_either"]]
        return float(gee_share(either, "follows_gaze")["p_value"])
    return float(wilcoxon_paired(participant_rates(frame, ii, "follows_gaze"),
                                 participant_rates(frame, ii, "hit"), wilcoxon)["p_value"])


def replicate_seed(seed: int, participants: int, repetition: int) -> int:
    """The simulator's seed of one replicate (independent streams per (seed, n, rep))."""
    return int(np.random.SeedSequence([seed, participants, repetition]).generate_state(1)[0])


def _rejections(simulate: Simulate, test: Test, participants: int, repetitions: int,
                alpha: float, seed: int) -> tuple[int, int, float]:
    """(rejections, failed tests (NaN p), seconds per replicate)."""
    start = time.perf_counter()
    rejected = failed = 0
    for repetition in range(repetitions):
        p = test(simulate(participants, replicate_seed(seed, participants, repetition)))
        if p != p:
            failed += 1
        elif p < alpha:
            rejected += 1
    return rejected, failed, (time.perf_counter() - start) / max(1, repetitions)


def power_curve(simulate: Simulate, test: Test,
                participants: Sequence[int] = (4, 8, 12, 16, 20, 30),
                repetitions: int = 200, alpha: float = ALPHA, seed: int = 0,
                progress: Callable[[int, float], Any] | None = None) -> pd.DataFrame:
    """Power of ``test`` per number of participants.

    Args:
        simulate: ``simulate(n_participants, seed) -> responses`` (responses.csv columns).
        test: ``test(responses) -> p_value`` (a NaN p counts as not rejected, and in
            ``failed``).
        participants: the sample sizes.
        repetitions: simulated studies per sample size.
        alpha: the test's level.
        seed: the base seed (replicate seeds: :func:`replicate_seed`).
        progress: called as ``progress(n_participants, power)`` after each sample size.

    Returns:
        One row per sample size: participants, power, power_ci_low, power_ci_high (Wilson
        95 %), rejections, failed, repetitions, alpha, seconds_per_replicate.
    """
    if repetitions < 1:
        raise InputError(f"repetitions = {repetitions}; allowed: 1 or more")
    rows = []
    for n in participants:
        rejected, failed, seconds = _rejections(simulate, test, int(n), repetitions, alpha,
                                                seed)
        low, high = wilson(rejected, repetitions)
        rows.append({"participants": int(n), "power": rejected / repetitions,
                     "power_ci_low": float(low), "power_ci_high": float(high),
                     "rejections": rejected, "failed": failed, "repetitions": repetitions,
                     "alpha": alpha, "seconds_per_replicate": seconds})
        if progress is not None:
            progress(int(n), rejected / repetitions)
    return pd.DataFrame(rows)


def participants_for_power(curve: pd.DataFrame, target: float = 0.8) -> int | None:
    """The fewest participants of ``curve`` whose power reaches ``target`` (and stays there
    at every larger size); None when none does."""
    ordered = curve.sort_values("participants")
    reached = (ordered["power"] >= target).to_numpy()
    for i in range(len(reached)):
        if reached[i:].all():
            return int(ordered["participants"].iloc[i])
    return None


def false_positive_rate(simulate_null: Simulate, test: Test, n: int = 20,
                        repetitions: int = 200, alpha: float = ALPHA,
                        seed: int = 0) -> pd.DataFrame:
    """The share of null studies (no effect put in) that ``test`` rejects: it should be near
    ``alpha``.

    Returns:
        One row: participants, repetitions, rejections, failed, false_positive_rate, ci_low,
        ci_high (Wilson 95 %), alpha, seconds_per_replicate.
    """
    if repetitions < 1:
        raise InputError(f"repetitions = {repetitions}; allowed: 1 or more")
    rejected, failed, seconds = _rejections(simulate_null, test, n, repetitions, alpha, seed)
    low, high = wilson(rejected, repetitions)
    return pd.DataFrame([{"participants": n, "repetitions": repetitions,
                          "rejections": rejected, "failed": failed,
                          "false_positive_rate": rejected / repetitions,
                          "ci_low": float(low), "ci_high": float(high), "alpha": alpha,
                          "seconds_per_replicate": seconds}])
