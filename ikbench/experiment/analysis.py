"""The pointing experiment's analysis: what an HRI reviewer expects, from the files alone.

Reads DIR/design.json and DIR/participant_*/trials.csv + responses.csv (the contract in
docs: file formats), drops practice rows, and reports:

- :func:`cell_table`: per cell (G, P60, GP60, I60, ...) and per condition: answered, timed out,
  hits with Wilson 95 % intervals, under I the gaze-following rate, touch error and reaction
  time medians with their quartiles;
- :func:`mixed_model`: a mixed-effects logistic regression of a hit on the cell with
  participant random intercepts (statsmodels' variational Bayes), and a GEE logistic with
  small-sample robust Wald tests as the frequentist check; the reference is P at each fraction;
- :func:`contrasts`: the hypotheses (H1a GP vs P, H1b GP vs G, H2 gaze vs pointing under I),
  each by a participant-level Wilcoxon signed-rank test and by a GEE Wald test, two-sided, with
  Holm's correction within each method's family;
- :func:`confusion`: target x answer counts per cell;
- :func:`observer_fit`: each model observer's noise fitted by maximum likelihood;
- :func:`analyze`: all of it, and with an output folder its CSVs, figures and analysis.md.

statsmodels is an optional dependency (``pip install 'ikbench[experiment]'``).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize, stats

from ikbench.core.errors import InputError
from ikbench.experiment.design import CONDITIONS, TRIAL_COLUMNS, cell_name
from ikbench.experiment.records import RESPONSE_COLUMNS

#: Significance level of every test and the coverage 1 - ALPHA of every interval.
ALPHA = 0.05
INSTALL = "pip install 'ikbench[experiment]' (the statsmodels package)"

# column -> (kind, must be non-empty); kinds: str, int, float (empty -> NaN), bool, id (an
# int goal id or empty -> float NaN)
TRIAL_TYPES: dict[str, tuple[str, bool]] = {
    "participant": ("str", True), "trial": ("int", True), "block": ("int", True),
    "practice": ("bool", True), "condition": ("str", True), "fraction": ("float", False),
    "cell": ("str", True), "target": ("int", True), "gaze_target": ("id", False),
    "head_z_motor_deg": ("float", False), "head_y_motor_deg": ("float", False),
    "target_x_px": ("float", False), "target_y_px": ("float", False),
    "trajectory": ("str", False), "stop_step": ("float", False), "stop_x_mm": ("float", False),
    "stop_y_mm": ("float", False), "stop_z_mm": ("float", False),
    "duration_s": ("float", False), "gaze_lead_s": ("float", False),
}
RESPONSE_TYPES: dict[str, tuple[str, bool]] = {
    "participant": ("str", True), "trial": ("int", True), "attempt": ("int", True),
    "block": ("int", True), "practice": ("bool", True), "condition": ("str", True),
    "fraction": ("float", False), "cell": ("str", True), "target": ("int", True),
    "gaze_target": ("id", False), "answer_target": ("id", False),
    "touch_x_px": ("float", False), "touch_y_px": ("float", False),
    "touch_error_px": ("float", False), "touch_error_mm": ("float", False),
    "reaction_s": ("float", False), "timed_out": ("bool", True), "backend": ("str", False),
    "simulated": ("bool", True), "observer": ("str", False), "timestamp_utc": ("str", False),
}
# (the kinds above cover the columns of trials.csv and responses.csv, in their order:
# tests/test_experiment_analysis.py checks it)

#: ``predict(trials, params) -> (n_trials, n_goals)`` answer probabilities, goals in the
#: design's order; ``trials`` holds trials.csv's columns, one row per answered response.
Predict = Callable[[pd.DataFrame, Mapping[str, float]], np.ndarray]


def _statsmodels() -> Any:
    try:
        import statsmodels.api as sm
    except ImportError:
        raise InputError(f"analysis: the model and contrasts need statsmodels, which is not "
                         f"installed: {INSTALL}") from None
    return sm


# --------------------------------------------------------------------------- reading


def design_cells(design: Mapping[str, Any]) -> list[str]:
    """The design's cells in report order: G, then per fraction P, GP, I (e.g. G, P60, GP60,
    I60, P80, GP80, I80)."""
    conditions = [c for c in CONDITIONS if c in design.get("conditions", CONDITIONS)]
    cells = ["G"] if "G" in conditions else []
    for fraction in design.get("fractions", []):
        cells += [cell_name(c, fraction) for c in conditions if c != "G"]
    return cells


@dataclass(frozen=True)
class Study:
    """One experiment folder, read and checked.

    Attributes:
        folder: the folder read.
        design: design.json, parsed.
        trials: every participant's trials.csv, concatenated (trials.csv columns).
        responses: every participant's responses.csv, concatenated (responses.csv columns;
            answer_target and gaze_target as float ids, NaN when empty).
        simulated: the design says simulated, or any response comes from a simulated
            participant.
    """

    folder: Path
    design: dict[str, Any]
    trials: pd.DataFrame
    responses: pd.DataFrame
    simulated: bool

    @property
    def goals(self) -> list[int]:
        """The goal ids, in the design's order."""
        return [int(g) for g in self.design["goals"]["ids"]]

    @property
    def cells(self) -> list[str]:
        """The cells that hold analysed responses, in the design's order."""
        present = set(self.analysed()["cell"])
        return [c for c in design_cells(self.design) if c in present]

    @property
    def fractions(self) -> list[float]:
        """The design's fractions (0.6, 0.8)."""
        return [float(f) for f in self.design.get("fractions", [])]

    def analysed(self) -> pd.DataFrame:
        """The responses the analysis uses: practice rows dropped; with boolean columns hit
        (answer == target), follows_gaze (answer == gaze_target) and follows_either."""
        frame = self.responses[~self.responses["practice"]].copy()
        answered = ~frame["timed_out"]
        frame["hit"] = answered & (frame["answer_target"] == frame["target"])
        frame["follows_gaze"] = answered & (frame["answer_target"] == frame["gaze_target"])
        frame["follows_either"] = frame["hit"] | frame["follows_gaze"]
        return frame.reset_index(drop=True)

    def answered(self) -> pd.DataFrame:
        """:meth:`analysed` without the timed-out rows."""
        frame = self.analysed()
        return frame[~frame["timed_out"]].reset_index(drop=True)


def _first_line(mask: pd.Series) -> int:
    return int(np.flatnonzero(mask.to_numpy())[0]) + 2  # line 1 is the header


