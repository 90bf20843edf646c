"""The statistics and the verdict of ``ikbench recommend``, from the long-form rows.

Per method (:func:`per_method`), pooled over the seeds: success with its Wilson 95 %
interval, per-call p50 and p99 with percentile-bootstrap 95 % intervals (seeded), the first
call, the joint distance of the successes and, where an analytic solver takes the robot, the
share of successes on the nearest branch; per seed: success, p50, p99 and the rank.

The verdict (:func:`decide`) compares intervals, never point estimates alone:

- **budget**: a method is *within* the budget when its p99 interval lies at or below it,
  *misses* it when the interval lies above, and is *uncertain* otherwise; the candidates are
  those within (the uncertain ones only when none is within);
- **dominance** on the two criteria the verdict names, success and the median time per call:
  A dominates B when A is not worse on either (intervals overlap or A leads) and better on
  one outside the intervals;
- **recommended**: of the candidates no other dominates, the most successful (then the
  fastest); **tied**: the candidates that neither succeed more or less often than it by the
  exact sign test on the targets where the two differ nor are faster or slower by the paired
  bootstrap interval of the per-target time ratio (:func:`decide`'s ``pairs``, which
  ``ikbench recommend`` always gives; from a summary alone, those whose success and median
  intervals both overlap its); every other comparison of the recommended method with
  another (as reliable and faster, more successful but slower) is paired in the same way;
  **best** is said only where its success lead over every other candidate is outside the
  intervals;
- **ranking** (:func:`order`), pooled and on each seed alone with that seed's intervals: by
  budget class, then by front of the dominance, then success, then median time; the
  recommended method is the pooled ranking's first; Kendall's tau between the seeds'
  rankings is stated.
"""

from __future__ import annotations

import itertools
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ikbench.core.intervals import (
    RESAMPLES,
    bootstrap_quantiles,
    clearly_above,
    kendall_tau,
    wilson,
)

#: Budget classes, in the order the ranking takes them.
WITHIN, UNCERTAIN, MISSES, FAILED = "within", "uncertain", "misses", "cannot run"
CLASS_ORDER = {WITHIN: 0, UNCERTAIN: 1, MISSES: 2, FAILED: 3}
#: Roles in the table.
RECOMMENDED, TIED = "recommended", "tied"


@dataclass
class Verdict:
    """The decision: ``text`` (markdown), ``table`` (the per-method table, ranked, with each
    one's ``role``), ``recommended`` (None when no method meets the budget), ``tied`` and
    ``kendall_tau`` ("seed a vs seed b" -> tau)."""

    text: str
    table: pd.DataFrame
    recommended: str | None
    tied: list[str]
    kendall_tau: dict[str, float]


def _seed_of(name: str) -> int:
    """The bootstrap's seed for one method (the same every run)."""
    return zlib.crc32(name.encode())


def _budget_class(low_ms: float, high_ms: float, budget_ms: float) -> str:
    if not np.isfinite(high_ms):
        return FAILED
    if high_ms <= budget_ms:
        return WITHIN
    return MISSES if low_ms > budget_ms else UNCERTAIN


def _stats(g: pd.DataFrame, seed: int, resamples: int, budget_ms: float) -> dict[str, float]:
    """Success with its Wilson interval, per-call p50 and p99 with bootstrap intervals and
    the budget class of the rows ``g`` (one method; calls that raised have no time)."""
    ran = g[g["failure"].fillna("").astype(str) == ""]
    ok = g["success"].astype(bool)
    low, high = wilson(int(ok.sum()), len(g))
    q = bootstrap_quantiles(ran["time_s"].to_numpy(dtype=float) * 1000.0, (0.5, 0.99),
                            seed=seed, resamples=resamples)
    return {"success_pct": 100.0 * ok.mean() if len(g) else np.nan,
            "success_low_pct": 100.0 * low, "success_high_pct": 100.0 * high,
            "p50_ms": q[0, 0], "p50_low_ms": q[0, 1], "p50_high_ms": q[0, 2],
            "p99_ms": q[1, 0], "p99_low_ms": q[1, 1], "p99_high_ms": q[1, 2],
            "budget": _budget_class(q[1, 1], q[1, 2], budget_ms) if len(ran) else FAILED}


#: Bootstrap resamples of each seed's own intervals (its ranking; the pooled ones use more).
SEED_RESAMPLES = 1000
#: Columns of a seed's statistics kept in the table (the intervals only rank).
SEED_COLUMNS = ("success_pct", "p50_ms", "p99_ms", "budget")


