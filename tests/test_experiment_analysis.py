"""The pointing experiment's analysis (ikbench.experiment.analysis, figures, power) on
synthetic studies with known hit probabilities per cell and a participant effect."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("statsmodels")

from statsmodels.stats.proportion import proportion_confint  # noqa: E402

from ikbench.core.errors import InputError  # noqa: E402
from ikbench.experiment import analysis, power  # noqa: E402
from ikbench.experiment.analysis import (  # noqa: E402
    RESPONSE_COLUMNS,
    TRIAL_COLUMNS,
    analyze,
    cell_table,
    contrasts,
    mixed_model,
    observer_fit,
    read_study,
)

GOALS = list(range(1, 8))
CELLS = {"G": ("G", None), "P60": ("P", 0.6), "GP60": ("GP", 0.6), "I60": ("I", 0.6),
         "P80": ("P", 0.8), "GP80": ("GP", 0.8), "I80": ("I", 0.8)}
EFFECT = {"G": 0.5, "P60": 0.5, "GP60": 0.9, "I60": 0.3, "P80": 0.5, "GP80": 0.9, "I80": 0.3}
NULL = dict.fromkeys(CELLS, 0.5)


def _logit(p):
    return np.log(p / (1 - p))


def toy_predict(trials: pd.DataFrame, params) -> np.ndarray:
    """A toy observer: the goals lie 15 deg apart (x_px / 20); answers are Gaussian in angle
    around the true target's, with SD sigma_deg / fraction (G: fraction 1)."""
    sigma = params["sigma_deg"] / trials["fraction"].fillna(1.0).to_numpy()
    goal_deg = np.array(GOALS) * 300.0 / 20.0
    target_deg = trials["target_x_px"].to_numpy() / 20.0
    logits = -((goal_deg[None, :] - target_deg[:, None]) ** 2) / (2 * sigma[:, None] ** 2)
    p = np.exp(logits - logits.max(1, keepdims=True))
    return p / p.sum(1, keepdims=True)


def simulate(n_participants: int, seed: int, p_hit=EFFECT, gaze_share: float = 0.5,
             participant_sd: float = 0.5, per_cell: int = 20, timeout: float = 0.03,
             practice: int = 3, sigma_deg: float | None = None):
    """(trials, responses) of a synthetic study, every participant's rows in one frame each:
    per trial, a hit with probability expit(logit(p_hit[cell]) + u_participant); a miss
    goes, under I, to the gaze target with probability ``gaze_share``, else to a random other
    goal. With ``sigma_deg``, answers are drawn from :func:`toy_predict` instead. A timed-out
    attempt is repeated at once as attempt 2."""
    rng = np.random.default_rng(seed)
    names = list(p_hit)
    per = practice + per_cell * len(names)
    count = n_participants * per
    u = np.repeat(rng.normal(0.0, participant_sd, n_participants), per)
    main = np.tile(np.repeat(np.arange(len(names)), per_cell), (n_participants, 1))
    order = np.hstack([rng.integers(0, len(names), (n_participants, practice)),
                       rng.permuted(main, axis=1)]).ravel()
    cell = np.array(names)[order]
    condition = np.array([CELLS[c][0] for c in names])[order]
    fraction = np.array([np.nan if CELLS[c][1] is None else CELLS[c][1] for c in names])[order]
    target = rng.choice(GOALS, count)
    other = (target - 1 + rng.integers(1, len(GOALS), count)) % len(GOALS) + 1
    gaze = np.where(condition == "P", np.nan, np.where(condition == "I", other, target))
    index = np.tile(np.arange(per), n_participants)
    trials = pd.DataFrame({
        "participant": np.repeat([f"{i + 1:02d}" for i in range(n_participants)], per),
        "trial": index + 1, "block": 1 + index // 50, "practice": index < practice,
        "condition": condition, "fraction": fraction, "cell": cell, "target": target,
        "gaze_target": pd.array(gaze, dtype="Int64"), "head_z_motor_deg": 0.0,
        "head_y_motor_deg": -10.0, "target_x_px": target * 300.0, "target_y_px": 600.0,
        "trajectory": "trajectories/ours-exact/trajectory_1.csv", "stop_step": 40,
        "stop_x_mm": 200.0, "stop_y_mm": 100.0, "stop_z_mm": 50.0, "duration_s": 2.0,
        "gaze_lead_s": 0.3})[list(TRIAL_COLUMNS)]
    if sigma_deg is None:
        p = 1 / (1 + np.exp(-(_logit(np.array([p_hit[c] for c in names]))[order] + u)))
        random_other = (target - 1 + rng.integers(1, len(GOALS), count)) % len(GOALS) + 1
        to_gaze = (condition == "I") & (rng.random(count) < gaze_share)
        answer = np.where(rng.random(count) < p, target,
                          np.where(to_gaze, other, random_other))
    else:
        cum = toy_predict(trials, {"sigma_deg": sigma_deg}).cumsum(1)
        answer = np.array(GOALS)[(rng.random(count)[:, None] > cum).sum(1)]
    r = trials[["participant", "trial", "block", "practice", "condition", "fraction", "cell",
                "target", "gaze_target"]].copy()
    r["attempt"] = 1
    r["answer_target"] = pd.array(answer, dtype="Int64")
    r["touch_x_px"] = answer * 300.0 + rng.normal(0, 20, count)
    r["touch_y_px"] = 600.0 + rng.normal(0, 20, count)
    r["touch_error_px"] = np.hypot(r["touch_x_px"] - target * 300.0, r["touch_y_px"] - 600)
    r["touch_error_mm"] = r["touch_error_px"] * 467.0 / 2400.0
    r["reaction_s"] = rng.gamma(4.0, 0.3, count)
    r["timed_out"] = False
    r["backend"], r["simulated"] = "simulated", True
    r["observer"], r["timestamp_utc"] = "toy", "2025-01-01T00:00:00+00:00"
    timed = rng.random(count) < timeout
    late = r[timed].assign(attempt=2)
    r.loc[timed, ["answer_target", "touch_x_px", "touch_y_px", "touch_error_px",
                  "touch_error_mm"]] = pd.NA
    r.loc[timed, "reaction_s"] = 10.0
    r.loc[timed, "timed_out"] = True
    responses = pd.concat([r, late]).sort_index(kind="stable").reset_index(drop=True)
    return trials, responses[list(RESPONSE_COLUMNS)]


