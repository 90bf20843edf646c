"""A real Ctrl-C (SIGINT) while a long command solves: exit code 130, one line on stderr, and
its output folder unchanged or marked interrupted (issue 39). ``compare`` on touch poses is in
tests/test_compare_study.py, ``execute`` in tests/test_hw_execute.py, ``view`` in
tests/test_viewer.py."""

from __future__ import annotations

import json

import pytest

from tests.conftest import interrupt_while

ONE_LINE = ["ikbench: interrupted (Ctrl-C)"]


@pytest.mark.parametrize("command", [
    ["cartesian", "--methods", "sequential-ik"],
    ["compare", "--methods", "sequential-ik"],  # compare --problems runs the benchmark
])
def test_ctrl_c_while_the_cartesian_benchmark_solves(tmp_path, command):
    """After the first solve (its progress line), during the second."""
    code, err = interrupt_while([*command, "--problems", "fetch_arm__hello", "--seeds",
                                 "1,2,3,4,5,6,7,8", "--output", str(tmp_path / "out")],
                                tmp_path, "seed 1")
    assert (code, err.strip().splitlines()) == (130, ONE_LINE)
    assert not (tmp_path / "out").exists()


def test_ctrl_c_while_a_sweep_solves(tmp_path):
    grid = ",".join(str(v) for v in range(1, 301))
    code, err = interrupt_while(["sweep", "--weight", f"c0={grid}", "--output",
                                 str(tmp_path / "out")], tmp_path, "solving")
    assert (code, err.strip().splitlines()) == (130, ONE_LINE)
    assert not (tmp_path / "out").exists()


def test_ctrl_c_while_bench_times(tmp_path):
    code, err = interrupt_while(["bench", "--methods", "sequential-ik", "--repeat", "1000",
                                 "--output", str(tmp_path / "out")], tmp_path, "trajectory 1")
    assert (code, err.strip().splitlines()) == (130, ONE_LINE)
    assert not (tmp_path / "out").exists()


def test_ctrl_c_while_a_dataset_is_built(tmp_path):
    """Complete shards stay (the same command resumes); dataset.json says interrupted."""
    pytest.importorskip("pyarrow", reason="datasets need pyarrow: pip install 'ikbench[scale]'")
    out = tmp_path / "out"
    code, err = interrupt_while(["dataset", "--count", "100000", "--shard-size", "200",
                                 "--steps", "10", "--output", str(out)], tmp_path, "shard ")
    assert (code, err.strip().splitlines()) == (130, ONE_LINE)
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["complete"] is False and manifest["interrupted"]["shards_built"] >= 1
    assert not list(out.rglob("*.tmp"))  # no half-written shard


def test_a_ctrl_c_a_library_swallows_stops_the_command_at_its_next_progress_event(monkeypatch):
    """A KeyboardInterrupt raised inside a ctypes callback (llvmlite's, while numba compiles or
    loads a kernel) cannot propagate: Python prints it as ignored and goes on. The CLI's
    unraisable hook keeps it, and the next progress event raises it again, once."""
    import ctypes
    import sys

    from ikbench import cli
    from ikbench.runtime.progress import Reporter

    others = []
    monkeypatch.setattr(sys, "unraisablehook", cli._ctrl_c_not_swallowed(others.append))

    def callback():
        raise KeyboardInterrupt

    ctypes.CFUNCTYPE(None)(callback)()  # swallowed: returns normally
    reporter = Reporter("test", total=3, enabled=False)
    with pytest.raises(KeyboardInterrupt):
        reporter.advance()
    reporter.advance()  # raised once
    reporter.say("on")

    def failing():
        raise ValueError("not a Ctrl-C")

    ctypes.CFUNCTYPE(None)(failing)()
    assert [u.exc_type for u in others] == [ValueError]
    reporter.note("still on")


def test_a_swallowed_ctrl_c_is_raised_again_in_the_main_thread_without_a_progress_event():
    """Issue 64: JAX's garbage-collection callback (qpsolvers imports JAX, so pink and mink
    run it) swallows a Ctrl-C that lands in it, and ``ik`` says a progress line only every
    10 s while a library solves. The console command's hook raises it again in the main
    thread, with no progress event, once."""
    import os
    import signal
    import subprocess
    import sys
    import textwrap

    from tests.conftest import REPO

    script = textwrap.dedent("""
        import gc, sys, time
        from ikbench import cli
        from ikbench.runtime import progress
        sys.unraisablehook = cli._ctrl_c_not_swallowed(sys.unraisablehook,
                                                       progress.RERAISE_AFTER_S)
        def callback(phase, info):
            gc.callbacks.remove(callback)
            raise KeyboardInterrupt
        gc.callbacks.append(callback)
        gc.collect()
        print("swallowed", flush=True)
        for round_, wait_s in (("raised again", 30.0), ("once", 1.0)):  # safety nets
            try:
                deadline = time.monotonic() + wait_s  # no progress event in it
                while time.monotonic() < deadline:
                    time.sleep(0.01)
                print("not raised", flush=True)
            except KeyboardInterrupt:
                print(round_, flush=True)
    """)
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert done.stdout.splitlines() == ["swallowed", "raised again", "not raised"], done.stderr


def _snapshot(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("first, again, when, folder", [
    (["run", "--method", "sequential-ik", "--only", "1"],
     ["run", "--method", "sequential-ik", "--steps", "400"], "trajectory 2", "sequential-ik"),
    (["compare", "--methods", "sequential-ik", "--only", "1"],
     ["compare", "--methods", "sequential-ik,pink", "--repeat", "20"], "sequential-ik: ",
     "compare"),
    (["ik", "--robot", "panda", "--methods", "sequential-ik", "--count", "10"],
     ["ik", "--robot", "panda", "--methods", "sequential-ik", "--count", "5000"], "solving",
     "ik/panda"),
    (["cartesian", "--problems", "fetch_arm__hello", "--methods", "sequential-ik", "--seeds",
      "1"],
     ["cartesian", "--problems", "fetch_arm__hello", "--methods", "sequential-ik", "--seeds",
      "1,2,3,4,5,6,7,8"], "seed 1", "cartesian"),
])
def test_ctrl_c_never_replaces_a_complete_run(tmp_path, first, again, when, folder):
    """Issue 49: each long command interrupted over a complete run of its own leaves that run
    byte for byte as it was."""
    import subprocess
    import sys

    from tests.conftest import REPO

    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "ikbench.cli", *first, "--output", str(out),
                           "--quiet"], capture_output=True, text=True, cwd=REPO, timeout=600)
    assert done.returncode in (0, 1), done.stderr  # 1: a row that misses the contract
    before = _snapshot(out / folder)
    assert before
    code, err = interrupt_while([*again, "--output", str(out)], tmp_path, when)
    assert code == 130, err
    assert _snapshot(out / folder) == before