def per_method(table: pd.DataFrame, info: dict[str, dict], budget_ms: float,
               seeds: Sequence[int]) -> pd.DataFrame:
    """One row per method (see the module docstring) from the rows of every seed, with
    each seed's own statistics (suffix ``_seed<s>``)."""
    rows = []
    for method, g in table.groupby("method", sort=False):
        facts = info.get(method, {})
        failures = g["failure"].fillna("").astype(str)
        ran = failures == ""
        ok = g["success"].astype(bool)
        on = g.loc[ok, "on_nearest_branch"].dropna() if "on_nearest_branch" in g else []
        b_low, b_high = wilson(int(np.sum(on)), len(on))
        first = facts.get("first_call", {})
        row = {
            "method": method, "library": facts.get("library", ""),
            "deterministic": facts.get("deterministic"),  # None: not stated
            "status": "ok" if ran.any() else (failures.iloc[0] or "no call ran"),
            "targets": len(g), "successes": int(ok.sum()),
            **_stats(g, _seed_of(method), RESAMPLES, budget_ms),
            "failed_calls": int((~ran).sum()),
            "first_call_s": first.get("first_call_s", np.nan),
            "first_call_note": first.get("error", ""),
            "joint_distance_median_deg": g.loc[ok, "joint_distance_deg"].median(),
            "nearest_branch_pct": 100.0 * float(np.mean(on)) if len(on) else np.nan,
            "nearest_branch_low_pct": 100.0 * b_low, "nearest_branch_high_pct": 100.0 * b_high,
        }
        for s in seeds:
            part = _stats(g[g["seed"] == s], _seed_of(method) + s, SEED_RESAMPLES, budget_ms)
            row.update({f"{k}_seed{s}": v for k, v in part.items()})
        rows.append(row)
    return pd.DataFrame(rows)


def _interval(row, name: str, suffix: str = "") -> tuple[float, float]:
    unit = "_pct" if name == "success" else "_ms"
    return float(row[f"{name}_low{unit}{suffix}"]), float(row[f"{name}_high{unit}{suffix}"])


def dominates(a, b, suffix: str = "") -> bool:
    """True when method row ``a`` dominates ``b`` on success and median time per call: not
    worse on either (the intervals overlap or ``a`` leads) and better on one outside the
    intervals (``suffix``: one seed's columns, ``_seed<s>``)."""
    sa, sb = _interval(a, "success", suffix), _interval(b, "success", suffix)
    # time: lower is better, so compare the negated intervals
    ta, tb = _interval(a, "p50", suffix), _interval(b, "p50", suffix)
    ta, tb = (-ta[1], -ta[0]), (-tb[1], -tb[0])
    not_worse = not clearly_above(sb, sa) and not clearly_above(tb, ta)
    return not_worse and (clearly_above(sa, sb) or clearly_above(ta, tb))


def order(summary: pd.DataFrame, suffix: str = "") -> list[str]:
    """The methods ranked by the verdict's criterion (best first): by budget class (within,
    uncertain, misses, cannot run); within a class by front (the methods no other of the
    class dominates, then those only the first front dominates, ...); within a front by
    success, then median time. ``suffix``: rank on one seed's columns."""
    ranked: list[str] = []
    rows = {r["method"]: r for _, r in summary.iterrows()}
    for cls in sorted(CLASS_ORDER, key=lambda c: CLASS_ORDER[c]):
        left = [m for m, r in rows.items() if r[f"budget{suffix}"] == cls]
        while left:
            front = [m for m in left if cls == FAILED or not any(
                dominates(rows[o], rows[m], suffix) for o in left if o != m)] or left
            front.sort(key=lambda m: (-np.nan_to_num(rows[m][f"success_pct{suffix}"]),
                                      np.nan_to_num(rows[m][f"p50_ms{suffix}"], nan=np.inf)))
            ranked += front
            left = [m for m in left if m not in front]
    return ranked


def rankings(summary: pd.DataFrame, seeds: Sequence[int]) -> dict[int, list[str]]:
    """Each seed's ranking (:func:`order` on that seed's own statistics) of the methods
    that ran."""
    ran = summary[summary["budget"] != FAILED]
    return {s: order(ran, f"_seed{s}") for s in seeds}


def _pct(row) -> str:
    return (f"{row['success_pct']:.1f} % [{row['success_low_pct']:.1f}, "
            f"{row['success_high_pct']:.1f}]")


def _ms(value: float) -> str:
    return f"{value:.3g}"


def _ms_ci(row, name: str) -> str:
    return f"{_ms(row[f'{name}_ms'])} ms [{_ms(row[f'{name}_low_ms'])}, " \
           f"{_ms(row[f'{name}_high_ms'])}]"


def _ratio(slow: float, fast: float) -> str:
    return f"{slow / fast:.1f}x" if fast > 0 else "many times"


def _names(names: Sequence[str]) -> str:
    return ", ".join(names[:-1]) + f" and {names[-1]}" if len(names) > 1 else names[0]