def _read_table(path: Path, types: Mapping[str, tuple[str, bool]]) -> pd.DataFrame:
    """A contract CSV parsed column by column; InputError naming the file, line and value."""
    try:
        raw = pd.read_csv(path, dtype=str, keep_default_na=False, na_filter=False,
                          skip_blank_lines=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path}: not a readable CSV table ({reason})") from None
    missing = [c for c in types if c not in raw.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}; required: "
                         f"{', '.join(types)}")
    out: dict[str, Any] = {}
    for column, (kind, required) in types.items():
        text = raw[column].str.strip()
        empty = text == ""
        if required and empty.any():
            raise InputError(f"{path}: line {_first_line(empty)}: {column} is empty; it is "
                             f"required")
        if kind == "str":
            out[column] = text
        elif kind == "bool":
            lower = text.str.lower()
            bad = ~lower.isin(["true", "false", "1", "0"]) & ~empty
            if bad.any():
                line = _first_line(bad)
                raise InputError(f"{path}: line {line}: {column} = {text[bad].iloc[0]!r}; "
                                 f"allowed: True, False")
            out[column] = lower.isin(["true", "1"])
        else:
            values = pd.to_numeric(text.where(~empty, None), errors="coerce").astype(float)
            bad = ~empty & values.isna()
            if kind in ("int", "id"):
                bad |= ~empty & values.notna() & (values != values.round())
            if bad.any():
                allowed = {"float": "a number", "int": "an integer",
                           "id": "an integer goal id or empty"}[kind]
                raise InputError(f"{path}: line {_first_line(bad)}: {column} = "
                                 f"{text[bad].iloc[0]!r}; allowed: {allowed}")
            out[column] = values.astype(np.int64) if kind == "int" else values
    return pd.DataFrame(out)


def _read_design(path: Path) -> dict[str, Any]:
    try:
        design = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable JSON file ({exc})") from None
    if not isinstance(design, dict):
        raise InputError(f"{path}: a JSON object is required, got {type(design).__name__}")
    if design.get("kind", "experiment-design") != "experiment-design":
        raise InputError(f"{path}: kind = {design.get('kind')!r}; allowed: experiment-design")
    ids = design.get("goals", {}).get("ids") if isinstance(design.get("goals"), dict) else None
    if not isinstance(ids, list) or not ids:
        raise InputError(f"{path}: goals.ids is missing or empty; a list of goal ids is "
                         f"required")
    unknown = [c for c in design.get("conditions", CONDITIONS) if c not in CONDITIONS]
    if unknown:
        raise InputError(f"{path}: conditions {unknown}; allowed: {', '.join(CONDITIONS)}")
    return design


def _check_rows(path: Path, frame: pd.DataFrame, design: Mapping[str, Any],
                participant: str) -> None:
    """The checks trials.csv and responses.csv share: participant, condition, cell, ids."""
    goals = [int(g) for g in design["goals"]["ids"]]
    cells = design_cells(design)

    def refuse(mask: pd.Series, what: str, allowed: str) -> None:
        if mask.any():
            raise InputError(f"{path}: line {_first_line(mask)}: {what} = "
                             f"{frame.loc[mask.to_numpy(), what].iloc[0]!r}; allowed: {allowed}")

    refuse(frame["participant"] != participant, "participant",
           f"{participant!r} (the folder participant_{participant})")
    refuse(~frame["condition"].isin(design.get("conditions", CONDITIONS)), "condition",
           ", ".join(design.get("conditions", CONDITIONS)))
    no_fraction = frame["fraction"].isna() & (frame["condition"] != "G")
    refuse(no_fraction, "fraction", "a fraction for every condition but G")
    expected = [cell_name(c, f) for c, f in zip(frame["condition"], frame["fraction"])]
    refuse(frame["cell"] != pd.Series(expected, index=frame.index), "cell",
           f"the condition's cell (condition + percent, e.g. GP60); design cells: "
           f"{', '.join(cells)}")
    refuse(~frame["cell"].isin(cells), "cell", ", ".join(cells))
    allowed_ids = ", ".join(map(str, goals))
    refuse(~frame["target"].isin(goals), "target", allowed_ids)
    refuse(frame["gaze_target"].notna() & ~frame["gaze_target"].isin(goals), "gaze_target",
           allowed_ids)
    incongruent = frame["condition"] == "I"
    refuse(incongruent & (frame["gaze_target"].isna() | (frame["gaze_target"] ==
                                                          frame["target"])),
           "gaze_target", "under I a goal id other than the target")


def _check_responses(path: Path, responses: pd.DataFrame, trials: pd.DataFrame,
                     goals: Sequence[int]) -> None:
    def refuse(mask: pd.Series, message: str) -> None:
        if mask.any():
            row = responses[mask.to_numpy()].iloc[0]
            raise InputError(f"{path}: line {_first_line(mask)}: " + message.format(row=row))

    by_trial = trials.set_index("trial")
    refuse(~responses["trial"].isin(by_trial.index),
           "trial {row.trial} is not in " + str(path.parent / "trials.csv"))
    refuse(responses.duplicated(["trial", "attempt"]),
           "trial {row.trial} attempt {row.attempt} is answered twice")
    planned = by_trial.loc[responses["trial"]]
    for column in ("target", "cell"):
        differs = pd.Series(planned[column].to_numpy() != responses[column].to_numpy())
        refuse(differs, column + " = {row." + column + "!r} differs from trials.csv's for "
               "trial {row.trial}")
    answer = responses["answer_target"]
    refuse(answer.notna() & ~answer.isin(goals),
           "answer_target = {row.answer_target:g}; allowed: " + ", ".join(map(str, goals)) +
           ", or empty when timed out")
    refuse(answer.isna() & ~responses["timed_out"],
           "answer_target is empty but timed_out is False; an answer is required")
    refuse(answer.notna() & responses["timed_out"],
           "answer_target = {row.answer_target:g} but timed_out is True; empty is required")


def read_study(folder: str | Path) -> Study:
    """Read and check an experiment folder.

    Args:
        folder: DIR holding design.json and participant_XX/ folders, each with trials.csv and
            (once played) responses.csv.

    Returns:
        The :class:`Study`.

    Raises:
        InputError: no such folder, no design.json, no participants or no responses; a
            missing column; a malformed row (the file and line are named); a response for a
            trial not in the participant's trials.csv; an answer not among the goals, or
            empty without a timeout.
    """
    folder = Path(folder)
    where = "(an experiment folder holds design.json and participant_XX/ folders)"
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder {where}")
    if not (folder / "design.json").is_file():
        raise InputError(f"{folder}: no design.json {where}")
    design = _read_design(folder / "design.json")
    folders = sorted(p for p in folder.glob("participant_*") if p.is_dir())
    if not folders:
        raise InputError(f"{folder}: no participant_XX/ folders; nothing to analyse")
    all_trials, all_responses = [], []
    for sub in folders:
        participant = sub.name.removeprefix("participant_")
        if not (sub / "trials.csv").is_file():
            raise InputError(f"{sub}: no trials.csv (every participant folder holds one)")
        trials = _read_table(sub / "trials.csv", TRIAL_TYPES)
        _check_rows(sub / "trials.csv", trials, design, participant)
        if trials["trial"].duplicated().any():
            dup = trials["trial"].duplicated()
            raise InputError(f"{sub / 'trials.csv'}: line {_first_line(dup)}: trial "
                             f"{trials['trial'][dup].iloc[0]} is listed twice")
        all_trials.append(trials)
        if (sub / "responses.csv").is_file():
            responses = _read_table(sub / "responses.csv", RESPONSE_TYPES)
            _check_rows(sub / "responses.csv", responses, design, participant)
            _check_responses(sub / "responses.csv", responses, trials,
                             [int(g) for g in design["goals"]["ids"]])
            all_responses.append(responses)
    responses = (pd.concat(all_responses, ignore_index=True) if all_responses else
                 pd.DataFrame(columns=list(RESPONSE_COLUMNS)))
    if not len(responses) or responses["practice"].all():
        raise InputError(f"{folder}: no responses outside practice in participant_XX/"
                         f"responses.csv; nothing to analyse")
    simulated = bool(design.get("simulated", False)) or bool(responses["simulated"].any())
    return Study(folder, design, pd.concat(all_trials, ignore_index=True), responses,
                 simulated)


