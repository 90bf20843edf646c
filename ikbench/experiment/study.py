"""The study's model side put together: the cue geometry of a design's stimuli, simulated
studies fast enough for power analysis, the observers the analysis fits, and the commands'
``analyze`` and ``power``.

A design has few distinct stimuli (condition, fraction, target, gaze target); their cue
points are computed once (:func:`stimulus_cues`), and a simulated study draws every trial's
answer at once with the noise model of :mod:`ikbench.experiment.observers` (the same model
``experiment run --simulate`` plays trial by trial).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.io import atomic_savefig, atomic_write_csv, atomic_write_json, atomic_write_text
from ikbench.core.provenance import provenance
from ikbench.core.robot import load_robot
from ikbench.experiment import analysis, observers, power
from ikbench.experiment.design import read_design, read_trajectory
from ikbench.experiment.head import load_head
from ikbench.experiment.layout import GoalSet, load_goals
from ikbench.experiment.records import participants, read_trials

Key = tuple[str, float, int, int]


def _key(row: Mapping) -> Key:
    fraction = row["fraction"]
    gaze = row["gaze_target"]
    return (str(row["condition"]), -1.0 if pd.isna(fraction) else round(float(fraction), 6),
            int(row["target"]), -1 if pd.isna(gaze) else int(gaze))


@dataclass(frozen=True)
class Stimuli:
    """The cue points of every distinct stimulus of a design, and its trial lists."""

    goals: GoalSet
    trials: pd.DataFrame                 # every participant's trials.csv rows
    cues: dict[Key, dict[str, np.ndarray]]

    def of(self, rows: pd.DataFrame) -> list[dict[str, np.ndarray]]:
        return [self.cues[_key(r)] for _, r in rows.iterrows()]


def stimulus_cues(folder: str | Path) -> Stimuli:
    """Read a design folder and compute each distinct stimulus' cue points once."""
    folder = Path(folder)
    record = read_design(folder)
    robot, head = load_robot(), load_head()
    goals = load_goals()
    if [int(i) for i in record["goals"]["ids"]] != list(goals.ids):
        goals = load_goals(record["goals"]["targets_file"], robot)
    trials = pd.concat([read_trials(p) for p in participants(folder)], ignore_index=True)
    cues: dict[Key, dict[str, np.ndarray]] = {}
    poses: dict[str, np.ndarray] = {}
    for _, row in trials.iterrows():
        key = _key(row)
        if key in cues:
            continue
        path = row["trajectory"]
        if isinstance(path, str) and path and path not in poses:
            poses[path] = read_trajectory(folder, path, robot)
        cues[key] = observers.cue_points(row, robot, head, goals,
                                         poses.get(path) if isinstance(path, str) else None)
    return Stimuli(goals, trials, cues)


def cue_geometry(stimuli: Stimuli) -> pd.DataFrame:
    """Per stimulus: how far each cue's point lands from the true target and from the
    nearest other goal [mm], and which goal it names (what a noiseless observer answers)."""
    goals = stimuli.goals
    rows = []
    for (condition, fraction, target, gaze), cues in sorted(stimuli.cues.items()):
        row: dict = {"condition": condition, "fraction": None if fraction < 0 else fraction,
                     "target": target, "gaze_target": None if gaze < 0 else gaze}
        true = goals.points_mm[goals.index(target)]
        for cue in observers.CUES:
            point = cues.get(cue)
            if point is None or not np.all(np.isfinite(point)):
                row.update({f"{cue}_to_target_mm": math.nan, f"{cue}_names": None})
                continue
            row[f"{cue}_to_target_mm"] = round(float(np.linalg.norm(point - true)), 2)
            row[f"{cue}_names"] = goals.ids[int(goals.nearest(point))]
        rows.append(row)
    return pd.DataFrame(rows)