def decide(summary: pd.DataFrame, budget_ms: float, task: str, robot: str,
           per_seed: int, seeds: Sequence[int],
           pairs: Callable[[str, str], dict] | None = None) -> Verdict:
    """The recommendation, its ties and trade-offs, as a paragraph and a ranked table (see
    the module docstring). ``pairs(a, b)``: the paired comparison of two methods over the
    same targets (:func:`ikbench.studies.recommend.paired`: ``success`` and ``faster`` name
    the winner or say "tie", ``time_ratio`` is b's time per target over a's); with it, every
    statement that compares the recommended method with another is paired, and without it
    (a summary alone) the intervals decide."""
    ranked = order(summary)
    table = summary.set_index("method").loc[ranked].reset_index()
    ranks = rankings(table, seeds)
    for s, seed_order in ranks.items():
        table[f"rank_seed{s}"] = table["method"].map(
            {m: i + 1 for i, m in enumerate(seed_order)})
    table = table.drop(columns=[c for c in table.columns if "_seed" in c and not c.startswith(
        "rank") and not c.startswith(SEED_COLUMNS)])
    taus = {f"seed {a} vs seed {b}": kendall_tau(ranks[a], ranks[b])
            for a, b in itertools.combinations(seeds, 2)}
    table["role"] = table["budget"].map({WITHIN: "", UNCERTAIN: "p99 may pass the budget",
                                         MISSES: "misses the budget at p99",
                                         FAILED: "cannot run"})
    rows = {r["method"]: r for _, r in table.iterrows()}
    candidates = [m for m, r in rows.items() if r["budget"] == WITHIN]
    straddles = not candidates
    if straddles:
        candidates = [m for m, r in rows.items() if r["budget"] == UNCERTAIN]
    kind = {"pose": "6-D pose IK", "position": "position-only IK",
            "path": "pose paths (circles and lines, CppFlow's validity)"}.get(task, task)
    call = "path" if task == "path" else "call"
    unit = "paths" if task == "path" else "targets"
    head = (f"For {kind} on {robot} within {budget_ms:g} ms per {call} at p99 "
            f"({len(seeds)} seeds x {per_seed} {unit}, {len(seeds) * per_seed} in all; 95 % "
            "intervals in brackets)")
    agreement = _agreement(taus, seeds)
    if not candidates:
        ran = [m for m, r in rows.items() if r["budget"] != FAILED]
        text = f"{head}: no method meets the budget."
        if ran:
            fastest = min(ran, key=lambda m: rows[m]["p99_ms"])
            text += (f" The fastest at p99 is {fastest} ({_ms_ci(rows[fastest], 'p99')}); "
                     "give a larger --budget-ms to get a recommendation.")
        return Verdict(" ".join([text, agreement]), table, None, [], taus)
    rec = ranked[0]  # the first front of the candidates' class, most successful first
    r = rows[rec]
    if not any(rows[m]["success_pct"] > 0 for m in rows):
        text = (f"{head}: no method succeeded on any of the {unit}, so there is no "
                "recommendation; the criteria each row failed are in results.csv (on a path: "
                "CppFlow's, self-collision included).")
        return Verdict(" ".join([text, agreement]), table, None, [], taus)
    sentences = [f"{head}: use **{rec}**: success {_pct(r)}, {_ms_ci(r, 'p50')} per {call} at "
                 f"the median, p99 {_ms_ci(r, 'p99')}."]
    if straddles:
        sentences.append(f"No method's p99 is within {budget_ms:g} ms beyond doubt: {rec}'s "
                         "p99 interval straddles the budget.")
    others = [m for m in candidates if m != rec]
    s_rec = _interval(r, "success")
    versus = {m: _versus(rec, m, r, rows[m], pairs) for m in rows
              if m != rec and rows[m]["budget"] != FAILED}
    how = ("paired over the same targets: no difference in success by the sign test nor in "
           "time by the paired bootstrap interval" if pairs is not None
           else "success and median-time intervals overlap")
    if others and all(clearly_above(s_rec, _interval(rows[m], "success")) for m in others):
        among = "whose p99 may meet the budget" if straddles else "within the budget"
        sentences.append(f"{rec} is the best on success among the methods {among}: its lead "
                         "is outside the intervals.")
    tied = [m for m in others if versus[m]["success"] == versus[m]["faster"] == "tie"]
    if tied:
        sentences.append(f"Statistically tied with it ({how}): {_names(tied)}.")
    elif others:
        sentences.append("No other method within the budget is tied with it on both success "
                         "and median time.")
    same = "paired: a tie" if pairs is not None else "intervals overlap"
    slower = [m for m in others if versus[m]["success"] == "tie" and versus[m]["faster"] == rec]
    for m in sorted(slower, key=lambda m: rows[m]["p50_ms"])[:3]:
        sentences.append(f"{rec} is as reliable as {m} ({same}) and "
                         f"{_ratio(rows[m]['p50_ms'], r['p50_ms'])} faster per {call} at the "
                         f"median{versus[m]['ratio_text']}.")
    for m in [m for m in others if versus[m]["success"] == m]:
        sentences.append(f"{m} succeeds more often ({rows[m]['success_pct']:.1f} % vs "
                         f"{r['success_pct']:.1f} %{versus[m]['success_text']}) but is "
                         f"{_ratio(rows[m]['p50_ms'], r['p50_ms'])} slower per {call} at the "
                         "median.")
    faster = [m for m in others if versus[m]["faster"] == m and versus[m]["success"] == rec]
    for m in sorted(faster, key=lambda m: rows[m]["p50_ms"])[:2]:
        sentences.append(f"{m} is {_ratio(r['p50_ms'], rows[m]['p50_ms'])} faster per {call} "
                         f"at the median but succeeds less often ({rows[m]['success_pct']:.1f} "
                         f"% vs {r['success_pct']:.1f} %{versus[m]['success_text']}).")
    may_pass: list[str] = []
    over: list[str] = []
    for m, row in rows.items():
        if m in candidates or row["budget"] == FAILED:
            continue
        if versus[m]["success"] == m:
            how = ("misses" if row["budget"] == MISSES else "may pass (its interval straddles)")
            sentences.append(f"{m} succeeds more often ({row['success_pct']:.1f} % vs "
                             f"{r['success_pct']:.1f} %{versus[m]['success_text']}) but {how} "
                             f"the {budget_ms:g} ms budget at p99 ({_ms_ci(row, 'p99')}).")
        elif versus[m]["success"] == "tie":
            (may_pass if row["budget"] == UNCERTAIN else over).append(m)
    if may_pass:
        sentences.append(f"As reliable ({same}), but with a p99 that may pass the "
                         "budget: " + ", ".join(f"{m} ({_ms_ci(rows[m], 'p99')})"
                                                for m in may_pass) + ".")
    if over:
        sentences.append(f"As reliable ({same}), but over the budget at p99: {_names(over)}.")
    failed = [m for m, row in rows.items() if row["budget"] == FAILED]
    if failed:
        sentences.append(f"Did not run (cannot take the robot, or not within --minutes; the "
                         f"reasons are in the table): {_names(failed)}.")
    sentences.append(agreement)
    table.loc[table["method"] == rec, "role"] = RECOMMENDED
    table.loc[table["method"].isin(tied), "role"] = TIED
    return Verdict(" ".join(sentences), table, rec, tied, taus)


