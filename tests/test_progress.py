"""Progress a person can read (ikbench.runtime.progress): a bar on a terminal, JSON lines
with --log, a few plain lines for library calls, nothing when asked for quiet."""

from __future__ import annotations

import io
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from ikbench.methods.base import Method, Solution, hearing_fraction, report_fraction
from ikbench.runtime import progress
from ikbench.runtime.harness import Progress, solve_tasks
from ikbench.runtime.progress import Reporter
from ikbench.schemes.track import TrackPlan, track
from ikbench.schemes.walk import PointResult, walk_back


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


# ----- progress within an item (issue 49 item 5) ------------------------------------------------
class Fractions(Method):
    """Reports ``steps`` fractions per trajectory (``report_fraction``) and notes where the
    study's count stood at each; ``silent``: reports nothing."""

    name = "fractions"
    description = "reports how far it is (tests)"

    def __init__(self, steps: int = 4, silent: bool = False) -> None:
        super().__init__()
        self.steps, self.silent, self.seen = steps, silent, []

    def solve(self, robot, task, progress=None) -> Solution:
        self.seen.append(progress.position)
        for k in range(1, self.steps + 1):
            if not self.silent:
                report_fraction(k, self.steps)
            self.seen.append(progress.position)
        return Solution(np.zeros((task.goal.steps + 1, 1)), iterations=self.steps, duration_s=0.0,
                        loss=None)


def _tasks(count: int) -> list:
    return [SimpleNamespace(name=str(k + 1), goal=SimpleNamespace(steps=4, has_frames=False),
                            required=SimpleNamespace(end_pose=None))
            for k in range(count)]


def test_the_count_moves_within_a_trajectory_by_the_fraction_its_method_reports():
    """The bar sat at 6/7 through the whole 7th trajectory; now it is at 6 + the fraction."""
    method = Fractions(steps=4)
    solve_tasks(method, None, _tasks(3), Progress("run", stream=io.StringIO()))
    assert method.seen == [0.0, 0.25, 0.5, 0.75, 1.0,
                           1.0, 1.25, 1.5, 1.75, 2.0,
                           2.0, 2.25, 2.5, 2.75, 3.0]


def test_a_method_that_cannot_say_moves_the_count_once_per_trajectory():
    method = Fractions(steps=2, silent=True)
    solve_tasks(method, None, _tasks(3), Progress("run", stream=io.StringIO()))
    assert method.seen == [0, 0, 0, 1, 1, 1, 2, 2, 2]


def test_the_bar_shows_the_fractional_count_rounded(capsys):
    progress.configure("bar")
    seen = []

    class Bar(Fractions):
        def solve(self, robot, task, progress=None):
            report_fraction(1, 3)
            seen.append(progress._bar.format_dict["n"])
            return super().solve(robot, task, progress)

    solve_tasks(Bar(steps=1), None, _tasks(2), Progress("run"))
    assert seen == [0.33, 1.33]  # not 1.3333333333333333
    assert "/2" in capsys.readouterr().err


def test_a_fraction_is_clipped_never_nan_and_never_moves_the_count_back():
    reporter = Reporter("run", total=3, stream=io.StringIO())
    reporter.within(0.5)  # nothing begun: nothing moves
    assert reporter.position == 0
    heard = []
    with hearing_fraction(heard.append):
        for done, total in ((math.nan, 4), (1, 0), (1, math.nan), (1, -2), (5, 4), (1, 4)):
            report_fraction(done, total)
    assert heard == [1.0, 0.25]
    reporter.begin(3)  # a batch of three solved at once
    reporter.within(0.5)
    reporter.within(0.25)  # a second phase starting over: the count stays
    assert reporter.position == 1.5
    reporter.within(math.nan)
    reporter.advance(1)
    assert reporter.position == 1 + 0.5 * 2
    reporter.advance(2)
    assert (reporter.position, reporter.in_flight, reporter.fraction) == (3, 0, 0.0)