def predictors(stimuli: Stimuli, draws: int = 256) -> dict[str, analysis.Predict]:
    """``{observer: predict}`` for :func:`ikbench.experiment.analysis.observer_fit`: each
    model observer of :data:`ikbench.experiment.observers.OBSERVERS` with one noise sd
    (``sigma_deg``) and lapse 0.02."""

    def make(name: str) -> analysis.Predict:
        def predict(trials: pd.DataFrame, params: Mapping[str, float]) -> np.ndarray:
            return observers.predict(stimuli.of(trials), list(trials["condition"]),
                                     stimuli.goals, name, float(params["sigma_deg"]),
                                     float(params.get("lapse", 0.02)), draws)
        return predict

    return {name: make(name) for name in observers.OBSERVERS}


def _participant_trials(stimuli: Stimuli, n: int) -> pd.DataFrame:
    """n participants' main trials: the design's lists, reused in turn past its count."""
    lists = [t for _, t in stimuli.trials.groupby("participant", sort=True)]
    parts = []
    for i in range(n):
        part = lists[i % len(lists)]
        parts.append(part[~part["practice"]].assign(participant=f"{i + 1:02d}"))
    return pd.concat(parts, ignore_index=True)


def simulator(stimuli: Stimuli, model: observers.ObserverModel
              ) -> Callable[[int, int], pd.DataFrame]:
    """``simulate(n_participants, seed) -> responses`` of the model, every trial at once
    (no timeouts: each trial answered once)."""
    goals = stimuli.goals
    basis = np.stack([goals.screen.u, goals.screen.v])
    keys = sorted(stimuli.cues)
    index = {k: i for i, k in enumerate(keys)}
    points = np.full((len(keys), len(observers.CUES), 3), np.nan)
    for k, cues in stimuli.cues.items():
        for j, cue in enumerate(observers.CUES):
            if cue in cues:
                points[index[k], j] = cues[cue]
    distance = np.linalg.norm(points - goals.viewpoint_mm, axis=-1)      # (s, cues)
    sigma = np.array([model.noise_deg[c] for c in observers.CUES])

    def simulate(n: int, seed: int) -> pd.DataFrame:
        trials = _participant_trials(stimuli, n)
        rng = np.random.default_rng(seed)
        at = np.array([index[_key(r)] for r in trials[["condition", "fraction", "target",
                                                       "gaze_target"]].to_dict("records")])
        who = trials["participant"].astype(int).to_numpy() - 1
        scale = np.exp(rng.normal(0.0, model.participant_sd, n))[who]
        sd = distance[at] * np.tan(np.radians(sigma))[None] * scale[:, None]   # (t, cues)
        noisy = points[at] + (rng.normal(size=(len(at), len(sigma), 2)) @ basis) * sd[..., None]
        weight = np.where(np.isfinite(noisy).all(-1), 1.0 / sd ** 2, 0.0)
        combined = (np.nan_to_num(noisy) * weight[..., None]).sum(1) / np.maximum(
            weight.sum(1), 1e-300)[:, None]
        chosen = goals.nearest(combined)
        lapse = (rng.random(len(at)) < model.lapse) | (weight.sum(1) == 0)
        chosen = np.where(lapse, rng.integers(len(goals.ids), size=len(at)), chosen)
        return trials.assign(answer_target=np.asarray(goals.ids)[chosen], timed_out=False)

    return simulate


def null_simulator(stimuli: Stimuli, hit: float = 0.5, intercept_sd: float = 0.5
                   ) -> Callable[[int, int], pd.DataFrame]:
    """A null study: every cell's hit rate equal (``hit``, a participant's logit moved by
    N(0, intercept_sd)), and under I the gaze and the pointing target equally likely."""
    goals = stimuli.goals
    ids = np.asarray(goals.ids)

    def simulate(n: int, seed: int) -> pd.DataFrame:
        trials = _participant_trials(stimuli, n)
        rng = np.random.default_rng(seed)
        who = trials["participant"].astype(int).to_numpy() - 1
        logit = math.log(hit / (1 - hit)) + rng.normal(0.0, intercept_sd, n)[who]
        p = 1.0 / (1.0 + np.exp(-logit))
        target = trials["target"].to_numpy(int)
        gaze = trials["gaze_target"].fillna(-1).to_numpy(int)
        incongruent = (trials["condition"] == "I").to_numpy()
        u = rng.random(len(trials))
        other = ids[rng.integers(len(ids), size=len(trials))]
        answer = np.where(u < p, target, other)
        half = incongruent & (u < p) & (rng.random(len(trials)) < 0.5)
        answer = np.where(half, gaze, answer)
        return trials.assign(answer_target=answer, timed_out=False)

    return simulate