# --------------------------------------------------------------------------- rates


def wilson_interval(successes: Any, trials: Any) -> tuple[np.ndarray, np.ndarray]:
    """Wilson 95 % intervals (low, high) of success rates (statsmodels' proportion_confint);
    NaN without trials."""
    from statsmodels.stats.proportion import proportion_confint

    k = np.atleast_1d(np.asarray(successes, dtype=float))
    n = np.atleast_1d(np.asarray(trials, dtype=float))
    low, high = np.full(k.shape, np.nan), np.full(k.shape, np.nan)
    ok = n > 0
    if ok.any():
        lo, hi = proportion_confint(k[ok], n[ok], alpha=ALPHA, method="wilson")
        low[ok], high[ok] = lo, hi
    return low, high


def _rate(prefix: str, k: int, n: int) -> dict[str, float]:
    low, high = wilson_interval(k, n)
    return {prefix: k, f"{prefix}_rate": k / n if n else math.nan,
            f"{prefix}_ci_low": float(low[0]), f"{prefix}_ci_high": float(high[0])}


def _quartiles(values: pd.Series, name: str) -> dict[str, float]:
    v = values.dropna()
    q = v.quantile([0.25, 0.5, 0.75]).to_numpy() if len(v) else np.full(3, np.nan)
    return {f"{name}_median": q[1], f"{name}_q1": q[0], f"{name}_q3": q[2]}


def _summary(part: pd.DataFrame, level: str, name: str, condition: str,
             fraction: float) -> dict[str, Any]:
    answered = part[~part["timed_out"]]
    n, timed_out = len(answered), int(part["timed_out"].sum())
    row: dict[str, Any] = {"level": level, "cell": name, "condition": condition,
                           "fraction": fraction, "n_participants": part["participant"].nunique(),
                           "n_answered": n, "n_timed_out": timed_out,
                           "timeout_rate": timed_out / len(part) if len(part) else math.nan}
    row["hits"] = int(answered["hit"].sum())
    row.update({k: v for k, v in _rate("hit", row["hits"], n).items() if k != "hit"})
    gaze = condition == "I"
    follows = int(answered["follows_gaze"].sum()) if gaze else 0
    other = int((~answered["follows_either"]).sum()) if gaze else 0
    for prefix, k in (("follows_gaze", follows), ("other", other)):
        rate = _rate(prefix, k, n) if gaze else dict.fromkeys(_rate(prefix, 0, 0), math.nan)
        row.update(rate)
    row.update(_quartiles(answered["touch_error_px"], "touch_error_px"))
    row.update(_quartiles(answered["touch_error_mm"], "touch_error_mm"))
    row.update(_quartiles(answered["reaction_s"], "reaction_s"))
    return row


def cell_table(study: Study) -> pd.DataFrame:
    """Rates and medians per cell (level "cell") and per condition pooled over fractions
    (level "condition").

    Hit rates count answered trials only (a timeout is counted in n_timed_out and
    timeout_rate); their Wilson 95 % intervals treat trials as independent (the model and
    the contrasts account for participants). Under I: follows_gaze (answer == gaze_target)
    and other (neither target nor gaze target), with intervals; NaN elsewhere. Touch error
    [px] and [mm] and reaction time [s]: median, first and third quartile of answered trials.

    Returns:
        One row per cell, then per condition, in the design's order.
    """
    frame = study.analysed()
    rows = []
    for cell in study.cells:
        part = frame[frame["cell"] == cell]
        rows.append(_summary(part, "cell", cell, part["condition"].iloc[0],
                             float(part["fraction"].iloc[0])))
    for condition in [c for c in CONDITIONS if c in set(frame["condition"])]:
        rows.append(_summary(frame[frame["condition"] == condition], "condition", condition,
                             condition, math.nan))
    return pd.DataFrame(rows)


def confusion(study: Study) -> dict[str, pd.DataFrame]:
    """Target x answer counts of answered trials per cell (rows: target id, columns: answer
    id, every goal listed)."""
    answered = study.answered()
    goals = study.goals
    out = {}
    for cell in study.cells:
        part = answered[answered["cell"] == cell]
        table = pd.crosstab(part["target"], part["answer_target"].astype(int))
        table = table.reindex(index=goals, columns=goals, fill_value=0)
        table.index.name, table.columns.name = "target", "answer"
        out[cell] = table
    return out


