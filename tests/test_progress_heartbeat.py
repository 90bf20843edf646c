"""The progress heartbeat (ikbench.runtime.progress, issue 64 item 6): a line when no line was
written for PERIODIC_EVERY_S seconds, while a long item (one library call, a method that
reports nothing) runs; none after close, in off mode, for a disabled reporter, for a reporter
whose study returned, or after the command ended. The period is patched to a few hundredths
of a second; the tests wait by polling with a safety timeout and never assert elapsed
times."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import time
import warnings
from types import SimpleNamespace

import pytest

from ikbench.runtime import progress
from ikbench.runtime.progress import Reporter

PERIOD_S = 0.05
SAFETY_S = 10.0  # a safety net only: each wait ends as soon as what it waits for is there
BEAT = re.compile(r"^\[(\S+) \d+:\d\d\] .*; still working$")


@pytest.fixture(autouse=True)
def fast_heartbeat(monkeypatch):
    monkeypatch.setattr(progress, "PERIODIC_EVERY_S", PERIOD_S)
    yield
    progress.configure("lines", None)


def beats(stream: io.StringIO) -> list[str]:
    return [line for line in stream.getvalue().splitlines() if BEAT.match(line)]


def wait_for(condition, what: str) -> None:
    deadline = time.monotonic() + SAFETY_S
    while not condition():
        assert time.monotonic() < deadline, f"no {what} within {SAFETY_S} s"
        time.sleep(0.01)


def after_two_more_beats(stream: io.StringIO) -> None:
    """``stream``'s reporter (a control, opened in the test: one opened in a helper that
    returned gets no heartbeat) beat twice more: the heartbeat looked at all the others at
    least once since."""
    seen = len(beats(stream))
    wait_for(lambda: len(beats(stream)) >= seen + 2, "control heartbeat")


def test_a_reporter_that_hears_nothing_still_writes_lines():
    """compare went 140 s without a line while one library call solved a trajectory."""
    stream = io.StringIO()
    reporter = Reporter("compare", total=7, unit="method", stream=stream)
    reporter.advance(3, "ours-lm: solved")
    reporter.begin(1)
    reporter.say("ours-exact: solving")
    reporter.within(0.4)
    wait_for(lambda: len(beats(stream)) >= 2, "heartbeat")
    reporter.close()
    line = beats(stream)[0]
    assert line.startswith("[compare 0:0")
    assert line.endswith("] 3/7 done, method 4/7 at 40 %; ours-exact: solving; still working")


def test_a_line_written_by_an_event_resets_the_wait(monkeypatch):
    """The heartbeat fills silence only: a line an event wrote restarts the wait (the
    heartbeat's look called here directly, with a long period)."""
    monkeypatch.setattr(progress, "PERIODIC_EVERY_S", 3600.0)
    stream = io.StringIO()
    reporter = Reporter("run", total=10, stream=stream)
    reporter.advance(1, "solve 1")
    with progress._lock:
        progress._heartbeat_once()
    assert beats(stream) == []
    reporter._opened -= 7200.0  # as if opened two hours ago, its line one hour ago
    reporter._last_output -= 3600.0
    with progress._lock:
        progress._heartbeat_once()
    reporter.close()
    assert beats(stream) == ["[run 0:00] 1/10 done; solve 1; still working"]


def test_a_heartbeat_does_not_hold_back_the_next_events_line(monkeypatch, capsys):
    """periodic: compare's last line (`written to ...`) must still come after a heartbeat."""
    monkeypatch.setattr(progress, "PERIODIC_EVERY_S", 3600.0)
    progress.configure("periodic")
    reporter = Reporter("compare", total=1, unit="method")
    reporter.advance(1, "ours-lm: solved")
    reporter._opened -= 7200.0  # an hour of silence since its line
    reporter._last_output -= 3600.0
    reporter._last_line -= 3600.0
    monkeypatch.setitem(progress._heartbeat, "stderr_line", reporter._last_output)
    with progress._lock:
        progress._heartbeat_once()
    reporter.say("written to out/compare/")
    reporter.close()
    lines = capsys.readouterr().err.splitlines()
    assert [line.split("] ", 1)[1] for line in lines] == [
        "1/1 done; ours-lm: solved", "1/1 done; ours-lm: solved; still working",
        "1/1 done; written to out/compare/"]


def _silent_after(stop, reporter: Reporter, stream: io.StringIO) -> None:
    """``reporter`` beats; after ``stop()`` it writes nothing more while another reporter
    beats twice."""
    reporter.say("solving")
    wait_for(lambda: beats(stream), "heartbeat")
    stop()
    written = stream.getvalue()
    other_stream = io.StringIO()
    other = Reporter("control", total=1, stream=other_stream)
    after_two_more_beats(other_stream)
    other.close()
    assert stream.getvalue() == written


def test_no_heartbeat_after_close():
    stream = io.StringIO()
    reporter = Reporter("run", total=2, stream=stream)
    _silent_after(reporter.close, reporter, stream)


def test_no_heartbeat_when_off_or_disabled(capsys):
    progress.configure("off")
    quiet = Reporter("sweep", total=2)
    quiet.say("solving")
    disabled_stream = io.StringIO()
    disabled = Reporter("sweep", total=2, enabled=False, stream=disabled_stream)
    disabled.say("solving")
    other_stream = io.StringIO()
    other = Reporter("control", total=1, stream=other_stream)
    after_two_more_beats(other_stream)
    other.close()
    assert capsys.readouterr().err == ""
    assert disabled_stream.getvalue() == ""
    quiet.close()


def _opened_and_returned(stream: io.StringIO) -> Reporter:
    reporter = Reporter("compare", total=1, stream=stream)
    reporter.advance(1, "written")
    return reporter


def test_no_heartbeat_once_the_study_that_opened_the_reporter_returned():
    """compare's result keeps its reporter: a script going on after it must not get
    `still working` lines for a study that is over."""
    stream = io.StringIO()
    kept = _opened_and_returned(stream)  # noqa: F841 - kept alive, as a result would
    other_stream = io.StringIO()
    other = Reporter("control", total=1, stream=other_stream)
    after_two_more_beats(other_stream)
    other.close()
    assert beats(stream) == []


def test_no_heartbeat_after_the_command_ended():
    """The CLI calls reset() when a command ends: its reporters go silent."""
    stream = io.StringIO()
    _silent_after(progress.reset, Reporter("ik", stream=stream), stream)


def test_periodic_mode_on_stderr_beats_and_counts_as_the_periodic_line(capsys):
    """stderr a pipe or a log file: the heartbeat line is the periodic line plus `still
    working`, and one reporter speaks for the silence (the one that heard the latest
    event)."""
    progress.configure("periodic")
    outer = Reporter("reproduce", total=3)
    outer.say("study 1")
    inner = Reporter("run", total=7, unit="trajectory")
    inner.begin(1)
    inner.say("trajectory 1 (1/7): solving, n = 100")
    seen: list[str] = []

    def beaten(count: int) -> bool:
        seen.extend(capsys.readouterr().err.splitlines())
        return sum(bool(BEAT.match(line)) for line in seen) >= count

    wait_for(lambda: beaten(3), "heartbeat on stderr")
    inner.close()
    outer.close()
    heard = [BEAT.match(line).group(1) for line in seen if BEAT.match(line)]
    assert heard[:2] == ["run", "run"]
    assert any(line.endswith("0/7 done; trajectory 1 (1/7): solving, n = 100; still working")
               for line in seen)


def test_the_bar_is_redrawn_while_nothing_happens(capsys):
    """A terminal: the bar's elapsed time moves although no event comes."""
    progress.configure("bar")
    reporter = Reporter("bench", total=10, unit="solve")
    reporter.advance(1, "solve 1")
    capsys.readouterr()
    drawn: list[str] = []

    def redrawn() -> bool:
        drawn.append(capsys.readouterr().err)
        return sum(text.count("\r") for text in drawn) >= 2

    wait_for(redrawn, "bar redraw")
    reporter.close()
    assert "1/10" in "".join(drawn)


def test_the_heartbeat_leaves_a_swallowed_ctrl_c_to_the_next_event():
    """The Ctrl-C a library swallowed is raised by the next event, never by the thread."""
    stream = io.StringIO()
    reporter = Reporter("run", total=2, enabled=True, stream=stream)
    reporter.say("solving")
    progress.ctrl_c_swallowed()
    try:
        seen = len(beats(stream))
        wait_for(lambda: len(beats(stream)) >= seen + 2, "heartbeat")
        assert progress._swallowed_ctrl_c.is_set()
        with pytest.raises(KeyboardInterrupt):
            reporter.advance(1)
    finally:
        progress._swallowed_ctrl_c.clear()
        reporter.close()


def test_the_thread_is_a_daemon_and_ends_when_nothing_is_left():
    stream = io.StringIO()
    reporter = Reporter("run", total=2, stream=stream)
    reporter.say("solving")
    wait_for(lambda: beats(stream), "heartbeat")
    thread = progress._heartbeat["thread"]
    assert thread is not None and thread.daemon
    reporter.close()
    wait_for(lambda: not thread.is_alive(), "the heartbeat thread to end")


def test_a_failing_stream_does_not_stop_the_heartbeat():
    broken = io.StringIO()
    bad = Reporter("bad", total=1, stream=broken)
    bad.say("solving")
    broken.close()  # the heartbeat's print raises ValueError
    other_stream = io.StringIO()
    other = Reporter("control", total=1, stream=other_stream)
    after_two_more_beats(other_stream)
    other.close()
    bad.close()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork here")
def test_a_forked_child_does_not_beat_for_its_parents_reporters():
    stream = io.StringIO()
    reporter = Reporter("recommend", total=2, stream=stream)
    reporter.say("pilot paths")
    wait_for(lambda: beats(stream), "heartbeat")
    read, write = os.pipe()
    with warnings.catch_warnings():  # Python 3.12+: forking a process with threads
        warnings.simplefilter("ignore", DeprecationWarning)
        pid = os.fork()
    if pid == 0:  # the child: report what it watches, then leave at once
        try:
            os.write(write, str(len(progress._watched)).encode())
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read) as pipe:
        watched = pipe.read()
    os.waitpid(pid, 0)
    reporter.close()
    assert watched == "0"


