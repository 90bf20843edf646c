"""Writing the Cartesian path benchmark: trajectories, tables, figures, report, provenance.

``OUTPUT/cartesian/`` gets ``table.csv`` (one row per problem x method x seed),
``summary.csv`` (per problem x method), ``published.csv`` (the published figures of CppFlow and
TORM beside ours, each column labelled with its source; "not found" where none was found),
``<method>/trajectory_<problem>_seed<k>.csv`` (the first seed's, or all),
``pose_path_<problem>.png`` (target and
reached paths of every method's first seed, per-waypoint errors), ``report.md`` and
``run.json``. The folder is replaced whole (:func:`ikbench.core.io.staged_folder`).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.io import atomic_savefig, atomic_write_csv, atomic_write_text, staged_folder
from ikbench.core.problems import BENCHMARK_PROBLEMS, data_dir
from ikbench.core.provenance import provenance
from ikbench.core.trajectory import write_trajectory_csv
from ikbench.core.validity import SOURCE, describe
from ikbench.methods.ours_lm.start_search import REACH_SEEDS, waypoint_reach
from ikbench.methods.registry import get_method
from ikbench.render.first_call import first_call_section
from ikbench.render.leaderboard import backend_notes
from ikbench.render.pose_paths import plot_pose_path, reached
from ikbench.render.run_report import markdown_table
from ikbench.runtime.record import RECORD_FILE, RunRecord, files_written_by, jsonable

#: The study's result (:class:`ikbench.studies.cartesian.CartesianResult`): render takes
#: it as it comes, without importing the study (render is below the studies).
StudyResult = Any

NOT_FOUND = "not found"
#: Published columns: label -> (method, metric) in ikbench/data/cppflow/published.csv.
PUBLISHED = {
    "CppFlow time to valid [s] (Morgan et al., ICRA 2024, arXiv:2309.09102)":
        ("CppFlow", "time to valid solution"),
    "CppFlow success rate (Morgan et al., ICRA 2024)": ("CppFlow", "success rate"),
    "TORM time to valid [s] (Kang et al., IROS 2020)": ("TORM", "time to valid solution"),
    "TORM joint path length [rad] (jstmn/cppflow cppflow/utils.py TORM_TL_RESULTS)":
        ("TORM", "trajectory length (revolute joints)"),
}
IN_SET = "in CppFlow's benchmark set (cppflow/data_type_utils.py ALL_PROBLEM_FILENAMES)"
#: summary.csv's column of TORM's published joint path length, labelled with its source.
TORM_LENGTH = ("TORM joint path length [rad], published (jstmn/cppflow cppflow/utils.py "
               "TORM_TL_RESULTS)")


def torm_lengths() -> dict[str, float]:
    """problem -> TORM's joint path length [rad] (revolute joints) as CppFlow's repository
    records it (``ikbench/data/cppflow/torm_path_lengths.csv``); problems without one are
    left out."""
    table = pd.read_csv(data_dir() / "torm_path_lengths.csv")
    return {str(p): float(v) for p, v in zip(table["problem"],
                                             table["torm_joint_path_length_rad"])
            if not math.isnan(v)}


def published_table(problems: Iterable[str]) -> pd.DataFrame:
    """One row per problem: the published figures, labelled with their source, else
    ``not found`` (never estimated), from ``ikbench/data/cppflow/published.csv``."""
    with open(data_dir() / "published.csv", newline="", encoding="utf-8") as f:
        entries = list(csv.DictReader(f))
    rows = []
    for problem in problems:
        mine = [e for e in entries if e["problem"] == problem]
        row: dict[str, object] = {"problem": problem}
        for label, (method, metric) in PUBLISHED.items():
            hits = [e for e in mine if e["method"] == method and e["metric"] == metric]
            value = hits[0]["value"] if hits else NOT_FOUND
            row[label] = NOT_FOUND if value in ("NOT_FOUND", "NOT_RECORDED") else value
        row[IN_SET] = "yes" if problem in BENCHMARK_PROBLEMS else "no"
        rows.append(row)
    return pd.DataFrame(rows)


TRAJECTORIES = ("first", "all")


def write_folder(result: StudyResult, folder: Path, command: str = "",
                 trajectories: str = "first") -> Path:
    """Write the study's folder whole; return it. ``trajectories``: write the trajectory CSVs
    of the first seed only (``first``; the table names the files written) or of every seed."""
    previous = files_written_by(folder)
    table = result.table.copy()
    keep = [(p, m, s) for (p, m, s) in result.poses
            if trajectories == "all" or s == result.seeds[0]]
    table["trajectory"] = [path if (p, m, s) in keep else "" for p, m, s, path in
                           zip(table["problem"], table["method"], table["seed"],
                               table["trajectory"])]
    summary = summarise(table, getattr(result, "first_calls", {}))
    published = published_table(list(result.problems))
    reach = _reach_notes(result, table)
    with staged_folder(folder, keep=lambda rel: str(rel) not in previous) as tmp:
        files = []
        for problem, method, seed in keep:
            poses = result.poses[(problem, method, seed)]
            robot, task, _ = result.problems[problem]
            rel = f"{method}/trajectory_{problem}_seed{seed}.csv"
            write_trajectory_csv(tmp / rel, robot, poses, quaternion=True)
            files.append(rel)
        for name, frame in (("table.csv", table), ("summary.csv", summary),
                            ("published.csv", published)):
            atomic_write_csv(tmp / name, frame, float_format="%.10g")
            files.append(name)
        figures = {}
        for problem, (robot, task, _) in result.problems.items():
            curves = {m: reached(robot, task, result.poses[(problem, m, result.seeds[0])])
                      for m in result.methods if (problem, m, result.seeds[0]) in result.poses}
            file = f"pose_path_{problem}.png"
            atomic_savefig(tmp / file, plot_pose_path(
                task, curves, f"{problem} ({robot.name}, {task.goal.steps + 1} waypoints): target "
                f"and reached paths, seed {result.seeds[0]}", robot))
            figures[problem] = file
            files.append(file)
        record = RunRecord(
            kind="cartesian", command=command, methods=result.methods,
            settings=jsonable(result.settings),
            files=sorted([*files, "report.md", RECORD_FILE]),
            provenance=provenance(extra=tuple(_libraries(result.methods))),
            study={"problems": {p: str(v[2].source.name) for p, v in result.problems.items()},
                   "seeds": list(result.seeds), "options": result.options,
                   "validity": describe(), "validity_source": SOURCE,
                   "wall_time_s": result.wall_s, "runtimes": result.runtimes,
                   "first_calls": getattr(result, "first_calls", {})})
        atomic_write_text(tmp / RECORD_FILE, record.to_json())
        atomic_write_text(tmp / "report.md", report(result, summary, published, figures,
                                                    reach, record.to_dict()))
    return folder


def _libraries(methods) -> list[str]:

    return sorted({get_method(m).library for m in methods})


def _reach_notes(result, table) -> dict[str, str]:
    """problem -> a sentence on its waypoints that no IK reaches within the limits, for
    problems that no run solved validly (see :func:`.waypoint_reach`)."""
    notes = {}
    for problem, (robot, task, _) in result.problems.items():
        if table[table["problem"] == problem]["valid"].astype(bool).any():
            continue

        position, rotation = waypoint_reach(robot, task)
        out = np.flatnonzero((position >= 0.1) | (rotation >= 0.1))
        if not out.size:
            notes[problem] = ("every waypoint is reachable on its own within the limits; the "
                              "methods did not find a valid path through them")
            continue
        worst = int(out[np.argmax(np.maximum(position[out], rotation[out]))])
        notes[problem] = (
            f"{out.size} of {task.goal.steps + 1} waypoints ({_ranges(out)}) were not reached "
            f"within CppFlow's tolerances by IK from {REACH_SEEDS} seeded random poses each "
            f"within the joint limits (worst: waypoint {worst}, best IK error "
            f"{position[worst]:.3g} mm / {rotation[worst]:.3g} deg): as far as this search "
            "tells, no valid path exists")
    return notes


def _ranges(index) -> str:
    """``3-7, 12`` from sorted integers."""
    parts, start = [], index[0]
    for a, b in zip(index, [*index[1:], None]):
        if b is None or b != a + 1:
            parts.append(f"{start}-{a}" if a != start else f"{a}")
            start = b
    return ", ".join(parts)


def _cell(value, digits=3) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if abs(value) >= 10 ** digits:
        return f"{value:.0f}"
    return f"{value:.{digits}g}"


def report(result: StudyResult, summary: pd.DataFrame, published: pd.DataFrame,
           figures: dict[str, str], reach: dict[str, str], record: dict[str, Any]) -> str:
    """report.md of the study."""
    seeds = ", ".join(map(str, result.seeds))
    lines = [
        "# Cartesian path benchmark: CppFlow / TORM pose paths", "",
        f"Written by `{record['command'] or 'ikbench cartesian'}` (ikbench git "
        f"{record.get('git_revision')}) on {record['cpu']} ({record['cpu_count']} cores, shared "
        f"with other jobs: timings are noisy, compare medians and ratios), torch "
        f"{record['packages'].get('torch')}, Pinocchio {record['packages'].get('pin')}; "
        f"{result.wall_s:.0f} s in all.", "",
        f"Methods: {', '.join(result.methods)} (every method that follows goal frames unless "
        f"chosen); seeds {seeds}; one solve per problem, method and seed, timed by the study "
        "harness (wall time of the method's solve, set-up excluded). Every method stops at its "
        "first valid solution or gives up, so time_to_valid_s is its solve time when valid.", "",
        f"Valid, as CppFlow defines it ({SOURCE}): {describe()}.", "",
        *backend_notes(result.runtimes),
        "## Summary", "",
        "Per problem and method: valid runs of all runs; time to a valid solution [s], median "
        "(min-max) over the valid runs; the worst position [mm] and rotation [deg] errors and "
        "joint change [deg] over all runs; the median joint-space path length [deg, rad] "
        "(revolute joints, changes wrapped, as CppFlow's `path_length_rad`), TORM's published "
        "one (labelled with its source) and the ratio of ours to it.", "",
    ]
    view = summary.copy()
    view["valid"] = [f"{v}/{r}" for v, r in zip(view["valid_runs"], view["runs"])]
    view["time to valid [s]"] = [
        "" if math.isnan(m) else f"{m:.3g} ({lo:.3g}-{hi:.3g})" for m, lo, hi in
        zip(view["time_to_valid_median_s"], view["time_to_valid_min_s"],
            view["time_to_valid_max_s"])]
    columns = ["problem", "method", "valid", "time to valid [s]", "position_error_max_mm",
               "rotation_error_max_deg", "max_joint_change_deg", "max_joint_change_mm",
               "joint_path_length_median_deg", "joint_path_length_median_rad", TORM_LENGTH,
               "joint_path_length_over_torm", "failed_criteria"]
    if "first_call_s" in view:
        view["first call [s]"] = view["first_call_s"]
        columns.insert(4, "first call [s]")
        lines[-1:-1] = ["First call [s]: the method's import, set-up and first solve in a fresh "
                        "process, once per method, one measurement under the machine's load "
                        "(section First call below gives the split).", ""]
    lines += [_markdown(view[columns]), ""]
    lines += first_call_section(getattr(result, "first_calls", {}), "its first problem "
                                f"({next(iter(result.problems), '')}) with seed "
                                f"{result.seeds[0]}")
    if reach:
        lines += ["## Problems without a valid run", ""]
        lines += [f"- **{problem}**: {text}." for problem, text in reach.items()] + [""]
    lines += [
        "## Published figures", "",
        "Figures of CppFlow and TORM for these problems, each in a column labelled with its "
        "source. CppFlow's per-problem results tables (time to a valid solution, success rate) "
        "and TORM's were not found in the sources available to us (the papers' text was "
        "reachable only up to the abstract and introduction; no repository holds the tables): "
        "those cells say so rather than estimate. CppFlow's abstract states valid trajectories "
        "'up to 129x faster than current methods' (not attributed to a problem). TORM's joint "
        "path lengths come from the CppFlow repository ('what torm reports'); compare them with "
        "joint_path_length_median_rad above (revolute joints only).", "",
        _markdown(published), "",
        "## Figures", "",
    ]
    for problem, file in figures.items():
        lines += [f"### {problem}", "", f"![{problem}]({file})", ""]
    lines += ["## Files", "",
              "`table.csv`: one row per problem x method x seed (errors in mm and deg, joint "
              "changes and path lengths in joint degrees and mm, valid, time_to_valid_s, the "
              "failed criteria, a failure message if the solve raised, the trajectory file if "
              "written: the first seed's, or every seed's with --trajectories all); "
              "`summary.csv`: the summary above; `published.csv`: the published figures; "
              "`<method>/trajectory_<problem>_seed<k>.csv`: the poses (joint degrees, mm for "
              "the torso) with the end frame's position [mm] and quaternion (w, x, y, z); "
              "`run.json`: command, settings, versions, machine.", ""]
    return "\n".join(lines)


def _markdown(frame: pd.DataFrame) -> str:
    view = frame.copy()
    for column in view.columns:
        view[column] = [_cell(v) for v in view[column]]
    return markdown_table(view)


def summarise(table: pd.DataFrame, first_calls: dict | None = None) -> pd.DataFrame:
    """One row per problem x method: runs, valid runs, the median (and range) time to a valid
    solution over the valid runs, the median solve time over all runs, the worst errors and
    joint change, the median path length, and beside it TORM's published length (labelled,
    :data:`TORM_LENGTH`) and the ratio of ours to it. With ``first_calls`` (method -> its first
    call in a fresh process, ``ikbench cartesian --first-call``), ``first_call_s`` too (NaN
    for a method whose first call failed)."""
    torm = torm_lengths()
    rows = []
    for (problem, method), group in table.groupby(["problem", "method"], sort=False):
        valid = group[group["valid"].astype(bool)]
        times = valid["time_to_valid_s"]
        length_rad = float(np.radians(group["joint_path_length_deg"].median()))
        rows.append({
            "problem": problem, "method": method, "runs": len(group), "valid_runs": len(valid),
            "time_to_valid_median_s": times.median() if len(valid) else np.nan,
            "time_to_valid_min_s": times.min() if len(valid) else np.nan,
            "time_to_valid_max_s": times.max() if len(valid) else np.nan,
            "duration_median_s": group["duration_s"].median(),
            "joint_path_length_median_rad": length_rad,
            TORM_LENGTH: torm.get(problem, np.nan),
            "joint_path_length_over_torm": length_rad / torm[problem] if problem in torm
            else np.nan,
            "position_error_max_mm": group["position_error_max_mm"].max(),
            "rotation_error_max_deg": group["rotation_error_max_deg"].max(),
            "max_joint_change_deg": group["max_joint_change_deg"].max(),
            "max_joint_change_mm": group["max_joint_change_mm"].max(),
            "joint_path_length_median_deg": group["joint_path_length_deg"].median(),
            "env_collision_runs": int((group["env_collisions"].fillna(0) > 0).sum()),
            "self_collision_runs": int((group["self_collisions"].fillna(0) > 0).sum()),
            "min_clearance_median_mm": group["min_clearance_mm"].median(),
            "avoids_obstacles": bool(group["avoids_obstacles"].iloc[0]),
            "failed_criteria": ", ".join(sorted({c for text in group["failed_criteria"]
                                                 .fillna("") for c in str(text).split(",")
                                                 if c})),
        })
    summary = pd.DataFrame(rows)
    if first_calls:
        summary["first_call_s"] = summary["method"].map(
            {m: t.get("first_call_s", np.nan) for m, t in first_calls.items()}).astype(float)
    return summary