def confusion_long(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """:func:`confusion` as one long table: cell, target, answer, count."""
    parts = [t.stack().rename("count").reset_index().assign(cell=cell)
             for cell, t in tables.items()]
    if not parts:
        return pd.DataFrame(columns=["cell", "target", "answer", "count"])
    return pd.concat(parts, ignore_index=True)[["cell", "target", "answer", "count"]]


# --------------------------------------------------------------------------- model


@dataclass(frozen=True)
class ModelResult:
    """The mixed-effects logistic regression of a hit and its GEE check.

    Attributes:
        reference: fraction cell -> its reference cell, e.g. {"GP60": "P60", ...}.
        bayes: per fixed effect: term, kind, posterior_mean, posterior_sd (log-odds),
            odds_ratio, or_ci_low, or_ci_high (exp of mean and of mean -/+ 1.96 SD).
        random_sd: posterior median of the participants' random-intercept SD (log-odds),
            with random_sd_ci its 95 % interval.
        gee: per term: term, kind, estimate, se (bias-reduced robust), z (the Wald ratio),
            p_value (t, participants - 1 df), odds_ratio, or_ci_low, or_ci_high;
            exchangeable within-participant correlation in gee_correlation.
        n_trials, n_participants: the data fitted.
        notes: warnings the fits raised.
    """

    reference: dict[str, str]
    bayes: pd.DataFrame
    random_sd: float
    random_sd_ci: tuple[float, float]
    gee: pd.DataFrame
    gee_correlation: float
    n_trials: int
    n_participants: int
    notes: list[str] = field(default_factory=list)

    def table(self) -> pd.DataFrame:
        """Both models in one long table (model.csv): model, term, kind, estimate, se,
        ci_low, ci_high (95 %, the estimate's scale: log-odds, or the SD), statistic,
        p_value (GEE), odds_ratio, or_ci_low, or_ci_high (exp of the estimate and its
        interval)."""
        bayes = self.bayes.rename(columns={"posterior_mean": "estimate",
                                           "posterior_sd": "se"})
        bayes.insert(0, "model", "bayes-mixed-logit (VB)")
        sd = pd.DataFrame([{"model": "bayes-mixed-logit (VB)", "term": "participant SD",
                            "kind": "random-intercept SD (log-odds)",
                            "estimate": self.random_sd, "ci_low": self.random_sd_ci[0],
                            "ci_high": self.random_sd_ci[1]}])
        gee = self.gee.rename(columns={"z": "statistic"})
        gee.insert(0, "model", "gee-logit (exchangeable, bias-reduced robust SE)")
        table = pd.concat([bayes, sd, gee], ignore_index=True)
        fixed = table["term"] != "participant SD"
        table.loc[fixed, "ci_low"] = np.log(table["or_ci_low"])
        table.loc[fixed, "ci_high"] = np.log(table["or_ci_high"])
        return table[["model", "term", "kind", "estimate", "se", "ci_low", "ci_high",
                      "statistic", "p_value", "odds_ratio", "or_ci_low", "or_ci_high"]]


def _model_frame(study: Study) -> tuple[pd.DataFrame, list[tuple[str, str, str]],
                                        dict[str, str]]:
    """Answered trials with one 0/1 column per fixed effect: each fraction's reference cell
    (P there if present) gets a column for its fraction's logit, every other fraction cell an
    effect column (log odds ratio vs the reference), G its own logit."""
    answered = study.answered()
    cells = study.cells
    data = pd.DataFrame({"hit": answered["hit"].astype(float),
                         "participant": answered["participant"].to_numpy()})
    terms: list[tuple[str, str, str]] = []  # (column, term, kind)
    reference: dict[str, str] = {}
    if "G" in cells:
        data["x0"] = (answered["cell"] == "G").astype(float)
        terms.append(("x0", "G", "logit of the cell"))
    for fraction in study.fractions:
        at = [cell_name(c, fraction) for c in CONDITIONS[1:] if cell_name(c, fraction) in cells]
        if not at:
            continue
        ref = next((c for c in at if c.startswith("P")), at[0])
        column = f"x{len(terms)}"
        data[column] = answered["cell"].isin(at).astype(float)
        terms.append((column, ref, "logit of the reference cell"))
        for cell in at:
            reference[cell] = ref
            if cell != ref:
                column = f"x{len(terms)}"
                data[column] = (answered["cell"] == cell).astype(float)
                terms.append((column, f"{cell} vs {ref}", "log odds ratio vs the reference"))
    return data, terms, reference


def _fit_quietly(fit: Callable[[], Any], notes: list[str], label: str) -> Any:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit()
    for message in dict.fromkeys(str(w.message).splitlines()[0] for w in caught):
        notes.append(f"{label}: {message}")
    return result


def mixed_model(study: Study) -> ModelResult:
    """Fit hit ~ cell with participant random intercepts, and its GEE check.

    The Bayesian model is statsmodels' BinomialBayesMixedGLM (``from_formula``, ``fit_vb``:
    mean-field variational Bayes; statsmodels' default priors: each fixed effect N(0, 2^2)
    on the log-odds, the log of the random-intercept SD N(0, 0.5^2)). The mean field
    understates the posterior SD of the reference-cell logits (they share the random
    intercepts' mean); the effects' SDs are close to the GEE's robust SEs. The GEE is a
    logistic GEE, groups = participant, exchangeable working correlation, bias-reduced
    (Mancl-DeRouen) sandwich SEs, Wald tests and intervals referred to t with participants - 1
    degrees of freedom (the plain sandwich is too liberal with few participants).

    Reference: P at each fraction (P60 for GP60, I60; P80 for GP80, I80; the first cell of
    a fraction without P); G has its own logit term.

    Raises:
        InputError: statsmodels is missing, or fewer than 2 participants answered.
    """
    sm = _statsmodels()
    from statsmodels.genmod.bayes_mixed_glm import BinomialBayesMixedGLM

    data, terms, reference = _model_frame(study)
    if data["participant"].nunique() < 2:
        raise InputError(f"{study.folder}: the model needs answers of at least 2 "
                         f"participants, got {data['participant'].nunique()}")
    notes: list[str] = []
    formula = "hit ~ 0 + " + " + ".join(c for c, _, _ in terms)
    bayes_model = BinomialBayesMixedGLM.from_formula(
        formula, {"participant": "0 + C(participant)"}, data)
    vb = _fit_quietly(bayes_model.fit_vb, notes, "bayes")
    z = stats.norm.ppf(1 - ALPHA / 2)
    mean, sd = np.asarray(vb.fe_mean), np.asarray(vb.fe_sd)
    bayes = pd.DataFrame({"term": [t for _, t, _ in terms], "kind": [k for _, _, k in terms],
                          "posterior_mean": mean, "posterior_sd": sd,
                          "odds_ratio": np.exp(mean), "or_ci_low": np.exp(mean - z * sd),
                          "or_ci_high": np.exp(mean + z * sd)})
    log_sd, log_sd_sd = float(vb.vcp_mean[0]), float(vb.vcp_sd[0])
    gee_model = sm.GEE.from_formula(formula, groups="participant", data=data,
                                    family=sm.families.Binomial(),
                                    cov_struct=sm.cov_struct.Exchangeable())
    gee_fit = _fit_quietly(lambda: gee_model.fit(cov_type="bias_reduced"), notes, "gee")
    est, se = np.asarray(gee_fit.params), np.asarray(gee_fit.bse)
    df = int(data["participant"].nunique()) - 1
    q = stats.t.ppf(1 - ALPHA / 2, df)
    gee = pd.DataFrame({"term": bayes["term"], "kind": bayes["kind"], "estimate": est,
                        "se": se, "z": est / se, "p_value": 2 * stats.t.sf(np.abs(est / se), df),
                        "odds_ratio": np.exp(est), "or_ci_low": np.exp(est - q * se),
                        "or_ci_high": np.exp(est + q * se)})
    correlation = float(np.ravel(gee_model.cov_struct.dep_params)[0])
    return ModelResult(reference, bayes, math.exp(log_sd),
                       (math.exp(log_sd - z * log_sd_sd), math.exp(log_sd + z * log_sd_sd)),
                       gee, correlation, len(data), int(data["participant"].nunique()), notes)


# --------------------------------------------------------------------------- contrasts

#: The hypotheses in words, by id.
HYPOTHESES = {
    "H1a": "multimodal superiority: pointing with congruent gaze (GP) is hit more often than "
           "pointing alone (P)",
    "H1b": "multimodal superiority: pointing with congruent gaze (GP) is hit more often than "
           "gaze alone (G)",
    "H2": "ocular primacy: under incongruent cues (I) answers follow the gaze more often than "
          "the pointing",
}
WILCOXON = "Wilcoxon signed-rank on participants' rates (two-sided)"
GEE_Z = ("GEE logistic Wald test (exchangeable, bias-reduced robust SE, t reference with "
         "participants - 1 df; two-sided)")


def participant_rates(frame: pd.DataFrame, cells: Sequence[str], outcome: str) -> pd.Series:
    """Each participant's mean of the boolean column ``outcome`` over the rows in ``cells``."""
    part = frame[frame["cell"].isin(cells)]
    return part.groupby("participant")[outcome].mean()


def wilcoxon_paired(first: pd.Series, second: pd.Series, method: str = "auto"
                    ) -> dict[str, Any]:
    """Wilcoxon signed-rank test (two-sided, zero differences dropped) of the paired
    per-participant values; estimate: the mean difference first - second with its t 95 %
    interval.

    Args:
        first, second: one value per participant (index: participant).
        method: scipy.stats.wilcoxon's: "auto" is exact without ties or zeros (n <= 50), an
            exact permutation test with them at n <= 13 (about 0.1-1 s at n = 10-13), else
            the normal approximation; "asymptotic" is always the normal approximation.
    """
    both = pd.concat([first.rename("a"), second.rename("b")], axis=1, join="inner").dropna()
    diff = (both["a"] - both["b"]).to_numpy()
    row: dict[str, Any] = {"n_participants": len(diff), "statistic_name": "W",
                           "estimate": float(diff.mean()) if len(diff) else math.nan,
                           "ci_low": math.nan, "ci_high": math.nan, "statistic": math.nan,
                           "p_value": math.nan}
    if len(diff) >= 2:
        if np.ptp(diff) == 0:
            row["ci_low"] = row["ci_high"] = float(diff[0])
        else:
            ci = stats.ttest_1samp(diff, 0.0).confidence_interval(1 - ALPHA)
            row["ci_low"], row["ci_high"] = float(ci.low), float(ci.high)
    if len(diff) and not np.any(diff):
        row["statistic"], row["p_value"] = 0.0, 1.0
    elif len(diff):
        result = stats.wilcoxon(diff, zero_method="wilcox", alternative="two-sided",
                                method=method)
        row["statistic"], row["p_value"] = float(result.statistic), float(result.pvalue)
    return row


def _gee(endog: np.ndarray, exog: np.ndarray, groups: np.ndarray) -> Any:
    """A logistic GEE (exchangeable) with the bias-reduced (Mancl-DeRouen) sandwich SE: the
    plain robust SE is too small with few participants (GP vs G at 8 and 20 participants
    rejected 10 % and 9 % of 300 null studies at alpha 0.05; bias-reduced with the t
    reference: 4 % and 6 %)."""
    sm = _statsmodels()
    model = sm.GEE(endog, exog, groups=groups, family=sm.families.Binomial(),
                   cov_struct=sm.cov_struct.Exchangeable())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return model.fit(cov_type="bias_reduced")


def gee_contrast(frame: pd.DataFrame, first: Sequence[str], second: Sequence[str],
                 outcome: str = "hit") -> dict[str, Any]:
    """GEE logistic of ``outcome`` ~ 1 + [row in ``first``] on the rows of ``first`` and
    ``second`` (groups: participant, exchangeable, bias-reduced robust SE): the odds ratio
    first/second with its 95 % interval and the two-sided Wald test of log OR = 0 (t, participants
    - 1 df)."""
    part = frame[frame["cell"].isin([*first, *second])]
    row: dict[str, Any] = {"n_participants": part["participant"].nunique(),
                           "statistic_name": "z", "scale": "odds ratio"}
    x = part["cell"].isin(first).to_numpy(dtype=float)
    y = part[outcome].to_numpy(dtype=float)
    if len(part) < 2 or np.ptp(x) == 0:
        return {**row, **dict.fromkeys(["estimate", "ci_low", "ci_high", "statistic",
                                        "p_value"], math.nan)}
    fit = _gee(y, np.column_stack([np.ones_like(x), x]), part["participant"].to_numpy())
    return {**row, **_z_row(float(fit.params[1]), float(fit.bse[1]), np.exp,
                            row["n_participants"] - 1)}


def gee_share(frame: pd.DataFrame, outcome: str) -> dict[str, Any]:
    """GEE logistic intercept of ``outcome`` (groups: participant): the share with its 95 %
    interval and the two-sided Wald test of share = 0.5 (t, participants - 1 df)."""
    row: dict[str, Any] = {"n_participants": frame["participant"].nunique(),
                           "statistic_name": "z", "scale": "share"}
    y = frame[outcome].to_numpy(dtype=float)
    if len(y) < 2:
        return {**row, **dict.fromkeys(["estimate", "ci_low", "ci_high", "statistic",
                                        "p_value"], math.nan)}
    fit = _gee(y, np.ones((len(y), 1)), frame["participant"].to_numpy())
    return {**row, **_z_row(float(fit.params[0]), float(fit.bse[0]), _expit,
                            row["n_participants"] - 1)}


def _expit(x: Any) -> Any:
    return 1.0 / (1.0 + np.exp(-x))


def _z_row(estimate: float, se: float, transform: Callable[[Any], Any], df: int
           ) -> dict[str, Any]:
    """Estimate, 95 % interval (transformed) and two-sided p of a Wald ratio, referred to t
    with ``df`` degrees of freedom (NaN p below 1)."""
    if not (se > 0 and df >= 1):
        return {"estimate": float(transform(estimate)), "ci_low": math.nan,
                "ci_high": math.nan, "statistic": math.nan, "p_value": math.nan}
    q = stats.t.ppf(1 - ALPHA / 2, df)
    statistic = estimate / se
    return {"estimate": float(transform(estimate)),
            "ci_low": float(transform(estimate - q * se)),
            "ci_high": float(transform(estimate + q * se)), "statistic": statistic,
            "p_value": float(2 * stats.t.sf(abs(statistic), df))}


def _comparisons(cells: Sequence[str], fractions: Sequence[float]) -> list[dict[str, Any]]:
    """The hypothesis family present in the data: (hypothesis, comparison, first, second)."""
    out = []
    at = {f: str(round(f * 100)) for f in fractions}
    gp = [f"GP{p}" for p in at.values() if f"GP{p}" in cells]
    pp = [f"P{p}" for p in at.values() if f"P{p}" in cells]
    ii = [f"I{p}" for p in at.values() if f"I{p}" in cells]
    for p in at.values():
        if f"GP{p}" in cells and f"P{p}" in cells:
            out.append({"hypothesis": "H1a", "comparison": f"GP{p} vs P{p}",
                        "first": [f"GP{p}"], "second": [f"P{p}"]})
    if len([o for o in out if o["hypothesis"] == "H1a"]) > 1:
        out.append({"hypothesis": "H1a", "comparison": "GP vs P (pooled over fractions)",
                    "first": gp, "second": pp})
    if gp and "G" in cells:
        out.append({"hypothesis": "H1b", "comparison": "GP (pooled over fractions) vs G",
                    "first": gp, "second": ["G"]})
    for cell in ii:
        out.append({"hypothesis": "H2", "comparison": f"{cell}: follows gaze vs pointing",
                    "first": [cell], "second": [cell]})
    if len(ii) > 1:
        out.append({"hypothesis": "H2", "comparison": "I (pooled): follows gaze vs pointing",
                    "first": ii, "second": ii})
    return out


def contrasts(study: Study) -> pd.DataFrame:
    """The hypothesis tests, each by two methods, two-sided, Holm-corrected per method.

    H1a: GP vs P hit rate at each fraction and pooled; H1b: GP (pooled) vs G; H2: under I,
    follows gaze vs follows pointing at each fraction and pooled. Wilcoxon rows: the paired
    per-participant rates (H1: rate(first) - rate(second); H2: rate(follows gaze) -
    rate(follows pointing) among answered I trials), estimate = mean difference with its t
    95 % interval. GEE rows: H1 the odds ratio first/second; H2 the share of gaze-following
    among the answers that follow either cue, tested against 0.5.

    Returns:
        One row per (comparison, method): hypothesis, comparison, method, scale, estimate,
        ci_low, ci_high, statistic_name, statistic, p_value, p_holm (Holm within the
        method's rows), significant (p_holm < ALPHA), n_participants.
    """
    frame = study.answered()
    rows = []
    for spec in _comparisons(study.cells, study.fractions):
        base = {"hypothesis": spec["hypothesis"], "comparison": spec["comparison"]}
        if spec["hypothesis"] == "H2":
            wil = wilcoxon_paired(participant_rates(frame, spec["first"], "follows_gaze"),
                                  participant_rates(frame, spec["first"], "hit"))
            either = frame[frame["cell"].isin(spec["first"]) & frame["follows_either"]]
            gee = gee_share(either, "follows_gaze")
        else:
            wil = wilcoxon_paired(participant_rates(frame, spec["first"], "hit"),
                                  participant_rates(frame, spec["second"], "hit"))
            gee = gee_contrast(frame, spec["first"], spec["second"])
        rows.append({**base, "method": WILCOXON, "scale": "rate difference", **wil})
        rows.append({**base, "method": GEE_Z, **gee})
    columns = ["hypothesis", "comparison", "method", "scale", "estimate", "ci_low", "ci_high",
               "statistic_name", "statistic", "p_value", "p_holm", "significant",
               "n_participants"]
    table = pd.DataFrame(rows, columns=[c for c in columns if c not in ("p_holm",
                                                                         "significant")])
    table["p_holm"] = np.nan
    for _, part in table.groupby("method"):
        ok = part["p_value"].notna()
        if ok.any():
            from statsmodels.stats.multitest import multipletests

            adjusted = multipletests(part.loc[ok, "p_value"], alpha=ALPHA, method="holm")[1]
            table.loc[part.index[ok.to_numpy()], "p_holm"] = adjusted
    table["significant"] = table["p_holm"] < ALPHA
    return table[columns]


# --------------------------------------------------------------------------- observers


def _probabilities(predict: Predict, stimuli: pd.DataFrame, params: Mapping[str, float],
                   n_goals: int, name: str) -> np.ndarray:
    p = np.asarray(predict(stimuli, params), dtype=float)
    if p.shape != (len(stimuli), n_goals):
        raise InputError(f"observer {name}: predict returned shape {p.shape}; allowed: "
                         f"({len(stimuli)}, {n_goals}) (trials, goals)")
    if not np.all(np.isfinite(p)) or np.any(p < 0) or not np.allclose(p.sum(1), 1, atol=1e-6):
        raise InputError(f"observer {name}: predict returned rows that are not probabilities "
                         f"(finite, >= 0, summing to 1) at params {dict(params)}")
    return p


def observer_fit(study: Study, predict: Predict | Mapping[str, Predict],
                 parameter: str = "sigma_deg", bounds: tuple[float, float] = (0.1, 60.0),
                 fixed: Mapping[str, float] | None = None) -> pd.DataFrame:
    """Fit each model observer's noise parameter by maximum likelihood on the answered trials.

    Args:
        study: the study.
        predict: one :data:`Predict` or {observer name: Predict}; called as
            ``predict(trials, {**fixed, parameter: value})`` with ``trials`` the trials.csv
            rows of the answered responses (one row per response, trials.csv columns), it
            returns (n_trials, n_goals) answer probabilities, goals in the design's order.
        parameter: the fitted parameter's name (the noise SD, in [deg]).
        bounds: its search interval (minimize_scalar, bounded).
        fixed: the observer's other parameters, held fixed.

    Returns:
        One row per (observer, cell) and a cell "all" row: observer, cell, n_trials,
        observed_hit_rate, predicted_hit_rate, observed_follows_gaze_rate,
        predicted_follows_gaze_rate (I cells), the fitted ``parameter``, at_bound,
        log_likelihood, aic (2 k - 2 LL, k = 1), log_likelihood_chance (uniform answers).
        Probabilities are floored at 1e-12 in the likelihood.
    """
    observers = dict(predict) if isinstance(predict, Mapping) else {"observer": predict}
    answered = study.answered()
    keys = answered[["participant", "trial"]]
    stimuli = keys.merge(study.trials, on=["participant", "trial"], how="left")
    stimuli = stimuli[list(TRIAL_COLUMNS)]
    goals = study.goals
    index = {g: i for i, g in enumerate(goals)}
    answer = answered["answer_target"].astype(int).map(index).to_numpy()
    target = answered["target"].map(index).to_numpy()
    gaze = answered["gaze_target"].map(lambda g: index.get(int(g), -1) if g == g else -1)
    gaze = gaze.to_numpy()
    rows_at = np.arange(len(answered))
    rows = []
    for name, fn in observers.items():
        def loss(value: float, fn: Predict = fn, name: str = name) -> float:
            p = _probabilities(fn, stimuli, {**(fixed or {}), parameter: value}, len(goals),
                               name)
            return -float(np.log(np.maximum(p[rows_at, answer], 1e-12)).sum())

        best = optimize.minimize_scalar(loss, bounds=bounds, method="bounded",
                                        options={"xatol": 1e-3 * (bounds[1] - bounds[0])})
        value = float(best.x)
        p = _probabilities(fn, stimuli, {**(fixed or {}), parameter: value}, len(goals), name)
        hit_p = p[rows_at, target]
        gaze_p = np.where(gaze >= 0, p[rows_at, np.maximum(gaze, 0)], np.nan)
        shared = {"observer": name, parameter: value,
                  "at_bound": bool(min(abs(value - b) for b in bounds)
                                   < 1e-2 * (bounds[1] - bounds[0])),
                  "log_likelihood": -float(best.fun), "aic": 2 * 1 + 2 * float(best.fun),
                  "log_likelihood_chance": len(answered) * math.log(1 / len(goals))}
        for cell in [*study.cells, "all"]:
            mask = (answered["cell"] == cell).to_numpy() if cell != "all" else rows_at >= 0
            incongruent = cell.startswith("I")
            rows.append({"cell": cell, "n_trials": int(mask.sum()),
                         "observed_hit_rate": float(answered["hit"][mask].mean()),
                         "predicted_hit_rate": float(hit_p[mask].mean()),
                         "observed_follows_gaze_rate":
                             float(answered["follows_gaze"][mask].mean()) if incongruent
                             else math.nan,
                         "predicted_follows_gaze_rate":
                             float(np.nanmean(gaze_p[mask])) if incongruent else math.nan,
                         **shared})
    first = ["observer", "cell", "n_trials", "observed_hit_rate", "predicted_hit_rate",
             "observed_follows_gaze_rate", "predicted_follows_gaze_rate"]
    table = pd.DataFrame(rows)
    return table[first + [c for c in table.columns if c not in first]]


# --------------------------------------------------------------------------- analyze


@dataclass(frozen=True)
class Analysis:
    """Everything :func:`analyze` computed (model and contrasts None with fewer than two
    participants; observers None without observers)."""

    study: Study
    cells: pd.DataFrame
    model: ModelResult | None
    contrasts: pd.DataFrame | None
    confusion: dict[str, pd.DataFrame]
    observers: pd.DataFrame | None
    notes: list[str] = field(default_factory=list)

    def markdown(self) -> str:
        """analysis.md."""
        return analysis_markdown(self)


def analyze(folder: str | Path, output: str | Path | None = None,
            observers: Mapping[str, Predict] | None = None, **fit: Any) -> Analysis:
    """Read a study and compute the whole analysis; with ``output``, write it there.

    Args:
        folder: the experiment folder (design.json, participant_XX/).
        output: a folder for analysis.csv (the cell table), contrasts.csv, model.csv,
            confusion.csv (cell, target, answer, count), observers.csv (with observers),
            analysis.json (provenance), hit_rates.png, incongruent.png (with I cells),
            confusion.png, reaction_times.png and analysis.md, each written atomically.
        observers: {name: predict} fitted by :func:`observer_fit`.
        **fit: further arguments of :func:`observer_fit` (parameter, bounds, fixed).

    Raises:
        InputError: as :func:`read_study`, or statsmodels is missing.
    """
    study = read_study(folder)
    notes: list[str] = []
    model, tests = None, None
    if study.answered()["participant"].nunique() >= 2:
        model = mixed_model(study)
        tests = contrasts(study)
    else:
        notes.append("fewer than 2 participants answered: no model and no contrasts")
    fitted = observer_fit(study, observers, **fit) if observers else None
    result = Analysis(study, cell_table(study), model, tests, confusion(study), fitted, notes)
    if output is not None:
        write_analysis(result, output)
    return result


def write_analysis(analysis: Analysis, output: str | Path) -> Path:
    """Write an :class:`Analysis`'s files into ``output`` (see :func:`analyze`); return
    analysis.md's path."""
    from ikbench.core.io import write_study_files
    from ikbench.core.provenance import provenance
    from ikbench.experiment import figures

    tables: dict[str, tuple[pd.DataFrame, str]] = {
        "analysis.csv": (analysis.cells, "%.6g"),
        "confusion.csv": (confusion_long(analysis.confusion), "%.6g")}
    if analysis.contrasts is not None:
        tables["contrasts.csv"] = (analysis.contrasts, "%.6g")
    if analysis.model is not None:
        tables["model.csv"] = (analysis.model.table(), "%.6g")
    if analysis.observers is not None:
        tables["observers.csv"] = (analysis.observers, "%.6g")
    study = analysis.study
    record = {"kind": "experiment-analysis", "folder": str(study.folder),
              "simulated": study.simulated, "alpha": ALPHA, "cells": study.cells,
              "participants": sorted(study.answered()["participant"].unique().tolist()),
              "reference": analysis.model.reference if analysis.model else None,
              "provenance": provenance(extra=("statsmodels", "patsy", "formulaic"))}
    chance = 1 / len(study.goals)
    draw = {"hit_rates.png": lambda: figures.hit_rates(analysis.cells, chance),
            "confusion.png": lambda: figures.confusion(analysis.confusion),
            "reaction_times.png": lambda: figures.reaction_times(study.answered(),
                                                                 study.cells)}
    if any(c.startswith("I") for c in study.cells):
        draw["incongruent.png"] = lambda: figures.incongruent(analysis.cells)
    write_study_files(output, "analysis", tables, record, analysis.markdown, draw)
    return Path(output) / "analysis.md"


# --------------------------------------------------------------------------- analysis.md

BANNER = ("> **SIMULATED PARTICIPANTS — not human data.** Every answer below was produced by "
          "a model observer; nothing here is evidence about people.")


def _pct(value: float) -> str:
    return "–" if value != value else f"{100 * value:.0f} %"


def _rate_ci(rate: float, low: float, high: float) -> str:
    if rate != rate:
        return "–"
    return f"{100 * rate:.0f} % [{100 * low:.0f}, {100 * high:.0f}]"


def _num(value: Any, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and value != value):
        return "–"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{float(value):.{digits}g}"


def _p(value: float) -> str:
    if value != value:
        return "–"
    return "< 0.001" if value < 0.001 else f"{value:.3f}"


def _p_is(value: float) -> str:
    """"p = 0.012" or "p < 0.001"."""
    text = _p(value)
    return f"p {text}" if text.startswith("<") else f"p = {text}"


def _md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in rows]
    return lines + [""]


