"""Simulated participants: model observers that answer the trials from the same motions.

Each trial offers cues, each a point on the screen where it leads (mm, robot frame):

- ``gaze``: where NICO's line of sight (from between the eyes, head FK) meets the screen
  (conditions G, GP, I; the neutral head of P looks at no target and gives none);
- ``pointing``: where the finger's axis at the stop pose meets the screen (P, GP, I);
- ``position``: where the fingertip's motion, extrapolated in a straight line from its start
  through its stop point, meets the screen (P, GP, I).

The noise model, stated everywhere a simulation appears: a participant reads each cue with
an angular error, seen from their eyes (``viewpoint_mm``): the cue's point moves on the
screen by an isotropic Gaussian of standard deviation ``distance(eye, point) * tan(sigma)``
[mm]; the cues are combined by their precision (weights 1 / sd^2, an ideal observer); the
answer is the goal nearest to the combined point; with probability ``lapse`` the answer is a
goal drawn uniformly instead. Participants differ: each one's sigmas are multiplied by
``exp(N(0, participant_sd))``. The touched pixel is the answered target's pixel plus a
Gaussian scatter of ``touch_sd_mm``; the reaction time is log-normal (median
``reaction_median_s``, log-sd ``reaction_log_sd``); slower than the response window is a
timeout. Every draw comes from a generator seeded by (seed, participant, trial, attempt), so
a resumed run gives the answers an uninterrupted one would have.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot
from ikbench.experiment.design import stop_of
from ikbench.experiment.head import Head
from ikbench.experiment.layout import GoalSet

CUES = ("gaze", "pointing", "position")
#: The cues each condition offers.
CONDITION_CUES = {"G": ("gaze",), "P": ("pointing", "position"),
                  "GP": ("gaze", "pointing", "position"), "I": ("gaze", "pointing", "position")}
#: The model observers :func:`predict` knows: one cue each, or every cue the trial offers.
OBSERVERS = ("gaze", "pointing", "position", "combined")


@dataclass(frozen=True)
class ObserverModel:
    """A simulated participant's parameters (see the module doc).

    Attributes:
        noise_deg: angular sd [deg] of each cue (``gaze``, ``pointing``, ``position``).
        lapse: probability of a uniformly random answer.
        participant_sd: log-sd of the per-participant multiplier of the sigmas.
        touch_sd_mm: scatter of the touch around the answered target [mm].
        reaction_median_s, reaction_log_sd: the log-normal reaction time.
        response_window_s: a slower answer is a timeout [s].
    """

    noise_deg: Mapping[str, float] = field(
        default_factory=lambda: {"gaze": 3.0, "pointing": 6.0, "position": 6.0})
    lapse: float = 0.02
    participant_sd: float = 0.2
    touch_sd_mm: float = 3.0
    reaction_median_s: float = 0.9
    reaction_log_sd: float = 0.35
    response_window_s: float = 2.0

    def validate(self) -> None:
        for cue in CUES:
            if cue not in self.noise_deg:
                raise InputError(f"--noise-deg: give {cue}=SIGMA too (cues: {', '.join(CUES)})")
        for cue, sigma in self.noise_deg.items():
            if cue not in CUES:
                raise InputError(f"--noise-deg: {cue!r} is not a cue; cues: {', '.join(CUES)}")
            if not (math.isfinite(sigma) and 0 < sigma <= 90):
                raise InputError(f"--noise-deg {cue}={sigma}: give degrees in (0, 90]")
        if not 0 <= self.lapse <= 1:
            raise InputError(f"--lapse {self.lapse}: give a probability in [0, 1]")
        for name, value in (("--participant-sd", self.participant_sd),
                            ("--touch-sd", self.touch_sd_mm)):
            if not (math.isfinite(value) and 0 <= value <= 1000):
                raise InputError(f"{name} {value}: give a number >= 0")

    def label(self) -> str:
        """The model in one line, as responses.csv's ``observer`` column states it."""
        noise = ",".join(f"{c}={self.noise_deg[c]:g}" for c in CUES)
        return (f"ideal-combination noise_deg[{noise}] lapse={self.lapse:g} "
                f"participant_sd={self.participant_sd:g}")

    def record(self) -> dict:
        return {**asdict(self), "noise_deg": dict(self.noise_deg), "label": self.label()}


def parse_noise(text: str) -> dict[str, float]:
    """``"gaze=3,pointing=6,position=6"`` -> a dict, checked."""
    out = {}
    for item in str(text).split(","):
        name, _, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise InputError(f"--noise-deg: {item!r} is not CUE=DEGREES (cues: "
                             f"{', '.join(CUES)})") from None
    return out