def _versus(rec: str, m: str, r, row, pairs: Callable[[str, str], dict] | None) -> dict:
    """``rec`` against ``m``: ``success`` and ``faster`` (the winner's name or "tie"), paired
    where ``pairs`` is given, else by the intervals (success, median time), and the words the
    verdict adds (the sign test's counts, the paired time ratio)."""
    if pairs is None:
        s_rec, s_m = _interval(r, "success"), _interval(row, "success")
        t_rec, t_m = _interval(r, "p50"), _interval(row, "p50")
        return {"success": rec if clearly_above(s_rec, s_m) else m if clearly_above(s_m, s_rec)
                else "tie",
                "faster": rec if clearly_above(t_m, t_rec) else m if clearly_above(t_rec, t_m)
                else "tie", "success_text": "", "ratio_text": ""}
    pair = pairs(rec, m)
    ratio = pair["time_ratio"]
    ratio_text = (f"; paired, {m}'s time per target is {ratio:.3g}x {rec}'s [95 % "
                  f"{pair['time_ratio_low']:.3g}, {pair['time_ratio_high']:.3g}]"
                  if np.isfinite(ratio) else "")
    return {"success": pair["success"], "faster": pair["faster"],
            "success_text": (f"; paired over {pair['targets']}: {m} alone "
                             f"{pair['second_only']}, {rec} alone {pair['first_only']}, sign "
                             f"test p = {pair['sign_test_p']:.2g}"),
            "ratio_text": ratio_text}


def _agreement(taus: dict[str, float], seeds: Sequence[int]) -> str:
    values = [t for t in taus.values() if np.isfinite(t)]
    if not values:
        return "With fewer than two methods that ran, there is no ranking to compare."
    listed = ", ".join(f"{t:.2f}" for t in taus.values())
    named = ", ".join(map(str, seeds))
    text = ("The ranking by the same criterion (budget at p99, then dominance on success and "
            f"median time, then success) recomputed on each of the seeds {named} agrees with "
            f"Kendall tau {listed} between pairs of seeds (1: the same order)")
    if min(values) < 0.6:
        text += "; below the top it is not stable, so read the ties rather than the order"
    return text + "."
