"""One command that regenerates everything the paper reports, and the page that shows it.

:func:`reproduce` runs, into one results directory:

1. Table 1: ``ours`` on the paper's targets (:func:`ikbench.studies.run.run`) -> ``ours/``;
2. Table 2: the baseline as the paper made it, ``sequential-ik-walk`` (the authors' walk back
   from the touch pose: a touch-pose-only task, the start pose is free) in its default
   ``frame`` mode -> ``sequential-ik/``;
3. the baseline's other orientation modes, walked too -> ``sequential-ik-pointing/`` and
   ``sequential-ik-position/`` (``--orientation pointing`` / ``position``);
4. Table 2 as the authors ran it: ``ikpy-walk`` with their call (``--ikpy-orientation
   position``) -> ``ikpy/``, when ikpy is installed (``pip install 'ikbench[libs]'``;
   otherwise skipped, and README.md says so);
5. ``ours`` with ``--init interpolation`` (the paper's text) -> ``ours-init-interpolation/``,
   which measures how soon that initialisation stops;
6. the comparison report of all these runs
   (:func:`ikbench.paper.comparison.write_comparison_report`);
7. the loss-term ablation (:func:`ikbench.studies.ablation.ablate`, every single term and L2..L5
   together) -> ``ablation/``;
8. ``README.md``: each paper table beside the measured one, the baseline's three modes and
   the authors' ikpy call, the figures, the deviations from the paper, the versions and
   machine used.

``quick=True`` runs the same pipeline on a reduced configuration (:data:`QUICK`) to check that
it works end to end; its numbers are not the paper's.

The folders keep the names they had before the baselines had schemes (``sequential-ik/``,
``ikpy/``); their run.json names the method that wrote them (``sequential-ik-walk``,
``ikpy-walk``). ``sequential-ik`` and ``ikpy`` themselves now track from the start pose onto
the touch pose (the paper's task); ``ikbench compare`` runs them.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ikbench.core.errors import IkbenchError, InputError
from ikbench.core.io import atomic_write_text, check_writable
from ikbench.core.provenance import provenance
from ikbench.methods.registry import get_method, method_status
from ikbench.paper.ablation_claims import check_claims, claims_table
from ikbench.paper.baseline_runs import load_comparison
from ikbench.paper.comparison import (
    FIGURE_NAME,
    IKPY_TABLE2_NOTE,
    MODES_NOTE,
    PAPER_BASELINE_NOTE,
    TABLE2_UNITS_NOTE,
    claims_lines,
    escaped_table,
    modes_table,
    table2_comparison,
    write_comparison_report,
)
from ikbench.paper.values import paper_values, table1_comparison
from ikbench.render.run_report import markdown_table
from ikbench.runtime.progress import message
from ikbench.studies.ablation import FULL, SUMMARY_METRICS, ablate
from ikbench.studies.folders import RESULTS
from ikbench.studies.regeneration import STUDIES
from ikbench.studies.run import run

DEFAULT_OUTPUT = RESULTS
QUICK_OUTPUT = "results-quick"
OURS = "ours"
#: Table 2's folder and the method run into it: the paper's baseline scheme, the walk back
#: from the touch pose (``sequential-ik`` itself tracks from the start pose).
BASELINE = "sequential-ik"
BASELINE_METHOD = "sequential-ik-walk"
#: The baseline's other orientation modes: mode -> folder (Table 2 is ``frame``, the default).
BASELINE_MODES = {"pointing": f"{BASELINE}-pointing", "position": f"{BASELINE}-position"}
#: Table 2 as the authors ran it: their library and call (``ikpy-walk``, position only) ->
#: ``ikpy/``.
AUTHORS_RUN = "ikpy"
AUTHORS_METHOD = "ikpy-walk"
AUTHORS_STAGE = f"Table 2 as the authors ran it: {AUTHORS_METHOD}"
#: The task the walks solve, in words (README).
WALK_TASK = ("the authors' walk back from the touch pose (touch-pose-only task: the start "
             "pose is free)")
#: ``ours`` with the paper's text's initialisation (measures when it stops).
INTERPOLATION_RUN = "ours-init-interpolation"
#: The ablation variants: every single term, and L2..L5 together (the paper's last claim).
ABLATION_DROPS = ["each", "L2,L3,L4,L5"]
#: Ablation figures shown in README.md (mean over trajectories per variant).
SUMMARY_COLUMNS = ["iterations", "line_distance_mean_mm", "pointing_deviation_mean_deg",
                   "end_point_error_mm", "end_pose_error_deg", "mean_sq_jerk_deg2",
                   "velocity_sign_changes", "joint_interpolation_distance_deg"]
#: The reduced configuration of ``--quick``: one trajectory, n = 10, capped iterations.
QUICK = {"only": "1", "steps": 10, "max_iterations": 100}
#: What reproduce writes into the results directory (files and folders).
WRITES = ("README.md", "report.md", "pointing_deviation_per_step.png", OURS, BASELINE,
          *BASELINE_MODES.values(), AUTHORS_RUN, INTERPOLATION_RUN, "ablation")
class ReproduceError(IkbenchError):
    """A part the reproduction needs is missing."""


def _baseline() -> type:
    try:
        return get_method(BASELINE_METHOD)
    except IkbenchError as exc:
        raise ReproduceError(
            f"Table 2 needs the method {BASELINE_METHOD!r} (baselines/sequential_ik.py), "
            f"which this checkout does not register ({exc})") from None


def _authors_method():
    """ikpy-walk's method class, or (None, why not) when ikpy is not installed here."""
    status = method_status().get(AUTHORS_METHOD)
    if status is None:
        return None, f"the method {AUTHORS_METHOD!r} is not registered"
    return status.cls, status.reason


