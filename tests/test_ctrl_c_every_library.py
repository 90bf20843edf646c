"""Ctrl-C during each installed library's solve in ``ikbench ik`` (issue 64): a real SIGINT
sent while a method's timed calls run (its ``attempts 8: NAME: solving N targets`` line came
a second before, its ``succeeded`` line has not) ends the command with exit 130 and one line,
and the complete run's folder from before is left byte for byte as it was.

Every solver the registry knows is a case: one not installed, or one that cannot take the
UR5 (it fails to prepare), is skipped with the reason. The cases spawn one process each and
are marked slow (``-m slow``), but for one fast representative, TRAC-IK (a C++ extension).
The latency from the signal to the exit is printed (``-s``) and recorded as a property
(``ctrl_c_latency_s``), never asserted: the communicate timeout is a safety net only.

``inherited`` is how the process starts with SIGINT: ``default`` (Python installs its handler)
or ``ignored`` (SIG_IGN, as a script's ``cmd &`` inherits it; Python then installs none, the
console command installs its own)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ikbench.methods.registry import solver_status
from tests.conftest import REPO

ROBOT = "example-robot-data:ur5"
#: Targets per method: enough that its solve still runs a second after its "solving" line
#: (the test fails, saying so, when it has finished by then). The analytic and compiled
#: solvers take microseconds a call.
COUNT = 2000
COUNTS = {"eaik": 200000, "trac-ik": 20000, "ours-lm": 20000, "rtb-lm": 20000, "rtb-nr": 20000}
#: The representative that runs without ``-m slow``.
FAST = "trac-ik"
#: Seconds between the "solving" line and the signal.
AFTER_SOLVING_S = 1.0
#: Safety nets only (nothing is asserted about time): the "solving" line, then the exit.
SOLVING_TIMEOUT_S = 600.0
EXIT_TIMEOUT_S = 120.0
#: The variant with SIGINT inherited ignored: a few libraries of each kind.
IGNORED = ("trac-ik", "ikpy", "ours-lm", "pyroki")


@pytest.mark.parametrize("inherited, taken", [
    (signal.SIG_IGN, True),  # Python installed none: the console command does
    (signal.default_int_handler, True),
    (signal.SIG_DFL, False),  # a caller's choice stays
])
def test_the_console_command_takes_sigint_also_when_it_started_ignored(inherited, taken):
    from ikbench import cli

    before = signal.signal(signal.SIGINT, inherited)
    try:
        cli._take_sigint()
        assert signal.getsignal(signal.SIGINT) is (cli._on_sigint if taken else inherited)
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_ctrl_c_landing_where_compiled_code_drops_it_is_raised_later(monkeypatch):
    """numba's boxing calls ``_numba_unpickle`` and drops what it raises: a Ctrl-C landing
    there is raised at the next progress event (or by the timer, off here), elsewhere at
    once."""
    from ikbench import cli
    from ikbench.runtime import progress
    from ikbench.runtime.progress import Reporter

    monkeypatch.setattr(progress, "RERAISE_AFTER_S", None)  # no timer in pytest's process
    scope = {"__name__": "numba.core.serialize", "sys": sys}
    exec("def _numba_unpickle():\n    return sys._getframe()", scope)
    cli._on_sigint(signal.SIGINT, scope["_numba_unpickle"]())  # not raised there
    reporter = Reporter("test", total=2, enabled=False)
    with pytest.raises(KeyboardInterrupt):
        reporter.advance()
    reporter.advance()  # once
    with pytest.raises(KeyboardInterrupt):
        cli._on_sigint(signal.SIGINT, sys._getframe())


def _cases() -> list:
    cases = []
    for name in solver_status():
        for inherited in ("default", "ignored"):
            if inherited == "ignored" and name not in IGNORED:
                continue
            marks = [] if (name, inherited) == (FAST, "default") else [pytest.mark.slow]
            cases.append(pytest.param(name, inherited, marks=marks, id=f"{name}-{inherited}"))
    return cases


def _events(log: Path) -> list[str]:
    if not log.exists():
        return []
    texts = []
    for line in log.read_text().splitlines():
        try:
            texts.append(str(json.loads(line).get("text") or ""))
        except json.JSONDecodeError:  # the line being written
            pass
    return texts


def _disposition(inherited: str):  # type: ignore[no-untyped-def]
    handler = signal.SIG_IGN if inherited == "ignored" else signal.SIG_DFL
    return lambda: signal.signal(signal.SIGINT, handler)


@pytest.mark.parametrize("name, inherited", _cases())
def test_ctrl_c_during_the_solve_exits_130_and_keeps_the_complete_run(
        tmp_path, name, inherited, record_property):
    status = solver_status()[name]
    if status.cls is None:
        pytest.skip(f"{name}: {status.reason}")
    count = COUNTS.get(name, COUNT)
    out = tmp_path / "out"
    folder = out / "ik" / "ur5"
    folder.mkdir(parents=True)
    (folder / "results.csv").write_text("the complete run\n")
    log = tmp_path / "progress.jsonl"
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikbench.cli", "ik", "--robot", ROBOT, "--count", str(count),
         "--methods", name, "--attempts", "8", "--output", str(out), "--log", str(log)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
        preexec_fn=_disposition(inherited))
    solving = f"attempts 8: {name}: solving {count} targets, one per call"
    try:
        deadline = time.monotonic() + SOLVING_TIMEOUT_S
        while solving not in _events(log):
            failed = [t for t in _events(log) if "FAILED to prepare" in t]
            if failed:
                proc.kill()
                pytest.skip(f"{name} cannot run the UR5: {failed[0]}")
            assert proc.poll() is None, f"ended before solving: {proc.communicate()}"
            assert time.monotonic() < deadline, f"no {solving!r} line"
            time.sleep(0.05)
        time.sleep(AFTER_SOLVING_S)
        finished = [t for t in _events(log) if t.startswith(f"attempts 8: {name}: ")
                    and "succeeded" in t]
        assert proc.poll() is None and not finished, (
            f"{name} solved {count} targets within {AFTER_SOLVING_S} s: the signal would not "
            "land in its solve; raise its count in COUNTS")
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        _, err = proc.communicate(timeout=EXIT_TIMEOUT_S)
        latency_s = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    record_property("ctrl_c_latency_s", round(latency_s, 3))
    print(f"\nctrl-c {name} (SIGINT {inherited}): exit {proc.returncode} "
          f"{latency_s:.2f} s after the signal")
    assert proc.returncode == 130, err[-2000:]
    assert "ikbench: interrupted (Ctrl-C)" in err
    assert "Traceback" not in err, err[-2000:]
    assert [p.name for p in folder.iterdir()] == ["results.csv"]
    assert (folder / "results.csv").read_text() == "the complete run\n"
    assert sorted(p.name for p in out.rglob("*")) == ["ik", "results.csv", "ur5"]
