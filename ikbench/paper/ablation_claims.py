"""The paper's claims about its loss terms, checked on an ablation (``ikbench ablate``).

The paper (Results): "avoiding losses L0 or L6 has a devastating effect on the whole movement,
while the ablation of loss L1 moderately affects the pointing behavior. Ablation of L0 causes
the generated trajectory to resemble the linear movement in the angle space; L7 [sic: L6]
causes the robot arm to shake. The losses L2, L3, L4, and L5 [...] we could avoid for
applications where exact start and end poses are not crucial." Each claim becomes a measured
ratio against the full loss with a stated threshold and a verdict.
"""

from __future__ import annotations

import pandas as pd

from ikbench.render.run_report import markdown_table
from ikbench.studies.ablation import FULL, VariantMeans

#: A figure this many times the full loss's is "devastating".
DEVASTATING_FACTOR = 10.0
#: "Moderately affects": at least this factor above the full loss's (and not devastating).
MODERATE_FACTOR = 1.1
#: "Resembles joint-space linear motion": at most this fraction of the full loss's distance.
LINEAR_FRACTION = 0.5
#: "Shakes": at least this many times the full loss's joint-velocity sign changes.
SHAKE_FACTOR = 2.0
#: "Can be dropped": line distance and pointing deviation at most this factor of the full's.
KEEPS_SHAPE_FACTOR = 1.5



def _claim(claim: str, test: str, holds: bool | None, evidence: list[str]) -> dict:
    verdict = "not tested" if holds is None else ("holds" if holds else "does not hold")
    return {"claim": claim, "test": test, "verdict": verdict, "evidence": "; ".join(evidence)}


def check_claims(table: pd.DataFrame) -> list[dict]:
    """The paper's ablation claims, each judged from the table: holds / does not hold.

    Each claim compares a variant's mean over the trajectories with the full loss's on the
    same targets, with the thresholds named in ``test``; ``not tested`` when the variant it
    needs was not run. Returns a list of dicts (claim, test, verdict, evidence).
    """
    m = VariantMeans(table)
    claims = []
    for term in ("L0", "L6"):
        name, test = f"no-{term}", (
            f"line distance or mean squared jerk ≥ {DEVASTATING_FACTOR:g}× the full loss's")
        claim = f"Dropping {term} is devastating for the whole movement."
        if not m.has(FULL, name):
            claims.append(_claim(claim, test, None, [f"run with --drop {term}"]))
            continue
        ratios = [m.ratio(name, "line_distance_mean_mm"), m.ratio(name, "mean_sq_jerk_deg2")]
        claims.append(_claim(claim, test, max(ratios) >= DEVASTATING_FACTOR, [
            m.pair(name, "line_distance_mean_mm"), m.pair(name, "mean_sq_jerk_deg2"),
            m.pair(name, "pointing_deviation_mean_deg")]))

    claim = "Dropping L1 moderately affects the pointing."
    test = (f"pointing deviation ×{MODERATE_FACTOR:g} to ×{DEVASTATING_FACTOR:g} "
            "the full loss's")
    if m.has(FULL, "no-L1"):
        r = m.ratio("no-L1", "pointing_deviation_mean_deg")
        claims.append(_claim(claim, test, MODERATE_FACTOR <= r < DEVASTATING_FACTOR, [
            m.pair("no-L1", "pointing_deviation_mean_deg") + ", "
            + m.rises("no-L1", "pointing_deviation_mean_deg"),
            m.pair("no-L1", "line_distance_mean_mm")]))
    else:
        claims.append(_claim(claim, test, None, ["run with --drop L1"]))

    claim = "Without L0 the trajectory resembles linear motion in joint space."
    test = (f"distance from the joint-space interpolation ≤ {LINEAR_FRACTION:g}× the full "
            "loss's")
    column = "joint_interpolation_distance_deg"
    if m.has(FULL, "no-L0"):
        claims.append(_claim(claim, test, m.ratio("no-L0", column) <= LINEAR_FRACTION, [
            m.pair("no-L0", column) + ", " + m.rises("no-L0", column, lower=True),
            m.pair("no-L0", "line_distance_mean_mm")]))
    else:
        claims.append(_claim(claim, test, None, ["run with --drop L0"]))

    claim = "Without L6 the arm shakes."
    test = f"joint-velocity sign changes ≥ {SHAKE_FACTOR:g}× the full loss's"
    if m.has(FULL, "no-L6"):
        r = m.ratio("no-L6", "velocity_sign_changes", floor=1.0)
        claims.append(_claim(claim, test, r >= SHAKE_FACTOR, [
            m.pair("no-L6", "velocity_sign_changes") + " per trajectory",
            m.pair("no-L6", "mean_sq_jerk_deg2"), m.pair("no-L6", "mean_sq_joint_step_deg2")]))
    else:
        claims.append(_claim(claim, test, None, ["run with --drop L6"]))

    name = "no-L2-L3-L4-L5"
    claim = ("L2, L3, L4 and L5 can be dropped where exact start and end poses are not "
             "crucial.")
    test = (f"line distance and pointing deviation ≤ {KEEPS_SHAPE_FACTOR:g}× the full loss's; "
            "what is lost: start/end errors")
    if m.has(FULL, name):
        shape = ["line_distance_mean_mm", "pointing_deviation_mean_deg"]
        holds = max(m.ratio(name, c) for c in shape) <= KEEPS_SHAPE_FACTOR
        claims.append(_claim(claim, test, holds, [
            m.pair(name, "line_distance_mean_mm"),
            m.pair(name, "pointing_deviation_mean_deg"),
            "lost: " + m.pair(name, "start_point_error_mm"),
            m.pair(name, "end_point_error_mm"), m.pair(name, "start_pose_error_deg"),
            m.pair(name, "end_pose_error_deg")]))
    else:
        claims.append(_claim(claim, test, None, ["run with --drop L2,L3,L4,L5"]))
    return claims


def claims_table(claims: list[dict]) -> str:
    """The claims as a Markdown table (claim, verdict, evidence, test)."""
    frame = pd.DataFrame(claims)[["claim", "verdict", "evidence", "test"]]
    frame["verdict"] = "**" + frame["verdict"] + "**"
    return markdown_table(frame)



QUOTE = (
    "The paper (Results): \"avoiding losses L0 or L6 has a devastating effect on the whole "
    "movement, while the ablation of loss L1 moderately affects the pointing behavior. "
    "Ablation of L0 causes the generated trajectory to resemble the linear movement in the "
    "angle space; L7 [sic: L6, the smoothness term] causes the robot arm to shake. The "
    "losses L2, L3, L4, and L5 [...] we could avoid for applications where exact start and "
    "end poses are not crucial.\" Means over the trajectories:")


def ablation_section(table: pd.DataFrame) -> list[str]:
    """The report section: the paper's words and each claim's verdict."""
    return ["## The paper's claims", "", QUOTE, "", claims_table(check_claims(table)), ""]