def _elapsed(seconds: float) -> str:
    """``0.2 s``, ``42.0 s`` or ``2 min 36 s``."""
    if seconds < 59.95:
        return f"{seconds:.1f} s"
    minutes, seconds = divmod(int(round(seconds)), 60)
    return f"{minutes} min {seconds:02d} s"


def _output_dir(output: str | Path | None, quick: bool) -> Path:
    """The results directory; InputError for an empty ``--output``."""
    if output is None:
        return Path(QUICK_OUTPUT if quick else DEFAULT_OUTPUT)
    if not str(output).strip():
        raise InputError(f"--output: {str(output)!r} is empty; give a directory (default "
                         f"{DEFAULT_OUTPUT}, or {QUICK_OUTPUT} with --quick)")
    return Path(output)


def check_output(output: str | Path | None, quick: bool = False) -> Path:
    """The results directory, checked for writing (before any solving, not after minutes
    of it); InputError for an empty ``output``, OutputError for one that cannot be written."""
    output = _output_dir(output, quick)
    for first in (output / OURS / "table.csv", output / "README.md"):
        check_writable(first)
    return output


def reproduce(output: str | Path | None = None, quick: bool = False,
              progress: bool = True) -> dict[str, float]:
    """Regenerate Tables 1 and 2, the comparison, the ablation, the figures and README.md.

    Args:
        output: results directory (default ``results``, or ``results-quick`` when quick).
        quick: the reduced configuration :data:`QUICK` (a pipeline check, not the paper).
        progress: print progress to stderr.

    Returns:
        Wall time [s] per stage, plus ``"total"``.

    Raises:
        InputError: an empty ``output``.
        OutputError: before any work, when the results directory cannot be written.
        ReproduceError: before any work, when sequential-ik-walk or the comparison is
            missing.
    """
    output = check_output(output, quick)
    baseline = _baseline()
    subset: dict[str, Any] = {"only": QUICK["only"], "steps": QUICK["steps"]} if quick else {}
    ours_options: dict[str, Any] = {"max_iterations": QUICK["max_iterations"]} if quick else {}
    ours = get_method(OURS)

    def modes(mode, name, title=None):
        return (title or f"{BASELINE_METHOD} --orientation {mode}",
                lambda: run(baseline(orientation=mode), output=output, progress=progress,
                            name=name, **subset))

    authors, _ = _authors_method()
    stages = [
        ("Table 1: ours", lambda: run(ours(**ours_options), output=output,
                                      progress=progress, **subset)),
        modes("frame", BASELINE, f"Table 2: {BASELINE_METHOD}"),
        *[modes(mode, name) for mode, name in BASELINE_MODES.items()],
        *([(AUTHORS_STAGE, lambda: run(authors(orientation="position"), output=output,
                                       progress=progress, name=AUTHORS_RUN, **subset))]
          if authors is not None else []),
        ("ours --init interpolation",
         lambda: run(ours(init="interpolation", **ours_options), output=output,
                     progress=progress, name=INTERPOLATION_RUN, **subset)),
        ("comparison report", lambda: write_comparison_report(output)),
        ("ablation", lambda: ablate(ABLATION_DROPS, "ours", output=output,
                                    options=ours_options, progress=progress, **subset)),
    ]
    started = time.perf_counter()
    times, results = {}, {}
    total = len(stages) + 1

    def say(text):
        message(f"reproduce {_elapsed(time.perf_counter() - started)}", text, progress)

    say(f"{'quick pipeline check' if quick else 'full reproduction'} into {output}/, "
        f"{total} stages")
    for k, (title, stage) in enumerate(stages):
        say(f"stage {k + 1}/{total}: {title}")
        stage_start = time.perf_counter()
        results[title] = stage()
        times[title] = time.perf_counter() - stage_start
        say(f"stage {k + 1}/{total}: {title} done in {_elapsed(times[title])}")
    say(f"stage {total}/{total}: {output}/README.md")
    times["total"] = time.perf_counter() - started
    path = write_results_readme(output, times, quick, results["comparison report"])
    times["total"] = time.perf_counter() - started
    say(f"done: {path}; total time {_elapsed(times['total'])}")
    return times