def test_an_open_reporter_never_keeps_the_process_alive():
    """A reporter left open at exit: the process ends at once, no error at shutdown."""
    code = ("from ikbench.runtime import progress\n"
            "progress.PERIODIC_EVERY_S = 0.01\n"
            "r = progress.Reporter('left', total=2)\n"
            "r.say('solving')\n"
            "import time; time.sleep(0.3)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert "still working" in done.stderr
    assert "Fatal Python error" not in done.stderr and "Traceback" not in done.stderr


def test_the_cli_writes_heartbeats_through_a_pipe_while_one_long_call_solves(tmp_path):
    """`ikbench run` with stderr a pipe (periodic mode) and a method whose solve is one
    silent call (sequential-ik made to sleep first): heartbeat lines come while it solves."""
    code = ("import sys, time\n"
            "from ikbench.runtime import progress\n"
            "progress.PERIODIC_EVERY_S = 0.2\n"
            "from ikbench.methods.registry import get_method\n"
            "cls = get_method('sequential-ik')\n"
            "solve = cls.solve\n"
            "def slow(self, *args, **kwargs):\n"
            "    time.sleep(1.5)\n"
            "    return solve(self, *args, **kwargs)\n"
            "cls.solve = slow\n"
            "from ikbench.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    done = subprocess.run([sys.executable, "-c", code, "run", "--method", "sequential-ik",
                           "--only", "1", "--steps", "10", "--no-animation", "--output",
                           str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if BEAT.match(line)]
    assert lines, done.stderr
    assert any(line.endswith("] 0/1 done; trajectory 1 (1/1): solving, n = 10; still working")
               for line in lines), lines


def test_the_ikbench_function_that_called_the_opener_counts_as_running():
    """compare.run opens the reporter and returns; run_comparison, its caller in ikbench,
    then writes the folder: the heartbeat goes on until that caller returns too. A caller
    outside ikbench (a script, this test) does not count."""
    import numpy as np

    from ikbench.methods.base import Method, Solution
    from ikbench.runtime.harness import solve_tasks

    task = SimpleNamespace(name="1", goal=SimpleNamespace(steps=4, has_frames=False),
                           required=SimpleNamespace(end_pose=None))

    opened = []

    class Opens(Method):
        name = "opens"
        description = "opens a reporter in its solve (tests)"

        def solve(self, robot, task, progress=None) -> Solution:
            opened.append(Reporter("inner", stream=io.StringIO()))
            return Solution(np.zeros((task.goal.steps + 1, 1)), iterations=1,
                            duration_s=0.0, loss=None)

    solve_tasks(Opens(), None, [task])
    called_here = Reporter("here", stream=io.StringIO())
    assert len(opened[0]._opened_by[1]) == 2  # solve, and the harness that called it
    assert len(called_here._opened_by[1]) == 1
    called_here.close()
    opened[0].close()