def _median_iqr(row: Mapping[str, Any], name: str, digits: int = 3) -> str:
    if row[f"{name}_median"] != row[f"{name}_median"]:
        return "–"
    return (f"{_num(row[f'{name}_median'], digits)} ({_num(row[f'{name}_q1'], digits)}–"
            f"{_num(row[f'{name}_q3'], digits)})")


def _design_lines(analysis: Analysis) -> list[str]:
    study, design = analysis.study, analysis.study.design
    analysed = study.analysed()
    per = analysed.groupby("participant").size()
    backends = sorted(set(study.responses["backend"]) - {""})
    observers = sorted(set(study.responses["observer"]) - {""})
    goals = study.goals
    lines = [f"- folder: `{study.folder}`; method: {design.get('method', '–')}; "
             f"seed: {design.get('seed', '–')}",
             f"- conditions: {', '.join(design.get('conditions', CONDITIONS))}; fractions: "
             f"{', '.join(_pct(f) for f in study.fractions)} of the fingertip path (G: none)",
             f"- cells analysed: {', '.join(study.cells)}",
             f"- goals: {len(goals)} (ids {', '.join(map(str, goals))}); chance level "
             f"1/{len(goals)} = {_pct(1 / len(goals))}",
             f"- participants: {analysed['participant'].nunique()} with responses (design: "
             f"{design.get('participants', '–')}); trials analysed per participant: "
             f"{per.min()}–{per.max()} (practice excluded, timed-out attempts included)",
             f"- answered: {int((~analysed['timed_out']).sum())}; timed out: "
             f"{int(analysed['timed_out'].sum())} (counted per cell, not in hit rates)",
             f"- back-ends: {', '.join(backends) or '–'}"]
    if observers:
        lines.append(f"- simulated observers: {'; '.join(f'`{o}`' for o in observers)}")
    return lines + [""]


