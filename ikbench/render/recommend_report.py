"""The files of ``ikbench recommend``, written whole or not at all
(:func:`ikbench.core.io.staged_folder`) into ``OUTPUT/recommend/<robot>/``:

- ``recommend.md``: the verdict, the protocol and the sample (its size and how it was
  sized), the table with its intervals, the figure, the command that reproduces it, the
  machine and the versions;
- ``recommend.csv``: the table, one row per method (the columns of
  :func:`ikbench.studies.verdict.per_method`, each seed's rank, the ``role``);
- ``results.csv``: the raw rows (seed x method x target, ``ikbench ik``'s columns);
- ``pareto.png``: success against the median time per call, 95 % intervals as error bars;
- ``CITATIONS.bib``: ikbench's and each library's own citation
  (``ikbench/data/citations.json``, :func:`bibtex`);
- ``run.json``: settings, plan, per-method facts, Kendall tau, provenance.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.io import atomic_savefig, staged_folder
from ikbench.core.provenance import library_versions, provenance
from ikbench.render.ik_report import robot_slug
from ikbench.render.labels import label_points
from ikbench.render.palette import distinct_colors

FOLDER = "recommend"
#: The budget class of a method no call of which ran (ikbench.studies.verdict.FAILED).
CANNOT_RUN = "cannot run"
#: The study's result (:class:`ikbench.studies.recommend.Recommendation`), taken as it
#: comes (render is below the studies).
Result = Any
FILES = ("recommend.md", "recommend.csv", "results.csv", "pareto.png", "CITATIONS.bib",
         "run.json")


#: Each library's citation (distribution name -> BibTeX), with the libraries it rests on.
CITATIONS = Path(__file__).resolve().parents[1] / "data" / "citations.json"


def bibtex(libraries: Iterable[str]) -> str:
    """The BibTeX of ikbench and of ``libraries`` (distribution names), each once, in order,
    with those they rest on (:data:`CITATIONS`); a library without an entry gets a comment
    saying so."""
    data = json.loads(CITATIONS.read_text(encoding="utf-8"))
    names = list(dict.fromkeys(["ikbench", *libraries]))
    for name in list(names):
        names += [n for n in data["also"].get(name, ()) if n not in names]
    parts = [data["bibtex"].get(name, f"% {name}: no citation known to ikbench; see its "
                                      "project page") for name in names]
    return "\n\n".join(parts) + "\n"


def folder_of(output: str | os.PathLike, robot: Any) -> Path:
    """``output/recommend/<robot>``."""
    return Path(output) / FOLDER / robot_slug(robot)


def write_folder(result: Result, folder: Path, command: str) -> list[Path]:
    """Write every file (see the module docstring) into ``folder``; the paths written."""
    libraries = sorted({f["library"] for f in result.methods.values() if f.get("library")})
    record = _record(result, command, libraries)
    with staged_folder(folder) as tmp:
        result.table.to_csv(tmp / "recommend.csv", index=False, float_format="%.6g")
        rows = result.results
        if "library_ok" in rows:
            rows = rows.astype({"library_ok": "boolean"})
        rows.to_csv(tmp / "results.csv", index=False, float_format="%.17g")
        pareto(result, tmp / "pareto.png")
        (tmp / "CITATIONS.bib").write_text(bibtex(libraries), encoding="utf-8")
        (tmp / "recommend.md").write_text(markdown(result, record), encoding="utf-8")
        (tmp / "run.json").write_text(json.dumps(record, indent=2, default=str) + "\n",
                                      encoding="utf-8")
    return [folder / name for name in FILES]


def _record(result: Result, command: str, libraries: list[str]) -> dict:
    return {"command": command, "robot": result.robot.describe(),
            "settings": asdict(result.settings), "plan": asdict(result.plan),
            "methods": result.methods, "recommended": result.recommended,
            "tied": result.tied, "kendall_tau": result.kendall_tau,
            "paired": result.paired,
            "wall_s": result.wall_s,
            "load_average": {"start": result.load_start,
                             "end": tuple(round(v, 2) for v in os.getloadavg())},
            "library_versions": library_versions(libraries),
            "provenance": provenance(extra=libraries)}


def duration(seconds: float) -> str:
    """``seconds`` in us, ms or s with 3 significant digits ("-" when not finite)."""
    if not np.isfinite(seconds):
        return "-"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if abs(seconds) >= scale or unit == "us":
            break
    return f"{seconds / scale:.3g} {unit}"


def _f(value: float, digits: int = 3) -> str:
    return "-" if value is None or not np.isfinite(value) else f"{value:.{digits}g}"


def _ci(row: pd.Series, name: str, unit: str) -> str:
    v, lo, hi = row[f"{name}_{unit}"], row[f"{name}_low_{unit}"], row[f"{name}_high_{unit}"]
    if not np.isfinite(v):
        return "-"
    if unit == "pct":
        return f"{v:.1f} [{lo:.1f}, {hi:.1f}]"
    return f"{_f(v)} [{_f(lo)}, {_f(hi)}]"


def cannot_run(row: pd.Series) -> str:
    """"cannot run: <reason>" for a method no call of which ran ("not run: ..." as it is),
    "" for one that ran: such a row has no rate, no interval."""
    if row["budget"] != CANNOT_RUN:
        return ""
    status = str(row["status"])
    return status if status.startswith("not run") else f"cannot run: {status}"


def table_lines(result: Result) -> list[str]:
    """The markdown table: one row per method, ranked; a method that cannot run says why
    in place of its rate and intervals."""
    seeds = result.settings.seeds
    lines = ["| method | role | success [%] | per call p50 [ms] | per call p99 [ms] | budget "
             "at p99 | first call [s] | joint distance median [deg] | nearest branch [%] | "
             "rank per seed | failed calls |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, row in result.table.iterrows():
        name = row["method"] + (" (not deterministic)" if row["deterministic"] is False
                                or row["deterministic"] is np.False_ else "")
        first = _f(row["first_call_s"]) if np.isfinite(row["first_call_s"]) else (
            row["first_call_note"] or "-")
        ranks = ", ".join(_f(row.get(f"rank_seed{s}", np.nan)) for s in seeds)
        why = cannot_run(row)
        if why:
            lines.append(f"| {name} | - | {why} | - | - | - | - | - | - | - | "
                         f"{row['failed_calls']} |")
            continue
        status = "" if row["status"] == "ok" else f" ({row['status']})"
        lines.append(
            f"| {name} | {row['role']}{status} | {_ci(row, 'success', 'pct')} "
            f"| {_ci(row, 'p50', 'ms')} | {_ci(row, 'p99', 'ms')} | {row['budget']} "
            f"| {first} | {_f(row['joint_distance_median_deg'])} "
            f"| {_ci(row, 'nearest_branch', 'pct')} | {ranks} | {row['failed_calls']} |")
    return lines


def markdown(result: Result, record: dict) -> str:
    """recommend.md (see the module docstring)."""
    s, robot = result.settings, result.robot
    prov = record["provenance"]
    revision = prov["git_revision"] or prov["packages"].get("ikbench")
    tolerance = f"{s.tolerance_mm:g} mm" + (f" and {s.tolerance_deg:g} deg"
                                            if s.task == "pose" else "")
    versions = record["library_versions"]
    lines = [
        f"# Which IK solver for {robot.name}?",
        "",
        result.verdict,
        "",
        "![success against the median time per call, 95 % intervals](pareto.png)",
        "",
        "## Table",
        "",
        (f"Success: FK through Pinocchio within {tolerance} and within the joint limits, "
         if s.task != "path" else "Success: CppFlow's validity of the whole path, ") +
        "with its Wilson 95 % interval. Per-call p50 and p99: every call's time on the "
        "solver's clock (set-up untimed), with percentile-bootstrap 95 % intervals (2000 "
        f"resamples, seeded). Budget at p99: *within* when the p99 interval is at or below "
        f"{s.budget_ms:g} ms, *misses* when it lies above, *uncertain* when it straddles. "
        "First call: a fresh process's import, set-up and first solve. Joint distance: from "
        "the first initial configuration, successes only. Nearest branch: share of the "
        "successes on the analytic solution nearest to the start (where an analytic solver "
        "takes the robot). Rank per seed: the ranking on each seed alone.",
        "",
        *table_lines(result),
        "",
        "## Protocol and sample",
        "",
        f"Robot: {robot.name} ({robot.dof} joints, {robot.root_link} -> {robot.end_frame}). "
        + (_path_protocol(result) if s.task == "path" else _pose_protocol(result)),
        "",
        f"Wall time of the whole run {result.wall_s:.0f} s ({result.wall_s / 60:.2f} min of "
        f"--minutes {s.minutes:g}" + (f", which it may pass by {result.plan.margin_s:.0f} s"
                                      if result.plan.margin_s else "")
        + "; the writing and the interpreter's start not included).",
        "",
        "Kendall tau between the seeds' rankings: " + ", ".join(
            f"{k}: {_f(v, 2)}" for k, v in result.kendall_tau.items()) + ".",
        "",
        "## Reproduce",
        "",
        f"`{record['command']}`",
        "",
        f"Machine: {prov['cpu']} ({prov['cpu_count']} logical CPUs), {prov['platform']}, "
        f"Python {prov['python']}; ikbench {revision}"
        f"; load average (1, 5, 15 min) at the start {record['load_average']['start']}, at the "
        f"end {record['load_average']['end']} (other jobs slow every timing).",
        "",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items() if v) + ".",
        "",
        "Cite the libraries you use: CITATIONS.bib.",
        "",
    ]
    return "\n".join(lines)


def _pose_protocol(result: Result) -> str:
    s, plan = result.settings, result.plan
    n = plan.targets_per_seed
    cost = ", ".join(f"{m} {duration(c)}" for m, c in plan.cost_s.items())
    compiled = {m: c for m, c in plan.compile_s.items() if c >= 1.0}
    compile_note = (" The first set-ups took longer than the second by " + ", ".join(
        f"{m} {c:.0f} s" for m, c in compiled.items()) + " (a compile, or loading a compiled "
        "cache), spent before the sample was sized and counted in --minutes." if compiled
        else "")
    over = plan.overrun_s
    over_note = (f" The smallest sample did not fit: the run was expected to pass --minutes by "
                 f"about {over:.0f} s beyond its margin." if over > 0 else "")
    return (
        f"Task: {'6-D pose' if s.task == 'pose' else 'position only'}. Targets: FK of "
        "configurations drawn uniformly within the joint limits (every one reachable), "
        f"seeds {', '.join(map(str, s.seeds))}, {n} per seed ({n * len(s.seeds)} per method). "
        f"The deterministic protocol of `ikbench ik`: at most {s.attempts} attempts per target "
        "from a seeded sequence of initial configurations, the same for every method, with no "
        "wall-clock cut (success is a function of the seed and the code; TRAC-IK races its "
        "own timeout and is not deterministic).\n\n"
        f"Sample size: a pilot of {plan.pilot_targets} targets per method (another seed) "
        f"cost per target {cost}; with the set-ups ({sum(plan.setup_s.values()):.0f} s) and "
        f"the first calls (estimated {sum(plan.first_call_estimate_s.values()):.0f} s"
        f"{'' if plan.first_calls_fit else ', measured only as the time allows'}), "
        f"{n} targets per seed fit --minutes {s.minutes:g}: the sample was estimated at "
        f"{plan.sample_estimate_s:.0f} s.{compile_note}{over_note}")


def _path_protocol(result: Result) -> str:
    s, plan = result.settings, result.plan
    n, shape = plan.targets_per_seed, plan.path_shape
    cost = ", ".join(f"{m} {c:.3g} s" if np.isfinite(c) else f"{m} did not finish (stopped)"
                     for m, c in plan.cost_s.items())
    return (
        f"Task: 6-D pose paths of {shape['segments'] + 1} poses, circles and lines "
        "alternating, each from the end-frame pose of a configuration drawn uniformly within "
        "the joint limits (the robot starts there), its orientation held; a circle of radius "
        f"{shape['circle_radius_share']:g} x the reach at the start in the start frame's x-y "
        f"plane, a line of {shape['line_length_share']:g} x the reach along a random "
        "direction. The start is reachable; the rest of a path need not be (no ground truth). "
        f"Seeds {', '.join(map(str, s.seeds))}, {n} paths per seed ({n * len(s.seeds)} per "
        "method). Success: CppFlow's validity of the written trajectory "
        "(ikbench.core.validity). Time: the harness's clock around each solve (set-up "
        "untimed). First calls are not measured for path methods.\n\n"
        f"Sample size: a pilot of one path per method (another seed, set-up included) took "
        f"{cost}; {n} paths per seed fit --minutes {s.minutes:g}: the sample was estimated "
        f"at {plan.sample_estimate_s:.0f} s.")


def pareto(result: Result, path: Path) -> None:
    """Success [%] against the median time per call [ms] (log), 95 % intervals as error
    bars, the recommended method ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    table = result.table[result.table["budget"] != "cannot run"]
    fig, ax = plt.subplots(figsize=(8.5, 5.2))
    palette = distinct_colors(len(table))
    points, names = [], []
    for k, (_, row) in enumerate(table.iterrows()):
        x, y = row["p50_ms"], row["success_pct"]
        # max(0, ...): round-off (a Wilson bound at 100 %), a percentile interval off its
        # estimate
        xerr = [[max(0.0, x - row["p50_low_ms"])], [max(0.0, row["p50_high_ms"] - x)]]
        yerr = [[max(0.0, y - row["success_low_pct"])], [max(0.0, row["success_high_pct"] - y)]]
        marker = "o" if row["budget"] == "within" else "x"
        ax.errorbar(x, y, xerr=xerr, yerr=yerr, fmt=marker, color=palette[k],
                    capsize=3, label=f"{row['method']} (p99 {row['budget']})")
        points.append((x, y))
        names.append(row["method"])
        if row["role"] == "recommended":
            ax.plot(x, y, "o", ms=16, mfc="none", mec="k", label="recommended")
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("time per call, median [ms] (log; 95 % bootstrap interval)")
    ax.set_ylabel("success [%] (95 % Wilson interval)")
    s = result.settings
    ax.set_title(f"{result.robot.name}: {s.task} IK, budget {s.budget_ms:g} ms at p99, "
                 f"{result.plan.targets_per_seed} x {len(s.seeds)} targets (o: p99 within the "
                 "budget, x: not)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    label_points(ax, points, names, palette)  # last: the limits and the layout are set
    atomic_savefig(path, fig)
    plt.close(fig)
