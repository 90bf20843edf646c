"""``ikbench reproduce``: the whole pipeline end to end on the quick configuration, and clear
errors when a part it needs is missing."""

from __future__ import annotations

import contextlib
import io
import json
import re

import pandas as pd
import pytest

import ikbench.paper.reproduce as reproduce_module
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.methods.registry import method_status
from tests.conftest import exit_code, fails_if_called, unwritable_output_error

#: Table 2 as the authors ran it (ikpy-walk) is a stage when ikpy is installed ([libs]).
IKPY = method_status()["ikpy-walk"].available
STAGES = 9 if IKPY else 8
#: How the report labels the walks reproduce runs (the paper's baseline's task).
WALK = "walk from the touch pose: touch-pose-only task"


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """``reproduce --quick`` into a folder that already holds other commands' files."""
    out = tmp_path_factory.mktemp("reproduce") / "results"
    (out / "sweep").mkdir(parents=True)
    (out / "benchmark.md").write_text("by ikbench bench")
    (out / "benchmark_runs.csv").write_text("by ikbench bench")
    (out / "mystery.txt").write_text("by hand")
    (out / "ours_speed.csv").write_text("by benchmarks/ours_speed.py")
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        assert main(["reproduce", "--quick", "--output", str(out), "--log", "-"]) == 0
    return out, stdout.getvalue(), stderr.getvalue()


def test_quick_pipeline_end_to_end(quick):
    out, stdout, stderr = quick
    assert f"stage {STAGES}/{STAGES}" in stderr and "total time" in stderr
    assert stdout.splitlines()[-1].startswith("total")
    for name in ["ours/table.csv", "sequential-ik/table.csv", "ablation/table.csv",
                 "sequential-ik-pointing/table.csv", "sequential-ik-position/table.csv",
                 "ours-init-interpolation/table.csv", "report.md",
                 "ablation/report.md", "ablation/metrics.png", "README.md"]:
        assert (out / name).stat().st_size > 0, name
    for name, mode in [("sequential-ik", "frame"), ("sequential-ik-pointing", "pointing"),
                       ("sequential-ik-position", "position")]:
        record = json.loads((out / name / "run.json").read_text())
        assert record["settings"]["settings"]["orientation"] == mode and record["name"] == name
        # the authors' walk, as Table 2 was made (sequential-ik itself tracks)
        assert record["method"] == "sequential-ik-walk"
        assert record["settings"]["settings"]["scheme"] == "walk"
    assert json.loads((out / "ours-init-interpolation" / "run.json").read_text())[
        "settings"]["settings"]["init"] == "interpolation"
    if IKPY:  # the authors' call: ikpy walked back from the touch pose, position only
        record = json.loads((out / "ikpy" / "run.json").read_text())
        settings = record["settings"]["settings"]
        assert record["method"] == "ikpy-walk" and record["name"] == "ikpy"
        assert settings["orientation"] == "position" and settings["scheme"] == "walk"
    ablation = pd.read_csv(out / "ablation/table.csv")
    assert list(ablation["variant"]) == ["full", "no-L0", "no-L1", "no-L2", "no-L3", "no-L4",
                                         "no-L5", "no-L6", "no-L2-L3-L4-L5"]
    readme = (out / "README.md").read_text()
    for heading in ["## Table 1", "## Table 2", "### The baseline's three orientation modes",
                    "## Comparison with the baseline", "## Ablation of the loss terms",
                    "## Deviations from the paper", "## Versions and machine"]:
        assert heading in readme
    assert "quick pipeline check" in readme
    assert "paper line distance [mm]" in readme and "paper start point variation [mm]" in readme
    assert readme.count("**holds**") + readme.count("**does not hold**") == 6
    # every figure and report the page links to exists
    for link in [part.split(")")[0] for part in readme.split("](")[1:]]:
        assert (out / link).exists(), link


def test_readme_says_which_command_wrote_what(quick):
    out, _, _ = quick
    readme = (out / "README.md").read_text()
    assert "Everything in this folder" not in readme
    assert ("`ikbench reproduce --quick` wrote `README.md`, `report.md`, "
            "`pointing_deviation_per_step.png`, `ours/`, `sequential-ik/`, "
            "`sequential-ik-pointing/`, `sequential-ik-position/`, "
            + ("`ikpy/`, " if IKPY else "") + "`ours-init-interpolation/`, "
            "`ablation/`.") in readme
    assert "`benchmark.md`, `benchmark_runs.csv` by `ikbench bench --output results`" in readme
    assert ("`sweep/` by `ikbench sweep --weight c0=1,10,100,1000 --weight c1=10,50,200,500 "
            "--output results/sweep`") in readme
    assert ("`ours_speed.csv` by `python benchmarks/ours_speed.py --output "
            "results/ours_speed.csv`") in readme
    assert "`mystery.txt` by no stage of `ikbench reproduce`" in readme


