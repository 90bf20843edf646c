"""Progress a person can read (ikbench.runtime.progress): a bar on a terminal, JSON lines
with --log, a few plain lines for library calls, nothing when asked for quiet."""

from __future__ import annotations

import io
import json

import pytest

from ikbench.runtime import progress
from ikbench.runtime.progress import Reporter


@pytest.fixture(autouse=True)
def restore():
    yield
    progress.configure("lines", None)


def test_a_bar_replaces_a_line_per_update(capsys):
    """bench printed ~1,500 lines a second; the bar redraws a few times a second."""
    progress.configure("bar")
    with Reporter("bench", total=5000, unit="solve") as bar:
        for k in range(5000):
            bar.advance(1, f"trajectory {k}")
    err = capsys.readouterr().err
    assert "bench" in err and "/5000" in err and "solve/s" in err  # count, rate
    assert err.count("\n") < 10 and err.count("\r") < 500


def test_log_lines_are_json_and_the_last_update_is_always_there():
    log = io.StringIO()
    progress.configure("off", log)
    reporter = Reporter("dataset", total=3000, unit="trajectory")
    reporter.note("3000 trajectories in 3 shards")
    for _ in range(3):
        reporter.advance(1000, "shard")
    reporter.close()
    events = [json.loads(line) for line in log.getvalue().splitlines()]
    assert [e["event"] for e in events] == ["note", "advance", "advance", "close"]
    assert events[-2]["done"] == events[-2]["total"] == 3000  # the last, though within 0.5 s
    assert set(events[0]) == {"t_s", "label", "event", "done", "total", "text"}


def test_plain_lines_are_throttled_and_notes_always_shown():
    stream = io.StringIO()
    reporter = Reporter("bench", total=1000, stream=stream)
    for k in range(1000):
        reporter.advance(1, f"solve {k}")
    reporter.note("FAILED: trajectory 3")
    lines = stream.getvalue().splitlines()
    assert lines[0] == "[bench] 1/1000 solve 0" and lines[-2] == "[bench] 1000/1000 solve 999"
    assert lines[-1] == "[bench] FAILED: trajectory 3" and len(lines) <= 4


def test_quiet_and_disabled_report_nothing(capsys):
    progress.configure("off")
    Reporter("sweep", total=2).advance(2, "done")
    Reporter("sweep", enabled=False, stream=io.StringIO()).note("not shown")
    assert capsys.readouterr().err == ""


def test_a_command_leaves_the_library_default_behind(tmp_path):
    """The CLI sets the mode for one command (off: stderr is not a terminal here) and its
    --log file; after it, a library call in the same process reports lines again."""
    from ikbench.cli import main

    log = tmp_path / "log.jsonl"
    assert main(["sweep", "--weight", "c0=10", "--only", "1", "--steps", "4", "--output",
                 str(tmp_path / "out"), "--log", str(log)]) == 0
    assert progress.mode() == "lines" and progress._config["log"] is None
    assert log.read_text().splitlines()[-1].startswith('{"t_s"')  # written and closed


def test_a_log_file_gets_a_start_line_and_then_one_every_ten_seconds(monkeypatch, capsys):
    """With stderr a pipe or a log file there was no output for minutes; a tqdm bar there
    would be a redraw per update."""
    clock = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock[0])
    progress.configure("periodic")
    with Reporter("run", total=7, unit="trajectory") as reporter:
        for k in range(70):  # one update every 0.5 s for 35 s
            reporter.say(f"trajectory {k // 10 + 1}: iteration {k}, loss 12.5")
            if k % 10 == 9:
                reporter.advance(1, f"trajectory {k // 10 + 1}: done")
            clock[0] += 0.5
        reporter.note("trajectory 7: FAILED: no solution")
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["[run 0:00] 0/7 done; trajectory 1: iteration 0, loss 12.5",
                     "[run 0:10] 2/7 done; trajectory 3: iteration 20, loss 12.5",
                     "[run 0:20] 4/7 done; trajectory 5: iteration 40, loss 12.5",
                     "[run 0:30] 6/7 done; trajectory 7: iteration 60, loss 12.5",
                     "[run 0:35] trajectory 7: FAILED: no solution"]


def test_a_method_without_a_loss_shows_a_dash_not_nan():
    assert progress.loss_text(float("nan")) == progress.loss_text(None) == "\u2013"
    assert progress.loss_text(12.34567) == "12.3457"
    assert progress.loss_text(12.34567, 3) == "12.346"


def test_run_sequential_ik_through_a_pipe(tmp_path):
    """`run --method sequential-ik` printed `loss NaN`; stderr, not a terminal, now gets a
    start line (no bar) and the table shows a dash."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "ikbench.cli", "run", "--method",
                           "sequential-ik", "--only", "1", "--steps", "10", "--no-animation",
                           "--output", str(tmp_path)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "nan" not in proc.stdout.lower() and "nan" not in proc.stderr.lower()
    header, row = proc.stdout.splitlines()[:2]
    assert row.split()[header.split().index("loss")] == "\u2013"
    assert proc.stderr.splitlines()[0].startswith("[sequential-ik 0:0")
    assert "\r" not in proc.stderr and len(proc.stderr.splitlines()) <= 2