# ----- results/README.md ---------------------------------------------------------------------
def _read(output: Path, name: str) -> pd.DataFrame:
    return pd.read_csv(output / name, dtype={"trajectory": str})


def _figures(folder: str, names: list[str]) -> list[str]:
    return [f"![{folder} {name}]({folder}/{name})" for name in names] + [""]


def _span(values, digits: int = 0) -> str:
    """``89-99`` (or ``98`` when all equal)."""
    lo, hi = float(np.min(values)), float(np.max(values))
    return f"{lo:.{digits}f}" if f"{lo:.{digits}f}" == f"{hi:.{digits}f}" else \
        f"{lo:.{digits}f}-{hi:.{digits}f}"


def _table1_findings(table: pd.DataFrame) -> list[str]:
    """Data-driven remarks on the measured Table 1 against the paper's."""
    paper = paper_values()["table1"]
    scale = paper_values()["table1_cm_to_mm"]
    rows = [(r, paper[str(r["trajectory"])]) for _, r in table.iterrows()
            if str(r["trajectory"]) in paper]
    if not rows:
        return []
    ratios = [r["iterations"] / p["iterations"] for r, p in rows]
    distance = max(abs(r["line_distance_mean_mm"] - p["line_distance_mean_printed"] * scale)
                   for r, p in rows)
    pointing = max(abs(r["pointing_deviation_mean_deg"] - p["pointing_deviation_mean_deg"])
                   for r, p in rows)
    return [
        f"- **Table 1 as measured.** `ours` (seed 0; the paper states no seed) needs "
        f"{min(ratios):.2f}x to {max(ratios):.2f}x the paper's iterations per trajectory; "
        f"mean line distances differ from the paper's (read as cm) by at most {distance:.2f} mm "
        f"and mean pointing deviations by at most {pointing:.1f} deg (the paper rounds them to "
        "whole degrees).",
    ]