def _verdict(rows: pd.DataFrame) -> list[str]:
    out = []
    for _, wil in rows[rows["method"] == WILCOXON].iterrows():
        gee = rows[(rows["method"] == GEE_Z) & (rows["comparison"] == wil["comparison"])]
        check = ""
        if len(gee):
            g = gee.iloc[0]
            agree = bool(g["significant"]) == bool(wil["significant"])
            check = (f"; the GEE check {'agrees' if agree else 'DISAGREES'} "
                     f"({g['scale']} {_num(g['estimate'])}, Holm {_p_is(g['p_holm'])})")
        effect = (f"mean difference {100 * wil['estimate']:+.0f} percentage points "
                  f"[{100 * wil['ci_low']:+.0f}, {100 * wil['ci_high']:+.0f}], "
                  f"{wil['n_participants']} participants, Holm {_p_is(wil['p_holm'])}")
        if wil["p_holm"] != wil["p_holm"]:
            text = "not testable (too few paired participants)"
        elif not wil["significant"]:
            text = (f"no evidence of a difference ({effect}); this does not show that the "
                    f"rates are equal")
        elif wil["estimate"] > 0:
            text = f"evidence of a difference in the hypothesised direction ({effect})"
        else:
            text = f"evidence of a difference OPPOSITE to the hypothesis ({effect})"
        out.append(f"  - {wil['comparison']}: {text}{check}.")
    return out