def make_study(folder: Path, n_participants: int = 10, seed: int = 1, simulated: bool = True,
               **kwargs) -> Path:
    trials, responses = simulate(n_participants, seed, **kwargs)
    design = {"kind": "experiment-design", "conditions": ["G", "P", "GP", "I"],
              "fractions": [0.6, 0.8],
              "goals": {"ids": GOALS, "pixels": {str(g): [300.0 * g, 600.0] for g in GOALS}},
              "screen": {"size_px": [2400, 1350], "size_mm": [467.0, 267.0]},
              "participants": n_participants, "seed": seed, "method": "ours-exact",
              "simulated": simulated}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "design.json").write_text(json.dumps(design))
    for (pid, t), (_, r) in zip(trials.groupby("participant"),
                                responses.groupby("participant")):
        sub = folder / f"participant_{pid}"
        sub.mkdir()
        t.to_csv(sub / "trials.csv", index=False)
        if not simulated:
            r = r.assign(simulated=False, backend="stdin", observer="")
        r.to_csv(sub / "responses.csv", index=False)
    return folder


def sim_responses(n: int, seed: int, **kwargs) -> pd.DataFrame:
    return simulate(n, seed, **kwargs)[1]


@pytest.fixture(scope="module")
def effect_study(tmp_path_factory):
    return read_study(make_study(tmp_path_factory.mktemp("effect") / "study", 14, seed=3,
                                 gaze_share=0.9))


# --------------------------------------------------------------------------- tables