def _initialisation_finding(ours: pd.DataFrame, interpolation: pd.DataFrame) -> str:
    """The initialisation deviation with the iterations measured in both runs."""
    return (
        "- **Initialisation.** The paper's text initialises the logits from the joint-space "
        "interpolation of start and touch pose; the authors' released code uses PyTorch's "
        "default random `nn.Linear` initialisation. `ours` defaults to the code's (seeded) "
        "random initialisation, which reproduces the paper's iteration counts and losses "
        f"({_span(ours['iterations'])} iterations here). With `--init interpolation` (the "
        f"text; run into [{INTERPOLATION_RUN}/]({INTERPOLATION_RUN}/report.md)) the paper's "
        "stopping rule fires after "
        f"{_span(interpolation['iterations'])} iterations (median "
        f"{interpolation['iterations'].median():.0f}), at mean line distances of "
        f"{_span(interpolation['line_distance_mean_mm'], 2)} mm and mean pointing deviations "
        f"of {_span(interpolation['pointing_deviation_mean_deg'], 1)} deg.")


def _authors_section(output: Path, times: dict) -> list[str]:
    """README lines: Table 2 as the authors ran it (``ikpy/``), or why that stage was skipped."""

    heading = f"### Table 2 as the authors ran it (`{AUTHORS_METHOD}`, their call)"
    if AUTHORS_STAGE not in times:
        _, reason = _authors_method()
        return [heading, "", f"Not run: {reason}. `ikbench reproduce` runs it when ikpy is "
                "installed.", ""]
    table = _read(output, f"{AUTHORS_RUN}/table.csv")
    return [heading, "", markdown_table(table2_comparison(table)), "", IKPY_TABLE2_NOTE, "",
            f"Task solved: {WALK_TASK}.", "",
            f"Details: [{AUTHORS_RUN}/report.md]({AUTHORS_RUN}/report.md).", "",
            *_figures(AUTHORS_RUN, ["trajectories_3d.png", "pointing_error.png"])]


def _baseline_finding(frame: pd.DataFrame, authors: bool = False) -> str:
    """The Table 2 baseline deviation with the pointing deviation measured per mode (and by
    the authors' own ikpy call when ``authors``)."""
    paper = paper_values()["table2"]
    ids = [t for t in dict.fromkeys(frame["trajectory"]) if t in paper]
    by_run = {name: frame[frame["method"] == name]
              for name in (OURS, BASELINE, BASELINE_MODES["position"])}
    position = BASELINE_MODES["position"]
    paper_deg = [paper[t]["pointing_deviation_mean_deg"] for t in ids]
    paper_text = f" against the paper's {_span(paper_deg)} deg" if ids else ""
    return (
        "- **Table 2 baseline.** The text says the traditional IK specified the orientation as "
        "well as the point; the authors' script solved the position only (ikpy's "
        "`inverse_kinematics_frame` without `orientation_mode`), on another URDF, walking back "
        "from the touch pose (a touch-pose-only task: the start pose is free, unlike the "
        "paper's own task, Sec. 3). Solving that problem here "
        f"(`{BASELINE_METHOD} --orientation position`, [{position}/]({position}/report.md)) "
        "gives "
        "mean pointing deviations of "
        f"{_span(by_run[position]['pointing_deviation_mean_deg'], 1)} deg per "
        f"trajectory{paper_text}, on the line (mean line distances "
        f"{_span(by_run[position]['line_distance_mean_mm'], 2)} mm). The full frame "
        f"(`{BASELINE_METHOD}`'s default, [{BASELINE}/]({BASELINE}/report.md), Table 2 here) "
        "gives "
        f"{_span(by_run[BASELINE]['pointing_deviation_mean_deg'], 2)} deg at mean line "
        f"distances of {_span(by_run[BASELINE]['line_distance_mean_mm'], 2)} mm (`{OURS}`: "
        f"{_span(by_run[OURS]['line_distance_mean_mm'], 2)} mm)." + (
            "" if not authors else
            f" The authors' own call on this robot (`{AUTHORS_METHOD}`, "
            f"[{AUTHORS_RUN}/]({AUTHORS_RUN}/report.md)) gives "
            f"{_span(frame[frame['method'] == AUTHORS_RUN]['pointing_deviation_mean_deg'], 1)}"
            " deg at mean line distances of "
            f"{_span(frame[frame['method'] == AUTHORS_RUN]['line_distance_mean_mm'], 4)} mm."))