def analyze_folder(folder: Path, output: Path) -> str:
    """``experiment analyze``: the analysis with every model observer fitted; a summary."""
    stimuli = stimulus_cues(folder)
    result = analysis.analyze(folder, output, observers=predictors(stimuli))
    atomic_write_csv(output / "cue_geometry.csv", cue_geometry(stimuli))
    kind = "SIMULATED participants" if result.study.simulated else "participants"
    n = result.study.answered()["participant"].nunique()
    return f"analysis of {n} {kind} written to {output} (analysis.md)"


def parse_sizes(participants_text: str, repetitions: int) -> list[int]:
    """``experiment power``'s ``--participants`` (``"4,8,12"``) and ``--repetitions``,
    checked."""
    try:
        sizes = [int(w) for w in str(participants_text).split(",")]
    except ValueError:
        raise InputError(f"--participants {participants_text!r}: give whole numbers, e.g. "
                         "4,8,12") from None
    if not sizes or min(sizes) < 2 or max(sizes) > 500:
        raise InputError(f"--participants {participants_text!r}: each from 2 to 500")
    if not 1 <= repetitions <= 10000:
        raise InputError(f"--repetitions {repetitions}: give 1 to 10000")
    return sizes


def power_study(folder: Path, output: Path, model: observers.ObserverModel,
                participants: str | Sequence[int], repetitions: int, hypothesis: str,
                seed: int) -> str:
    """``experiment power``: power per number of participants (``"4,8"`` or a list), and the
    false-positive rate of the same test on :func:`null_simulator`'s studies, written to
    ``output``."""
    sizes = (parse_sizes(participants, repetitions) if isinstance(participants, str)
             else list(participants))
    stimuli = stimulus_cues(folder)
    test = power.h1_test if hypothesis == "H1" else power.h2_test
    curve = power.power_curve(simulator(stimuli, model), test, sizes, repetitions, seed=seed)
    null_n = max(sizes)
    false_positive = power.false_positive_rate(null_simulator(stimuli), test, null_n,
                                               repetitions, seed=seed + 1).iloc[0].to_dict()
    needed = power.participants_for_power(curve, 0.8)
    record = {"kind": "experiment-power", "simulated": True, "hypothesis": hypothesis,
              "model": model.record(), "seed": seed, "repetitions": repetitions,
              "participants_for_80_percent": needed,
              "false_positive": _jsonable(false_positive), "provenance": provenance()}
    atomic_write_csv(output / "power.csv", curve)
    atomic_write_json(output / "power.json", record)
    atomic_savefig(output / "power.png", _power_figure(curve, hypothesis, model))
    atomic_write_text(output / "power.md", _power_markdown(curve, record))
    return (f"{hypothesis}: 80 % power at {needed if needed else 'more than ' + str(max(sizes))}"
            f" participants (simulated, {model.label()}); false-positive rate "
            f"{_rate(false_positive)} at {null_n} participants; written to {output}")


def _jsonable(value: object) -> object:
    if isinstance(value, Mapping):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def _rate(value: object) -> str:
    if isinstance(value, Mapping):
        rate = value.get("rate", value.get("false_positive_rate"))
        low, high = value.get("ci_low"), value.get("ci_high")
        if rate is not None and low is not None:
            return f"{float(rate):.3f} [{float(low):.3f}, {float(high):.3f}]"  # type: ignore[arg-type]
        return str(rate)
    return f"{float(value):.3f}"  # type: ignore[arg-type]


