"""The leaderboard of ``ikbench compare``: one table per track, the contract above each, and
``pareto.png``.

Every figure comes from ``results.csv`` (:func:`ikbench.studies.compare.compare`), itself
measured from the trajectory CSVs. A row per method and track: how many trajectories met
each criterion and all of them, the worst pose errors, line distance (mean and max), pointing
(all steps and the judged part), the largest joint step and the speed limit's use, jerk, the
time of one trajectory solved alone (median, min-max over repetitions and trajectories), the
batched time per trajectory where the method batches, and the ratio to the reference method's
single-trajectory time in the same run. When the tasks carry obstacles (``Contract.obstacles``)
each row also counts the trajectories free of collisions (``collisions_count``), the smallest
clearance to the obstacles, whether the method avoids obstacles and the judge's collision
check per trajectory (``collision_check_ms``: one figure for every method, outside every
method's time); the header lists the obstacles, the check's geometry and each method's own
collision avoidance (inside its time). Without obstacles the tables are exactly as before.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ikbench.core.contract import TRACK_TITLES, Contract
from ikbench.core.defaults import PUBLISHED_BACKENDS, REFERENCE_METHOD
from ikbench.core.io import atomic_savefig, atomic_write_csv, atomic_write_text
from ikbench.core.legibility import LEGIBILITY_COLUMNS
from ikbench.core.obstacles import parse_obstacles
from ikbench.render.palette import distinct_colors
from ikbench.render.run_report import _matplotlib
from ikbench.runtime.record import RunFolder

if TYPE_CHECKING:
    from pathlib import Path

    from matplotlib.figure import Figure

#: Criterion -> its short column title.
CRITERION_TITLES = {"start_pose": "start", "end_pose": "touch", "limits": "limits",
                    "speed": "speed", "line": "line", "pointing": "pointing",
                    "collisions": "no collision"}
#: Legibility column -> its title (medians over the trajectories; ikbench.core.legibility).
LEGIBILITY_TITLES = {"position_legibility": "position legibility",
                     "position_inferred_s": "position inferred [s]",
                     "pointing_legibility": "pointing legibility",
                     "pointing_inferred_s": "pointing inferred [s]",
                     "predictability": "predictability",
                     "dimensionless_jerk": "dimensionless jerk",
                     "peak_joint_jerk_deg_s3": "peak joint jerk [deg/s^3]"}


def leaderboard(results: pd.DataFrame, reference: str, contract: Contract) -> pd.DataFrame:
    """One row per track and method (tracks: the contract's and ``touch``)."""
    tracks = list(dict.fromkeys([contract.track, "touch"]))
    ref = results[results["method"] == reference]["time_median_s"].median()
    rows = []
    for track in tracks:
        judged = contract.with_track(track)
        success = "success" if track == contract.track else "success_touch"
        for name, group in results.groupby("method", sort=False):
            rows.append(_board_row(name, group, track, judged, success, ref))
    if contract.obstacles and "collision_check_ms" in results:
        # the judge's check: one computation for every method, so one figure for all (the
        # median over every method's trajectories; results.csv keeps each trajectory's)
        check_ms = results["collision_check_ms"].astype(float).median()
        geometry = "; ".join(sorted(set(results["collision_geometry"].dropna().astype(str))))
        own = results.groupby("method", sort=False)["collision_check_ms"].agg(
            lambda v: v.astype(float).median())
        for row in rows:
            row.update(collision_check_ms=check_ms, collision_geometry=geometry,
                       collision_check_own_ms=float(own[row["method"]]))
    return pd.DataFrame(rows)


def with_first_calls(board: pd.DataFrame, first_calls: dict[str, dict] | None
                     ) -> pd.DataFrame:
    """``board`` with ``first_call_s`` (each method's first call in a fresh process [s],
    ``ikbench compare --first-call``; NaN where it failed or the method did not run), when
    ``first_calls`` is given; unchanged (no column) otherwise."""
    if not first_calls:
        return board
    board = board.copy()
    board["first_call_s"] = board["method"].map(
        {m: t.get("first_call_s", np.nan) for m, t in first_calls.items()}).astype(float)
    return board


def _board_row(name, group, track, judged: Contract, success: str, ref) -> dict:
    solved = group[group["ok_solved"] == True]  # noqa: E712 (object column)
    count = len(group)
    status = sorted(set(group["status"].astype(str)))
    if track != "paper":  # the walk honours the touch-pose-only track
        status = sorted({"solved" if s.startswith("does not honour") else s for s in status})
    library, version = group["library"].iloc[0], group["library_version"].iloc[0]
    row = {"track": track, "method": name,
           "library": library if isinstance(library, str) else "",  # not installed: none
           "version": version if isinstance(version, str) else None,
           "scheme": group["scheme"].dropna().iloc[0] if group["scheme"].notna().any() else "",
           "status": "; ".join(status), "trajectories": count,
           "success_count": int(group[success].astype(bool).sum()),
           "success": float(group[success].astype(bool).mean()) if count else 0.0}
    for criterion in judged.criterion_names():
        if criterion in judged.criteria():
            row[f"{criterion}_count"] = int((group[f"ok_{criterion}"] == True).sum())  # noqa
        else:
            row[f"{criterion}_count"] = np.nan

    def agg(column, how):
        if column not in solved:  # a results.csv from before the column
            return np.nan
        values = solved[column].astype(float).dropna()
        return float(getattr(values, how)()) if len(values) else np.nan

    row.update(start_pose_error_max_deg=agg("start_pose_error_deg", "max"),
               end_pose_error_max_deg=agg("end_pose_error_deg", "max"),
               line_distance_mean_mm=agg("line_distance_mean_mm", "median"),
               line_distance_max_mm=agg("line_distance_max_mm", "max"),
               pointing_deviation_mean_deg=agg("pointing_deviation_mean_deg", "median"),
               pointing_deviation_judged_mean_deg=agg("pointing_deviation_judged_mean_deg",
                                                      "median"),
               max_joint_step_deg=agg("max_joint_step_deg", "max"),
               speed_limit_use=agg("speed_limit_use", "max"),
               mean_sq_jerk_deg2=agg("mean_sq_jerk_deg2", "median"),
               time_median_s=agg("time_median_s", "median"),
               time_min_s=agg("time_min_s", "min"), time_max_s=agg("time_max_s", "max"),
               time_batched_s=agg("time_batched_s", "median"))
    row["time_vs_reference"] = (row["time_median_s"] / ref if ref and ref > 0
                                else np.nan)
    row["note"] = "" if len(solved) else str(group["failure"].iloc[0])
    # after the earlier obstacle-free columns, so older readers keep theirs (as results.csv
    # has them: before the obstacle columns); medians over the trajectories
    row.update({column: agg(column, "median") for column in LEGIBILITY_COLUMNS})
    if judged.obstacles:  # after every obstacle-free column, so those stay as they were
        row.update(min_clearance_mm=agg("min_clearance_mm", "min"),
                   avoids_obstacles=bool(group["avoids_obstacles"].astype(bool).any()))
    return row


def fmt(value: float | None, digits: int = 3) -> str:
    """A number in a precision that shows differences: 3 significant digits, scientific
    below 1e-3 (5.6e-05, not 0.000); NaN as an empty cell."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    value = float(value)
    if value == 0:
        return "0"
    if abs(value) < 1e-3 or abs(value) >= 1e5:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}" if abs(value) < 10 ** digits else f"{value:.0f}"


def _table(board: pd.DataFrame, reference: str, judged: Contract) -> list[str]:
    criteria = judged.criteria()
    head = (["method", "library", "scheme", "status", "success"]
            + [CRITERION_TITLES[c] for c in criteria]
            + ["start err [deg]", "touch err [deg]", "line mean [mm]", "line max [mm]",
               "pointing all [deg]", "pointing judged [deg]", "max step [deg]",
               "speed use", "jerk [deg^2]", "time single [s] median (min-max)",
               "time batched [s]", f"x {reference}"]
            + (["first call [s]"] if "first_call_s" in board else [])
            + list(LEGIBILITY_TITLES.values())
            + (["min clearance [mm]", "avoids obstacles"] if judged.obstacles else [])
            + (["collision check [ms]"] if "collision_check_ms" in board else []))
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for _, row in board.iterrows():
        n = int(row["trajectories"])
        cells = [row["method"], " ".join(v for v in (row["library"], row["version"])
                                          if isinstance(v, str) and v),  # none: not installed
                 str(row["scheme"]), str(row["status"]),
                 f"**{int(row['success_count'])}/{n}**"]
        cells += [f"{int(row[f'{c}_count'])}/{n}" if not pd.isna(row[f"{c}_count"]) else ""
                  for c in criteria]
        time = (f"{fmt(row['time_median_s'])} ({fmt(row['time_min_s'])}-"
                f"{fmt(row['time_max_s'])})" if not pd.isna(row["time_median_s"]) else "")
        cells += [fmt(row["start_pose_error_max_deg"]), fmt(row["end_pose_error_max_deg"]),
                  fmt(row["line_distance_mean_mm"]), fmt(row["line_distance_max_mm"]),
                  fmt(row["pointing_deviation_mean_deg"]),
                  fmt(row["pointing_deviation_judged_mean_deg"]),
                  fmt(row["max_joint_step_deg"]), fmt(row["speed_limit_use"]),
                  fmt(row["mean_sq_jerk_deg2"]), time, fmt(row["time_batched_s"]),
                  fmt(row["time_vs_reference"])]
        if "first_call_s" in board:
            cells.append(fmt(row["first_call_s"]))
        cells += [fmt(row.get(column, np.nan)) for column in LEGIBILITY_TITLES]
        if judged.obstacles:
            cells += [fmt(row["min_clearance_mm"]),
                      "yes" if row["avoids_obstacles"] else "no"]
        if "collision_check_ms" in board:
            cells.append(fmt(row["collision_check_ms"]))
        if row["note"]:
            cells[3] += f": {row['note'][:120]}"
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def leaderboard_markdown(board: pd.DataFrame, record: dict, contract: Contract) -> str:
    """leaderboard.md: per track, the contract in words, then the table."""
    steps = record["steps"]
    unit = "motor deg" if record["robot"].get("pose_unit", "").startswith("motor") else "deg"
    lines = [f"# Leaderboard: {record['robot']['name']}, targets {record['targets']}", "",
             f"{len(record['trajectories'])} trajectories (n = {steps}). Every method "
             "receives the same task contract (`Task.contract`) and is judged by "
             "`ikbench.core.metrics.contract_metrics` from the trajectory CSVs it wrote; "
             "success is never what a method reports. Counts: trajectories meeting each "
             "criterion. Errors are the worst over the trajectories (pose errors, line max, "
             "max step, speed use) or the median (line mean, pointing, jerk). Time single: "
             "one trajectory solved alone, timed by the study harness, median over "
             f"{record['repeat']} repetitions then over the trajectories (min-max over both); "
             "time batched: a batching method's share of one call that solves all "
             f"trajectories; x {record['reference']}: time single over "
             f"`{record['reference']}`'s, measured in the same run. Speed use: the largest "
             "joint step over the step the speed limit allows (1 = at the limit). Legibility, "
             "inferred times, predictability and jerk (`ikbench.core.legibility`, "
             "docs/legibility.md): medians over the trajectories.", ""]
    if "first_call_s" in board:
        lines += [_first_call_paragraph(record.get("first_calls") or {}), ""]
    if record.get("obstacles"):
        lines += _obstacles_paragraph(record["obstacles"])
    lines += collision_check_paragraph(board)
    for track in dict.fromkeys(board["track"]):
        judged = contract.with_track(track)
        lines += [f"## Track `{track}`: {TRACK_TITLES[track]}", "",
                  judged.describe(steps, unit), "",
                  *_table(board[board["track"] == track], record["reference"], judged), ""]
    lines += construction_notes(record)
    lines += [f"Machine: {record['cpu']} ({record['cpu_count']} cores); libraries: "
              + ", ".join(f"{k} {v}" for k, v in record["libraries"].items())
              + f"; ikbench git {record['git_revision']}.", ""]
    return "\n".join(lines)


def _first_call_paragraph(first_calls: dict[str, dict]) -> str:
    """The header's words on the first-call column (``--first-call``) and the split."""
    from ikbench.render.first_call import FIRST_CALL_MEANING

    split = "; ".join(
        f"{m}: failed: {t['error']}" if "error" in t else
        f"{m}: import {fmt(t['import_s'])}, set-up {fmt(t['setup_s'])}, first solve "
        f"{fmt(t['solve_s'])}" for m, t in first_calls.items())
    return (f"{FIRST_CALL_MEANING[0].upper()}{FIRST_CALL_MEANING[1:]}; each method solved the "
            f"first trajectory once on this robot. Split [s]: {split or 'not recorded'}.")


def construction_notes(record: dict) -> list[str]:
    """The header's notes on what a row cannot fail and what runs it: the criteria a scheme
    meets by construction, the methods whose trajectories are one result shown twice, and
    each method's backend (``runtimes``; older run.json files have none of these)."""
    schemes = record.get("schemes") or {}
    track = [m for m, s in schemes.items() if str(s).startswith("track")]
    walk = [m for m, s in schemes.items() if str(s).startswith("walk")]
    lines = []
    if track:
        lines += [f"By construction: the track scheme ({', '.join(track)}) sets the first pose "
                  "to the start pose and the last to the touch pose, so its start and touch "
                  "criteria hold by construction; it is judged on the path between.", ""]
    if walk:
        lines += [f"By construction: the walk ({', '.join(walk)}) sets the last pose to the "
                  "touch pose, so its touch criterion holds by construction.", ""]
    for group in record.get("identical") or []:
        lines += [f"Same trajectories: {' and '.join(group)} produced the same poses on every "
                  "trajectory (within 1e-6 of a pose unit): one result shown "
                  f"{len(group)} times.", ""]
    avoidance = record.get("collision_avoidance") or {}
    if avoidance:
        lines += ["Own collision avoidance, timed as part of the method (its work, inside its "
                  "time single): " + "; ".join(f"{m} {label}" for m, label in avoidance.items())
                  + ".", ""]
    runtimes = record.get("runtimes") or {}
    lines += backend_notes(runtimes)
    if runtimes:
        lines += ["Backends: " + "; ".join(
            f"{m} {r.get('backend')}" + (f" ({r['threads']} thread{'s' * (r['threads'] != 1)})"
                                         if r.get("threads") else "")
            for m, r in runtimes.items()) + ".", ""]
    return lines


def backend_notes(runtimes: dict) -> list[str]:
    """A header paragraph per method that ran on another backend than its published figures
    (:data:`~ikbench.core.defaults.PUBLISHED_BACKENDS`: ours-lm's compiled numba solver):
    ``runtimes`` maps a method to its ``runtime()`` (run.json)."""
    lines = []
    for method, published in PUBLISHED_BACKENDS.items():
        runtime = runtimes.get(method) or {}
        backend = runtime.get("backend")
        if not backend or backend == published:
            continue
        why = f" (numba cannot import: {runtime['numba']})" if runtime.get("numba") else ""
        lines += [f"**{method} ran on {backend}**{why}, not on {published}, the backend of "
                  "the published tables: its times (and, under a time budget, its success) "
                  "are not theirs.", ""]
    return lines


def collision_check_paragraph(board: pd.DataFrame) -> list[str]:
    """The header line on the judge's collision check (boards with ``collision_check_ms``):
    what it checks, that it is the same for every method and outside every method's time, and
    each method's own median as measured (they differ by the clock's noise only)."""
    if "collision_check_ms" not in board or board["collision_check_ms"].isna().all():
        return []
    first = board.iloc[0]
    return [f"Collision check [ms]: the judge's check of one trajectory (every waypoint, every "
            f"checked pair; geometry: {first['collision_geometry']}, coal), the same "
            "computation for every method's trajectory, run after the solve and outside every "
            "method's clock, so no method's time includes it; the column is its median over "
            f"all methods' trajectories; on each method's own: "
            + ", ".join(f"{row['method']} {fmt(row['collision_check_own_ms'])}"
                        for _, row in board.drop_duplicates("method").iterrows()
                        if not pd.isna(row["collision_check_own_ms"]))
            + " (results.csv `collision_check_ms`: each trajectory's).", ""]


def _obstacles_paragraph(obstacles: dict) -> list[str]:
    """The header lines naming the obstacles (run.json's ``obstacles``)."""

    items = parse_obstacles(obstacles["items"], "run.json")
    return [f"Obstacles ({obstacles['source']}), on every task: "
            + "; ".join(o.describe() for o in items) + ". Collisions are judged with the "
            "robot's collision model (docs/collisions.md): \"no collision\" counts the "
            "trajectories with no waypoint in collision with an obstacle or with the robot "
            "itself; min clearance is the smallest signed distance to an obstacle [mm] "
            "(negative: a penetration). Methods that do not avoid obstacles still solve the "
            "tasks; a collision fails their row.", ""]


def plot_pareto(results: pd.DataFrame, sweep: pd.DataFrame | None, contract: Contract
                ) -> Figure:
    """Two panels: time vs line distance (max), and line distance vs pointing (judged part)
    with ours-lm's weight sweep as a curve; one colour per library."""

    plt = _matplotlib()
    fig, (ax_t, ax_p) = plt.subplots(1, 2, figsize=(13, 7.0))
    solved = results[results["ok_solved"] == True]  # noqa: E712
    libraries = list(dict.fromkeys(solved["library"]))
    colors = distinct_colors(len(libraries))
    markers = "osD^v<>pPX*h"
    floor = 1e-7
    for k, (name, group) in enumerate(solved.groupby("method", sort=False)):
        color = colors[libraries.index(group["library"].iloc[0])]
        marker = markers[k % len(markers)]
        line = group["line_distance_max_mm"].astype(float).clip(lower=floor)
        met = group["success"].astype(bool).sum()
        label = f"{name} ({met}/{len(group)} meet the {contract.track} contract)"
        ax_t.scatter(group["time_median_s"], line, color=color, marker=marker, s=22,
                     alpha=0.45)
        ax_t.scatter(group["time_median_s"].median(), line.median(), color=color,
                     marker=marker, s=120, edgecolor="k", label=label)
        if contract.pointing:
            ax_p.scatter(line.median(), group["pointing_deviation_judged_mean_deg"].median(),
                         color=color, marker=marker, s=120, edgecolor="k", label=name)
    if sweep is not None and len(sweep):
        ax_p.plot(sweep["line_distance_max_median_mm"].clip(lower=floor),
                  sweep["pointing_deviation_judged_mean_median_deg"], "-o", color="0.3", ms=4,
                  label="ours-lm weight sweep (c0)")
        for k, (_, row) in enumerate(sweep.iterrows()):
            if k % 2:  # every other label: they would overlap
                continue
            point = (max(row["line_distance_max_median_mm"], floor),
                     row["pointing_deviation_judged_mean_median_deg"])
            ax_p.annotate(f"c0={row['c0']:g}", point, fontsize=7, xytext=(0, -11),
                          textcoords="offset points", ha="center")
    tol = contract.tolerances
    for ax in (ax_t, ax_p):
        ax.grid(alpha=0.3, which="both")
    ax_t.axhline(tol["line_distance_max_mm"], color="r", ls="--", lw=0.8,
                 label=f"line tolerance {tol['line_distance_max_mm']:g} mm")
    ax_t.set_xscale("log")
    ax_t.set_yscale("log")
    ax_t.set_xlabel("time to solve one trajectory alone [s] (median over repetitions)")
    ax_t.set_ylabel("largest distance from the line [mm]")
    ax_t.set_title("Time vs accuracy (small: per trajectory; large: median)", fontsize=10)
    ax_t.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.14), ncol=2,
                frameon=False)
    ax_p.set_xscale("log")
    ax_p.set_xlabel("largest distance from the line [mm] (median over trajectories)")
    ax_p.set_ylabel("pointing deviation, judged part [deg] (median)")
    ax_p.axvline(tol["line_distance_max_mm"], color="r", ls="--", lw=0.8)
    if contract.pointing:
        ax_p.axhline(tol["pointing_judged_mean_deg"], color="r", ls="--", lw=0.8)
    ax_p.set_title("Line vs pointing: the libraries and ours-lm's weight trade-off\n"
                   "(lower left is better; dashed: the tolerances)", fontsize=10)
    ax_p.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.14), ncol=3,
                frameon=False)
    fig.tight_layout()
    return fig