def test_cell_table_counts_and_rates_equal_a_direct_computation(effect_study):
    raw = pd.concat([pd.read_csv(p) for p in sorted(effect_study.folder.glob(
        "participant_*/responses.csv"))])
    raw = raw[~raw["practice"]]
    table = cell_table(effect_study).set_index(["level", "cell"]).loc["cell"]
    assert list(table.index) == list(CELLS)
    for cell, part in raw.groupby("cell"):
        answered = part[~part["timed_out"]]
        hits = int((answered["answer_target"] == answered["target"]).sum())
        assert table.loc[cell, "n_answered"] == len(answered)
        assert table.loc[cell, "n_timed_out"] == int(part["timed_out"].sum())
        assert table.loc[cell, "hits"] == hits
        assert table.loc[cell, "hit_rate"] == pytest.approx(hits / len(answered))
        assert table.loc[cell, "reaction_s_median"] == pytest.approx(
            answered["reaction_s"].median())
        if cell.startswith("I"):
            gaze = int((answered["answer_target"] == answered["gaze_target"]).sum())
            assert table.loc[cell, "follows_gaze_rate"] == pytest.approx(gaze / len(answered))
        else:
            assert np.isnan(table.loc[cell, "follows_gaze_rate"])
    pooled = cell_table(effect_study).set_index(["level", "cell"]).loc[("condition", "GP")]
    gp = raw[raw["condition"] == "GP"]
    assert pooled["n_answered"] == int((~gp["timed_out"]).sum())


def test_the_wilson_interval_is_statsmodels(effect_study):
    row = cell_table(effect_study).set_index("cell").loc["P60"]
    low, high = proportion_confint(row["hits"], row["n_answered"], alpha=0.05,
                                   method="wilson")
    assert (row["hit_ci_low"], row["hit_ci_high"]) == pytest.approx((low, high), abs=1e-12)
    assert row["hit_ci_low"] < row["hit_rate"] < row["hit_ci_high"]


def test_confusion_counts_sum_to_the_answered_and_the_diagonal_to_the_hits(effect_study):
    tables = analysis.confusion(effect_study)
    cells = cell_table(effect_study).set_index(["level", "cell"]).loc["cell"]
    assert list(tables) == list(CELLS)
    for cell, table in tables.items():
        assert list(table.index) == GOALS and list(table.columns) == GOALS
        assert table.to_numpy().sum() == cells.loc[cell, "n_answered"]
        assert np.trace(table.to_numpy()) == cells.loc[cell, "hits"]


# --------------------------------------------------------------------------- model, tests


def test_mixed_model_finds_the_effect_against_p_at_each_fraction(effect_study):
    model = mixed_model(effect_study)
    assert model.reference["GP60"] == "P60" and model.reference["I80"] == "P80"
    for frame, column in ((model.bayes, "posterior_mean"), (model.gee, "estimate")):
        terms = frame.set_index("term")[column]
        # logit(0.9) - logit(0.5) = 2.2; logit(0.3) - logit(0.5) = -0.85
        assert terms["GP60 vs P60"] > 1.0 and terms["GP80 vs P80"] > 1.0
        assert terms["I60 vs P60"] < 0
    assert model.gee.set_index("term").loc["GP60 vs P60", "p_value"] < 0.001
    assert 0.1 < model.random_sd < 1.5  # participant_sd 0.5 put in
    assert {"bayes-mixed-logit (VB)", "gee-logit (exchangeable, bias-reduced robust SE)"} == set(
        model.table()["model"])


def test_an_effect_put_in_is_found(effect_study):
    table = contrasts(effect_study).set_index(["comparison", "method"])
    pooled = table.xs("GP vs P (pooled over fractions)", level="comparison")
    assert (pooled["p_value"] < 0.01).all() and (pooled["p_holm"] < 0.01).all()
    wil = pooled.loc[analysis.WILCOXON]
    assert 0.25 < wil["estimate"] < 0.55 and wil["ci_low"] > 0  # 0.9 - 0.5 put in
    assert wil["n_participants"] == 14
    assert pooled.loc[analysis.GEE_Z, "estimate"] > 3  # odds ratio 9 put in
    assert table.xs("GP (pooled over fractions) vs G", level="comparison")["p_value"].max() \
        < 0.01


def test_no_effect_gives_no_significant_difference(tmp_path):
    study = read_study(make_study(tmp_path / "null", 14, seed=5, p_hit=NULL))
    table = contrasts(study)
    h1 = table[table["hypothesis"].isin(["H1a", "H1b"])]
    assert len(h1) == 8 and (h1["p_value"] > 0.01).all()
    assert (h1["p_holm"] >= h1["p_value"]).all()