def _power_figure(curve: pd.DataFrame, hypothesis: str, model: observers.ObserverModel):  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.errorbar(curve["participants"], curve["power"],
                yerr=[curve["power"] - curve["power_ci_low"],
                      curve["power_ci_high"] - curve["power"]], marker="o", capsize=3)
    ax.axhline(0.8, color="grey", linestyle="--", linewidth=1)
    ax.text(curve["participants"].min(), 0.81, "80 %", color="grey", va="bottom")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("participants")
    ax.set_ylabel("power (share of significant studies)")
    ax.set_title(f"{hypothesis}, SIMULATED studies\n{model.label()}", fontsize=8)
    return fig


def _power_markdown(curve: pd.DataFrame, record: Mapping) -> str:
    lines = ["# Power by simulation (SIMULATED participants, not human data)", "",
             f"Hypothesis {record['hypothesis']}; model: {record['model']['label']}; "
             f"{record['repetitions']} simulated studies per size; seed {record['seed']}.", "",
             "| participants | power | 95 % CI |", "|---|---|---|"]
    for _, r in curve.iterrows():
        lines.append(f"| {int(r['participants'])} | {r['power']:.3f} | "
                     f"[{r['power_ci_low']:.3f}, {r['power_ci_high']:.3f}] |")
    lines += ["", f"Participants for 80 % power: {record['participants_for_80_percent']}.",
              f"False-positive rate of the same test on null studies: "
              f"{_rate(record['false_positive'])}.", "", "![power](power.png)", ""]
    return "\n".join(lines)


def compare_methods(folders: Mapping[str, Path]) -> pd.DataFrame:
    """Methods compared by the same (simulated) participants: ``{method: analysed folder}``,
    each a design of the same seed and simulation seed but another ``--method``, so each
    participant's noise draws are the same under every method (common random numbers) and
    the comparison is paired by participant.

    Returns:
        One row per (cell, method): hit rate with its Wilson 95 % interval (from the folder's
        analysis), the pointing and position cues' median distance to the target [mm] (the
        noiseless geometry), and against the first method: the mean paired difference of the
        participants' hit rates and the Wilcoxon signed-rank p-value (two-sided).
    """
    from scipy import stats

    studies = {m: analysis.read_study(f) for m, f in folders.items()}
    geometry = {m: cue_geometry(stimulus_cues(f)) for m, f in folders.items()}

    def hits(study: analysis.Study) -> pd.DataFrame:
        return study.answered().assign(
            hit=lambda d: d["answer_target"].astype(int) == d["target"].astype(int))

    first = next(iter(studies))
    base = hits(studies[first])
    rows = []
    for method, study in studies.items():
        table = analysis.cell_table(study)
        answered = hits(study)
        for _, cell in table[table["level"] == "cell"].iterrows():
            name = cell["cell"]
            mine = answered[answered["cell"] == name].groupby("participant")["hit"].mean()
            theirs = base[base["cell"] == name].groupby("participant")["hit"].mean()
            paired = pd.concat([mine, theirs], axis=1, join="inner").dropna()
            difference = p_value = math.nan
            if method != first and len(paired) >= 2:
                d = paired.iloc[:, 0] - paired.iloc[:, 1]
                difference = float(d.mean())
                p_value = (1.0 if np.allclose(d, 0) else
                           float(stats.wilcoxon(paired.iloc[:, 0], paired.iloc[:, 1]).pvalue))
            g = geometry[method]
            condition = str(name).rstrip("0123456789")
            fraction = (float(str(name)[len(condition):]) / 100) if name != "G" else None
            part = g[(g["condition"] == condition) & ((g["fraction"].isna()) if fraction is None
                                                      else np.isclose(g["fraction"], fraction))]
            rows.append({"cell": name, "method": method, "hit_rate": cell["hit_rate"],
                         "hit_ci_low": cell["hit_ci_low"], "hit_ci_high": cell["hit_ci_high"],
                         "pointing_to_target_median_mm": float(
                             part["pointing_to_target_mm"].median()) if len(part) else math.nan,
                         "position_to_target_median_mm": float(
                             part["position_to_target_mm"].median()) if len(part) else math.nan,
                         "versus": first if method != first else "",
                         "paired_difference": difference, "wilcoxon_p": p_value,
                         "participants": len(paired) if method != first else len(mine),
                         "simulated": bool(study.simulated)})
    return pd.DataFrame(rows)
