"""The paper's claims about its traditional baseline, judged on measured tables.

The paper (Section "Results") says of its traditional baseline: generation is much faster,
the pointing vector is much worse, the start pose varies significantly (constant with ours),
and the fluency is comparable. :func:`check_claims` turns each into a measured ratio and a
stated threshold (:data:`FASTER_FACTOR`, ...), with a verdict *holds* / *does not hold*, from
the per-run summary (:func:`ikbench.paper.baseline_runs.summarise`). Pure functions: tables
in, verdicts and sentences out; reading the run folders is :mod:`ikbench.paper.baseline_runs`'s,
the report :mod:`ikbench.paper.comparison`'s.

Baseline runs are those of the method families :data:`METHOD_FAMILIES`: ``sequential-ik`` /
``sequential-ik-walk`` (e.g. one per ``--orientation`` mode) and ``ikpy`` / ``ikpy-walk``,
the authors' own library (``ikpy-walk --ikpy-orientation position`` is the call they made for
Table 2). Every baseline run states the task it solved, from its scheme (run.json's settings
``scheme``; folders written before the schemes existed have none and are walks):
:data:`SCHEME_TASKS`. The paper's baseline walked back from the touch pose (the start pose is
wherever the walk ends: a touch-pose-only task); a ``track`` run starts at the recorded start
pose and lands on the touch pose (the paper's own task, Sec. 3).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from ikbench.runtime.record import RunRecord

OURS, BASELINE = "ours", "sequential-ik"
#: The paper authors' own baseline library; its runs are baseline runs too.
IKPY = "ikpy"
#: The walk variants of the baselines (the paper's Table 2 scheme: back from the touch pose).
BASELINE_WALK, IKPY_WALK = "sequential-ik-walk", "ikpy-walk"
#: Baseline method -> its family (the registered methods that share options and modes).
METHOD_FAMILIES = {BASELINE: BASELINE, BASELINE_WALK: BASELINE, IKPY: IKPY, IKPY_WALK: IKPY}
#: The scheme of a baseline run whose run.json records none (written before the schemes:
#: every such sequential-ik and ikpy run walked back from the touch pose).
DEFAULT_SCHEME = "walk"
#: Scheme -> (how the run solved it, the task it solved) in words.
SCHEME_TASKS = {
    "walk": ("walk from the touch pose", "touch-pose-only task: the start pose is free"),
    "track": ("track from the start pose", "the paper's task: start and touch poses fixed"),
}
#: The schemes in report order (the paper's Table 2 scheme first).
SCHEME_ORDER = ("walk", "track")
#: "much faster": the median duration of ours is at least this many times the baseline's.
FASTER_FACTOR = 10.0
#: "much worse": the baseline's mean pointing deviation is at least this many times ours.
WORSE_FACTOR = 2.0
#: "constant" start pose: within this many motor degrees of the recorded start pose p^s.
CONSTANT_START_DEG = 1.0
#: "varies": the baseline's median start-pose error is at least this many times ours' largest.
VARIES_FACTOR = 10.0
#: "comparable" fluency: the baseline's median figure is within this factor of ours (either way).
COMPARABLE_FACTOR = 2.0
#: The baseline's orientation modes, in report order, and what each solves per point.
ORIENTATION_MODES = {
    "frame": "goal point, line direction and a fixed roll, the full frame (the paper's text; "
             f"the default of `{BASELINE_WALK}`, and Table 2)",
    "pointing": "goal point and pointing direction, roll free",
    "position": "goal point only (what the authors' ikpy call solved)",
}
#: ikpy's modes (``--ikpy-orientation``), in report order.
IKPY_MODES = {
    "position": "goal point only, by the authors' own call (ikpy's inverse_kinematics_frame "
                f"without orientation_mode; walked, `{IKPY_WALK}`: Table 2 as they ran it)",
    "pointing": "goal point and pointing axis (ikpy's orientation_mode), roll free",
}
#: The baseline method families in report order: the option naming their mode, and their modes.
BASELINE_METHODS = {BASELINE: ("--orientation", ORIENTATION_MODES),
                    IKPY: ("--ikpy-orientation", IKPY_MODES)}


def scheme_of(method: str, record: RunRecord) -> str | None:
    """A run's scheme from its run.json: the settings' ``scheme``, else ``walk`` for the
    baseline families (runs written before the schemes all walked), else None."""
    scheme = record.method_settings().get("scheme")
    if scheme is not None:
        return str(scheme)
    return DEFAULT_SCHEME if METHOD_FAMILIES.get(method, method) in BASELINE_METHODS else None


def task_text(scheme: str | None, short: bool = False) -> str:
    """The task a scheme solves, in words (:data:`SCHEME_TASKS`): ``walk from the touch pose
    (touch-pose-only task: the start pose is free)``; with ``short`` ``walk from the touch
    pose: touch-pose-only task``; "" for None, the scheme itself when unknown."""
    if scheme is None:
        return ""
    if scheme not in SCHEME_TASKS:
        return f"scheme {scheme}"
    how, task = SCHEME_TASKS[scheme]
    return f"{how}: {task.split(':')[0]}" if short else f"{how} ({task})"


def _missing_text(row, name: str) -> str:
    """``sequential-ik: 197 of 350 points missed the IK tolerance`` or "" when unknown."""
    missed = row.get("points missing the IK tolerance", np.nan)
    solved = row.get("points solved", np.nan)
    if pd.isna(missed):
        return ""
    of = f" of {solved:.0f}" if not pd.isna(solved) else ""
    return f"{name}: {missed:.0f}{of} points missed the IK tolerance"


def check_claims(summary: pd.DataFrame, baseline: str = BASELINE,
                 reference: str = OURS, scheme: str | None = None) -> pd.DataFrame:
    """The paper's four claims about its baseline, each with numbers and a verdict.

    Args:
        summary: :func:`summarise` output (one row per run, column ``method``).
        baseline: the baseline run's name (folder) in ``summary``.
        reference: the run of the paper's method (``ours``).
        scheme: the baseline run's scheme (``walk`` / ``track``, :attr:`MethodRun.scheme`):
            the start-pose claim says what it shows for it (a property of the walk; a track
            starts at the recorded start pose by construction). None: not stated.
    """
    ours = summary.set_index("method").loc[reference]
    base = summary.set_index("method").loc[baseline]
    o, b = reference, baseline

    def ratio(a, c):
        return float(a) / float(c) if c else float("inf")

    speed = ratio(ours["median duration [s]"], base["median duration [s]"])
    pointing = ratio(base["mean pointing deviation [deg]"], ours["mean pointing deviation [deg]"])
    start = ratio(base["median |p_0 - p^s| [deg]"], ours["max |p_0 - p^s| [deg]"])
    step = ratio(base["median mean sq. joint step [deg^2]"],
                 ours["median mean sq. joint step [deg^2]"])
    jerk = ratio(base["median mean sq. jerk [deg^2]"], ours["median mean sq. jerk [deg^2]"])

    def comparable(r):
        return 1.0 / COMPARABLE_FACTOR <= r <= COMPARABLE_FACTOR

    line = ""
    if "mean line distance [mm]" in base and "mean line distance [mm]" in ours:
        line = (f"; meanwhile mean line distance: {o} {ours['mean line distance [mm]']:.2f} mm, "
                f"{b} {base['mean line distance [mm]']:.2f} mm")
    missing = _missing_text(base, b)
    claims = [
        ("sequential generation is much faster",
         f"median duration: {o} {ours['median duration [s]']:.3g} s, {b} "
         f"{base['median duration [s]']:.3g} s; ratio {o} / {b} = {speed:.0f}",
         f"ratio >= {FASTER_FACTOR:g}", speed >= FASTER_FACTOR),
        ("its pointing deviation is much worse",
         f"mean pointing deviation: {o} {ours['mean pointing deviation [deg]']:.2f} deg, "
         f"{b} {base['mean pointing deviation [deg]']:.2f} deg; ratio {b} / {o} = "
         f"{pointing:.2f}{line}" + (f"; {missing}" if missing else ""),
         f"ratio >= {WORSE_FACTOR:g}", pointing >= WORSE_FACTOR),
        ("its start pose varies, while ours is constant" + START_CLAIM_NOTES.get(scheme or "", ""),
         f"|p_0 - p^s| [motor deg]: {o} max {ours['max |p_0 - p^s| [deg]']:.3f}, "
         f"{b} median {base['median |p_0 - p^s| [deg]']:.2f} (ratio {start:.0f}); "
         f"spread of start poses over the trajectories: {o} "
         f"{ours['start pose spread [deg]']:.3f} deg, {b} "
         f"{base['start pose spread [deg]']:.2f} deg; of start points: {o} "
         f"{ours['start point spread [mm]']:.2f} mm, {b} "
         f"{base['start point spread [mm]']:.2f} mm; max |P_0 - P_s|: {o} "
         f"{ours['max |P_0 - P_s| [mm]']:.2f} mm, {b} "
         f"{base['max |P_0 - P_s| [mm]']:.2f} mm",
         f"{o} max <= {CONSTANT_START_DEG:g} deg and {b} median >= "
         f"{VARIES_FACTOR:g} x {o} max",
         ours["max |p_0 - p^s| [deg]"] <= CONSTANT_START_DEG and start >= VARIES_FACTOR),
        ("the fluency is comparable",
         f"median mean squared joint step: {o} "
         f"{ours['median mean sq. joint step [deg^2]']:.2f}, {b} "
         f"{base['median mean sq. joint step [deg^2]']:.2f} deg^2 (ratio {step:.2f}); median "
         f"mean squared jerk: {o} {ours['median mean sq. jerk [deg^2]']:.3f}, {b} "
         f"{base['median mean sq. jerk [deg^2]']:.3f} deg^2 (ratio {jerk:.2f})",
         f"both ratios within 1/{COMPARABLE_FACTOR:g} .. {COMPARABLE_FACTOR:g}",
         comparable(step) and comparable(jerk)),
    ]
    return pd.DataFrame(
        [{"paper's claim": c, "measured": m, "criterion": k,
          "verdict": "holds" if ok else "does not hold"} for c, m, k, ok in claims])
#: What the start-pose claim is about for each scheme (appended to the claim).
START_CLAIM_NOTES = {
    "walk": " (a property of the walk: this run walked from the touch pose, a touch-pose-only "
            "task, so its start pose is wherever the walk ends)",
    "track": " (this run tracked from the start pose, the paper's task: it starts at the "
             "recorded start pose by construction, so the claim cannot hold here: it describes "
             "the walk, not point-by-point IK as such)",
}


def pointing_tradeoff_note(summary: pd.DataFrame, baseline: str = BASELINE,
                           reference: str = OURS) -> str:
    """A plain sentence when the baseline points better than ours only by leaving the line
    (its mean line distance at least :data:`WORSE_FACTOR` x ours), else ""."""
    rows = summary.set_index("method")
    ours, base = rows.loc[reference], rows.loc[baseline]
    if "mean line distance [mm]" not in rows.columns:
        return ""
    ours_line, base_line = ours["mean line distance [mm]"], base["mean line distance [mm]"]
    better_pointing = (base["mean pointing deviation [deg]"]
                       < WORSE_FACTOR * ours["mean pointing deviation [deg]"])
    if not (better_pointing and base_line >= WORSE_FACTOR * max(ours_line, 1e-12)):
        return ""
    missing = _missing_text(base, f"`{baseline}`")
    return (f"Why the pointing claim fails for `{baseline}`: damped least squares weighs "
            "metres against radians, and where the target cannot be reached it keeps the "
            f"orientation and gives up the position. Its mean line distance is "
            f"{base_line:.2f} mm against {ours_line:.2f} mm for `{reference}` "
            f"({base_line / max(ours_line, 1e-12):.0f}x)"
            + (f" and {missing.split(': ', 1)[1]}" if missing else "")
            + ": it points along the line without following it, so its small pointing "
            "deviation is not a like-for-like win.")
