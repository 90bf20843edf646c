"""ikbench bench: timings, ratios, losses and the files it writes; bad input via the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.methods.ours import Ours
from ikbench.studies.bench import (
    TOTAL,
    TOTAL_BATCHED,
    BenchResult,
    benchmark,
    markdown,
    parse_repeat,
    speedup_ranges,
    write,
)
from tests.conftest import fails_if_called, unwritable_output_error


def test_parse_repeat():
    assert parse_repeat("5,ours=3", ["ours", "ours-lm"]) == {"ours": 3, "ours-lm": 5}
    assert parse_repeat(2, ["ours-lm"]) == {"ours-lm": 2}
    for bad in ("0", "x", "ours=", "=3", "5,ours=-1"):
        with pytest.raises(InputError, match="--repeat"):
            parse_repeat(bad, ["ours"])
    with pytest.raises(InputError, match="--repeat: 'foo=3' names 'foo', which is not "
                                         "benchmarked; methods: ours, ours-lm"):
        parse_repeat("2,foo=3", ["ours", "ours-lm"])
    assert parse_repeat("2, ours-lm = 4", ["ours", "ours-lm"]) == {"ours": 2, "ours-lm": 4}
    # the default's ours=3 applies only when ours is benchmarked
    assert parse_repeat(None, ["ours", "ours-lm"]) == {"ours": 3, "ours-lm": 5}
    assert parse_repeat(None, ["ours-lm"]) == {"ours-lm": 5}


def test_benchmark_two_methods_summary_and_files(tmp_path):
    # a capped Adam keeps the test fast; the ratios are against the first method
    solvers = {"ours": Ours(max_iterations=20, init="interpolation")}
    result = benchmark(["ours", "ours-lm"], repeat="2,ours=1", warmup=0, only="1,3", steps=8,
                       solvers=solvers, progress=False)
    s = result.summary.set_index(["method", "trajectory"])
    assert set(s.index) == {("ours", "1"), ("ours", "3"), ("ours", TOTAL), ("ours-lm", "1"),
                            ("ours-lm", "3"), ("ours-lm", TOTAL), ("ours-lm", TOTAL_BATCHED)}
    assert s.loc[("ours-lm", "1"), "rounds"] == 2 and s.loc[("ours", "1"), "rounds"] == 1
    row = s.loc[("ours-lm", "3")]
    assert row["wall_min_s"] <= row["wall_median_s"] <= row["wall_max_s"]
    # 20 Adam steps are far from the optimum that LM reaches
    assert s.loc[("ours-lm", "1"), "loss"] < s.loc[("ours", "1"), "loss"]
    assert s.loc[("ours-lm", "1"), "loss_change_vs_ours_pct"] < 0
    total = s.loc[("ours-lm", TOTAL)]
    assert total["speedup_vs_ours"] == pytest.approx(
        s.loc[("ours", TOTAL), "wall_median_s"] / total["wall_median_s"])
    runs = result.runs
    assert len(runs[(runs["method"] == "ours-lm") & (runs["mode"] == "single")]) == 4
    assert bool(s["within_limits"].dropna().all())

    path = write(result, tmp_path)
    assert pd.read_csv(path).shape[0] == len(result.summary)
    record = json.loads((tmp_path / "benchmark.json").read_text())
    assert record["repeat"] == {"ours": 1, "ours-lm": 2}
    assert {"cpu", "git_revision", "packages"} <= set(record)
    assert record["packages"]["scipy"]           # ours-lm's LAPACK pbsv comes from scipy
    md = (tmp_path / "benchmark.md").read_text()
    assert "## Totals" in md and "speedup_vs_ours" in md


def test_bench_cli_writes_csv(tmp_path, capsys):
    code = main(["bench", "--methods", "ours-lm", "--repeat", "2", "--warmup", "0",
                 "--only", "2", "--steps", "6", "--output", str(tmp_path), "--quiet"])
    assert code == 0
    out = capsys.readouterr().out
    assert "total" in out and "benchmark.csv" in out
    frame = pd.read_csv(tmp_path / "benchmark.csv", dtype={"trajectory": str})
    assert list(frame["trajectory"]) == ["2", TOTAL, TOTAL_BATCHED]


@pytest.mark.parametrize("args, message", [
    (["--methods", "ours,nope"], "ikbench: error: --methods: unknown method 'nope'; available:"),
    (["--repeat", "ours=x"], "ikbench: error: --repeat: 'ours=x' is not N or method=N"),
    (["--warmup", "-1"], "ikbench: error: argument --warmup: -1 is out of range; give a "
     "number of warm-up rounds from 0 to 100"),
    (["--threads", "0"], "ikbench: error: argument --threads: 0 is out of range; give a "
     "number of threads from 1 to 1024"),
    (["--only", "9"], "ikbench: error: --only: unknown trajectory id(s) '9'; available:"),
    (["--repeat", "2,foo=3"], "ikbench: error: --repeat: 'foo=3' names 'foo', which is not "
     "benchmarked; methods: ours-lm"),
])
def test_bench_cli_bad_input_one_line_exit_2(tmp_path, args, message):
    exe = [sys.executable, "-m", "ikbench.cli", "bench", "--methods", "ours-lm",
           "--output", str(tmp_path), "--quiet", *args]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(message)
    assert not (tmp_path / "benchmark.csv").exists()


def test_markdown_states_the_range_of_per_trajectory_speedups():
    rows = [("ours", "1", 2.0), ("ours", "2", 9.0), ("ours", TOTAL, 11.0),
            ("ours-lm", "1", 0.01), ("ours-lm", "2", 0.002), ("ours-lm", TOTAL, 0.012),
            ("ours-lm", TOTAL_BATCHED, 0.005)]
    summary = pd.DataFrame([{"method": m, "trajectory": t, "rounds": 3, "wall_median_s": w,
                             "wall_min_s": w, "wall_max_s": w, "loss": 1.0} for m, t, w in rows])
    base = summary[summary["method"] == "ours"].set_index("trajectory")["wall_median_s"]
    summary["speedup_vs_ours"] = [base.get(t, base[TOTAL]) / w for _, t, w in rows]
    summary["loss_change_vs_ours_pct"] = 0.0
    for column in ("line_distance_mean_mm", "pointing_deviation_mean_deg",
                   "end_point_error_mm", "within_limits"):
        summary[column] = 0.0
    # per trajectory 200x and 4500x; the total (917x) lies between and hides the 200x
    assert speedup_ranges(summary, "ours") == {"ours-lm": (200.0, "1", 4500.0, "2")}
    record = {"methods": ["ours", "ours-lm"], "repeat": {"ours": 3, "ours-lm": 3},
              "warmup": 1, "targets": "paper", "trajectories": ["1", "2"], "steps": 50,
              "packages": {}, "cpu": "cpu", "cpu_count": 2, "torch_threads": 1,
              "python": "3", "platform": "p", "git_revision": "g", "created_utc": "t"}
    md = markdown(BenchResult(summary, pd.DataFrame(), record))
    assert "- ours-lm: 200.0x (trajectory 1) to 4500.0x (trajectory 2)" in md


def test_bench_cli_checks_the_output_before_timing(tmp_path, capsys, monkeypatch):
    import ikbench.studies.bench

    fails_if_called(monkeypatch, ikbench.studies.bench, "benchmark")
    err = unwritable_output_error(capsys, tmp_path, ["bench", "--methods", "ours-lm", "--quiet"])
    assert "cannot write" in err


def test_a_timed_result_without_its_markdown_cannot_be_made():
    """TimedResult.markdown is abstract: a timing study's result must say how it reads."""
    import pandas as pd

    from ikbench.studies.shape import TimedResult

    class NoText(TimedResult):
        STEM = "x"

    with pytest.raises(TypeError, match="markdown"):
        NoText(pd.DataFrame(), pd.DataFrame(), {})