def test_h2_detects_gaze_following_when_it_is_put_in(effect_study, tmp_path):
    table = contrasts(effect_study)
    h2 = table[table["comparison"] == "I (pooled): follows gaze vs pointing"].set_index(
        "method")
    assert (h2["p_value"] < 0.01).all()
    assert h2.loc[analysis.WILCOXON, "estimate"] > 0.2
    assert h2.loc[analysis.GEE_Z, "estimate"] > 0.6  # share of gaze-following > 0.5
    # hit 0.5 and every miss to the gaze target: gaze and pointing followed alike
    balanced = read_study(make_study(tmp_path / "balanced", 14, seed=8, p_hit=NULL,
                                     gaze_share=1.0))
    h2 = contrasts(balanced)
    h2 = h2[h2["comparison"] == "I (pooled): follows gaze vs pointing"]
    assert (h2["p_value"] > 0.01).all()


def test_the_observer_fit_recovers_a_known_sigma(tmp_path):
    study = read_study(make_study(tmp_path / "obs", 8, seed=11, sigma_deg=12.0))
    fit = observer_fit(study, {"toy": toy_predict}, bounds=(1.0, 60.0))
    overall = fit[fit["cell"] == "all"].iloc[0]
    assert overall["sigma_deg"] == pytest.approx(12.0, rel=0.2)
    assert not overall["at_bound"]
    assert overall["aic"] == pytest.approx(2 - 2 * overall["log_likelihood"])
    assert overall["log_likelihood"] > overall["log_likelihood_chance"]
    cells = fit.set_index("cell")
    assert abs(cells.loc["G", "predicted_hit_rate"] - cells.loc["G", "observed_hit_rate"]) \
        < 0.1


def test_a_predict_returning_the_wrong_shape_is_refused(effect_study):
    with pytest.raises(InputError, match=r"observer bad: predict returned shape \(\d+, 3\)"):
        observer_fit(effect_study, {"bad": lambda t, p: np.full((len(t), 3), 1 / 3)})


# --------------------------------------------------------------------------- power


def test_power_rises_with_participants_for_a_real_effect():
    effect = {"P60": 0.5, "GP60": 0.62, "P80": 0.5, "GP80": 0.62}

    def sim(n, seed):
        return sim_responses(n, seed, p_hit=effect, per_cell=10, timeout=0.0, practice=0)

    seen = []
    curve = power.power_curve(sim, power.h1_test, participants=(6, 24), repetitions=30,
                              seed=1, progress=lambda n, p: seen.append(n))
    assert seen == [6, 24]
    assert list(curve["participants"]) == [6, 24]
    assert curve["power"].iloc[1] >= curve["power"].iloc[0] + 0.3
    assert (curve["power_ci_low"] <= curve["power"]).all()
    assert (curve["power"] <= curve["power_ci_high"]).all()


def test_participants_for_power_takes_the_first_size_that_stays_above():
    curve = pd.DataFrame({"participants": [4, 8, 12, 16], "power": [0.1, 0.82, 0.79, 0.9]})
    assert power.participants_for_power(curve, 0.8) == 16
    assert power.participants_for_power(curve, 0.95) is None


@pytest.mark.parametrize("test", [power.h1_test, power.h2_test])
def test_the_false_positive_rate_of_a_null_generator_is_near_alpha(test):
    def null(n, seed):  # no H1 effect; under I gaze and pointing followed alike (hit 0.5,
        # every miss to the gaze target)
        return sim_responses(n, seed, p_hit=NULL, gaze_share=1.0, per_cell=8, timeout=0.0,
                             practice=0)

    rate = power.false_positive_rate(null, test, n=16, repetitions=100, seed=2).iloc[0]
    assert rate["repetitions"] == 100 and rate["failed"] == 0
    assert 0.0 <= rate["false_positive_rate"] <= 0.15


def test_the_gee_tests_agree_in_direction_with_the_wilcoxon():
    responses = sim_responses(12, 4, gaze_share=0.9)
    assert power.h1_test(responses, "gee") < 0.01 and power.h2_test(responses, "gee") < 0.01
    with pytest.raises(InputError, match="allowed: wilcoxon, gee"):
        power.h1_test(responses, "t")


# --------------------------------------------------------------------------- bad input


def _rewrite(path: Path, edit) -> None:
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    edit(frame)
    frame.to_csv(path, index=False)


def test_a_missing_column_is_named(tmp_path):
    folder = make_study(tmp_path / "s", 2)
    _rewrite(folder / "participant_02" / "responses.csv",
             lambda f: f.pop("reaction_s"))
    with pytest.raises(InputError, match=r"participant_02/responses.csv: missing column\(s\) "
                                         r"reaction_s"):
        read_study(folder)


