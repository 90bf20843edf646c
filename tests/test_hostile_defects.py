"""The defects issue 39 found, each checked through the CLI as it was met. The generated
hostile-input test (tests/test_hostile_input.py) covers every option; Ctrl-C is in
tests/test_interrupt.py."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.robot_packages import robots_folder
from ikbench.core.trajectory import write_trajectory_csv
from ikbench.methods import registry
from tests.conftest import PAPER_START, REPO, exit_code, without_progress

DURATION = ("argument --duration: {} is {}; give a duration [s] from 0.001 to 3600")


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


@pytest.fixture
def traj(tmp_path, robot):
    return write_trajectory_csv(tmp_path / "t.csv", robot, [PAPER_START] * 5)


# ----- --duration means the same everywhere --------------------------------------------------
@pytest.mark.parametrize("value, why", [("inf", "not a finite number"),
                                        ("1e308", "out of range"), ("1e-300", "out of range")])
@pytest.mark.parametrize("argv", [["run"], ["letters", "P"], ["compare"], ["plan", "{traj}"],
                                  ["export", "{traj}", "--format", "csv-rad", "--output", "x"],
                                  ["execute", "{traj}", "--port", "emulator"],
                                  ["view", str(REPO / "results" / "ours")]])
def test_duration_is_refused_alike_by_every_command(tmp_path, traj, capsys, argv, value, why):
    """run --duration inf wrote "duration_s": Infinity (exit 0, or a traceback from the
    animation); 1e308 overflowed; 1e-300 was taken."""
    argv = [a.format(traj=traj) for a in argv]
    assert exit_code([*argv, f"--duration={value}", "--output", str(tmp_path / "out")]
                     if argv[0] in ("run", "letters", "compare") else
                     [*argv, f"--duration={value}"]) == 2
    assert DURATION.format(value, why) in _one_line(capsys)
    assert not (tmp_path / "out").exists()


# ----- sizes that allocate, refused up front --------------------------------------------------
def test_export_rate_beyond_the_maximum_is_refused(traj, tmp_path, capsys):
    """export --rate 1e12 --timing topp took 15.9 GB within 90 s."""
    assert exit_code(["export", str(traj), "--format", "csv-rad", "--output",
                      str(tmp_path / "x.csv"), "--timing", "topp", "--rate", "1e12"]) == 2
    assert "argument --rate: 1e12 is out of range; give a rate [Hz] more than 0 to 10,000 " \
           "(or 0: one point per solved pose)" in _one_line(capsys)


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_DATA, (2 * 2**30, 2 * 2**30))


def test_export_points_beyond_the_memory_are_refused_with_the_estimate(tmp_path):
    """10 kHz for an hour is 36 million points: refused before one is built, in a child
    limited to 2 GiB, with the estimate and the most that fit."""
    traj = REPO / "results" / "ours" / "trajectory_1.csv"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "ikbench.cli", "export", str(traj), "--format",
                           "csv-rad", "--output", str(tmp_path / "x.csv"), "--timing",
                           "min-jerk", "--rate", "10000", "--duration", "3600"],
                          capture_output=True, text=True, preexec_fn=_limit_memory,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("ikbench: error: --rate: 36,000,00")  # points (+ the end)
    assert " points need about " in done.stderr
    assert " of memory; " in done.stderr and "at most " in done.stderr
    assert done.stderr.count("\n") == 1 and not (tmp_path / "x.csv").exists()
    assert time.perf_counter() - started < 60  # start-up included; no timed assertion beyond


@pytest.mark.parametrize("argv, message", [
    (["compare", "--repeat", "1e12"],
     "argument --repeat: 1e12 is out of range; give a number of solves from 1 to 1000"),
    (["bench", "--repeat", "1000000000000"],
     "--repeat: '1000000000000' is not N or method=N with N an integer from 1 to 1000"),
    (["sweep", "--weight", "c0=" + ",".join(map(str, range(1, 20001)))],
     "--weight: the grid makes 140,007 trajectories (20,001 settings x 7 tasks), more than "
     "one batch takes, 100,000"),
])
def test_counts_beyond_their_maximum_are_refused(tmp_path, capsys, argv, message):
    """compare/bench --repeat 1e12 were accepted without a bound."""
    assert exit_code([*argv, "--output", str(tmp_path / "out")]) == 2
    assert message in _one_line(capsys)
    assert not (tmp_path / "out").exists()


def test_a_sweep_reports_progress_while_it_measures(tmp_path, capsys):
    """A sweep of 10,001 settings measured for 80 s without a word."""
    log = tmp_path / "progress.jsonl"
    assert main(["sweep", "--weight", "c0=10,100", "--only", "1,2", "--steps", "6", "--output",
                 str(tmp_path / "out"), "--log", str(log)]) == 0
    events = [json.loads(line) for line in log.read_text().splitlines()]
    notes = [e["text"] for e in events if e["event"] == "note"]
    assert any("measuring" in n for n in notes)
    advances = [e for e in events if e["event"] == "advance"]
    assert advances and advances[-1]["done"] == advances[-1]["total"] == 6  # 3 settings x 2
    err = capsys.readouterr().err  # not a terminal: no bar, a start line and the notes
    assert without_progress(err) == "" and "\r" not in err and "measuring" in err


# ----- errors that name the real fault ---------------------------------------------------------
def test_a_dangling_joint_is_named_as_the_fault(tmp_path, capsys):
    """The error blamed --end-frame ("is not below the base link")."""
    text = (REPO / "tests" / "data" / "unaligned_arm.urdf").read_text()
    broken = tmp_path / "broken.urdf"
    broken.write_text(text.replace('<child link="l2"/>', '<child link="l2x"/>'))
    assert main(["fk", "--robot", str(broken), "--end-frame", "l5"]) == 2
    assert _one_line(capsys).startswith(
        "ikbench: error: --robot: broken.urdf: joint 'slide' names the child link 'l2x', which "
        "the URDF does not define; links: world_link, base, l1, l2, l3")


# ----- quiet, true console output --------------------------------------------------------------
def test_library_chatter_is_kept_off_the_table(tmp_path, capfd):
    """TRAC-IK's KDL printed "The root link %s has an inertia ..." on stdout above the results;
    Drake warned once per joint. Now: one note per library at the end (--verbose:
    tests/test_chatter.py)."""
    pytest.importorskip("pytracik")
    pytest.importorskip("pydrake")
    if robots_folder("example-robot-data") is None:
        pytest.skip("needs example-robot-data: pip install 'ikbench[robots]'")
    argv = ["ik", "--robot", "example-robot-data:panda", "--methods", "trac-ik,drake-ik",
            "--count", "2", "--output", str(tmp_path)]
    assert main(argv) == 0
    out, err = capfd.readouterr()
    assert "root link" not in out and "safety_controller" not in out + err.split("note:")[0]
    notes = [line for line in err.splitlines() if line.startswith("note: ")]
    # Drake parses the URDF text written from the model (core/urdf_model.py), which holds no
    # tag Drake ignores: it may print nothing at all; whatever it prints is one note
    assert "trac-ik printed 1 line(s)" in notes[0] and len(notes) <= 2
    assert all("--verbose shows it" in note for note in notes)


def test_a_missing_library_is_a_row_saying_so_and_the_exit_code_too(tmp_path, capsys,
                                                                      monkeypatch):
    """A method not installed showed library nan in the leaderboard and compare exited 0."""
    monkeypatch.setitem(registry.method_status(), "missing-lib", registry.MethodStatus(
        "missing-lib", None, "needs not_a_lib (pip install 'ikbench[libs]')"))
    assert main(["compare", "--methods", "ours-lm,missing-lib", "--only", "1", "--steps", "4",
                 "--repeat", "1", "--output", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    err = without_progress(err)
    assert "missing-lib: not installed" in err and err.count("\n") == 1
    board = (tmp_path / "compare" / "leaderboard.md").read_text()
    row = next(line for line in board.splitlines() if line.startswith("| missing-lib"))
    assert "not installed" in row and "nan" not in row


def test_batch_share_times_are_labelled(tmp_path, capsys):
    """The console table showed ours-lm's duration_s as 0.000: a share of one batched solve."""
    assert main(["run", "--method", "ours-lm", "--only", "1,2", "--steps", "6",
                 "--no-animation", "--output", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "duration_s (batch share)" in out
    assert "the 2 trajectories were solved in one batched call of " in out
    shares = pd.read_csv(tmp_path / "ours-lm" / "table.csv")["duration_s"]
    assert f"{shares.iloc[0]:.3g}" in out  # significant digits, not 0.000


def test_run_help_shows_the_common_options_first(capsys):
    """run --help was 620 lines, --output, --name and --problem lost among library options."""
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) < 150 and "--lm-tolerance" not in "\n".join(lines)
    first = "\n".join(lines[:40])
    assert all(flag in first for flag in ("--method", "--output", "--name", "--problem"))
    with pytest.raises(SystemExit):
        main(["run", "--help-methods"])
    assert "--lm-tolerance" in capsys.readouterr().out
    assert main(["methods", "ours-lm"]) == 0
    assert "  --lm-tolerance" in capsys.readouterr().out