def readme_table(board: pd.DataFrame, reference: str = REFERENCE_METHOD) -> str:
    """The compact table README.md shows, from ``leaderboard.csv``'s rows of the paper's
    track: success per criterion, time single and its ratio, line distance, pointing in the
    judged part, largest step; the first call in a fresh process when measured
    (``--first-call``)."""
    rows = board[board["track"] == "paper"]
    first = "first_call_s" in board
    head = ["method", "scheme", "success", "start", "touch", "speed", "line", "pointing",
            "time single [s]", f"x {reference}", *(["first call [s]"] if first else []),
            "line max [mm]", "pointing judged [deg]", "max step [deg]"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for _, row in rows.iterrows():
        n = int(row["trajectories"])

        def count(criterion, row=row, n=n):
            value = row.get(f"{criterion}_count")
            return "" if pd.isna(value) else f"{int(value)}/{n}"

        lines.append("| " + " | ".join([
            str(row["method"]), str(row["scheme"]) if not pd.isna(row["scheme"]) else "",
            f"**{int(row['success_count'])}/{n}**", count("start_pose"), count("end_pose"),
            count("speed"), count("line"), count("pointing"), fmt(row["time_median_s"]),
            fmt(row["time_vs_reference"]), *([fmt(row["first_call_s"])] if first else []),
            fmt(row["line_distance_max_mm"]),
            fmt(row["pointing_deviation_judged_mean_deg"]),
            fmt(row["max_joint_step_deg"])]) + " |")
    return "\n".join(lines)


def render(folder: str | Path) -> None:
    """Write ``leaderboard.md``, ``leaderboard.csv`` and ``pareto.png`` of a compare folder
    again from its ``results.csv``, ``pareto_sweep.csv`` and ``run.json`` (nothing is solved:
    for a change of presentation only)."""
    from pathlib import Path


    folder = Path(folder)
    record = RunFolder(folder).read_record("leaderboard")
    contract = Contract.from_dict(record.study["contract"])
    results = pd.read_csv(folder / "results.csv", dtype={"trajectory": str})
    sweep_path = folder / "pareto_sweep.csv"
    sweep = pd.read_csv(sweep_path) if sweep_path.exists() else None
    board = with_first_calls(leaderboard(results, record.study["reference"], contract),
                             record.study.get("first_calls"))
    atomic_write_csv(folder / "leaderboard.csv", board, float_format="%.6g")
    atomic_write_text(folder / "leaderboard.md",
                      leaderboard_markdown(board, record.to_dict(), contract))
    atomic_savefig(folder / "pareto.png", plot_pareto(results, sweep, contract))
