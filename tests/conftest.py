"""Shared fixtures. Tests are seeded and run in float64 where they check numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikbench import load_robot, load_targets

REPO = Path(__file__).resolve().parents[1]

PAPER_START = [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67]


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture(scope="session")
def paper_targets():
    return load_targets()


def exit_code(argv: list[str]) -> int:
    """The exit code of ``ikbench ARGV`` in this process, whether the command was refused
    while parsing (argparse exits) or later (``main`` returns it)."""
    from ikbench.cli import main

    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def interrupt_while(argv: list[str], cwd: Path, when: str, timeout_s: float = 180.0
                    ) -> tuple[int, str]:
    """Run ``ikbench ARGV --log LOG`` in a new process, send it a real Ctrl-C (SIGINT) once a
    progress line of the log holds ``when`` (it is then solving), and return its exit code and
    stderr less its progress lines (``[label m:ss] ...``: stderr is a pipe, so the command
    writes a start line and one every ~10 s). Fails when that line does not come within
    ``timeout_s``."""
    import os
    import signal
    import subprocess
    import sys
    import time

    log = cwd / "progress.jsonl"
    log.unlink(missing_ok=True)  # a reused cwd's log would hold an earlier run's lines
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "ikbench.cli", *argv, "--log", str(log)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=cwd)
    deadline = time.monotonic() + timeout_s
    try:
        while not any(when in line for line in _complete_events(log)):
            assert proc.poll() is None, f"ended before {when!r}: {proc.communicate()}"
            assert time.monotonic() < deadline, f"no progress line with {when!r}"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, without_progress(err)


def _complete_events(log: Path) -> list[str]:
    """The events of a JSON-lines progress log written so far, each as JSON text; a last line
    still being written (not yet a whole JSON object) is left for the next look."""
    import json

    events = []
    for line in (log.read_text().splitlines() if log.exists() else []):
        try:
            events.append(json.dumps(json.loads(line)))
        except json.JSONDecodeError:
            break
    return events


def without_progress(err: str) -> str:
    """stderr less the progress lines a command writes when it is not a terminal
    (``[label m:ss] ...``, :mod:`ikbench.runtime.progress`'s periodic mode)."""
    import re

    return "".join(line for line in err.splitlines(keepends=True)
                   if not re.match(r"\[\S+ \d+:\d\d(:\d\d)?\] ", line))


def blocked_output(tmp_path: Path, blocked_by: str, name: str) -> tuple[Path, str]:
    """An output path that cannot be written, and the reason the error must name.

    ``blocked_by="file"``: ``name`` under a regular file; ``"directory"``: a directory itself.
    """
    blocker = tmp_path / "blocker"
    if blocked_by == "file":
        blocker.write_text("not a folder")
        return blocker / name, f"{blocker} is a file, not a directory"
    blocker.mkdir()
    return blocker, "it is a directory"


def register_temporarily(monkeypatch, cls) -> None:
    """Make the method class ``cls`` available by its name for one test."""
    from ikbench.methods.registry import MethodStatus, method_status

    monkeypatch.setitem(method_status(), cls.name, MethodStatus(cls.name, cls))


def method_class(name: str):
    """The method's class; skipped only when its library is not installed (the registry's
    ``needs ...``); an adapter that fails to import for another reason fails the test."""
    from ikbench.methods.registry import method_status

    status = method_status()[name]
    if not status.available:
        if status.reason.startswith("needs "):
            pytest.skip(f"{name}: {status.reason}")
        pytest.fail(f"{name}: {status.reason}")
    return status.cls


def fails_if_called(monkeypatch, module, name: str) -> None:
    """Replace ``module.name`` by a function that fails the test: a command must check its
    output folder before it does that work."""

    def called(*args, **kwargs):
        raise AssertionError(f"{module.__name__}.{name} ran before the output was checked")

    monkeypatch.setattr(module, name, called)


def unwritable_output_error(capsys, tmp_path: Path, argv: list[str]) -> str:
    """``ikbench ARGV --output FILE/out`` with FILE a regular file: exit code 2 and one line on
    stderr that says FILE is a file; returns that line."""
    (tmp_path / "file").write_text("")
    assert exit_code([*argv, "--output", str(tmp_path / "file" / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file" in err, err
    return err


def one_line_error(capsys, argv: list[str]) -> str:
    """``ikbench ARGV`` is refused: exit code 2 and one line on stderr, which it returns."""
    assert exit_code(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def central_differences(f, x: np.ndarray, step: float) -> np.ndarray:
    """The derivatives of ``f`` by central differences along each entry j of x's last axis,
    (f(x + step e_j) - f(x - step e_j)) / (2 step), stacked on a new last axis. Every row of a
    batch ``x`` moves at once, so f must treat its rows independently."""
    columns = []
    for j in range(x.shape[-1]):
        plus, minus = x.copy(), x.copy()
        plus[..., j] += step
        minus[..., j] -= step
        columns.append((np.asarray(f(plus)) - np.asarray(f(minus))) / (2 * step))
    return np.stack(columns, axis=-1)