def _contrast_lines(analysis: Analysis) -> list[str]:
    table = analysis.contrasts
    if table is None or not len(table):
        return ["No contrasts (too few participants or cells).", ""]
    lines = ["Two-sided tests at alpha = 0.05; Holm's correction within each method's family "
             "(all rows of that method). The verdicts use the participant-level Wilcoxon "
             "test (participants are the unit); the GEE Wald test is the check. Wilcoxon "
             "estimates: mean paired difference of participants' rates (t 95 % interval); "
             "GEE estimates: H1 the odds ratio, H2 the share of gaze-following among answers "
             "that follow either cue (0.5 = no primacy). Intervals are not adjusted for "
             "multiplicity; the verdicts are (Holm).", ""]
    for hypothesis, words in HYPOTHESES.items():
        rows = table[table["hypothesis"] == hypothesis]
        if len(rows):
            lines += [f"- **{hypothesis}** ({words}):", *_verdict(rows)]
    lines.append("")
    rows = [[r["hypothesis"], r["comparison"], r["method"], r["scale"], _num(r["estimate"]),
             f"[{_num(r['ci_low'])}, {_num(r['ci_high'])}]",
             f"{r['statistic_name']} = {_num(r['statistic'])}", _p(r["p_value"]),
             _p(r["p_holm"]), r["n_participants"]] for _, r in table.iterrows()]
    return lines + _md_table(["hypothesis", "comparison", "method", "scale", "estimate",
                              "95 % CI", "statistic", "p", "p (Holm)", "participants"], rows)