DEVIATIONS = [
    "- **Unit of the distance columns.** The paper's \"distance from the line [mm]\" (Tables 1 "
    "and 2) and \"start point variation [mm]\" (Table 2) are in centimetres: the authors' own "
    "trajectories (ikbench/paper/data/reference) measure 10x the printed values in mm. Paper "
    "columns here show the printed values x 10, in mm. Its Fig. 2 caption says cm; ikbench "
    "plots mm.",
    "- **R_y sign slip.** The paper prints the rotation about y with its sine signs swapped; "
    "the standard right-handed R_y is used (it reproduces the authors' trajectories' "
    "figures; see `urdf/generate_urdf.py`).",
    "- **Stopping rule.** The text says training stops \"when the angles do not change enough\" "
    "or the shape is sufficient; the code (used here) stops when the loss is below 10 and "
    "above the median of the last 10 losses.",
    "- **Ablation term name.** The ablation paragraph says \"L7 causes the robot arm to "
    "shake\"; there is no L7: the smoothness term L6 is meant (and tested here).",
    "- **Durations** depend on the machine; the paper's were measured on the authors' CPU.",
]


def _provenance_lines(output: Path, command: str) -> list[str]:
    """What in ``output`` this command wrote, and which commands wrote the rest."""
    others = sorted(p.name for p in output.iterdir()
                    if not p.name.startswith(".") and p.name not in WRITES)
    by_command: dict[str, list[str]] = {}
    writers = {w.split("/")[0]: study.shown(Path("results")) for study in STUDIES
               for w in study.writes}
    for name in others:
        writer = writers.get(name, "")
        by_command.setdefault(writer, []).append(
            name + ("/" if (output / name).is_dir() else ""))
    written = ", ".join(f"`{n}/`" if (output / n).is_dir() else f"`{n}`" for n in WRITES
                        if n == "README.md" or (output / n).exists())
    text = f"`{command}` wrote {written}."
    if others:
        parts = [f"{', '.join(f'`{n}`' for n in names)} by `{cmd}`" if cmd else
                 f"{', '.join(f'`{n}`' for n in names)} by no stage of `ikbench reproduce`"
                 for cmd, names in sorted(by_command.items())]
        text += (" The other files here come from other commands, which `ikbench reproduce` "
                 "does not run (`ikbench reproduce --all` runs every one): " + "; ".join(parts)
                 + ".")
    return [text, ""]


