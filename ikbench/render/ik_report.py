"""The files of ``ikbench ik``: results table, targets, leaderboard, figures, provenance.

``OUTPUT/ik/<robot>/`` is written whole or not at all (:func:`ikbench.core.io.staged_folder`):

- ``results.csv`` (``results.parquet`` above :data:`PARQUET_ROWS` rows when pyarrow is
  installed): one row per attempts rule x method x target (:data:`ikbench.studies.ik.COLUMNS`),
  with each answer's joint values ``q0 ..`` in URDF units (named in run.json);
- ``summary.csv``: the leaderboard's figures, one row per attempts rule and method
  (:func:`summarise`).
- ``targets.csv`` (``targets.parquet`` alike): each target's configuration [pose units],
  end-frame pose (position [mm], rotation matrix), initial pose (row 0 of its sequence),
  whether it is reachable, its stress (``sigma_min``, ``limit_margin_deg``) and, where an
  analytic solver takes the robot, its number of branches;
- ``branches.csv``: those branches, one row per target and solution [pose units];
- ``leaderboard.md``: the task, tolerances and protocol (budget, initial configurations,
  attempts rule) above one table per attempts rule, the ground truth (silent failures,
  branches, unreachable targets: :func:`ground_truth_section`), the published figures for the
  robot (labelled as published, with their source), the machine and versions;
- ``times.png``: the distribution of per-call times per rule; ``success_vs_tolerance.png``;
  ``stress.csv`` and ``stress.png``: success and median time per quantile bin of the targets'
  smallest Jacobian singular value;
- ``run.json``: command, settings, per-method facts, batched throughput, the solution
  columns, provenance (machine and versions).
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

from ikbench.baselines.eaik_ik import EaikSolver
from ikbench.baselines.trac_ik import TracIKSolver
from ikbench.core.io import atomic_savefig, staged_folder
from ikbench.core.provenance import library_versions, provenance
from ikbench.render.first_call import first_call_table
from ikbench.render.ik_published import published_for
from ikbench.render.leaderboard import backend_notes
from ikbench.render.palette import distinct_colors

#: The study's result (:class:`ikbench.studies.ik.IKResult`): render takes it as it
#: comes, without importing the study (render is below the studies).
StudyResult = Any


PARQUET_ROWS = 50_000
#: Position tolerances [mm] of the success curve.
CURVE_MM = np.geomspace(1e-3, 10.0, 41)
#: The attempts rule that restarts until success or the budget.
AUTO = "auto"


def robot_slug(robot: Any) -> str:
    """The robot's folder name (its name, without a package prefix)."""
    return str(robot.name).split(":")[-1].replace("/", "_")


def write_folder(result: StudyResult, folder: Path, command: str = "") -> Path:
    """Write every file (see the module docstring) into ``folder``; return it."""

    with staged_folder(folder) as tmp:
        _results(result, tmp)
        _targets(result, tmp)
        summary = with_bare_calls(summarise(result.table, result.batches,
                                            first_calls(result.methods)), result.methods)
        model = getattr(result, "init_model", None)
        if model:  # --init learned: the model's figures in every row (the same starts)
            for key in ("model_query_ms", "model_error_mm", "model_error_deg",
                        "training_samples", "training_cpu_min", "model_file"):
                summary[key] = model[key]
        summary.to_csv(tmp / "summary.csv", index=False, float_format="%.6g")
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
        table.to_csv(tmp / "results.csv", index=False, float_format="%.17g")


def _targets(result: StudyResult, tmp: Path) -> None:
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
    if t.reachable is not None:
        columns["reachable"] = t.reachable
    if getattr(t, "unreachable_kind", None) is not None:
        columns["unreachable_kind"] = t.unreachable_kind
    if t.sigma_min is not None and t.limit_margin_deg is not None:
        columns["sigma_min"], columns["limit_margin_deg"] = t.sigma_min, t.limit_margin_deg
    if t.branches is not None:
        columns["branches"] = [len(b) for b in t.branches]
        branches_frame(t.branches).to_csv(tmp / "branches.csv", index=False,
                                          float_format="%.17g")
    frame = pd.DataFrame(columns).rename_axis("target").reset_index()
    if parquet(result):
        frame.to_parquet(tmp / "targets.parquet", index=False)
    else:
        frame.to_csv(tmp / "targets.csv", index=False, float_format="%.17g")


def branches_frame(sets: list[np.ndarray]) -> pd.DataFrame:
    """branches.csv: one row per target and analytic branch (``target``, ``branch``, ``q0``
    ...) [pose units]."""
    rows = [(k, b, *q) for k, found in enumerate(sets) for b, q in enumerate(found)]
    dof = max((s.shape[1] for s in sets), default=0)
    return pd.DataFrame(rows, columns=["target", "branch", *[f"q{j}" for j in range(dof)]])