def _model_lines(model: ModelResult | None) -> list[str]:
    if model is None:
        return ["No model (fewer than 2 participants).", ""]
    refs = sorted(set(model.reference.values()))
    lines = [f"hit ~ cell + (1 | participant), {model.n_trials} answered trials, "
             f"{model.n_participants} participants. Reference: {', '.join(refs)} (P at each "
             f"fraction); a reference term is its cell's logit (exp: its odds), an effect term "
             f"the log odds ratio against its fraction's reference; G has its own logit.", "",
             "Bayesian mixed logit (statsmodels BinomialBayesMixedGLM, variational Bayes; "
             "priors N(0, 2²) on fixed effects). The mean-field posterior understates the SD "
             "of the reference terms; read the effects.", ""]
    rows = [[r["term"], _num(r["posterior_mean"]), _num(r["posterior_sd"]),
             _num(r["odds_ratio"]), f"[{_num(r['or_ci_low'])}, {_num(r['or_ci_high'])}]"]
            for _, r in model.bayes.iterrows()]
    lines += _md_table(["term", "posterior mean", "posterior SD", "exp (OR)", "95 % interval"],
                       rows)
    lines += [f"Random-intercept SD (participants, log-odds): {_num(model.random_sd)} "
              f"[{_num(model.random_sd_ci[0])}, {_num(model.random_sd_ci[1])}].", "",
              f"GEE logistic (exchangeable working correlation "
              f"{_num(model.gee_correlation)}, bias-reduced robust SE, two-sided Wald tests "
              f"and intervals on t with {model.n_participants - 1} df):", ""]
    rows = [[r["term"], _num(r["estimate"]), _num(r["se"]), _num(r["z"]), _p(r["p_value"]),
             _num(r["odds_ratio"]), f"[{_num(r['or_ci_low'])}, {_num(r['or_ci_high'])}]"]
            for _, r in model.gee.iterrows()]
    lines += _md_table(["term", "estimate", "robust SE", "Wald", "p", "exp (OR)", "95 % CI"],
                       rows)
    if model.notes:
        lines += ["Fit warnings: " + "; ".join(model.notes), ""]
    return lines


def _cell_lines(cells: pd.DataFrame) -> list[str]:
    header = ["participants", "answered", "timed out", "hits", "hit rate [95 % CI]",
              "touch error px", "touch error mm", "reaction s"]
    lines: list[str] = []
    for level, title in (("cell", "Per cell"), ("condition", "Per condition (pooled over "
                                                             "fractions)")):
        part = cells[cells["level"] == level]
        rows = [[r["cell"], r["n_participants"], r["n_answered"], r["n_timed_out"], r["hits"],
                 _rate_ci(r["hit_rate"], r["hit_ci_low"], r["hit_ci_high"]),
                 _median_iqr(r, "touch_error_px"), _median_iqr(r, "touch_error_mm"),
                 _median_iqr(r, "reaction_s")] for _, r in part.iterrows()]
        lines += [f"### {title}", "", *_md_table([level, *header], rows)]
    incongruent = cells[(cells["level"] == "cell") & (cells["condition"] == "I")]
    if len(incongruent):
        rows = [[r["cell"], r["n_answered"],
                 _rate_ci(r["follows_gaze_rate"], r["follows_gaze_ci_low"],
                          r["follows_gaze_ci_high"]),
                 _rate_ci(r["hit_rate"], r["hit_ci_low"], r["hit_ci_high"]),
                 _rate_ci(r["other_rate"], r["other_ci_low"], r["other_ci_high"])]
                for _, r in incongruent.iterrows()]
        lines += ["### Incongruent cues (I)", "",
                  *_md_table(["cell", "answered", "follows gaze", "follows pointing (hit)",
                              "other"], rows)]
    return lines


def _observer_lines(table: pd.DataFrame | None) -> list[str]:
    if table is None:
        return []
    parameter = next(c for c in table.columns if c not in (
        "observer", "cell", "n_trials", "observed_hit_rate", "predicted_hit_rate",
        "observed_follows_gaze_rate", "predicted_follows_gaze_rate"))
    lines = ["## Model observers (maximum likelihood)", ""]
    overall = table[table["cell"] == "all"]
    rows = [[r["observer"], _num(r[parameter]) + (" (at bound)" if r["at_bound"] else ""),
             _num(r["log_likelihood"], 6), _num(r["aic"], 6), _num(r["log_likelihood_chance"], 6)]
            for _, r in overall.iterrows()]
    lines += _md_table(["observer", parameter, "log-likelihood", "AIC", "LL of chance"], rows)
    rows = [[r["observer"], r["cell"], r["n_trials"], _pct(r["observed_hit_rate"]),
             _pct(r["predicted_hit_rate"]), _pct(r["observed_follows_gaze_rate"]),
             _pct(r["predicted_follows_gaze_rate"])] for _, r in table.iterrows()]
    return lines + _md_table(["observer", "cell", "trials", "hit observed", "hit predicted",
                              "follows gaze observed", "follows gaze predicted"], rows)


def analysis_markdown(analysis: Analysis) -> str:
    """The report a reader can check: design, rates with intervals, model, contrasts with
    verdicts, confusion matrices, observers' fit and the figures."""
    study = analysis.study
    lines = ["# Pointing experiment: analysis", ""]
    if study.simulated:
        lines += [BANNER, ""]
    lines += ["## Design", "", *_design_lines(analysis), "## Hypotheses and verdicts", "",
              *_contrast_lines(analysis), "## Hit rates", "",
              "Wilson 95 % intervals over answered trials (trials treated as independent; "
              "the model and contrasts account for participants). Touch error and reaction "
              "time: median (first–third quartile) of answered trials.", "",
              *_cell_lines(analysis.cells),
              "![hit rates per cell](hit_rates.png)", ""]
    if any(c.startswith("I") for c in study.cells):
        lines += ["![incongruent cues](incongruent.png)", ""]
    lines += ["## Mixed-effects model", "", *_model_lines(analysis.model),
              "## Confusion matrices (target x answer, answered trials)", ""]
    for cell, table in analysis.confusion.items():
        rows = [[target, *table.loc[target].tolist()] for target in table.index]
        lines += [f"**{cell}**", "", *_md_table(["target \\ answer",
                                                 *map(str, table.columns)], rows)]
    lines += ["![confusion matrices](confusion.png)", "",
              *_observer_lines(analysis.observers),
              "## Reaction times", "", "![reaction times per cell](reaction_times.png)", ""]
    if analysis.notes:
        lines += ["## Notes", "", *[f"- {n}" for n in analysis.notes], ""]
    if study.simulated:
        lines += [BANNER, ""]
    return "\n".join(lines)