def cue_points(trial: Mapping, robot: Robot, head: Head, goals: GoalSet,
               poses: np.ndarray | None) -> dict[str, np.ndarray]:
    """The screen point [mm] of each cue the trial offers (NaN where a ray misses)."""
    condition = str(trial["condition"])
    out: dict[str, np.ndarray] = {}
    screen = goals.screen
    nan = np.full(3, np.nan)
    if "gaze" in CONDITION_CUES[condition]:
        pose = np.array([trial["head_z_motor_deg"], trial["head_y_motor_deg"]], float)
        out["gaze"] = screen.ray_hit_mm(head.eye_point_mm(pose), head.gaze_direction(pose))
    if condition != "G" and poses is not None:
        stop, _, point = stop_of(robot, poses, float(trial["fraction"]))
        fk = robot.fk(stop[None])
        out["pointing"] = screen.ray_hit_mm(fk.point_mm[0], fk.direction[0])
        start = robot.fk(poses[:1]).point_mm[0]
        motion = point - start
        out["position"] = (screen.ray_hit_mm(point, motion) if np.linalg.norm(motion) > 1e-9
                           else nan)
    return out


def _sd_mm(point: np.ndarray, viewpoint: np.ndarray, sigma_deg: float) -> float:
    return float(np.linalg.norm(point - viewpoint) * math.tan(math.radians(sigma_deg)))


def combine(cues: Mapping[str, np.ndarray], sds: Mapping[str, float],
            noise: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The precision-weighted mean of the noisy cue points (None: no usable cue)."""
    points, weights = [], []
    for cue, point in cues.items():
        if not np.all(np.isfinite(point)):
            continue
        points.append(point + noise[cue] * sds[cue])
        weights.append(1.0 / sds[cue] ** 2)
    if not points:
        return None
    w = np.asarray(weights)
    return (np.asarray(points) * w[:, None]).sum(0) / w.sum()


def participant_scale(model: ObserverModel, seed: int, participant: int) -> float:
    """This participant's multiplier of every sigma."""
    rng = np.random.default_rng([seed, participant, 0, 0])
    return float(math.exp(rng.normal(0.0, model.participant_sd)))


def answer(trial: Mapping, cues: Mapping[str, np.ndarray], goals: GoalSet,
           model: ObserverModel, seed: int, attempt: int) -> dict:
    """A simulated participant's response to one trial (the responses.csv figures)."""
    participant = int(trial["participant"])
    rng = np.random.default_rng([seed, participant, int(trial["trial"]), attempt])
    scale = participant_scale(model, seed, participant)
    sds = {c: _sd_mm(p, goals.viewpoint_mm, model.noise_deg[c] * scale)
           for c, p in cues.items() if np.all(np.isfinite(p))}
    screen = goals.screen
    noise = {c: rng.normal(size=2) @ np.stack([screen.u, screen.v]) for c in CUES}
    combined = combine({c: cues[c] for c in sds}, sds, noise)
    lapse = rng.random() < model.lapse
    uniform = int(rng.integers(len(goals.ids)))
    index = uniform if (lapse or combined is None) else int(goals.nearest(combined))
    touch_mm = goals.points_mm[index] + model.touch_sd_mm * (
        rng.normal(size=2) @ np.stack([screen.u, screen.v]))
    reaction = float(model.reaction_median_s * math.exp(rng.normal(0.0, model.reaction_log_sd)))
    if reaction > model.response_window_s:
        return {"answer_target": None, "touch_px": None, "reaction_s": None, "timed_out": True}
    return {"answer_target": goals.ids[index], "touch_px": screen.mm_to_px(touch_mm),
            "reaction_s": round(reaction, 4), "timed_out": False}


def predict(cues: Sequence[Mapping[str, np.ndarray]], conditions: Sequence[str], goals: GoalSet,
            observer: str, sigma_deg: float, lapse: float = 0.02, draws: int = 256,
            seed: int = 0) -> np.ndarray:
    """Each goal's probability (n_trials, n_goals) of being answered, by one model observer.

    ``gaze``, ``pointing`` and ``position`` read only their cue (a trial without it is a
    uniform guess); ``combined`` reads every cue its condition offers, all with ``sigma_deg``.
    Monte Carlo with ``draws`` draws per trial from one fixed seed (common random numbers, so
    the likelihood is smooth enough in sigma to maximise).
    """
    if observer not in OBSERVERS:
        raise InputError(f"observer {observer!r}: one of {', '.join(OBSERVERS)}")
    k = len(goals.ids)
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(draws, len(CUES), 2))
    basis = np.stack([goals.screen.u, goals.screen.v])          # (2, 3)
    out = np.full((len(cues), k), 1.0 / k)
    for i, (trial_cues, condition) in enumerate(zip(cues, conditions)):
        used = [c for c in (CUES if observer == "combined" else (observer,))
                if c in CONDITION_CUES[condition] and c in trial_cues
                and np.all(np.isfinite(trial_cues[c]))]
        if not used:
            continue
        points = np.zeros((draws, 3))
        total = 0.0
        for j, cue in enumerate(CUES):
            if cue not in used:
                continue
            sd = _sd_mm(trial_cues[cue], goals.viewpoint_mm, sigma_deg)
            points += (trial_cues[cue] + (normals[:, j] @ basis) * sd) / sd ** 2
            total += 1.0 / sd ** 2
        chosen = goals.nearest(points / total)
        counts = np.bincount(chosen, minlength=k) / draws
        out[i] = (1 - lapse) * counts + lapse / k
    return out
