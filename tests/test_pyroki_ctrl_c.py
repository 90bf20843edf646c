"""Ctrl-C while PyRoki solves or compiles (issue 64): the KeyboardInterrupt is raised after
the jitted call returns, also when the process inherited SIGINT ignored (a script's
background job), and an interrupted ``ikbench ik`` leaves the complete run's folder as it
was; XLA's deterministic flags never override the user's (issue 58)."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time

import pytest

from ikbench.baselines import pyroki_trajopt as pt
from tests.conftest import REPO


@pytest.fixture
def sigint_restored():
    before = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, before)
    pt._CTRL_C[0] = False


@pytest.mark.parametrize("inherited", [signal.SIG_IGN, signal.default_int_handler])
def test_a_ctrl_c_during_a_call_is_raised_after_it(sigint_restored, inherited):
    signal.signal(signal.SIGINT, inherited)
    pt._guard_ctrl_c()
    assert signal.getsignal(signal.SIGINT) is pt._on_sigint
    pt._CTRL_C[0] = False
    try:  # Python's handler raises at once; the ignored one is raised after the call
        signal.raise_signal(signal.SIGINT)
    except KeyboardInterrupt:
        assert inherited is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt):
        pt._honour_ctrl_c()
    pt._honour_ctrl_c()  # once only


def test_the_xla_flags_keep_what_the_user_set():
    flags = pt._xla_flags("--xla_cpu_max_isa=SSE4_2 --xla_dump_to=/tmp/x")
    assert flags.split()[:2] == ["--xla_cpu_max_isa=SSE4_2", "--xla_dump_to=/tmp/x"]
    assert "--xla_cpu_max_isa=AVX2" not in flags
    assert "--xla_cpu_multi_thread_eigen=false" in flags
    assert pt._xla_flags(flags) == flags
    assert pt._xla_flags("") == " ".join(pt.XLA_DETERMINISTIC)


@pytest.mark.skipif(importlib.util.find_spec("pyroki") is None, reason="pyroki not installed")
def test_ctrl_c_while_pyroki_compiles_keeps_the_complete_run(tmp_path):
    """SIGINT ignored as a script's ``cmd &`` inherits it, sent while pyroki compiles
    (its longest call): exit 130 and the earlier run's folder untouched."""
    folder = tmp_path / "out" / "ik" / "ur5"
    folder.mkdir(parents=True)
    (folder / "results.csv").write_text("the complete run\n")
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikbench.cli", "ik", "--robot", "example-robot-data:ur5",
         "--count", "3", "--methods", "pyroki", "--attempts", "8",
         "--output", str(tmp_path / "out")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        for line in proc.stderr:
            if "pyroki: preparing" in line:
                break
        time.sleep(1.0)
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=150)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "ikbench: interrupted (Ctrl-C)" in err
    assert [p.name for p in folder.iterdir()] == ["results.csv"]
    assert (folder / "results.csv").read_text() == "the complete run\n"