def test_readme_text_is_measured_and_self_contained(quick):
    out, _, _ = quick
    readme = (out / "README.md").read_text()
    for stale in ("settings above", "see the last section", "59-70", "about 100 iterations"):
        assert stale not in readme, stale
    # the three modes, from their runs
    modes = readme.split("### The baseline's three orientation modes")[1].split("\n## ")[0]
    for name in ("sequential-ik", "sequential-ik-pointing", "sequential-ik-position"):
        table = pd.read_csv(out / name / "table.csv")
        row = next(line for line in modes.splitlines() if line.startswith(f"| {name} |"))
        assert f"| {table['pointing_deviation_mean_deg'].iloc[0]:.2f} |" in row
        assert f"| {table['line_distance_mean_mm'].iloc[0]:.2f} |" in row
        assert f"| {table['start_point_error_mm'].iloc[0]:.2f} |" in row
    # the deviations quote the runs
    interpolation = pd.read_csv(out / "ours-init-interpolation" / "table.csv")
    assert f"fires after {interpolation['iterations'].iloc[0]} iterations" in readme
    position = pd.read_csv(out / "sequential-ik-position" / "table.csv")
    assert (f"mean pointing deviations of {position['pointing_deviation_mean_deg'].iloc[0]:.1f}"
            " deg per trajectory against the paper's 65 deg") in readme
    # the task the baseline runs solved: the authors' walk (touch pose only)
    assert "Task solved: the authors' walk back from the touch pose (touch-pose-only task: " \
        "the start pose is free), as the paper's Table 2 was made" in readme
    assert "| task solved |" in modes
    assert "all walks from the touch pose (touch-pose-only task)" in modes
    # one claims table per mode, each with the line distance in the pointing claim
    for name, mode in [("sequential-ik", "frame"), ("sequential-ik-pointing", "pointing"),
                       ("sequential-ik-position", "position")]:
        heading = f"### `{name}` (sequential-ik-walk, --orientation {mode}; {WALK})"
        assert f"{heading} against `ours`" in readme
        claims = readme.split(heading)[1].split("\n### ")[0]
        assert "Task solved: walk from the touch pose (touch-pose-only task" in claims
        assert "a property of the walk" in claims
        pointing = next(line for line in claims.splitlines()
                        if line.startswith("| its pointing deviation is much worse"))
        assert "meanwhile mean line distance: ours " in pointing and f", {name} " in pointing
        assert f"{name}: " in pointing and " points missed the IK tolerance" in pointing
    # stage times: sub-second stages are not "0 s"
    stages = readme.split("| stage | wall time |")[1].split("\n\n")[0]
    times = [line.split(" | ")[1].rstrip(" |") for line in stages.splitlines()[2:]]
    assert len(times) == STAGES and all(re.fullmatch(r"\d+\.\d s|\d+ min \d\d s", t)
                                   for t in times), times


def test_elapsed_shows_tenths_below_a_minute():
    assert reproduce_module._elapsed(0.2) == "0.2 s"
    assert reproduce_module._elapsed(42.04) == "42.0 s"
    assert reproduce_module._elapsed(156.4) == "2 min 36 s"


def test_empty_output_is_rejected(capsys):
    assert exit_code(["reproduce", "--quick", "--output", ""]) == 2  # the CLI refuses it first
    err = capsys.readouterr().err
    assert err == ("ikbench: error: argument --output: '' is empty; give a file or "
                   "folder to write (see ikbench reproduce --help)\n")
    with pytest.raises(InputError, match=r"--output: '' is empty; give a directory \(default "
                       r"results, or results-quick with --quick\)"):
        reproduce_module._output_dir("", quick=True)  # and so does the library


def test_unwritable_output_fails_before_any_solve(tmp_path, monkeypatch, capsys):
    fails_if_called(monkeypatch, reproduce_module, "run")
    err = unwritable_output_error(capsys, tmp_path, ["reproduce", "--quick"])
    assert "is a file, not a directory" in err
    out = tmp_path / "results"
    (out / "README.md").mkdir(parents=True)  # README.md, written last, is taken by a folder
    assert main(["reproduce", "--quick", "--output", str(out)]) == 2
    assert "README.md: it is a directory" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["README.md"]  # no ours/ left behind


def test_help_gives_the_measured_duration(capsys):
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "takes a few minutes on 2 cores" in text and "15 minutes" not in text


def test_missing_baseline_is_a_clear_error_before_any_work(tmp_path, monkeypatch, capsys):
    real = reproduce_module.get_method

    def no_baseline(name):
        if name == "sequential-ik-walk":
            raise InputError(f"--method: unknown method {name!r}; available: ours")
        return real(name)

    monkeypatch.setattr(reproduce_module, "get_method", no_baseline)
    assert main(["reproduce", "--quick", "--output", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ikbench: error: Table 2 needs the method 'sequential-ik-walk' "
                          "(baselines/sequential_ik.py)")
    assert not (tmp_path / "r").exists()


@pytest.mark.skipif(not IKPY, reason=f"ikpy-walk: {method_status()['ikpy-walk'].reason}")
def test_readme_shows_table2_as_the_authors_ran_it(quick):
    out, _, _ = quick
    readme = (out / "README.md").read_text()
    section = readme.split("### Table 2 as the authors ran it (`ikpy-walk`, their call)")[1]
    section = section.split("\n### ")[0]
    table = pd.read_csv(out / "ikpy" / "table.csv")
    assert f"| {table['line_distance_mean_mm'].iloc[0]:.2f} |" in section
    assert "their library (ikpy) and their call" in section
    assert "Task solved: the authors' walk back from the touch pose" in section
    assert f"### `ikpy` (ikpy-walk, --ikpy-orientation position; {WALK}) against `ours`" \
        in readme
    assert "The authors' own call on this robot (`ikpy-walk`" in readme
    report = (out / "report.md").read_text()
    assert f"## Beside the paper's Table 2: ikpy (ikpy-walk, --ikpy-orientation position; " \
        f"{WALK}), the authors' call" in report


def test_a_skipped_authors_stage_is_explained(monkeypatch, tmp_path):
    monkeypatch.setattr(reproduce_module, "_authors_method",
                        lambda: (None, "needs ikpy (pip install 'ikbench[libs]')"))
    lines = reproduce_module._authors_section(tmp_path, {"Table 2: sequential-ik": 1.0})
    assert lines[2] == ("Not run: needs ikpy (pip install 'ikbench[libs]'). `ikbench "
                        "reproduce` runs it when ikpy is installed.")