def test_an_answer_not_among_the_goals_is_named_with_its_line(tmp_path):
    folder = make_study(tmp_path / "s", 2, timeout=0.0)

    def edit(frame):
        frame.loc[4, "answer_target"] = "9"

    _rewrite(folder / "participant_01" / "responses.csv", edit)
    with pytest.raises(InputError, match=r"participant_01/responses.csv: line 6: "
                                         r"answer_target = 9; allowed: 1, 2, 3, 4, 5, 6, 7"):
        read_study(folder)


def test_a_response_for_a_trial_not_in_trials_csv_is_named(tmp_path):
    folder = make_study(tmp_path / "s", 2, timeout=0.0)

    def edit(frame):
        frame.loc[2, "trial"] = "999"

    _rewrite(folder / "participant_02" / "responses.csv", edit)
    with pytest.raises(InputError, match=r"responses.csv: line 4: trial 999 is not in "
                                         r".*participant_02/trials.csv"):
        read_study(folder)


def test_a_malformed_value_is_named_with_its_line(tmp_path):
    folder = make_study(tmp_path / "s", 2)

    def edit(frame):
        frame.loc[0, "trial"] = "two"

    _rewrite(folder / "participant_01" / "trials.csv", edit)
    with pytest.raises(InputError, match=r"trials.csv: line 2: trial = 'two'; allowed: an "
                                         r"integer"):
        read_study(folder)


def test_an_empty_answer_without_a_timeout_is_refused(tmp_path):
    folder = make_study(tmp_path / "s", 2, timeout=0.0)

    def edit(frame):
        frame.loc[5, "answer_target"] = ""

    _rewrite(folder / "participant_01" / "responses.csv", edit)
    with pytest.raises(InputError, match="line 7: answer_target is empty but timed_out is "
                                         "False"):
        read_study(folder)


def test_an_empty_folder_is_refused(tmp_path):
    with pytest.raises(InputError, match="no design.json"):
        read_study(tmp_path)
    folder = make_study(tmp_path / "s", 1)
    for path in folder.glob("participant_*/responses.csv"):
        path.unlink()
    with pytest.raises(InputError, match="no responses outside practice"):
        read_study(folder)


# --------------------------------------------------------------------------- analyze


def test_analyze_writes_every_file_and_labels_simulated_data(tmp_path):
    folder = make_study(tmp_path / "s", 6, seed=2, gaze_share=0.9)
    out = tmp_path / "out"
    result = analyze(folder, out, observers={"toy": toy_predict}, bounds=(1.0, 60.0))
    expected = {"analysis.csv", "contrasts.csv", "model.csv", "confusion.csv",
                "observers.csv", "analysis.json", "analysis.md", "hit_rates.png",
                "incongruent.png", "confusion.png", "reaction_times.png"}
    assert {p.name for p in out.iterdir()} == expected
    text = (out / "analysis.md").read_text()
    assert text.count("SIMULATED PARTICIPANTS — not human data") == 2
    assert "no evidence of a difference" in text or "hypothesised direction" in text
    long = pd.read_csv(out / "confusion.csv")
    assert list(long.columns) == ["cell", "target", "answer", "count"]
    assert long["count"].sum() == result.cells.query("level == 'cell'")["n_answered"].sum()
    cells = pd.read_csv(out / "analysis.csv")
    assert list(cells["cell"][cells["level"] == "cell"]) == list(CELLS)
    assert json.loads((out / "analysis.json").read_text())["simulated"] is True


def test_people_get_no_simulated_banner(tmp_path):
    folder = make_study(tmp_path / "s", 3, simulated=False)
    result = analyze(folder)
    assert not result.study.simulated
    assert "SIMULATED" not in result.markdown()


def test_the_column_kinds_cover_the_files_columns_in_order():
    from ikbench.experiment import analysis
    from ikbench.experiment.design import TRIAL_COLUMNS
    from ikbench.experiment.records import RESPONSE_COLUMNS

    assert tuple(analysis.TRIAL_TYPES) == TRIAL_COLUMNS
    assert tuple(analysis.RESPONSE_TYPES) == RESPONSE_COLUMNS
