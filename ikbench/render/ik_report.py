"""The files of ``ikbench ik``: results table, targets, leaderboard, figures, provenance.

``OUTPUT/ik/<robot>/`` is written whole or not at all (:func:`ikbench.core.io.staged_folder`):

- ``results.csv`` (``results.parquet`` above :data:`PARQUET_ROWS` rows when pyarrow is
  installed): one row per method x target (:data:`ikbench.studies.ik.COLUMNS`);
- ``targets.csv`` (``targets.parquet`` alike): each target's configuration [pose units],
  end-frame pose (position [mm], rotation matrix) and initial pose;
- ``leaderboard.md``: the task and tolerances, one row per method, the machine and versions;
- ``times.png``: the distribution of per-IK times; ``success_vs_tolerance.png``;
- ``run.json``: command, settings, per-method facts, provenance (machine and versions).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: The study's result (:class:`ikbench.studies.ik.IKResult`): render takes it as it
#: comes, without importing the study (render is below the studies).
StudyResult = Any


PARQUET_ROWS = 50_000
#: Position tolerances [mm] of the success curve.
CURVE_MM = np.geomspace(1e-3, 10.0, 41)


def write_folder(result: StudyResult, folder: Path, command: str = "") -> Path:
    """Write every file (see the module docstring) into ``folder``; return it."""
    from ikbench.core.io import staged_folder

    with staged_folder(folder) as tmp:
        _results(result, tmp)
        _targets(result, tmp)
        summary = summarise(result.table)
        record = _record(result, command)
        (tmp / "leaderboard.md").write_text(leaderboard(result, summary, record),
                                            encoding="utf-8")
        (tmp / "run.json").write_text(json.dumps(record, indent=2, default=str) + "\n",
                                      encoding="utf-8")
        _figures(result, tmp)
    return folder


def parquet(result: StudyResult) -> bool:
    """True when the tables go to Parquet: above :data:`PARQUET_ROWS` result rows, with
    pyarrow installed."""
    import importlib.util

    return len(result.table) > PARQUET_ROWS and importlib.util.find_spec("pyarrow") is not None


def _results(result: StudyResult, tmp: Path) -> None:
    table = result.table.astype({"library_ok": "boolean"})
    if parquet(result):
        table.to_parquet(tmp / "results.parquet", index=False)
    else:
        table.to_csv(tmp / "results.csv", index=False, float_format="%.6g")


def _targets(result: StudyResult, tmp: Path) -> None:
    import pandas as pd

    robot, t = result.robot, result.targets
    columns = {}
    for j, name in enumerate(robot.joint_names):
        columns[f"target_{name}"] = t.q_target[:, j]
    for j, axis in enumerate("xyz"):
        columns[f"{axis}_mm"] = t.T_target[:, j, 3] * 1000.0
    for i in range(3):
        for j in range(3):
            columns[f"R{i}{j}"] = t.T_target[:, i, j]
    for j, name in enumerate(robot.joint_names):
        columns[f"init_{name}"] = t.q_init[:, j]
    frame = pd.DataFrame(columns).rename_axis("target").reset_index()
    if parquet(result):
        frame.to_parquet(tmp / "targets.parquet", index=False)
    else:
        frame.to_csv(tmp / "targets.csv", index=False, float_format="%.10g")


def _record(result: StudyResult, command: str) -> dict:
    from ikbench.core.provenance import library_versions, provenance

    libraries = sorted({m["library"] for m in result.methods.values()})
    import os

    return {"command": command, "robot": result.robot.describe(),
            "settings": asdict(result.settings), "methods": result.methods,
            "library_versions": library_versions(libraries), "wall_s": result.wall_s,
            "load_average": {"start": getattr(result, "load_start", None),
                             "end": tuple(round(v, 2) for v in os.getloadavg())},
            "provenance": provenance(extra=libraries)}


def _load(record: dict) -> str:
    load = record["load_average"]
    return " at the start, ".join(", ".join(f"{v:g}" for v in load[k]) if load[k] else "-"
                                  for k in ("start", "end")) + " at the end"


def _fmt(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def leaderboard(result: StudyResult, summary: pd.DataFrame, record: dict[str, Any]) -> str:
    """leaderboard.md: the task above the table, one row per method (see the module doc)."""
    s, robot = result.settings, result.robot
    prov = record["provenance"]
    kind = ("6-D pose (position and rotation)" if s.kind == "pose"
            else "position only (rotation free)")
    init = ("random (uniform within the limits, seeded, independent of the target)"
            if s.init == "random" else f"nearby (the target's configuration moved by up to "
            f"{s.perturb_deg:g} deg per joint)")
    tolerance = f"{s.tolerance_mm:g} mm" + (f" and {s.tolerance_deg:g} deg"
                                            if s.kind == "pose" else "")
    lines = [
        f"# Single-pose IK: {robot.name}",
        "",
        f"Robot: {robot.name} ({robot.dof} joints, {robot.root_link} -> {robot.end_frame}; "
        f"{robot.config.get('description', '')}). Targets: {s.count}, FK of configurations "
        f"drawn uniformly within the joint limits, seed {s.seed}. Goal: {kind}. Initial "
        f"pose: {init}. **Success**: FK through Pinocchio within {tolerance} and within the "
        "joint limits (the library's own claim is not used). Times: wall time of each call "
        "(`time.perf_counter`, set-up untimed); a batched method solves every target in one "
        "call, and its time per IK is that call's time divided by the targets.",
        "",
        "| method | library | targets | success | time median [ms] | p95 [ms] | max [ms] | "
        "batched time per IK [ms] | position error median [mm] | rotation error median "
        "[deg] | joint distance median [deg] | iterations median | failed calls |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    versions = record["library_versions"]
    for row in summary.itertuples(index=False):
        facts = result.methods[row.method]
        library = f"{facts['library']} {versions.get(facts['library']) or ''}".strip()
        note = "" if facts["deterministic"] else " (not deterministic)"
        lines.append(
            f"| {row.method}{note} | {library} | {row.targets} | {row.success_pct:.2f} % "
            f"| {_fmt(row.time_median_ms)} | {_fmt(row.time_p95_ms)} | {_fmt(row.time_max_ms)} "
            f"| {_fmt(row.batched_time_per_ik_ms)} | {_fmt(row.position_error_median_mm)} "
            f"| {_fmt(row.rotation_error_median_deg)} | {_fmt(row.joint_distance_median_deg)} "
            f"| {_fmt(row.iterations_median)} | {row.failed_calls} |")
    capped = {m: f["count"] for m, f in result.methods.items() if f["count"] < s.count}
    lines += [""]
    if capped:
        lines.append("Capped (`--max-count-per-method`, the first targets only): " + ", ".join(
            f"{m} {n}" for m, n in capped.items()) + ".")
    lines += [
        "Iterations count: " + "; ".join(f"{m}: {f['iterations_are']}"
                                         for m, f in result.methods.items()) + ".",
        "",
        f"Machine: {prov['cpu']} ({prov['cpu_count']} logical CPUs), {prov['platform']}, "
        f"Python {prov['python']}; ikbench {prov['git_revision'] or ''}. Wall time of the run "
        f"{result.wall_s:.0f} s; load average (1, 5, 15 min) {_load(record)} (other jobs on "
        "the machine slow every timing). Versions in run.json.",
        "",
        f"Command: `{record['command']}`" if record["command"] else "",
        "",
        "![per-IK time](times.png) ![success against tolerance](success_vs_tolerance.png)",
        "",
    ]
    return "\n".join(lines)


def _figures(result: StudyResult, tmp: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ikbench.core.io import atomic_savefig

    table, s = result.table, result.settings
    fig, ax = plt.subplots(figsize=(8.5, 4.2))
    for k, (method, g) in enumerate(table.groupby("method", sort=False)):
        color = f"C{k % 10}"
        batch = g["batched_time_per_ik_s"].iloc[0]
        if np.isfinite(batch):
            ax.axvline(batch * 1000.0, color=color, ls="--", label=f"{method} (batched, per IK)")
            continue
        times = np.sort(g["time_s"].to_numpy() * 1000.0)
        ax.step(times, np.arange(1, len(times) + 1) / len(times) * 100.0, where="post",
                color=color, label=method)
    ax.set_xscale("log")
    ax.set_xlabel("time per IK [ms] (log)")
    ax.set_ylabel("calls done within that time [%]")
    ax.set_title(f"{result.robot.name}: per-IK time, {s.count} targets ({s.kind}, {s.init} "
                 "start)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    atomic_savefig(tmp / "times.png", fig)

    ratio = s.tolerance_deg / s.tolerance_mm
    curve = success_curve(table, s.kind, ratio, CURVE_MM)
    fig, ax = plt.subplots(figsize=(8.5, 4.2))
    for k, method in enumerate(curve.columns):
        ax.plot(curve.index, curve[method], color=f"C{k % 10}", label=method)
    ax.axvline(s.tolerance_mm, color="k", ls=":", lw=1, label="stated tolerance")
    ax.set_xscale("log")
    xlabel = "position tolerance [mm] (log)"
    if s.kind == "pose":
        xlabel += f"; rotation tolerance {ratio:g} deg per mm of it"
    ax.set_xlabel(xlabel)
    ax.set_ylabel("success [%]")
    ax.set_ylim(-2, 102)
    ax.set_title(f"{result.robot.name}: success against tolerance")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    atomic_savefig(tmp / "success_vs_tolerance.png", fig)


def summarise(table: pd.DataFrame) -> pd.DataFrame:
    """One row per method: targets, successes, success %, per-IK time median / p95 / max
    [ms] (batched methods: their share, in their own column), errors of the successes,
    joint distance, iterations, failed calls."""
    rows = []
    for method, g in table.groupby("method", sort=False):
        ok = g[g["success"].astype(bool)]
        batched = bool(np.isfinite(g["batched_time_per_ik_s"]).any())
        times = g["time_s"] * 1000.0
        rows.append({
            "method": method, "targets": len(g), "solved": len(ok),
            "success_pct": 100.0 * len(ok) / len(g),
            "time_median_ms": np.nan if batched else times.median(),
            "time_p95_ms": np.nan if batched else times.quantile(0.95),
            "time_max_ms": np.nan if batched else times.max(),
            "batched_time_per_ik_ms": g["batched_time_per_ik_s"].iloc[0] * 1000.0
            if batched else np.nan,
            "position_error_median_mm": ok["position_error_mm"].median(),
            "rotation_error_median_deg": ok["rotation_error_deg"].median(),
            "joint_distance_median_deg": ok["joint_distance_deg"].median(),
            "iterations_median": g["iterations"].median(),
            "failed_calls": int((g["failure"].fillna("") != "").sum()),
        })
    return pd.DataFrame(rows)


def success_curve(table: pd.DataFrame, kind: str, ratio_deg_per_mm: float,
                  tolerances_mm: Iterable[float]) -> pd.DataFrame:
    """Success rate [%] per method at each position tolerance (rotation tolerance scaled
    alike: ``ratio_deg_per_mm`` x it), within the limits; one column per method."""
    out = {}
    for method, g in table.groupby("method", sort=False):
        p = g["position_error_mm"].to_numpy()
        r = g["rotation_error_deg"].to_numpy()
        inside = g["within_limits"].to_numpy(dtype=bool)
        rates = []
        for tol in tolerances_mm:
            ok = inside & (p <= tol)
            if kind == "pose":
                ok &= r <= tol * ratio_deg_per_mm
            rates.append(100.0 * ok.mean())
        out[method] = rates
    return pd.DataFrame(out, index=pd.Index(list(tolerances_mm), name="tolerance_mm"))