def write_results_readme(output: str | Path, times: dict[str, float], quick: bool,
                         comparison: str | Path) -> Path:
    """Write ``output/README.md`` from the files the stages wrote; return its path.

    Args:
        output: the results directory.
        times: wall time [s] per stage and ``"total"``.
        quick: whether the quick configuration produced the results.
        comparison: the comparison report's path.
    """

    output = Path(output)
    figure = Path(os.path.relpath(Path(comparison).parent / FIGURE_NAME, output)).as_posix()
    comparison = Path(os.path.relpath(comparison, output)).as_posix()
    ours, baseline = _read(output, f"{OURS}/table.csv"), _read(output, f"{BASELINE}/table.csv")
    interpolation = _read(output, f"{INTERPOLATION_RUN}/table.csv")
    ablation = _read(output, "ablation/table.csv")
    summary = _read(output, "ablation/summary.csv")
    claims = check_claims(ablation)
    measured = load_comparison(output)
    record = provenance()
    command = "ikbench reproduce" + (" --quick" if quick else "")
    lines = [
        "# Reproduction of *Generating and Customizing Robotic Arm Trajectories using Neural "
        "Networks* (Lúčny et al.)", "",
        f"Produced by `{command}` "
        + (f"(**quick pipeline check**: trajectory {QUICK['only']}, n = {QUICK['steps']}, "
           f"at most {QUICK['max_iterations']} iterations; not the paper's configuration) "
           if quick else "")
        + f"in {_elapsed(times['total'])} on {record['cpu']} ({record['cpu_count']} cores, "
        f"torch threads {record['torch_threads']}), {record['created_utc']}. Every measured "
        "number is computed by `ikbench.core.metrics` from the trajectory CSVs written here; paper "
        "values appear only in columns labelled *paper*.", "",
        *_provenance_lines(output, command),
        "| stage | wall time |", "|---|---|",
        *[f"| {stage} | {_elapsed(t)} |" for stage, t in times.items()], "",
        "## Table 1: the paper's method (`ours`)", "",
        markdown_table(table1_comparison(ours), {"loss": 2, "paper loss": 2,
                                                 "duration [s]": 1, "paper duration [s]": 0}),
        "", "Details: [ours/report.md](ours/report.md).", "",
        *_figures("ours", ["trajectories_3d.png", "pointing_error.png"]),
        f"## Table 2: the traditional baseline (`{BASELINE_METHOD}`, --orientation frame)", "",
        markdown_table(table2_comparison(baseline)), "", TABLE2_UNITS_NOTE, "",
        PAPER_BASELINE_NOTE, "",
        f"Task solved: {WALK_TASK}, as the paper's Table 2 was made; the orientation modes "
        f"and the authors' call below walk too. `{BASELINE}` and `ikpy` (without `-walk`) track "
        "from the start pose onto the touch pose instead (the paper's task: start and touch "
        "poses fixed); `ikbench compare` runs them.", "",
        f"Details: [{BASELINE}/report.md]({BASELINE}/report.md).", "",
        *_figures(BASELINE, ["trajectories_3d.png", "pointing_error.png"]),
        *_authors_section(output, times),
        "### The baseline's three orientation modes", "",
        f"`{BASELINE_METHOD}` into `{BASELINE}/` (frame, its default), "
        + ", ".join(f"`{name}/` (`--orientation {mode}`)" for mode, name in
                    BASELINE_MODES.items())
        + (f", the authors' call (`{AUTHORS_METHOD}`) `{AUTHORS_RUN}/`"
           if AUTHORS_STAGE in times else "")
        + f", all walks from the touch pose (touch-pose-only task), beside `{OURS}` and the "
        "paper's Table 2:", "",
        escaped_table(modes_table(measured.frame, measured.runs, measured.targets.steps,
                                  measured.targets.is_paper)), "", MODES_NOTE, "",
        "## Comparison with the baseline", "",
        f"The paper's claims about its baseline, checked for each mode and stating the task "
        f"each run solved (from "
        f"[{comparison}]({comparison}), `ikbench.paper.comparison`, which also has the runs "
        "side by "
        "side per trajectory).", "",
        *claims_lines(measured.summary, measured.runs, measured.frame, level=3),
        f"![pointing deviation per step]({figure})", "",
        "## Ablation of the loss terms", "", claims_table(claims), "",
        markdown_table(summary[["variant", "trajectories", "hit_cap", *SUMMARY_COLUMNS]]
                       .rename(columns={"hit_cap": "runs at cap", **SUMMARY_METRICS}),
                       {"iterations": 0}), "",
        f"Means over the trajectories; `{FULL}` is the paper's loss. Details, per-trajectory "
        "figures and the tests behind each verdict: [ablation/report.md](ablation/report.md).",
        "", *_figures("ablation", ["metrics.png", "trajectories_3d.png", "joints.png"]),
        "## Deviations from the paper", "", *DEVIATIONS,
        _initialisation_finding(ours, interpolation),
        _baseline_finding(measured.frame, AUTHORS_STAGE in times),
        *([] if quick else _table1_findings(ours)),
        *[f"- **Ablation: not confirmed.** {c['claim']} ({c['evidence']}; test: {c['test']})"
          for c in claims if c["verdict"] == "does not hold"], "",
        "## Versions and machine", "",
        f"- ikbench git {record['git_revision']}; Python {record['python']}; "
        f"{record['platform']}", f"- CPU: {record['cpu']}, {record['cpu_count']} cores "
        f"(torch threads {record['torch_threads']}; OMP_NUM_THREADS="
        f"{os.environ.get('OMP_NUM_THREADS', 'unset')})",
        "- packages: " + ", ".join(f"{k} {v}" for k, v in record["packages"].items()), ""]
    return atomic_write_text(output / "README.md", "\n".join(lines))