def _record(result: StudyResult, command: str) -> dict:

    robot = result.robot
    libraries = sorted({m["library"] for m in result.methods.values()})
    units = ["m" if p else "rad" for p in robot.prismatic]
    return {"command": command, "robot": robot.describe(),
            "settings": asdict(result.settings), "methods": result.methods,
            "batched": result.batches, "init_model": getattr(result, "init_model", None),
            "solution_columns": {f"q{j}": {"joint": name, "unit": unit}
                                 for j, (name, unit) in enumerate(zip(robot.joint_names,
                                                                      units))},
            "library_versions": library_versions(libraries), "wall_s": result.wall_s,
            "load_average": {"start": getattr(result, "load_start", None),
                             "end": tuple(round(v, 2) for v in os.getloadavg())},
            "provenance": provenance(extra=libraries)}


def _load(record: dict) -> str:
    load = record["load_average"]
    return " at the start, ".join(", ".join(f"{v:g}" for v in load[k]) if load[k] else "-"
                                  for k in ("start", "end")) + " at the end"


def _cell(text: str, limit: int = 160) -> str:
    """Text for one markdown table cell: on one line, ``|`` escaped, at most ``limit``
    characters."""
    text = " ".join(str(text).split()).replace("|", "\\|")
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _fmt(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def rule_title(rule: str, auto_rows: int, runs: int = 1) -> str:
    """The heading of one attempts rule's table (``runs``: how often it was run)."""
    if rule == AUTO:
        repeated = (f"median of {runs} runs on the same targets and rows, their spread "
                    "(min-max) in brackets" if runs > 1
                    else "one run: its spread unmeasured (`--repeat R` runs it R times)")
        return (f"Budgeted, with restarts (`--attempts auto`): from the next initial "
                f"configuration until the answer holds or the budget is spent (at most "
                f"{auto_rows}); load-dependent: its successes depend on the machine's load "
                f"and speed, not on the seed alone; {repeated}")
    if rule == "1":
        return ("Single descents (`--attempts 1`): one descent from the first initial "
                "configuration, the same for every method, no wall-clock cut")
    return (f"Deterministic, at most {rule} attempts (`--attempts {rule}`): from the same "
            f"{rule} seeded initial configurations, no wall-clock cut")


def deterministic_note(result: StudyResult, rule: str) -> list[str]:
    """Below a fixed-count rule's heading: K, what bounds each method's attempt, and the
    methods that are not deterministic (none for a file written before the rule had it)."""
    if rule == AUTO:
        return []
    methods = result.methods
    bounds = "; ".join(f"{m}: {f['attempt_bound']}" for m, f in methods.items()
                       if f.get("attempt_bound"))
    chance = [m for m, f in methods.items() if not f["deterministic"]]
    lines = [f"K = {rule}: each method gets at most {rule} attempts, from rows 0..{int(rule) - 1}"
             " of each target's seeded sequence, and no wall-clock budget: the success column "
             "is a function of the seed and the code alone (the times are measured as in every "
             "table)."]
    if bounds:
        lines.append(f"One attempt is bounded by the method's own limits: {bounds}.")
    if chance:
        lines.append(f"{', '.join(chance)}: the one row that is not deterministic: it needs a "
                     "finite timeout and draws its own restarts, so it keeps the budget "
                     f"({result.settings.budget_ms:g} ms) as its timeout and its success may "
                     "differ between runs.")
    return [" ".join(lines), ""]


def _spread(row: Any, name: str, digits: int, unit: str) -> str:
    """``value unit (min-max)`` of a figure run several times; ``value unit`` else."""
    value = getattr(row, name)
    low, high = getattr(row, f"{name}_min", np.nan), getattr(row, f"{name}_max", np.nan)
    text = f"{value:.{digits}f}{unit}" if digits else f"{_fmt(value)}{unit}"
    if getattr(row, "runs", 1) > 1 and np.isfinite(low) and np.isfinite(high):
        text += (f" ({low:.{digits}f}-{high:.{digits}f})" if digits
                 else f" ({_fmt(low)}-{_fmt(high)})")
    return text


def protocol(result: StudyResult) -> str:
    """The protocol paragraph of the leaderboard: budget, initial configurations, restarts,
    times."""
    s = result.settings
    budget = ("no wall-clock budget (`--budget-ms inf`)" if not np.isfinite(s.budget_ms)
              else f"a budget of **{s.budget_ms:g} ms** of wall-clock time per target")
    if any(str(r) != AUTO for r in s.attempts):
        budget += (" under `--attempts auto` (a fixed-count table has no wall-clock cut: each "
                   "attempt is bounded by the method's own limits, TRAC-IK excepted)")
    repeat = getattr(s, "repeat", 1)
    if repeat > 1 and AUTO in [str(r) for r in s.attempts]:
        budget += (f"; the `auto` table is run **{repeat} times** on the same targets and rows "
                   "(the load decides part of its successes): its cells give the median over "
                   "the runs and their (min-max)")
    first = ("drawn uniformly within the limits, independent of the target" if s.init ==
             "random" else f"the target's configuration moved by up to {s.perturb_deg:g} deg "
             "per joint")
    if s.init == "learned":
        first = ("the best proposal of the pose model `--model`; rows 1 .. K - 1 its next "
                 "ones, rows past K as below")
    itself = [m for m, f in result.methods.items() if f["restarts_itself"]]
    restarted = [m for m, f in result.methods.items() if not f["restarts_itself"]]
    lines = [f"**Protocol**, the same for every method: {budget}; **initial "
             f"configurations**: a seeded sequence per target, the same for every method "
             f"(row 0: `--init {s.init}`, {first}; rows 1, 2, ...: drawn uniformly within the "
             f"limits by target k's child of seed {s.seed}, `SeedSequence({s.seed}).spawn`); "
             "**attempts**: the rule of each table below."]
    if itself:
        lines.append(f"{', '.join(itself)} restart by themselves: each gets the rows the rule "
                     "allows and the budget in one call.")
    if restarted:
        lines.append(f"{', '.join(restarted)} are restarted by the study from the next row "
                     "until the answer holds (checked as the judge checks it, outside the "
                     "clock) or the budget is spent (an attempt started before it runs out "
                     "finishes).")
    lines.append("**Times** (the solver's clock): `time.perf_counter` around the solver's "
                 "calls only, one target per call, all its attempts included; the study's "
                 "check of each attempt, its bookkeeping and the set-up are untimed, and the "
                 "budget is counted on the same clock: median, mean, p95, max. "
                 "Batched throughput (every target in one call, the same solver, rows and "
                 "budget per target as the per-call table beside it) is its own column, in "
                 "targets per second.")
    if getattr(s, "unreachable", 0.0):
        lines.append("The batched rate is over all targets, the unreachable ones included: "
                     "each of those runs to its last attempt (or the budget), so it costs many "
                     "reachable targets' time and lowers the rate.")
    return " ".join(lines)


def leaderboard(result: StudyResult, summary: pd.DataFrame, record: dict[str, Any]) -> str:
    """leaderboard.md: the task and protocol above one table per attempts rule (see the
    module docstring)."""
    s, robot = result.settings, result.robot
    prov = record["provenance"]
    kind = ("6-D pose (position and rotation)" if s.kind == "pose"
            else "position only (rotation free)")
    tolerance = f"{s.tolerance_mm:g} mm" + (f" and {s.tolerance_deg:g} deg"
                                            if s.kind == "pose" else "")
    lines = [
        f"# Single-pose IK: {robot.name}",
        "",
        f"Robot: {robot.name} ({robot.dof} joints, {robot.root_link} -> {robot.end_frame}; "
        f"{robot.config.description}). Targets: {s.count}, FK of configurations "
        f"drawn uniformly within the joint limits, seed {s.seed}. Goal: {kind}. **Success**: "
        f"FK through Pinocchio within {tolerance} and within the joint limits (the method's "
        "own claim is not used).",
        "",
        protocol(result),
        "",
    ]
    versions = record["library_versions"]
    for rule, table in summary.groupby("attempts_rule", sort=False):
        runs = int(table["runs"].max()) if "runs" in table else 1
        lines += [f"## {rule_title(str(rule), result.auto_rows, runs)}", "",
                  *deterministic_note(result, str(rule)),
                  LEADERBOARD_HEAD, "|---" * len(LEADERBOARD_COLUMNS) + "|"]
        for row in table.itertuples(index=False):
            facts = result.methods[row.method]
            library = f"{facts['library']} {versions.get(facts['library']) or ''}".strip()
            notes = [] if facts["deterministic"] else ["not deterministic"]
            if facts["restarts_itself"]:
                notes.append("restarts itself")
            if str(rule) == "1" and not facts["one_descent"]:
                notes.append("its own restarts within the budget: not one descent")
            note = f" ({'; '.join(notes)})" if notes else ""
            if getattr(row, "cannot_run", ""):  # no call ran: no rate, no times
                lines.append(f"| {row.method}{note} | {library} | {row.targets} | cannot run: "
                             f"{_cell(row.cannot_run)} |" + " - |" * (len(LEADERBOARD_COLUMNS) - 4))
                continue
            batch = "-"
            if np.isfinite(row.batched_per_s):
                batch = (f"{row.batched_per_s:,.0f} ({row.batched_threads:.0f} threads, "
                         f"{row.batched_success_pct:.2f} %)")
            lines.append(
                f"| {row.method}{note} | {library} | {row.targets} "
                f"| {_spread(row, 'success_pct', 2, ' %')} "
                f"| {_fmt(row.attempts_median)} | {_fmt(row.attempts_max)} "
                f"| {_spread(row, 'time_median_ms', 0, '')} | {_fmt(row.time_mean_ms)} "
                f"| {_fmt(row.time_p95_ms)} | {_fmt(row.time_max_ms)} | {batch} "
                f"| {_fmt(row.position_error_median_mm)} "
                f"| {_fmt(row.rotation_error_median_deg)} "
                f"| {_fmt(row.joint_distance_median_deg)} | {_fmt(row.iterations_median)} "
                f"| {row.failed_calls} "
                f"| {_fmt(getattr(row, 'bare_call_median_ms', np.nan))} "
                f"| {_fmt(getattr(row, 'x_eaik_call', np.nan))} |")
        lines.append("")
    lines += bare_call_note(result.methods)
    lines += stability_note(result.methods)
    lines += ground_truth_section(result, summary)
    capped = {m: f["count"] for m, f in result.methods.items() if f["count"] < s.count}
    if capped:
        lines += ["Capped (`--max-count-per-method`, the first targets only): " + ", ".join(
            f"{m} {n}" for m, n in capped.items()) + ".", ""]
    lines += ["Iterations count: " + "; ".join(f"{m}: {f['iterations_are']}"
                                              for m, f in result.methods.items()) + ".", ""]
    runtimes = {m: f.get("runtime") for m, f in result.methods.items() if f.get("runtime")}
    lines += backend_notes(runtimes)
    if runtimes:
        lines += ["Backends: " + "; ".join(f"{m} {r['backend']}" for m, r in runtimes.items())
                  + ".", ""]
    lines += first_call_section(result.methods)
    lines += published_section(robot_slug(robot), summary)
    lines += [
        f"Machine: {prov['cpu']} ({prov['cpu_count']} logical CPUs), {prov['platform']}, "
        f"Python {prov['python']}; ikbench {prov['git_revision'] or ''}. Wall time of the run "
        f"{result.wall_s:.0f} s; load average (1, 5, 15 min) {_load(record)} (other jobs on "
        "the machine slow every timing). Versions in run.json.",
        "",
        f"Command: `{record['command']}`" if record["command"] else "",
        "",
        "![per-call time](times.png) ![success against tolerance](success_vs_tolerance.png) "
        "![success and time against the distance to a singularity](stress.png)",
        "",
    ]
    return "\n".join(lines)


#: The columns of each rule's leaderboard table, and its header line.
LEADERBOARD_COLUMNS = (
    "method", "library", "targets", "success", "attempts median", "attempts max",
    "time per call median [ms]", "mean [ms]", "p95 [ms]", "max [ms]", "batched [targets/s]",
    "position error median [mm]", "rotation error median [deg]", "joint distance median [deg]",
    "iterations median", "failed calls", "library call [ms]", "x_eaik_call")
LEADERBOARD_HEAD = "| " + " | ".join(LEADERBOARD_COLUMNS) + " |"
#: How each value of ``PoseSolver.stable_across_machines`` reads.
STABILITY = {True: "stable", False: "not stable", None: "not measured"}


def stability_note(methods: dict[str, dict]) -> list[str]:
    """Which methods' deterministic answers hold on another machine (docs/ik.md, "What is
    guaranteed"): measured by ``benchmarks/determinism_check.py``."""
    groups: dict[str, list[str]] = {}
    for name, facts in methods.items():
        groups.setdefault(STABILITY[facts.get("stable_across_machines")], []).append(name)
    return ["**Across machines** (same package versions; `benchmarks/determinism_check.py`, "
            "which emulates another CPU's kernels and thread counts): the deterministic "
            "columns are the same on one machine run to run for every method but TRAC-IK; on "
            "another machine only for the stable ones. "
            + "; ".join(f"{k}: {', '.join(v)}" for k, v in groups.items()) + ".", ""]


def bare_call_note(methods: dict[str, dict]) -> list[str]:
    """What "library call" and ``x_eaik_call`` mean, and each method's bare call."""
    calls = {m: f["bare_call"] for m, f in methods.items()
             if f.get("bare_call_median_ms") is not None and f.get("bare_call")}
    if not calls:
        return []
    eaik = ("; **x_eaik_call**: the time per call median over EAIK's library call in this "
            "run (the analytic limit as the library)" if EaikSolver.name in calls else "")
    return ["**Library call**: the median time [ms] of the library's own call alone, once per "
            "target from row 0 on inputs converted in advance, timed beside the method's first run "
            "(before its call on odd targets, after it on even ones); "
            "the time per call median minus it is the glue the adapter (and, past one "
            "attempt, the restarts) adds (`glue_median_ms` in summary.csv)" + eaik
            + ". Not measured (-) where the call cannot be isolated. The calls: "
            + "; ".join(f"{m}: {c}" for m, c in calls.items()), ""]


def first_call_section(methods: dict[str, dict]) -> list[str]:
    """The first call of each method in a fresh process (``--first-call``), as a table: the
    import of the registry and the method's module, the set-up (the robot, the library's model,
    compiling or loading compiled code) and the first solve [s]; none when not timed."""
    timed = {m: f["first_call"] for m, f in methods.items() if f.get("first_call")}
    if not timed:
        return []
    lines = ["## First call", "",
             "What a user waits for before the first answer, in a fresh Python process (after "
             "the runs above: numba's cache as they left it), for target 0 under the first "
             "table's rule:", "", *first_call_table(timed, _fmt)]
    return [*lines, ""]


def ground_truth_section(result: StudyResult, summary: pd.DataFrame) -> list[str]:
    """What the judge knows beyond each answer (:mod:`ikbench.studies.ik_truth`): silent
    failures, the analytic branches, the unreachable targets; one table per attempts rule."""
    t = result.targets
    if "claims" not in summary:
        return []
    text = ["## Ground truth", "",
            "**Silent failures**: of the answers a library judged itself (`library_ok`), those "
            "it called a success that the judge rejects, and those it called a failure that "
            "hold."]
    if t.branches is not None:
        text.append(f"**Branches**: every target's solutions within the limits, by "
                    f"{t.branches_by} (analytic, `branches.csv`); of each method's successes, "
                    "the share on the configuration nearest the initial one (the one that "
                    "keeps a tracked motion continuous), and how much farther from the "
                    "initial configuration the others are [deg, norm over the joints].")
    else:
        text.append("**Branches**: no analytic solver takes this robot (or the targets are "
                    "positions): no branch columns.")
    unreachable = int((~t.reachable).sum()) if t.reachable is not None else 0
    if unreachable:
        kinds = _unreachable_kinds(t)
        counts = ", ".join(f"{kinds.count(kind)} {label}" for kind, label in UNREACHABLE_KINDS
                           if kind in kinds)
        text.append(f"**Unreachable targets**: {unreachable} of {len(t.reachable)} targets are "
                    f"provably unreachable (`--unreachable`): {counts}; the tables above count "
                    "the reachable ones only. Here: judged successes on them (none can hold), "
                    "the library's own claims, and the time it took to give up; then the "
                    "same per kind.")
        if t.branches is None:
            text.append("No analytic solver takes this robot (or the targets are positions): "
                        "every unreachable target is beyond the reach bound.")
    lines = [text[0], "", " ".join(text[2:]), ""]  # the heading on its own line
    for rule, table in summary.groupby("attempts_rule", sort=False):
        head = ["method", "claimed, judge rejects", "denied, holds"]
        if t.branches is not None:
            head += ["on the nearest branch", "excess median [deg]", "excess p95 [deg]"]
        if unreachable:
            head += ["unreachable: judged success", "claimed", "give up median [ms]",
                     "give up p95 [ms]"]
        runs = int(table["runs"].max()) if "runs" in table else 1
        lines += [f"### {rule_title(str(rule), result.auto_rows, runs)}", "",
                  "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for row in table.itertuples(index=False):
            if getattr(row, "cannot_run", ""):
                lines.append(f"| {row.method} | cannot run |" + " - |" * (len(head) - 2))
                continue
            cells = ([row.method, "no claims", "no claims"] if not row.claims else
                     [row.method, f"{row.claimed_rejected} of {row.claims}",
                      f"{row.denied_holding} of {row.claims}"])
            if t.branches is not None:
                cells += ["-" if not np.isfinite(row.on_nearest_branch_pct)
                          else f"{row.on_nearest_branch_pct:.1f} %",
                          _fmt(row.branch_excess_median_deg), _fmt(row.branch_excess_p95_deg)]
            if unreachable:
                cells += [str(row.unreachable_judged_success), str(row.unreachable_claimed),
                          _fmt(row.give_up_median_ms), _fmt(row.give_up_p95_ms)]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        if unreachable:
            lines += _unreachable_by_kind(result, str(rule))
    return lines


#: The kinds of unreachable targets (``unreachable_kind``) and their words in the report.
UNREACHABLE_KINDS = (("beyond_reach", "beyond the reach bound"),
                     ("orientation_impossible",
                      "at a reachable position with an orientation the analytic solver proves "
                      "impossible there"))


def _unreachable_kinds(t) -> list[str]:
    """Each unreachable target's kind (targets without ``unreachable_kind``: beyond the
    reach bound, the only kind before it)."""
    if getattr(t, "unreachable_kind", None) is None:
        return ["beyond_reach"] * int((~t.reachable).sum())
    return [str(k) or "beyond_reach" for k, ok in zip(t.unreachable_kind, t.reachable) if not ok]


def _unreachable_by_kind(result: StudyResult, rule: str) -> list[str]:
    """Per method and kind of unreachable target (one attempts rule): targets, judged
    successes, the library's claims, and the give-up time (median) [ms]."""
    t, table = result.targets, result.table
    if getattr(t, "unreachable_kind", None) is None or "target" not in table:
        return []
    kind = pd.Series(t.unreachable_kind, dtype=object)
    part = table[(table["attempts_rule"].astype(str) == rule)
                 & ~table["reachable"].astype(bool)].copy()
    part["unreachable_kind"] = kind.reindex(part["target"].to_numpy()).to_numpy()
    part["unreachable_kind"] = part["unreachable_kind"].replace("", "beyond_reach")
    lines = ["| method | unreachable kind | targets | judged success | claimed | "
             "give up median [ms] |", "|---|---|---|---|---|---|"]
    for (method, which), g in part.groupby(["method", "unreachable_kind"], sort=False):
        claimed = int(g["library_ok"].astype("boolean").fillna(False).astype(bool).sum())
        lines.append(f"| {method} | {which} | {g['target'].nunique()} | "
                     f"{int(g['success'].astype(bool).sum())} | {claimed} | "
                     f"{_fmt(g['time_s'].median() * 1000.0)} |")
    return [*lines, ""]


def published_section(robot: str, summary: pd.DataFrame) -> list[str]:
    """The published figures of ``robot`` (:mod:`ikbench.render.ik_published`), labelled as
    published with their source, beside this run's trac-ik; none: no lines."""
    figures = published_for(robot)
    if not figures:
        return []
    lines = ["## Published figures (other machines and protocols: not comparable one to one)",
             "",
             "| solver | success (published) | time (published) [ms] | the time is | protocol "
             "| source |",
             "|---|---|---|---|---|---|"]
    for p in figures:
        lines.append(f"| {p.solver} | {p.success_pct:g} % | {p.time_ms:g} | {p.time_is} "
                     f"| {p.protocol} | {p.source} |")
    here = summary[summary["method"] == TracIKSolver.name]
    if len(here):
        lines += ["", "This run's trac-ik (Python binding, this machine): " + "; ".join(
            f"`--attempts {r.attempts_rule}` {r.success_pct:.2f} %, median "
            f"{_fmt(r.time_median_ms)} ms, mean {_fmt(r.time_mean_ms)} ms per call, mean of "
            f"the successes {_fmt(r.time_success_mean_ms)} ms" for r in here.itertuples())
            + "."]
    return lines + [""]


def _figures(result: StudyResult, tmp: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    table, s = result.table, result.settings
    rules = list(dict.fromkeys(table["attempts_rule"]))
    colors = method_colors(table)
    # a method no call of which ran has no curve: the legend says it cannot run
    unable = [m for m, g in table.groupby("method", sort=False) if cannot_run(g)]

    def say_unable(ax) -> None:
        for method in unable:
            ax.plot([], [], ls="none", label=f"{method}: cannot run")

    fig, axes = plt.subplots(len(rules), 1, figsize=(8.5, 3.6 * len(rules)), squeeze=False)
    for ax, rule in zip(axes[:, 0], rules):
        part = table[table["attempts_rule"] == rule]
        for method, g in part.groupby("method", sort=False):
            if method in unable:
                continue
            times = np.sort(g["time_s"].dropna().to_numpy() * 1000.0)
            if len(times):
                ax.step(times, np.arange(1, len(times) + 1) / len(times) * 100.0, where="post",
                        color=colors[method], label=method)
        if np.isfinite(s.budget_ms):
            ax.axvline(s.budget_ms, color="k", ls=":", lw=1, label="budget")
        ax.set_xscale("log")
        say_unable(ax)
        ax.set_xlabel("time per call [ms] (log), all attempts included")
        ax.set_ylabel("calls done within [%]")
        ax.set_title(f"{result.robot.name}: --attempts {rule}, {s.count} targets ({s.kind}, "
                     f"{s.init} start)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    atomic_savefig(tmp / "times.png", fig)

    ratio = s.tolerance_deg / s.tolerance_mm
    fig, axes = plt.subplots(len(rules), 1, figsize=(8.5, 3.6 * len(rules)), squeeze=False)
    for ax, rule in zip(axes[:, 0], rules):
        curve = success_curve(table[table["attempts_rule"] == rule], s.kind, ratio, CURVE_MM)
        for method in curve.columns:
            if method not in unable:
                ax.plot(curve.index, curve[method], color=colors[method], label=method)
        say_unable(ax)
        ax.axvline(s.tolerance_mm, color="k", ls=":", lw=1, label="stated tolerance")
        ax.set_xscale("log")
        xlabel = "position tolerance [mm] (log)"
        if s.kind == "pose":
            xlabel += f"; rotation tolerance {ratio:g} deg per mm of it"
        ax.set_xlabel(xlabel)
        ax.set_ylabel("success [%]")
        ax.set_ylim(-2, 102)
        ax.set_title(f"{result.robot.name}: success against tolerance, --attempts {rule}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    atomic_savefig(tmp / "success_vs_tolerance.png", fig)
    if result.targets.sigma_min is not None:
        stress_table(result).to_csv(tmp / "stress.csv", index=False, float_format="%.6g")
        _stress_figure(result, tmp / "stress.png")


def method_colors(table: pd.DataFrame) -> dict[str, tuple]:
    """One distinct colour per method of ``table`` (in its order), the same in every panel
    and figure of the study (:func:`ikbench.render.palette.distinct_colors`)."""
    methods = list(dict.fromkeys(table["method"]))
    return dict(zip(methods, distinct_colors(len(methods))))


#: Bins of the stress figure: quantiles of the targets' smallest singular value.
STRESS_BINS = 6


def stress_table(result: StudyResult) -> pd.DataFrame:
    """Success [%] and median time per call [ms] per method and bin of the targets' smallest
    Jacobian singular value (reachable targets, the first attempts rule): one row each."""
    t, table = result.targets, result.table
    rule = table["attempts_rule"].iloc[0]
    part = table[table["attempts_rule"] == rule]
    if "reachable" in part:
        part = part[part["reachable"].astype(bool)]
    sigma = np.asarray(t.sigma_min)[part["target"].to_numpy(dtype=int)]
    reachable = t.sigma_min if t.reachable is None else t.sigma_min[t.reachable]
    edges = np.unique(np.quantile(reachable, np.linspace(0, 1, STRESS_BINS + 1)))
    bins = np.clip(np.searchsorted(edges, sigma, side="right") - 1, 0, len(edges) - 2)
    part = part.assign(bin=bins)
    rows = []
    for (method, b), g in part.groupby(["method", "bin"], sort=False):
        rows.append({"attempts_rule": rule, "method": method, "sigma_low": edges[b],
                     "sigma_high": edges[b + 1], "targets": len(g),
                     "success_pct": 100.0 * g["success"].astype(bool).mean(),
                     "time_median_ms": 1000.0 * g["time_s"].median()})
    return pd.DataFrame(rows).sort_values(["method", "sigma_low"], kind="stable")


def _stress_figure(result: StudyResult, path: Path) -> None:
    import matplotlib.pyplot as plt

    table = pd.read_csv(path.with_name("stress.csv"))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8.5, 6.4), sharex=True)
    colors = method_colors(result.table)
    for method, g in table.groupby("method", sort=False):
        middle = np.sqrt(np.maximum(g["sigma_low"], 1e-12) * g["sigma_high"])
        style = dict(color=colors[method], marker="o", ms=3, label=method)
        top.plot(middle, g["success_pct"], **style)
        bottom.plot(middle, g["time_median_ms"], **style)
    top.set_ylabel("success [%]")
    top.set_ylim(-2, 102)
    bottom.set_ylabel("time per call, median [ms] (log)")
    bottom.set_yscale("log")
    bottom.set_xscale("log")
    bottom.set_xlabel("smallest singular value of the target configuration's Jacobian "
                      f"(log; {STRESS_BINS} quantile bins; near 0: a singularity)")
    rule = table["attempts_rule"].iloc[0] if len(table) else ""
    top.set_title(f"{result.robot.name}: success and time against the distance to a "
                  f"singularity, --attempts {rule}")
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
    top.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    atomic_savefig(path, fig)


#: results.csv's run column (absent from files written before it: one run).
RUN = "run"
#: summary.csv's last columns: the runs of a rule and the spread of its figures over them.
SPREAD = ("runs", "success_pct_min", "success_pct_max", "time_median_ms_min",
          "time_median_ms_max")


def first_calls(methods: dict[str, dict]) -> dict[str, float]:
    """Method -> its first call in a fresh process [ms] (``ikbench ik --first-call``), where
    it was timed and succeeded."""
    return {name: 1000.0 * facts["first_call"]["first_call_s"]
            for name, facts in methods.items()
            if "first_call_s" in (facts.get("first_call") or {})}


def with_bare_calls(summary: pd.DataFrame, methods: dict[str, dict]) -> pd.DataFrame:
    """``summary`` with the library's own call (``ikbench ik``'s
    :func:`~ikbench.studies.ik.bare_call_times`, in ``methods``: run.json's): columns
    ``bare_call_median_ms`` (NaN where not measured), ``glue_median_ms`` (the per-call median
    minus it: what the adapter and, past one attempt, the restarts add) and ``x_eaik_call``
    (the per-call median over EAIK's bare call in the same run; NaN without eaik), before
    the run spread and first-call columns, which stay the last."""
    bare = {m: float(f["bare_call_median_ms"]) for m, f in methods.items()
            if f.get("bare_call_median_ms") is not None}
    out = summary.copy()
    out["bare_call_median_ms"] = out["method"].map(lambda m: bare.get(m, np.nan)).astype(float)
    out["glue_median_ms"] = out["time_median_ms"] - out["bare_call_median_ms"]
    eaik = bare.get(EaikSolver.name)
    out["x_eaik_call"] = (out["time_median_ms"] / float(eaik) if eaik else np.nan)
    added = ["bare_call_median_ms", "glue_median_ms", "x_eaik_call"]
    tail = [c for c in out.columns if c in (*SPREAD, "first_call_ms")]  # stay the last
    return out[[c for c in out.columns if c not in added and c not in tail] + added + tail]


def summarise(table: pd.DataFrame, batches: dict | None = None,
              first_call_ms: dict[str, float] | None = None) -> pd.DataFrame:
    """One row per attempts rule and method: targets, successes, success %, attempts, time
    per call median / mean / p95 / max [ms] and mean of the successes, the batched
    throughput [targets/s] with its threads and success (``batches``: rule -> method ->
    :func:`ikbench.studies.ik._batch`'s figures; NaN for methods that do not batch), errors
    of the successes, joint distance, iterations, failed calls. A rule run several times
    (column ``run``): each figure is the median over the runs, and the last columns
    (:data:`SPREAD`) give the runs and the min-max of success % and of median time per call;
    a table without the column is one run. ``first_call_ms``: method -> its first call in a
    fresh process [ms], the last column (where given)."""
    summary = _summarise(table, batches)
    if first_call_ms:
        summary["first_call_ms"] = summary["method"].map(first_call_ms).astype(float)
    return summary


def _summarise(table: pd.DataFrame, batches: dict | None) -> pd.DataFrame:
    if RUN not in table:
        return _summarise_run(table, batches or {})
    rows = []
    for _, g in table.groupby(["attempts_rule", "method"], sort=False):
        per_run = _summarise_run(g, batches or {}, by_run=True)
        row = per_run.iloc[0].copy()
        for name in per_run.select_dtypes("number").columns:  # equal in every run: as is
            if per_run[name].nunique(dropna=False) > 1:
                value = per_run[name].median()  # counts stay integers where they can
                integral = per_run[name].dtype.kind in "iu" and float(value).is_integer()
                row[name] = int(value) if integral else value
        row["runs"] = len(per_run)
        for name in ("success_pct", "time_median_ms"):
            row[f"{name}_min"], row[f"{name}_max"] = per_run[name].min(), per_run[name].max()
        rows.append(row)
    return pd.DataFrame(rows).reset_index(drop=True)


def _summarise_run(table: pd.DataFrame, batches: dict, by_run: bool = False) -> pd.DataFrame:
    """:func:`summarise` of one run (``by_run``: one row per run of the one rule and method
    in ``table``)."""
    rows = []
    keys = ["attempts_rule", "method", RUN] if by_run else ["attempts_rule", "method"]
    for key, g in table.groupby(keys, sort=False):
        rule, method = key[:2]
        unreachable = g[~g["reachable"].astype(bool)] if "reachable" in g else g.iloc[:0]
        if "reachable" in g:
            g = g[g["reachable"].astype(bool)]
        ok = g[g["success"].astype(bool)]
        times = g["time_s"] * 1000.0
        batch = batches.get(str(rule), {}).get(method, {})
        rows.append({
            "attempts_rule": rule, "method": method, "targets": len(g), "solved": len(ok),
            "success_pct": 100.0 * len(ok) / len(g),
            "attempts_median": g["attempts"].median(), "attempts_mean": g["attempts"].mean(),
            "attempts_max": g["attempts"].max(),
            "time_median_ms": times.median(), "time_mean_ms": times.mean(),
            "time_p95_ms": times.quantile(0.95), "time_max_ms": times.max(),
            "time_success_mean_ms": (ok["time_s"] * 1000.0).mean(),
            "batched_per_s": batch.get("targets_per_s", np.nan),
            "batched_threads": batch.get("threads", np.nan),
            "batched_success_pct": batch.get("success_pct", np.nan),
            "position_error_median_mm": ok["position_error_mm"].median(),
            "rotation_error_median_deg": ok["rotation_error_deg"].median(),
            "joint_distance_median_deg": ok["joint_distance_deg"].median(),
            "iterations_median": g["iterations"].median(),
            "failed_calls": int((g["failure"].fillna("") != "").sum()),
            "cannot_run": cannot_run(g),
            **_truth(g, ok, unreachable),
        })
    return pd.DataFrame(rows)


def cannot_run(g: pd.DataFrame) -> str:
    """Why a method ran no call at all (its library could not take the robot: every row
    failed with the same ``prepare: ...``), else "": such a method has no success rate."""
    failures = g["failure"].fillna("").astype(str).unique()
    if len(failures) == 1 and failures[0].startswith("prepare: "):
        return failures[0].removeprefix("prepare: ")
    return ""


def _truth(g: pd.DataFrame, ok: pd.DataFrame, unreachable: pd.DataFrame) -> dict[str, Any]:
    """The ground-truth figures of one method's rows (:mod:`ikbench.studies.ik_truth`): its
    claims against the judge's verdict, its answers' branches, its unreachable targets."""
    said = g[g["library_ok"].notna()]
    claimed = said["library_ok"].astype(bool)
    holds = said["success"].astype(bool)
    on = ok["on_nearest_branch"] if "on_nearest_branch" in ok else pd.Series(dtype=float)
    g_on = g["on_nearest_branch"] if "on_nearest_branch" in g else pd.Series(dtype=float)
    excess = ok["branch_excess_deg"] if "branch_excess_deg" in ok else pd.Series(dtype=float)
    out = {"claims": len(said), "claimed_rejected": int((claimed & ~holds).sum()),
           "denied_holding": int((~claimed & holds).sum()),
           # of all its successes (one on no branch counts as not on the nearest), as the
           # report says; NaN where no row of the method has a branch verdict (no branches)
           "on_nearest_branch_pct": (100.0 * float((on == 1).sum()) / len(ok)
                                     if len(ok) and g_on.notna().any() else np.nan),
           "branch_excess_median_deg": excess.median(),
           "branch_excess_p95_deg": excess.quantile(0.95) if excess.notna().any() else np.nan,
           "unreachable_targets": len(unreachable)}
    if len(unreachable):
        out.update({
            "unreachable_judged_success": int(unreachable["success"].astype(bool).sum()),
            "unreachable_claimed": int(unreachable["library_ok"].fillna(False).astype(bool)
                                       .sum()),
            "give_up_median_ms": unreachable["time_s"].median() * 1000.0,
            "give_up_p95_ms": unreachable["time_s"].quantile(0.95) * 1000.0})
    return out


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
