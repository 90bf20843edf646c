"""Shared fixtures. Tests are seeded and run in float64 where they check numbers."""

from __future__ import annotations

from pathlib import Path

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
    stderr. Fails when that line does not come within ``timeout_s``."""
    import json
    import os
    import signal
    import subprocess
    import sys
    import time

    log = cwd / "progress.jsonl"
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "ikbench.cli", *argv, "--log", str(log)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=cwd)
    deadline = time.monotonic() + timeout_s
    try:
        while not any(when in json.dumps(json.loads(line))
                      for line in (log.read_text().splitlines() if log.exists() else [])):
            assert proc.poll() is None, f"ended before {when!r}: {proc.communicate()}"
            assert time.monotonic() < deadline, f"no progress line with {when!r}"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, err


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
