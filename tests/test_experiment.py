"""The pointing experiment: design, records, simulated participants, playback on the emulator,
bad input through the CLI (issue 59)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.experiment import observers
from ikbench.experiment.design import TRIAL_COLUMNS, DesignSpec, build, stop_of, williams_square
from ikbench.experiment.layout import load_goals
from ikbench.experiment.play import PlaySpec, run
from ikbench.experiment.records import (
    RESPONSE_COLUMNS,
    ResponseLog,
    next_trial,
    read_responses,
    read_trials,
)

SMALL = {"participants": 2, "seed": 3, "repeats": 1, "practice": 1}


@pytest.fixture(scope="module")
def small_design(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("exp") / "study"
    build(DesignSpec(**SMALL)).write(folder)
    return folder


def _copy(folder: Path, tmp_path: Path) -> Path:
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(folder, out)
    return out


def test_the_same_seed_writes_the_same_trial_lists(tmp_path):
    a, b = build(DesignSpec(**SMALL)), build(DesignSpec(**SMALL))
    for name in a.trials:
        pd.testing.assert_frame_equal(a.trials[name], b.trials[name])
    other = build(DesignSpec(**{**SMALL, "seed": 4}))
    assert not a.trials["participant_01"]["target"].equals(other.trials["participant_01"]["target"])


def test_trial_lists_hold_the_contracts_columns_and_every_cell(small_design):
    trials = read_trials(small_design / "participant_01")
    assert tuple(trials.columns) == TRIAL_COLUMNS
    main = trials[~trials["practice"]]
    assert set(main["cell"]) == {"G", "P60", "P80", "GP60", "GP80", "I60", "I80"}
    counts = main.groupby("cell")["target"].apply(lambda t: sorted(t)).tolist()
    assert all(c == list(range(1, 8)) for c in counts)        # each target once per cell
    assert (main.loc[main["condition"] == "I", "gaze_target"]
            != main.loc[main["condition"] == "I", "target"]).all()
    assert main.loc[main["condition"] == "P", "gaze_target"].isna().all()
    assert main.loc[main["condition"] == "G", "fraction"].isna().all()
    blocks = main.groupby("block")["cell"].nunique()
    assert (blocks == 1).all() and len(blocks) == 7            # blocked: one cell a block


def test_block_orders_are_a_balanced_latin_square():
    for k in (4, 7):
        rows = williams_square(k)
        assert len(rows) == (k if k % 2 == 0 else 2 * k)
        follows = np.zeros((k, k), int)
        for row in rows:
            assert sorted(row) == list(range(k))
            for a, b in zip(row, row[1:]):
                follows[a, b] += 1
        off = follows[~np.eye(k, dtype=bool)]
        assert off.min() == off.max()                       # each pair equally often


def test_the_arm_stops_at_the_fraction_of_the_fingertips_path(small_design):
    robot = load_robot()
    poses = pd.read_csv(small_design / "trajectories/ours-exact/trajectory_3.csv")
    q = poses[list(robot.joint_names)].to_numpy(float)
    points = robot.fk(q).point_mm
    total = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
    for fraction in (0.6, 0.8):
        _, step, stop = stop_of(robot, q, fraction)
        walked = np.linalg.norm(np.diff(points[:step + 1], axis=0), axis=1).sum() + \
            np.linalg.norm(stop - points[step])
        assert walked == pytest.approx(fraction * total, rel=2e-3)


def test_gaze_trials_look_at_their_gaze_target(small_design):
    from ikbench.experiment.head import load_head

    head, goals = load_head(), load_goals()
    trials = read_trials(small_design / "participant_02")
    for _, t in trials[trials["condition"].isin(["G", "GP", "I"])].iterrows():
        pose = [t["head_z_motor_deg"], t["head_y_motor_deg"]]
        point = goals.points_mm[goals.index(int(t["gaze_target"]))]
        assert head.angle_to_point_deg(pose, point) < 0.01


def test_simulated_participants_answer_every_trial_and_resume_repeats_none(small_design,
                                                                          tmp_path):
    folder = _copy(small_design, tmp_path)
    whole = _copy(small_design, tmp_path / "b")
    run(PlaySpec(whole, log=lambda line: None))
    reference = read_responses(whole / "participant_01")
    # an interrupted run: the first 20 answers, then a resume
    trials = read_trials(folder / "participant_01")
    log = ResponseLog(folder / "participant_01", trials, load_goals().ids)
    for _, row in reference.head(20).iterrows():
        log.append({**row.to_dict(), "timed_out": bool(row["timed_out"])})
    run(PlaySpec(folder, log=lambda line: None))
    resumed = read_responses(folder / "participant_01")
    cols = ["trial", "attempt", "answer_target", "touch_x_px", "timed_out"]
    pd.testing.assert_frame_equal(resumed[cols], reference[cols])
    answered = resumed.loc[~resumed["timed_out"], "trial"]
    assert not answered.duplicated().any()
    assert set(answered) | set(resumed.loc[resumed["timed_out"], "trial"]) == set(trials["trial"])
    assert list(resumed.columns) == list(RESPONSE_COLUMNS)
    assert resumed["simulated"].all()
    assert next_trial(trials, resumed) is None


def test_a_timed_out_trial_is_repeated_at_the_end_of_its_block(small_design):
    trials = read_trials(small_design / "participant_01")
    block = trials[trials["block"] == 1]
    first = int(block["trial"].iloc[0])
    responses = pd.DataFrame([{**{c: None for c in RESPONSE_COLUMNS}, "trial": first,
                               "timed_out": True}])
    for trial in block["trial"].iloc[1:]:
        responses = pd.concat([responses, pd.DataFrame([{"trial": int(trial),
                                                         "timed_out": False}])])
    responses = responses.reset_index(drop=True)
    step = next_trial(trials[trials["block"] >= 1], responses)
    assert step is not None and int(step.trial["trial"]) == first and step.attempt == 2


def test_the_log_refuses_what_does_not_match_the_trial_list(small_design, tmp_path):
    folder = _copy(small_design, tmp_path) / "participant_01"
    trials = read_trials(folder)
    log = ResponseLog(folder, trials, load_goals().ids)
    row = {c: None for c in RESPONSE_COLUMNS} | {"trial": 1, "timed_out": False,
                                                  "answer_target": 9, "backend": "file"}
    with pytest.raises(InputError, match="answer 9 of trial 1 is not a target"):
        log.append(row)
    with pytest.raises(InputError, match="trial 999 is not in the trial list"):
        log.append(row | {"trial": 999})
    log.append(row | {"answer_target": 2})
    with pytest.raises(InputError, match="answered already"):
        log.append(row | {"answer_target": 3})
    assert len(read_responses(folder)) == 1


def test_a_gaze_cue_makes_simulated_answers_follow_the_gaze(small_design):
    """With gaze much less noisy than the arm, incongruent trials follow the gaze."""
    robot, goals = load_robot(), load_goals()
    from ikbench.experiment.head import load_head

    head = load_head()
    model = observers.ObserverModel(noise_deg={"gaze": 1.0, "pointing": 20.0, "position": 20.0},
                                    lapse=0.0, reaction_median_s=0.5)
    trials = read_trials(small_design / "participant_01")
    incongruent = trials[trials["condition"] == "I"]
    follow = 0
    for _, t in incongruent.iterrows():
        poses = pd.read_csv(small_design / t["trajectory"])[list(robot.joint_names)].to_numpy()
        cues = observers.cue_points(t, robot, head, goals, poses)
        out = observers.answer(t, cues, goals, model, seed=1, attempt=1)
        follow += out["answer_target"] == t["gaze_target"]
    assert follow >= 0.8 * len(incongruent)


def test_screen_fit_places_the_authors_targets_near_the_touch_points():
    goals = load_goals()
    assert goals.ids == (1, 2, 3, 4, 5, 6, 7)
    assert goals.screen.fit_residuals_mm.max() < 15.0
    back = goals.screen.mm_to_px(goals.points_mm)
    assert np.abs(back - goals.pixels).max() < 1e-6


def test_emulator_trial_plays_forward_to_its_fraction_and_back(small_design, tmp_path):
    """On the bus emulator: the head reaches its gaze angles, the arm the trial's stop pose
    (the bus log shows it), then both go back."""
    from ikbench.experiment.head import load_head
    from ikbench.experiment.play import BusPresenter, bus_config
    from ikbench.hw.emulator import Emulator

    robot, head, goals = load_robot(), load_head(), load_goals()
    trials = read_trials(small_design / "participant_01")
    trial = trials[trials["condition"] == "GP"].iloc[0].to_dict()
    config = bus_config()
    start = np.concatenate([goals.targets.start_pose, head.rest_motor_deg])
    seen = {}
    with Emulator(config, start) as emulator:
        assert emulator.port is not None

        def answer(t, attempt):
            seen["pose"] = emulator.present_deg()
            return {"answer_target": 1, "touch_px": goals.pixels[0], "reaction_s": 0.5,
                    "timed_out": False}

        BusPresenter(small_design, emulator.port, "emulator", robot, head, answer,
                     lambda line: None).present(trial, 1)
        final = emulator.present_deg()
        writes = emulator.sync_writes()
    poses = pd.read_csv(small_design / trial["trajectory"])[list(robot.joint_names)].to_numpy()
    stop, _, stop_mm = stop_of(robot, poses, float(trial["fraction"]))
    at_stop = seen["pose"]
    fingertip = robot.fk(at_stop[None, :7]).point_mm[0]
    assert np.linalg.norm(fingertip - stop_mm) < 2.0                  # mm
    assert np.abs(at_stop[7:] - [trial["head_z_motor_deg"], trial["head_y_motor_deg"]]).max() < 0.2
    assert np.abs(final - start).max() < 0.2                          # back at the start
    assert len(writes) > 20


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ikbench", "experiment", *args],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(("args", "message"), [
    (["--conditions", "G,X"], "'X' is not a condition"),
    (["--fractions", "0.6,1.2"], "1.2 is outside (0, 1]"),
    (["--fractions", "0"], "0.0 is outside (0, 1]"),
    (["--participants", "0"], "--participants 0"),
    (["--duration", "0.5"], "give a longer --duration"),
])
def test_bad_design_input_is_one_line_and_writes_nothing(tmp_path, args, message):
    out = tmp_path / "study"
    result = _cli("design", "--output", str(out), "--repeats", "1", *args)
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_bad_goal_file_and_malformed_answers_are_one_line(tmp_path, small_design):
    goals = tmp_path / "goals.json"
    goals.write_text('{"joint_names": ["r_shoulder_z", "r_shoulder_y", "r_arm_x", "r_elbow_y",'
                     ' "r_wrist_z", "r_wrist_x", "r_indexfinger_x"], "start_pose": [-24.92, '
                     '81.45, 46.55, 94.37, -59.03, 28.0, 45.67], "targets": {"a": [33, 39, 25, '
                     '134, 102, 77, -168], "b": [37, 31, 23, 119, 107, 113, -177]}}')
    result = _cli("design", "--goals", str(goals), "--output", str(tmp_path / "s"))
    assert result.returncode == 2 and "ids must be positive integers" in result.stderr
    folder = _copy(small_design, tmp_path)
    answers = tmp_path / "answers.csv"
    answers.write_text("participant,trial\n1,1\n")
    result = _cli("run", str(folder), "--emulator", "--answers", str(answers))
    assert result.returncode == 2 and "missing column(s) answer_target" in result.stderr
    assert not (folder / "participant_01" / "responses.csv").exists()


def test_a_design_never_replaces_a_study_with_answers(small_design, tmp_path):
    folder = _copy(small_design, tmp_path)
    run(PlaySpec(folder, only=(1,), log=lambda line: None))
    result = _cli("design", "--output", str(folder), "--repeats", "1")
    assert result.returncode == 2 and "holds responses" in result.stderr
    assert (folder / "participant_01" / "responses.csv").exists()


def test_ctrl_c_during_a_simulated_run_then_resume_loses_and_repeats_nothing(small_design,
                                                                            tmp_path):
    """SIGINT to ``experiment run --simulate`` in the middle, then the same command again:
    the responses equal those of an uninterrupted run, row for row."""
    import signal
    import time

    whole = _copy(small_design, tmp_path / "whole")
    assert _cli("run", str(whole), "--simulate").returncode == 0
    folder = _copy(small_design, tmp_path / "cut")
    process = subprocess.Popen([sys.executable, "-m", "ikbench", "experiment", "run",
                                str(folder), "--simulate"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    log = folder / "participant_01" / "responses.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and (not log.exists() or log.stat().st_size < 2000):
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    if process.returncode == 0:
        pytest.skip("the run finished before the interrupt landed")
    assert process.returncode == 130, err
    partial = sum(len(read_responses(p)) for p in sorted(folder.glob("participant_*")))
    assert _cli("run", str(folder), "--simulate").returncode == 0
    cols = ["trial", "attempt", "answer_target", "touch_x_px", "timed_out"]
    total = 0
    for p in sorted(whole.glob("participant_*")):
        mine = read_responses(folder / p.name)
        pd.testing.assert_frame_equal(mine[cols], read_responses(p)[cols])
        total += len(mine)
    assert 0 < partial < total


def test_an_answer_outside_the_goal_set_is_refused_in_one_line(small_design, tmp_path):
    folder = _copy(small_design, tmp_path)
    answers = tmp_path / "answers.csv"
    answers.write_text("participant,trial,answer_target,touch_x_px,touch_y_px,reaction_s\n"
                       "1,1,9,100,100,0.5\n")
    result = _cli("run", str(folder), "--emulator", "--answers", str(answers))
    assert result.returncode == 2, result.stderr
    assert "answer 9 of trial 1 is not a target id" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (folder / "participant_01" / "responses.csv").exists()


def test_the_analysis_finds_an_effect_put_in_and_none_where_none_was(small_design):
    """Vectorised simulated studies (the power analysis'): gaze less noisy than pointing gives
    GP > P and gaze-following under I; the null studies give p > 0.05 for these seeds."""
    from ikbench.experiment import power, study

    stimuli = study.stimulus_cues(small_design)
    effect = study.simulator(stimuli, observers.ObserverModel())
    null = study.null_simulator(stimuli)
    responses = effect(24, 1)       # 7 I trials per fraction each: a small design
    assert power.h1_test(responses) < 0.01 and power.h2_test(responses) < 0.05
    answered = responses
    gp = (answered.query("condition == 'GP'")["answer_target"]
          == answered.query("condition == 'GP'")["target"]).mean()
    p = (answered.query("condition == 'P'")["answer_target"]
         == answered.query("condition == 'P'")["target"]).mean()
    assert gp > p
    assert power.h1_test(null(16, 2)) > 0.05 and power.h2_test(null(16, 3)) > 0.05


def test_analyze_and_power_through_the_cli(small_design, tmp_path):
    folder = _copy(small_design, tmp_path)
    assert _cli("run", str(folder), "--simulate").returncode == 0
    result = _cli("analyze", str(folder))
    assert result.returncode == 0, result.stderr
    out = folder / "analysis"
    assert "SIMULATED PARTICIPANTS" in (out / "analysis.md").read_text()
    table = pd.read_csv(out / "analysis.csv")
    assert set(table.loc[table["level"] == "cell", "cell"]) == {"G", "P60", "P80", "GP60",
                                                                 "GP80", "I60", "I80"}
    fitted = pd.read_csv(out / "observers.csv")
    assert set(fitted["observer"]) == set(observers.OBSERVERS)
    result = _cli("power", str(folder), "--participants", "3,6", "--repetitions", "5")
    assert result.returncode == 0, result.stderr
    curve = pd.read_csv(folder / "power" / "power.csv")
    assert list(curve["participants"]) == [3, 6] and curve["power"].between(0, 1).all()