def test_the_periodic_line_says_how_far_the_running_trajectory_is(monkeypatch, capsys):
    clock = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock[0])
    progress.configure("periodic")
    with Reporter("run", total=7, unit="trajectory") as reporter:
        reporter.advance(6, "trajectory 6: done")
        reporter.begin(1)
        reporter.say("trajectory 7 (7/7): solving, n = 100")
        for k in range(1, 11):  # the 7th takes 30 s, its method reports every 3 s
            clock[0] += 3.0
            reporter.within(k / 10)
        reporter.advance(1, "trajectory 7: done")
        reporter.begin(2)  # a batch: no fraction heard yet, so none is shown
        clock[0] += 10.0
        reporter.say("solving a batch")
        clock[0] += 10.0
        reporter.within(0.5)
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["[run 0:00] 6/7 done; trajectory 6: done",
                     "[run 0:12] 6/7 done, trajectory 7/7 at 40 %; trajectory 7 (7/7): "
                     "solving, n = 100",
                     "[run 0:24] 6/7 done, trajectory 7/7 at 80 %; trajectory 7 (7/7): "
                     "solving, n = 100",
                     "[run 0:40] 7/7 done; solving a batch",
                     "[run 0:50] 7/7 done, trajectory 8-9/7 at 50 %; solving a batch"]


def test_compare_counts_a_method_by_its_solves_done():
    """compare's bar counts methods: a method's warm-up and timed rounds move it."""
    from ikbench.studies.compare import solve_method

    heard = []
    method = Fractions(steps=2)
    with hearing_fraction(heard.append):
        single, batched = solve_method(("fractions", method, None, _tasks(2), 1, 2))
    assert heard == [k / 6 for k in range(1, 7)]  # the method's own fractions not heard here
    assert len(single) == 2 and batched == []


def test_the_sequential_schemes_report_their_waypoints():
    chain = SimpleNamespace(dof=1, clip=lambda q: q)

    class Goals(SimpleNamespace):
        def __len__(self):
            return 5

    def solve_point(i, warm):
        return PointResult(warm, 1, True)

    heard = []
    with hearing_fraction(heard.append):
        walk_back(solve_point, chain, Goals(q_touch=np.zeros(1), q_home=None))
    assert heard == [0.25, 0.5, 0.75, 1.0]
    heard.clear()
    plan = TrackPlan(np.zeros((5, 3)), None, np.zeros((5, 1)), np.zeros(1), np.zeros(1), 1)
    with hearing_fraction(heard.append):
        track(solve_point, chain, plan)
    assert heard == [1 / 3, 2 / 3, 1.0]  # steps 1..3; rows 0 and 4 are the given poses


@pytest.mark.parametrize("name, options", [
    ("ours", {"max_iterations": 40, "progress_every": 10, "stop": "none"}),
    ("sequential-ik", {}),
])
def test_ours_and_sequential_ik_say_how_far_they_are(robot, paper_targets, name, options):
    from ikbench.core.task import line_tasks
    from ikbench.methods.registry import get_method

    targets = paper_targets.select("1").with_steps(6)
    heard = []
    method = get_method(name)(**options)
    updates = SimpleNamespace(update=lambda task, iteration, loss: None)  # ours' status
    with hearing_fraction(heard.append):
        method.solve(robot, line_tasks(robot, targets)[0], updates)
    # ours: every 10 of its 40 iterations; sequential-ik tracks steps 1..5 of the 6 segments
    expected = [0.25, 0.5, 0.75, 1.0] if name == "ours" else [k / 5 for k in range(1, 6)]
    assert heard == pytest.approx(expected)


def test_compares_status_names_the_method_now_running(monkeypatch, capsys):
    """Between methods the periodic line names the one running, not the last one's result."""
    from ikbench.studies.compare import _begun

    clock = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock[0])
    progress.configure("periodic")
    work = [("first", None, None, [], 0, 1), ("second", None, None, [], 0, 1)]
    with Reporter("compare", total=2, unit="method") as reporter:
        jobs = _begun(work, reporter)
        next(jobs)
        clock[0] += 40.0
        reporter.advance(1, "first: solved, median 0.1 s")
        next(jobs)
        clock[0] += 40.0
        reporter.within(0.5)
    last = capsys.readouterr().err.splitlines()[-1]
    assert last == "[compare 1:20] 1/2 done, method 2/2 at 50 %; second: solving"
